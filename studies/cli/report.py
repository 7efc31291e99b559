"""``hingelab report RESULTS_DIR --out report.html``: one self-contained HTML page.

The kind of folder (cycle, sweep, paper validation, rsm paper, compare, calibrate) is
recognised by its files (``studies.report.page``); the page embeds its figures and
style, so it can be mailed or archived alone, and links to the result files relative
to where it is written. An unknown folder exits 1 with one line naming the path and
the files expected.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``report`` subcommand."""
    p = sub.add_parser(
        "report",
        help="one self-contained HTML page for a result folder (cycle, sweep, compare, …)",
        description=__doc__.splitlines()[0] if __doc__ else None,
    )
    p.add_argument("results", type=Path, metavar="RESULTS_DIR", help="a result folder")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="report.html",
        help="the page to write (default RESULTS_DIR/report.html)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab report``."""
    from studies.report.page import write_report

    out = args.out if args.out is not None else args.results / "report.html"
    path = write_report(args.results, out)
    print(f"report: {path} ({path.stat().st_size / 1e6:.1f} MB)")
    return 0
