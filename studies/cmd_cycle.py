"""``hingelab cycle``: the hysteresis cycle of a hinge, its loss factor and its files."""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

from cad.errors import ParameterError
from studies.args import add_geometry_arguments, settings_from_args, with_option
from studies.pipeline import dumps


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``cycle`` subcommand."""
    from fe.hinge.protocol import DEFAULT_MU

    p = sub.add_parser("cycle", help="run the 0 → +Fg → −Fg → +Fg cycle; write loop, η, fields")
    add_geometry_arguments(p)
    p.add_argument(
        "--model",
        type=Path,
        default=None,
        metavar="MODEL.toml",
        help="run the model a model file describes (geometry, mesh, materials, μ, protocol)",
    )
    p.add_argument(
        "--amplitude",
        type=float,
        default=None,
        metavar="N",
        help="force amplitude Fg [N] (default 400)",
    )
    p.add_argument(
        "--mu",
        type=float,
        default=None,
        metavar="X",
        help=f"pin-hole friction coefficient (default {DEFAULT_MU}; the paper gives none)",
    )
    p.add_argument(
        "--increments",
        type=int,
        default=None,
        metavar="N",
        help="increments per half cycle (default 20)",
    )
    p.add_argument(
        "--cycles",
        type=int,
        default=None,
        metavar="N",
        help="closed loops after the first loading (default 1)",
    )
    p.add_argument(
        "--ball-model",
        choices=("hertz", "full"),
        default=None,
        help="bearing hinge: balls as Hertz springs between meshed rings (hertz, default) "
        "or meshed with friction (full: one meshed ball and its raceway blocks, condensed "
        "once and used for every ball; docs/bearing_model.md)",
    )
    p.add_argument(
        "--interfaces",
        choices=("bonded", "contact"),
        default=None,
        help="bearing hinge: rings, pin, clevis and plate tied (bonded, default) or their six "
        "fits as Coulomb contacts at zero clearance (contact, the paper's ABAQUS model)",
    )
    p.add_argument(
        "--frames",
        type=int,
        default=4,
        metavar="K",
        help="write every K-th increment to the ParaView series (0: none; default 4)",
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab cycle``."""
    from fe.bearing.fits import FitSystem
    from fe.bearing.system import BearingSystem
    from fe.hinge.report import write_loop_csv, write_loop_png, write_time_series
    from model.service import ModelService
    from model.spec import DesignPoint

    t0 = time.perf_counter()
    if args.frames < 0:
        raise ParameterError(f"--frames must be ≥ 0, got {args.frames}")
    try:
        spec = _spec_from_args(args)
    except ParameterError as err:
        raise with_option(err) from err
    point = DesignPoint(amplitude_n=spec.cycle.amplitude_n, clearance_mm=_clearance(spec))
    service = ModelService(geometry_dir=lambda _c: args.out)
    prepared = service.prepare(spec, point.clearance_mm)
    bar = _progress_bar(args)
    # effects act on the condensed system; the progress bar is not threaded through them
    result = service.run_point(
        spec, point, progress=None if bar is None or spec.effects else bar.update_to
    )
    if bar is not None:
        bar.close()
    system, meshed, settings = prepared.system, prepared.meshed, result.settings
    files = {k: str(v) for k, v in meshed.files.items()}
    files["loop_csv"] = str(write_loop_csv(result, args.out / "loop.csv"))
    bearing = isinstance(system, BearingSystem | FitSystem)
    if bearing:
        what = f"bearing hinge, Fp = {getattr(spec.hinge, 'preload_n', 0.0):g} N"
    else:
        what = f"general hinge, Δr = {point.clearance_mm:g} mm"
    files["loop_png"] = str(
        write_loop_png(
            result,
            args.out / "loop.png",
            title=f"{what}, Fg = {settings.amplitude_n:g} N"
            + ("" if isinstance(system, BearingSystem) else f", μ = {settings.mu:g}"),
        )
    )
    if args.frames:
        if isinstance(system, FitSystem):
            from fe.bearing.report import write_fit_series

            pvd = write_fit_series(system, result, args.out / "fields", every=args.frames)
        elif isinstance(system, BearingSystem):
            from fe.bearing.report import write_bearing_series

            pvd = write_bearing_series(system, result, args.out / "fields", every=args.frames)
        else:
            pvd = write_time_series(system, result, args.out / "fields", every=args.frames)
        files["pvd"] = str(pvd)
    summary = _summary(result, system, meshed, files, time.perf_counter() - t0)
    if isinstance(system, BearingSystem):
        summary |= _bearing_summary(result, system, spec)
    elif isinstance(system, FitSystem):
        summary |= _fit_summary(result, system, spec)
    (args.out / "result.json").write_text(dumps(summary))
    if args.json:
        print(dumps(summary))
    elif isinstance(system, FitSystem):
        print(
            f"η = {summary['eta']:.5f}   W_cycle = {summary['W_cycle_Nmm']:.5g} N·mm   "
            f"δ(+Fg) = {summary['disp_at_peak_mm'] * 1e3:.3f} µm   energy balance "
            f"{summary['energy_balance_rel_err']:.1e}   (bearing hinge, frictional fits)   "
            f"{summary['wall_s']:.1f} s"
        )
        print(f"results in {args.out}/ (loop.csv, loop.png, result.json, fields/, mesh files)")
    elif isinstance(system, BearingSystem):
        pre = summary["preload_step"]
        what = (
            "meshed balls: ball-patch micro-slip only"
            if "ball_friction_work_loop_Nmm" in summary
            else "nothing dissipates in this model"
        )
        print(
            f"η = {summary['eta']:.2e}   W_cycle = {summary['W_cycle_Nmm']:.3g} N·mm "
            f"(U_max {summary['U_max_Nmm']:.4g} N·mm; {what})   "
            f"δ(+Fg) = {summary['disp_at_peak_mm'] * 1e3:.3f} µm   preload: plate travel "
            f"{pre['plate_travel_mm'] * 1e3:.2f} µm, contact angle {pre['contact_angle_mean_deg']:.2f}°   "
            f"{summary['wall_s']:.1f} s"
        )
        print(f"results in {args.out}/ (loop.csv, loop.png, result.json with ball loads, fields/)")
    else:
        print(
            f"η = {summary['eta']:.5f}   W_cycle = {summary['W_cycle_Nmm']:.5g} N·mm   "
            f"δ(+Fg) = {summary['disp_at_peak_mm'] * 1e3:.3f} µm   free play = {summary['free_play_mm'] * 1e3:.0f} µm "
            f"(removed)   energy balance {summary['energy_balance_rel_err']:.1e}   {summary['wall_s']:.1f} s"
        )
        print(
            f"results in {args.out}/ (loop.csv, loop.png, result.json, fields/cycle.pvd, mesh files)"
        )
    return 0


def _clearance(spec: Any) -> float:
    return float(getattr(spec.hinge, "clearance_mm", 0.0))


def _spec_from_args(args: argparse.Namespace) -> Any:
    """Return the ModelSpec of a model file or of the options, with the overrides applied."""
    from cad.general import GeneralHingeParams
    from fe.hinge.protocol import CycleSettings
    from model.service import check_spec
    from model.spec import ModelSpec

    if args.model is None and args.hinge == "bearing":
        spec = _bearing_spec(args)
    elif args.model is None:
        for option, value in (("--ball-model", args.ball_model), ("--interfaces", args.interfaces)):
            if value is not None:
                raise ParameterError(
                    f"{option} applies to the bearing hinge only, got {option} {value} "
                    "with --hinge general"
                )
        if args.preload is not None:
            raise ParameterError(
                f"--preload applies to the bearing hinge only, got --preload {args.preload}"
            )
        hinge = GeneralHingeParams(clearance_mm=0.0 if args.clearance is None else args.clearance)
        spec = ModelSpec("general", hinge, settings_from_args(args), CycleSettings())
    else:
        from model.file import read_model

        given = [
            f"--{n.replace('_', '-')}"
            for n in ("clearance", "preload", "size", "contact_size", "ball_model", "interfaces")
            if getattr(args, n) is not None
        ]
        if given or args.refinement != 0 or args.hinge != "general":
            raise ParameterError(
                f"--model describes the geometry and mesh; drop {given or ['--hinge/--refinement']} "
                "(only --amplitude, --mu, --increments, --cycles may override it)"
            )
        spec = read_model(args.model)
    check_spec(spec)
    overrides = {
        k: v
        for k, v in {
            "amplitude_n": args.amplitude,
            "mu": args.mu,
            "increments_per_stage": args.increments,
            "clearance_increments": args.increments,
            "n_cycles": args.cycles,
        }.items()
        if v is not None
    }
    try:
        cycle = dataclasses.replace(spec.cycle, **overrides)
    except ParameterError as err:  # name the option the user typed, not only the field
        raise with_option(err) from err
    return dataclasses.replace(spec, cycle=cycle)


def _bearing_spec(args: argparse.Namespace) -> Any:
    """The bearing hinge's ModelSpec from the command-line options."""
    from cad.bearing import BallModel, BearingHingeParams, Interfaces
    from fe.hinge.protocol import CycleSettings
    from model.spec import ModelSpec

    if args.clearance is not None:
        raise ParameterError(
            f"--clearance: the bearing hinge has no clearance (its balls are preloaded), "
            f"got --clearance {args.clearance}; use --preload N"
        )
    kw: dict[str, Any] = {}
    if args.preload is not None:
        kw["preload_n"] = args.preload
    if args.ball_model is not None:
        kw["ball_model"] = BallModel(args.ball_model)
    if args.interfaces is not None:
        kw["interfaces"] = Interfaces(args.interfaces)
    try:
        hinge = BearingHingeParams(**kw)
    except ParameterError as err:
        raise with_option(err) from err
    # full balls are the one-ball rig (fe.bearing.ball_rig), not balls meshed in the hinge:
    # the structure is meshed as for hertz, so full − hertz is the ball model alone
    mesh = settings_from_args(args, balls=False)
    return ModelSpec("bearing", hinge, mesh, CycleSettings())


def _bearing_summary(result: Any, system: Any, spec: Any) -> dict[str, Any]:
    """What the bearing hinge adds to the cycle's JSON: preload, balls, model choices."""
    from fe.bearing.cycle import ball_state_of, elastic_energy
    from fe.bearing.report import ball_table

    pre = ball_state_of(system, result.preload_state)
    m = result.metrics()
    return {
        **_bearing_common(system, spec),
        "ball_hertz_constant_N_per_mm1.5": system.balls.k_n,
        "preload_step": {
            "plate_travel_mm": float(pre.alpha[2]),
            "axial_float_mm": float(pre.alpha[1]),
            "ball_load_mean_N": float(pre.load_n.mean()),
            "contact_angle_mean_deg": float(pre.angle_deg.mean()),
            "elastic_energy_Nmm": elastic_energy(system, pre),
            "dissipation_Nmm": 0.0,
        },
        "balls": ball_table(system, result),
        "energy_balance_abs_Nmm": abs(
            m["W_cycle_Nmm"] - m["elastic_energy_change_Nmm"] - m["friction_work_Nmm"]
        ),
        "energy_balance_note": "nothing can dissipate (bonded interfaces, free-rolling balls): "
        "W_cycle is the loop's quadrature error, compare energy_balance_abs_Nmm with U_max_Nmm",
    } | (_full_ball_notes(result) if spec.hinge.ball_model.value == "full" else {})


def _full_ball_notes(result: Any) -> dict[str, Any]:
    """What differs in the JSON of a cycle with meshed (``full``) balls."""
    fric = sum(i.friction_work for i in result.increments[result.last_loop().start :])
    return {
        "ball_friction_work_loop_Nmm": fric,
        "energy_balance_note": "friction (micro-slip in the meshed ball patches) and "
        "open/close work of all ball contacts against the trapezoidal loop area",
        "preload_note": "the pair is seated frictionless (dissipation 0 by that choice); the "
        "ball patches' friction history starts after the preload",
    }


def _bearing_common(system: Any, spec: Any) -> dict[str, Any]:
    """The model choices every bearing-hinge cycle JSON starts with."""
    return {
        "hinge": "bearing",
        "preload_N": spec.hinge.preload_n,
        "ball_model": spec.hinge.ball_model.value,
        "interfaces": spec.hinge.interfaces.value,
        "n_balls": system.n_balls,
    }


def _fit_summary(result: Any, system: Any, spec: Any) -> dict[str, Any]:
    """What the bearing hinge with frictional fits adds to the cycle's JSON."""
    from fe.bearing.report import fit_ball_table

    return {
        "balls": fit_ball_table(system, result),
        **_bearing_common(system, spec),
        "n_contact_points": system.n_points,
        "preload_step": {
            "dissipation_Nmm": 0.0,
            "note": "assembled frictionlessly: the fits' friction history starts after it",
        },
    }


def _progress_bar(args: argparse.Namespace) -> Any:
    if args.no_progress or (not sys.stderr.isatty() and args.json):
        return None
    from tqdm import tqdm

    class Bar(tqdm):  # type: ignore[misc]  # tqdm ships no type hints
        def update_to(self, done: int, total: int) -> None:
            self.total = total
            self.update(done - self.n)

    return Bar(desc="increments", unit="inc", file=sys.stderr, leave=False)


def _summary(
    result: Any, system: Any, meshed: Any, files: dict[str, str], wall: float
) -> dict[str, Any]:
    m = result.metrics()
    incs = result.increments
    return {
        **m,
        "delta_definition": "δ_max = (δ(+Fg) − δ(−Fg))/2 of the last loop, free play removed; "
        "δ is the grip displacement relative to the tang's fixed face",
        "amplitude_N": result.settings.amplitude_n,
        "mu": result.settings.mu,
        "clearance_mm": result.clearance_mm,
        "n_dof": system.n_dof,
        "n_hex": meshed.report.n_hex,
        "n_contact_pairs": len(result.configs[1].geo.slave)
        if result.configs
        else len(result.states[-1].p),
        "n_surface_pairs": len(system.mesh.pairs),
        "increments": [
            {
                "stage": i.stage,
                "force_N": i.force_n,
                "disp_mm": i.disp_mm,
                "iterations": i.iterations,
                "open": i.n_open,
                "stick": i.n_stick,
                "slip": i.n_slip,
            }
            for i in incs
        ],
        "total_iterations": sum(i.iterations for i in incs),
        "timings_s": {"mesh": meshed.timings_s["mesh"], **system.timings_s, **result.timings_s},
        "files": files,
        "wall_s": wall,
    }
