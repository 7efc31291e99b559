"""``hingelab mesh``: build a hinge, mesh it, write STEP, .msh, .vtu and a PNG."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from model.jsonio import dumps
from studies.cli.args import GEOMETRY_OPTIONS, add_geometry_arguments, settings_from_args
from studies.outputs import mesh_summary

FIELD_OPTIONS = GEOMETRY_OPTIONS
"""Field → the options that set it: ``main`` words a refusal in the option the user typed."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``mesh`` subcommand."""
    p = sub.add_parser("mesh", help="build and mesh a hinge; write STEP, .msh, .vtu, PNG")
    add_geometry_arguments(p)
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--no-picture", action="store_true", help="skip the PNG (faster)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab mesh``."""
    from fe.kinds import DEFAULT_KIND, hinge_kind
    from mesh.meshed import build_and_mesh
    from studies.options import params_with

    t0 = time.perf_counter()
    settings = settings_from_args(args, cycle=False)
    kind = hinge_kind(args.hinge or DEFAULT_KIND)
    options = {"clearance_mm": "--clearance", "preload_n": "--preload"}
    values = {"clearance_mm": args.clearance, "preload_n": args.preload}
    model = kind.cad(params_with(kind, values, options))
    meshed = build_and_mesh(model, settings, args.out, picture=not args.no_picture)
    summary = mesh_summary(meshed, time.perf_counter() - t0)
    if args.json:
        print(dumps(summary))
    else:
        r = meshed.report
        print(
            f"{model.kind} hinge: {r.n_hex} hexes, {r.n_nodes} nodes, min scaled Jacobian "
            f"{r.min_scaled_jacobian:.3f}, {summary['wall_s']:.1f} s"
        )
        for name, path in meshed.files.items():
            print(f"  {name:5s} {path}")
    return 0
