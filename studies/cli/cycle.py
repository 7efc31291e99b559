"""``hingelab cycle``: the hysteresis cycle of a hinge, its loss factor and its files."""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

from cad.errors import ParameterError
from model.jsonio import dumps
from studies.cli.args import GEOMETRY_OPTIONS, add_geometry_arguments, settings_from_args
from studies.outputs import check_writable_dir


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``cycle`` subcommand."""
    from fe.cycle.protocol import DEFAULT_MU

    p = sub.add_parser("cycle", help="run the 0 → +Fg → −Fg → +Fg cycle; write loop, η, fields")
    add_geometry_arguments(p)
    p.add_argument(
        "--model",
        type=Path,
        default=None,
        metavar="MODEL.toml",
        help="run the model a model file describes (geometry, mesh, materials, μ, protocol; "
        "default: the options below)",
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


RUN_FILES = ("loop.csv", "loop.png", "result.json", "loop_partial.csv")
"""The files of one run in ``--out``; a new run removes an earlier run's before it writes."""


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab cycle``.

    The cycle is not stored between runs: an interrupted or failed cycle is recomputed by
    the next run (there is no state to resume from; a sweep keeps finished points). So
    the folder never mixes runs: before this run writes anything, an earlier run's
    files (``RUN_FILES``) are removed; a failed cycle leaves ``loop_partial.csv`` (its
    converged increments), a complete one ``loop.csv``, ``loop.png``, the fields and
    ``result.json``, written last; if the writing is interrupted, the files written so
    far are removed again.
    """
    from cad.errors import ConvergenceError
    from fe.cycle.loop_files import write_loop_csv
    from fe.cycle.result import CycleResult
    from model.service import ModelService
    from model.spec import DesignPoint

    t0 = time.perf_counter()
    if args.frames < 0:
        raise ParameterError(f"--frames must be ≥ 0, got {args.frames}")
    spec = _spec_from_args(args)
    check_writable_dir(args.out, "--out")  # before any work; a kind without a mesh writes none
    point = DesignPoint(spec.cycle.amplitude_n)  # the model's own design values
    service = ModelService(geometry_dir=lambda _label: args.out)
    try:
        prepared = service.prepare(spec, point)
        bar = _progress_bar(args)
        # effects act on the condensed system; the progress bar is not threaded through them
        try:
            result = service.run_point(
                spec, point, progress=None if bar is None or spec.effects else bar.update_to
            )
        finally:
            if bar is not None:
                bar.close()
    except ConvergenceError as err:
        if isinstance(err.partial, CycleResult) and err.partial.increments:
            _clear(args.out)
            path = write_loop_csv(err.partial, args.out / "loop_partial.csv")
            n = len(err.partial.increments)
            print(f"hingelab cycle: the {n} converged increments are in {path}", file=sys.stderr)
        raise
    except KeyboardInterrupt:
        return _interrupted(
            "nothing of the cycle is kept (it is not stored between runs); "
            "rerun the same command to recompute it"
        )
    written: list[Path] = []
    try:
        summary = _write_files(args, spec, point, prepared, result, written, t0)
    except BaseException as err:  # interrupted or failed: no loop.csv without result.json
        for path in written:
            path.unlink(missing_ok=True)
        if isinstance(err, KeyboardInterrupt):
            return _interrupted(
                "the cycle had finished, but its files were not all written and are removed "
                "(it is not stored between runs); rerun the same command to recompute it"
            )
        raise
    for line in summary["warnings"]:
        print(f"hingelab cycle: warning: {line}", file=sys.stderr)
    if args.json:
        print(dumps(summary))
    else:
        kind = spec.hinge_kind
        cut = f"   {summary['cutbacks']} cut-backs" if summary["cutbacks"] else ""
        print(f"{kind.headline(summary)}{cut}   {summary['wall_s']:.1f} s")
        names = ["loop.csv", "loop.png", "result.json"]
        names += ["fields/"] if "pvd" in summary["files"] else []
        names += ["mesh files"] if prepared.meshed is not None else []
        print(f"results in {args.out}/ ({', '.join(names)})")
    return 0


def _interrupted(what: str) -> int:
    """Say what an interrupted ``cycle`` kept, on stderr; return the exit status 130."""
    print(f"hingelab cycle: interrupted; {what}", file=sys.stderr)
    return 130


def _clear(out: Path) -> None:
    """Remove an earlier run's files (``RUN_FILES``) from ``out``."""
    for name in RUN_FILES:
        (out / name).unlink(missing_ok=True)


def _write_files(
    args: argparse.Namespace,
    spec: Any,
    point: Any,
    prepared: Any,
    result: Any,
    written: list[Path],
    t0: float,
) -> dict[str, Any]:
    """Write the loop, its plot, the fields and result.json (last); return the summary.

    Every file is appended to ``written`` as it is made, so the caller can remove them
    if the writing is interrupted.
    """
    from fe.cycle.loop_files import write_loop_csv, write_loop_png
    from model.code import code_version
    from model.spec import describe_point, hinge_at, resolve_structural
    from studies.convergence import warning_lines

    kind = spec.hinge_kind
    _clear(args.out)
    meshed = prepared.meshed
    files = {} if meshed is None else {k: str(v) for k, v in meshed.files.items()}
    written.append(write_loop_csv(result, args.out / "loop.csv"))
    files["loop_csv"] = str(written[-1])
    title = describe_point(spec, point)
    written.append(write_loop_png(result, args.out / "loop.png", title=title))
    files["loop_png"] = str(written[-1])
    t_fields = time.perf_counter()
    if args.frames:
        pvd = kind.write_fields(prepared.built, result, args.out / "fields", args.frames)
        if pvd is not None:
            files["pvd"] = str(pvd)
    t_fields = time.perf_counter() - t_fields
    summary = _summary(result, meshed, files)
    # the parameters the cycle really ran (interface_friction: the fits are contacts)
    own = kind.summary(prepared.built, hinge_at(resolve_structural(spec), point), result)
    timings = {**summary.pop("timings_s"), **own.pop("timings_s", {}), **result.timings_s}
    if args.frames:
        timings["fields"] = t_fields  # the ParaView series (recovery, stress, .vtu files)
    summary |= own | {"timings_s": timings, "wall_s": time.perf_counter() - t0}
    summary |= {"cutbacks": result.n_cutbacks, "warnings": warning_lines(result)}
    summary["code"] = code_version().short()  # which code computed it (model.code)
    written.append(args.out / "result.json")
    written[-1].write_text(dumps(summary))
    return summary


HINGE_OPTIONS = {
    "clearance_mm": "--clearance",
    "preload_n": "--preload",
    "ball_model": "--ball-model",
    "interfaces": "--interfaces",
}
"""Hinge parameter → the option that sets it (a kind without that field refuses it)."""

FIELD_OPTIONS = {
    **GEOMETRY_OPTIONS,
    "amplitude_n": ("--amplitude",),
    "mu": ("--mu",),
    "increments_per_stage": ("--increments",),
    "clearance_increments": ("--increments",),
    "n_cycles": ("--cycles",),
}
"""Field → the option that sets it: ``main`` words a refusal in the option (``--increments``)."""


def _spec_from_args(args: argparse.Namespace) -> Any:
    """Return the ModelSpec of a model file or of the options, with the overrides applied."""
    from fe.cycle.protocol import CycleSettings
    from fe.kinds import DEFAULT_KIND, hinge_kind
    from model.service import check_spec
    from model.spec import ModelSpec
    from studies.options import params_with

    if args.model is None:
        kind = hinge_kind(args.hinge or DEFAULT_KIND)
        values = {f: getattr(args, o[2:].replace("-", "_")) for f, o in HINGE_OPTIONS.items()}
        hinge = params_with(kind, values, HINGE_OPTIONS)
        spec = ModelSpec(kind.name, hinge, settings_from_args(args), CycleSettings())
    else:
        from model.file import read_model

        given = [
            f"--{n.replace('_', '-')}"
            for n in ("clearance", "preload", "size", "contact_size", "ball_model", "interfaces")
            if getattr(args, n) is not None
        ]
        if given or args.refinement != 0 or args.hinge is not None:
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
    return dataclasses.replace(spec, cycle=dataclasses.replace(spec.cycle, **overrides))


def _progress_bar(args: argparse.Namespace) -> Any:
    if args.no_progress or (not sys.stderr.isatty() and args.json):
        return None
    from tqdm import tqdm

    class Bar(tqdm):  # type: ignore[misc]  # tqdm ships no type hints
        def update_to(self, done: int, total: int) -> None:
            self.total = total
            self.update(done - self.n)

    return Bar(desc="increments", unit="inc", file=sys.stderr, leave=False)


def _summary(result: Any, meshed: Any, files: dict[str, str]) -> dict[str, Any]:
    """What every kind's cycle JSON holds: the metrics, the protocol, the increments, files."""
    incs = result.increments
    mesh = {} if meshed is None else {"n_hex": meshed.report.n_hex}
    return {
        **result.metrics(),
        "delta_definition": "δ_max = (δ(+Fg) − δ(−Fg))/2 of the last loop, free play removed; "
        "δ is the grip displacement relative to the tang's fixed face",
        "amplitude_N": result.settings.amplitude_n,
        "mu": result.settings.mu,
        **mesh,
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
        "timings_s": {} if meshed is None else {"mesh": meshed.timings_s["mesh"]},
        "files": files,
    }
