"""``hingelab sweep``: η over a clearance (or preload) × amplitude grid, traced and resumable."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cad.errors import ParameterError
from fe.cycle.protocol import DEFAULT_MU
from fe.kinds import DEFAULT_KIND, HingeKind, hinge_kind, kind_names
from model.jsonio import dumps
from studies.cli.args import GEOMETRY_OPTIONS, add_mesh_arguments, settings_from_args
from studies.cluster_options import add_cluster_arguments
from studies.options import params_with
from studies.sweep import SweepSettings, run_sweep


def _floats(name: str, text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError as err:
        raise ParameterError(f"{name} must be comma-separated numbers, got {text!r}") from err


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``sweep`` subcommand."""
    p = sub.add_parser(
        "sweep",
        help="run the cycle over a clearance (or preload) × amplitude grid (resumable, Dask)",
    )
    p.add_argument(
        "--hinge",
        choices=kind_names(),
        default=DEFAULT_KIND,
        help="a registered hinge kind; its design variable × amplitude is swept "
        "(general: clearance, bearing: preload; default general)",
    )
    p.add_argument(
        "--levels",
        default=None,
        metavar="LIST",
        help="levels of the kind's design variable (default: the kind's study levels)",
    )
    p.add_argument(
        "--clearance",
        default=None,
        metavar="LIST",
        help="clearances [mm] of the general hinge (its levels; default 0,0.1,0.2,0.3,0.4)",
    )
    p.add_argument(
        "--preload",
        default=None,
        metavar="LIST",
        help="axial preloads [N] of the bearing hinge (its levels; default 0,50,100,150,200)",
    )
    p.add_argument(
        "--interfaces",
        choices=("bonded", "contact"),
        default=None,
        help="bearing hinge: interfaces tied or frictional fits (default bonded)",
    )
    p.add_argument(
        "--amplitude",
        default="100,200,300,400,500",
        metavar="LIST",
        help="amplitudes [N] (default 100,200,300,400,500)",
    )
    p.add_argument(
        "--mu",
        type=float,
        default=DEFAULT_MU,
        metavar="X",
        help=f"friction coefficient (default {DEFAULT_MU})",
    )
    p.add_argument(
        "--increments",
        type=int,
        default=None,
        metavar="N",
        help="increments per half cycle (default 20 at zero clearance, 60 with clearance)",
    )
    add_cluster_arguments(p)
    add_mesh_arguments(p)
    p.add_argument(
        "--study",
        default=None,
        help="study name in the trace (default KIND_hinge, e.g. general_hinge)",
    )
    p.add_argument(
        "--out", type=Path, required=True, metavar="DIR", help="output folder (rerun to resume)"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


LEVEL_OPTIONS = {"--clearance": "clearance_mm", "--preload": "preload_n"}
"""Options that give the levels of a design variable by its name (``--levels`` for any)."""

FIELD_OPTIONS = {
    **GEOMETRY_OPTIONS,
    "clearance_mm": ("--levels", "--clearance"),
    "preload_n": ("--levels", "--preload"),
    "amplitude_n": ("--amplitude",),
    "mu": ("--mu",),
    "increments_per_stage": ("--increments",),
    "clearance_increments": ("--increments",),
}
"""Field → the options that set it: ``main`` words a refusal in the option the user typed."""


def _levels(args: argparse.Namespace, kind: HingeKind) -> tuple[float, ...] | None:
    """The levels given on the command line, checked to be the kind's design variable."""
    names = [v.name for v in kind.design_variables]
    given = {o: getattr(args, o[2:]) for o in LEVEL_OPTIONS if getattr(args, o[2:]) is not None}
    if args.levels is not None:
        given["--levels"] = args.levels
    for option, text in given.items():
        field = LEVEL_OPTIONS.get(option)
        if field is not None and field not in names:
            raise ParameterError(
                f"{option} is not a design variable of the {kind.title} (got {option} {text}); "
                f"its design variables: {', '.join(names) or 'none (amplitude only)'}"
            )
    if len(given) > 1:
        raise ParameterError(f"give the levels once, got {', '.join(given)}")
    if not given:
        return None
    option, text = next(iter(given.items()))
    return _floats(option, text)


def _settings(args: argparse.Namespace) -> SweepSettings:
    kind = hinge_kind(args.hinge)
    options = params_with(kind, {"interfaces": args.interfaces}, {"interfaces": "--interfaces"})
    hinge_options = tuple(
        (name, getattr(options, name)) for name in ("interfaces",) if args.interfaces is not None
    )
    return SweepSettings(
        levels=_levels(args, kind),
        amplitudes_n=_floats("--amplitude", args.amplitude),
        mu=args.mu,
        increments_per_stage=args.increments if args.increments is not None else 20,
        clearance_increments=args.increments if args.increments is not None else 60,
        mesh=settings_from_args(args),
        workers=args.workers,
        study=args.study or f"{kind.name}_hinge",
        scheduler=args.scheduler or None,
        hinge=kind.name,
        hinge_options=hinge_options,
    )


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab sweep``."""
    settings = _settings(args)

    def report(rec: dict[str, object]) -> None:
        if not args.json:
            p = rec["params"]
            eta = rec["results"].get("eta") if isinstance(rec["results"], dict) else None
            what = f"η = {eta:.5f}" if rec["status"] == "ok" else f"FAILED: {rec['error']}"
            print(f"  {p}: {what}", file=sys.stderr)

    outcome = run_sweep(settings, args.out, on_point=report)
    summary = {
        "ok": outcome.ok,
        "failed": outcome.failed,
        "skipped": outcome.skipped,
        "cached": outcome.cached,
        "trace": str(outcome.db),
        "table": str(outcome.table),
        "wall_s": outcome.wall_s,
        "increments_check": outcome.check,
    }
    for line in outcome.warnings:  # the doubled-increments check (studies.convergence)
        print(f"hingelab sweep: warning: {line}", file=sys.stderr)
    if args.json:
        print(dumps(summary))
    elif outcome.ok + outcome.cached + outcome.skipped == 0:
        print(
            f"no point succeeded ({outcome.failed} failed); see the errors above", file=sys.stderr
        )
    else:
        print(
            f"{outcome.ok} points computed, {outcome.cached} read back from results/, "
            f"{outcome.failed} failed, {outcome.skipped} already done "
            f"({outcome.wall_s:.0f} s). Trace: {outcome.db}"
        )
        columns = [v.column for v in hinge_kind(settings.hinge).design_variables]
        x = ",".join([*columns, "amplitude_N"])
        print(
            f"next: hingelab rsm fit {outcome.table} --x {x} --y eta --degree 4 "
            f"--trace {outcome.db}"
        )
    return 0 if outcome.failed == 0 else 1
