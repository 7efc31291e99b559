"""``hingelab paper``: the paper's study with our FE, both hinges, beside the paper's tables.

``hingelab paper --out DIR [--quick] [--interfaces contact|bonded] [--mu X] [--workers N]``
runs ``studies.paper.study`` and prints where its ``report.md`` is. Rerunning on the same
folder resumes both sweeps (finished points are read back, not recomputed).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from model.jsonio import dumps

FIELD_OPTIONS = {"mu": ("--mu",), "points": ("--points",)}
"""Field → the options that set it: ``main`` words a refusal in the option the user typed."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``paper`` subcommand."""
    p = sub.add_parser(
        "paper", help="the paper's study with our FE: both hinges, surfaces, report.md"
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument(
        "--quick", action="store_true", help="coarse meshes, 3 × 3 grids (minutes, not an hour)"
    )
    p.add_argument(
        "--interfaces",
        choices=("contact", "bonded"),
        default="contact",
        help="the modified hinge's interfaces: frictional fits as the paper's ABAQUS model "
        "(contact, default) or tied (bonded)",
    )
    p.add_argument(
        "--mu", type=float, default=0.2, metavar="X", help="friction coefficient (default 0.2)"
    )
    p.add_argument("--workers", type=int, default=1, metavar="N", help="Dask workers (default 1)")
    p.add_argument(
        "--points",
        type=int,
        default=0,
        metavar="K",
        help="smoke run: K amplitudes per hinge (default 0: every point)",
    )
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab paper``."""
    from studies.paper.study import PaperStudy, run_paper

    study = PaperStudy(
        quick=args.quick,
        interfaces=args.interfaces,
        mu=args.mu,
        workers=args.workers,
        points=args.points,
    )
    report = run_paper(study, args.out)
    if args.json:
        print(dumps(report))
    else:
        failed = sum(s["failed"] for s in report["sweeps"].values())
        print(
            f"report: {args.out / 'report.md'} ({report['wall_s']:.0f} s, {failed} points failed)"
        )
    failed = sum(s["failed"] for s in report["sweeps"].values())
    return 0 if failed == 0 else 1
