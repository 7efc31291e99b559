"""``hingelab trace DB POINT``: walk one sample point's chain back to its files.

Prints design parameters → STEP file → mesh (and its picture) → solver settings
and convergence → loop file (and its picture) → results, checking that every
recorded file still exists with the content it had when it was recorded. A
missing or changed file (its SHA-256 no longer the recorded one) is reported, never
opened; the exit status is then 1. ``hingelab trace --schema`` prints the database schema.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from cad.errors import ParameterError
from model.jsonio import dumps
from rsm import trace


def schema_text() -> str:
    """The schema of a trace database, as ``rsm.trace`` documents it."""
    doc = trace.__doc__ or ""
    start = doc.index("Schema (")
    end = doc.index("Example:", start)
    return doc[start:end].rstrip() + (
        "\n\nQuery it with any SQLite client, e.g.\n"
        '    sqlite3 trace.sqlite "SELECT p.id, r.value FROM points p JOIN results r '
        "ON r.point_id = p.id WHERE r.name = 'eta'\""
    )


def register(subparsers: Any) -> None:
    """Add the ``trace`` subcommand."""
    p = subparsers.add_parser(
        "trace",
        help="show how one sample point was produced (files, mesh, solver, loop, results)",
        description=__doc__.splitlines()[0] if __doc__ else None,
    )
    p.add_argument(
        "db", type=Path, nargs="?", help="trace database (trace.sqlite next to the study results)"
    )
    p.add_argument(
        "point", type=int, nargs="?", help="point id (as in 'point 17' of an rsm fit report)"
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.add_argument(
        "--schema", action="store_true", help="print the trace database's SQLite schema and exit"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the chain; return 1 if any of its files is missing or changed."""
    if args.schema:
        print(schema_text())
        return 0
    if args.db is None or args.point is None:
        raise ParameterError("give a trace database and a point id: hingelab trace DB POINT")
    t = trace.walk(args.db, args.point)
    if args.json:
        print(dumps(trace.trace_as_dict(t)))
    else:
        print(trace.format_trace(t))
    bad = [a for a in t.artifacts if a.state is not trace.ArtifactState.OK]
    for a in bad:
        print(f"hingelab trace: {a.message}", file=sys.stderr)
    return 1 if bad else 0
