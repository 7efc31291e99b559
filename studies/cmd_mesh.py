"""``hingelab mesh``: build a hinge, mesh it, write STEP, .msh, .vtu and a PNG."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from mesh.settings import MeshSettings
from studies.pipeline import HINGES, build_and_mesh, dumps, make_model, mesh_summary


def add_geometry_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options that choose a hinge and its mesh (shared with ``cycle``)."""
    p.add_argument(
        "--hinge", choices=HINGES, default="general", help="hinge kind (default: general)"
    )
    p.add_argument(
        "--clearance",
        type=float,
        default=None,
        metavar="MM",
        help="radial pin-hole clearance of the general hinge [mm] (default 0)",
    )
    p.add_argument(
        "--preload",
        type=float,
        default=None,
        metavar="N",
        help="axial bearing preload of the bearing hinge [N] (default 0)",
    )
    add_mesh_arguments(p)


def add_mesh_arguments(p: argparse.ArgumentParser) -> None:
    """Add the mesh-size options (shared with ``cycle`` and ``sweep``)."""
    p.add_argument(
        "--refinement", type=int, default=0, metavar="K", help="mesh level; each halves sizes (0-4)"
    )
    p.add_argument(
        "--size", type=float, default=None, metavar="MM", help="global element size at level 0 [mm]"
    )
    p.add_argument(
        "--contact-size",
        type=float,
        default=None,
        metavar="MM",
        help="master contact-surface element size at level 0 [mm]",
    )


def settings_from_args(args: argparse.Namespace) -> MeshSettings:
    """Return mesh settings from the parsed options."""
    kw: dict[str, float | int] = {"refinement": args.refinement}
    if args.size is not None:
        kw["size_mm"] = args.size
    if args.contact_size is not None:
        kw["contact_size_mm"] = args.contact_size
    return MeshSettings.for_hinge(args.hinge, **kw)


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
    t0 = time.perf_counter()
    settings = settings_from_args(args)
    model = make_model(args.hinge, clearance_mm=args.clearance, preload_n=args.preload)
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
