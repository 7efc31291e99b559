"""``hingelab diagnose``: which candidate effect is missing from the model.

``hingelab diagnose MODEL.toml DATA_DIR [--out DIR] [--workers N | --scheduler ADDRESS]
[--json]`` summarises every measured loop into
features (``validation.features``), fits every registry effect's parameter
(``validation.diagnose``; one mesh and factorisation per clearance, reused for every
candidate and value) and prints the residual pattern, the ranked candidates and the
verdict: ``effect_missing``, ``no_missing_effect``, ``indistinguishable`` or
``unexplained``. The baseline and every candidate's grid are independent runs: with
``--workers``/``--scheduler`` they run as batches of Dask tasks. On a model finer than
its kind's coarse preset the grids run on the coarse mesh and only the refinement and the
verdict on the model's own (``--no-screen``: everything on the model's mesh). Exit
status 0 whatever the verdict; 1 only for bad input.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from model.jsonio import dumps
from studies.cli.args import FIT_OPTIONS, add_fit_arguments
from studies.cluster_options import CLUSTER_OPTIONS, add_cluster_arguments, model_service

FIELD_OPTIONS = {**FIT_OPTIONS, **CLUSTER_OPTIONS, "candidates": ("--candidates",)}
"""Field → the options that set it: ``main`` words a refusal in the option the user typed."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``diagnose`` subcommand."""
    p = sub.add_parser("diagnose", help="rank the candidate effects that could explain the error")
    p.add_argument("model", type=Path, metavar="MODEL.toml", help="the model file")
    p.add_argument("data", type=Path, metavar="DATA_DIR", help="measurement folder (cases.csv)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="keep the cycles in DIR/results and write DIR/diagnosis.json; a rerun with the "
        "same DIR reads the cycles back (default: nothing kept)",
    )
    add_fit_arguments(p)
    add_cluster_arguments(p)
    p.add_argument(
        "--alpha",
        type=float,
        default=0.01,
        help="false-alarm probability, in (0, 0.5] (default 0.01)",
    )
    p.add_argument(
        "--no-screen",
        action="store_true",
        help="fit every candidate's grid on the model's own mesh (default: on the kind's coarse "
        "mesh when the model's is finer, then refined and judged on the model's own)",
    )
    p.add_argument(
        "--candidates",
        default=None,
        metavar="NAME[,NAME]",
        help="try only these effects (default: every one that applies to the model's hinge)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab diagnose``."""
    from cad.errors import ParameterError
    from model.file import read_model
    from validation.candidate_fit import DiagnoseSettings
    from validation.diagnose import diagnose
    from validation.features import FeatureSettings
    from validation.measurements import read_measurement_set

    if not 0.0 < args.alpha <= 0.5:  # 'not' also refuses NaN
        raise ParameterError(f"--alpha must be in (0, 0.5], got {args.alpha}")
    if args.candidates is not None and not args.candidates.strip(", "):
        raise ParameterError(f"--candidates must name at least one effect, got {args.candidates!r}")
    data = read_measurement_set(args.data)
    from validation.stroke_fit import is_displacement_set

    if is_displacement_set(data):  # candidates are the element's terms, not effects
        from studies.cli.stroke import run_diagnose

        return run_diagnose(args, data)
    spec = read_model(args.model)
    settings = DiagnoseSettings(
        features=FeatureSettings(rel_floor=args.model_error),
        alpha=args.alpha,
        increments_per_stage=args.increments,
        clearance_increments=2 * args.increments,
        screen=not args.no_screen,
        candidates=None
        if args.candidates is None
        else tuple(n.strip() for n in args.candidates.split(",") if n.strip()),
    )
    if args.out is not None:
        from studies.outputs import check_writable_dir

        check_writable_dir(args.out, "--out")  # before the model runs, not after
    with model_service(args, None if args.out is None else args.out / "results") as service:
        result = diagnose(spec, data, settings, service=service)
    if args.out is not None:
        (args.out / "diagnosis.json").write_text(dumps(result.to_dict()))
    if args.json:
        print(dumps(result.to_dict()))
    else:
        print(result.text())
        coarse = result.stats.get("screen_cycles", 0)
        more = f" (+{coarse:.0f} on the coarse mesh for the grids)" if coarse else ""
        print(f"{result.stats['n_cycles']:.0f} cycles{more}, {result.stats['wall_s']:.0f} s")
    return 0
