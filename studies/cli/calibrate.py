"""``hingelab calibrate``: add effects to the model, fit them, and log the error ledger.

``hingelab calibrate MODEL.toml DATA_DIR [--mu] --effects NAME[,NAME] --out DIR [--json]``
fits μ (with ``--mu``, first) and the named effects' parameters (``validation.calibrate``),
writes the extended model to ``DIR/MODEL.toml``, appends baseline → +effect → … to
``DIR/ledger.json`` and ``DIR/ledger.csv`` and draws ``DIR/ledger.png`` (error per step,
held-out error, noise level), then re-runs the comparison with the new model
(``hingelab compare``'s work, into ``DIR/compare/``: per-case errors and pass/fail,
overlays, error map, fingerprint) and prints how many cases pass with it;
``--no-compare`` skips that.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cad.errors import ParameterError
from model.jsonio import dumps
from studies.cli.args import FIT_OPTIONS, add_fit_arguments
from studies.cluster_options import CLUSTER_OPTIONS, add_cluster_arguments, model_service
from studies.outputs import check_writable_dir

if TYPE_CHECKING:
    from model.spec import ModelSpec
    from validation.measurements import MeasurementSet


FIELD_OPTIONS = {
    **FIT_OPTIONS,
    "default_rel_uncertainty": ("--uncertainty",),
    "eta_rel_sigma": ("--uncertainty",),
    **CLUSTER_OPTIONS,
}
"""Field → the options that set it: ``main`` words a refusal in the option the user typed."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``calibrate`` subcommand."""
    p = sub.add_parser("calibrate", help="fit named effects, write the model, log the error")
    p.add_argument("model", type=Path, metavar="MODEL.toml", help="the model file")
    p.add_argument("data", type=Path, metavar="DATA_DIR", help="measurement folder (cases.csv)")
    p.add_argument(
        "--effects", default="", metavar="NAME[,NAME]", help="effects to add (default: none)"
    )
    p.add_argument(
        "--mu", action="store_true", help="fit the friction coefficient first (bounded 0.02–0.8)"
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument("--json", action="store_true", help="print the ledger as JSON")
    add_fit_arguments(p)
    p.add_argument(
        "--uncertainty",
        type=float,
        default=0.05,
        metavar="U",
        help="stated relative σ of η-only cases, for the fit and the comparison (default 0.05)",
    )
    p.add_argument("--no-compare", action="store_true", help="do not re-run the comparison")
    p.add_argument(
        "--no-screen",
        action="store_true",
        help="fit each effect's grid on the model's own mesh (default: on the kind's coarse "
        "mesh when the model's is finer, then refined and judged on the model's own)",
    )
    add_cluster_arguments(p)
    p.add_argument(
        "--fit",
        default=None,
        metavar="TERMS",
        help="displacement-controlled data: element parameters to fit, one ledger step each, "
        "e.g. slip_force_n~band_tension_N^2,free_play_mm (param: a constant; ~cond: a law in "
        "the condition cond_<cond>; ^2: a parabola; default: none, required for such data)",
    )
    p.add_argument(
        "--leave-one-out",
        action="store_true",
        help="displacement-controlled data: predict each record from a fit without it "
        "(held-out error per step, leave_one_out.json)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab calibrate``."""
    from model.file import read_model, write_model
    from validation.calibrate import append_ledger, calibrate, plot_ledger
    from validation.candidate_fit import DiagnoseSettings
    from validation.features import FeatureSettings
    from validation.measurements import read_measurement_set

    data = read_measurement_set(args.data)
    from validation.stroke_fit import is_displacement_set

    if is_displacement_set(data):
        from studies.cli.stroke import run_calibrate

        return run_calibrate(args, data)
    if args.fit or args.leave_one_out:
        raise ParameterError(
            "calibrate: --fit/--leave-one-out need displacement-controlled data "
            f"(control = displacement in {args.data}/cases.csv)"
        )
    spec = read_model(args.model)
    names = [n.strip() for n in args.effects.split(",") if n.strip()]
    if not names and not args.mu:
        raise ParameterError("calibrate: give --effects NAME[,NAME] and/or --mu")
    settings = DiagnoseSettings(
        features=FeatureSettings(rel_floor=args.model_error, eta_rel_sigma=args.uncertainty),
        increments_per_stage=args.increments,
        clearance_increments=2 * args.increments,
        screen=not args.no_screen,
    )
    check_writable_dir(args.out, "--out")  # before the fit, not after
    with model_service(args, args.out / "results") as service:
        new_spec, rows = calibrate(spec, data, names, settings, fit_mu=args.mu, service=service)
        model_out = write_model(new_spec, args.out / "MODEL.toml")
        every = append_ledger(args.out, rows)
        png = plot_ledger(every, args.out / "ledger.png")
        comparison = None if args.no_compare else _compare(new_spec, data, args, service)
    if args.json:
        print(
            dumps(
                {"model": str(model_out), "ledger": every, "plot": str(png), "compare": comparison}
            )
        )
    else:
        for r in every:
            params = ", ".join(f"{k} = {v:.3g}" for k, v in r["params"].items())
            h = r["heldout_error"]  # null (NaN) in the strict-JSON ledger when not held out
            held = f"{h:8.2f} σ" if h is not None else "       —"
            print(
                f"{r['step']:<24} error {r['error']:8.2f} σ  held-out {held}  BIC {r['bic']:9.1f}  {params}"
            )
        last = every[-1]
        for key in last.get("moved", []):
            print(
                f"moved: {key} changed by more than its σ ({last['sigma'][key]:.3g}) in the joint re-fit"
            )
        print(f"model written to {model_out}; ledger in {args.out}/ (ledger.json, .csv, .png)")
        if last.get("file_error") is not None:
            print(
                f"the written model at its own increments: error {last['file_error']:.2f} σ, "
                f"{last['file_n_fitted']}/{last['n_points']} design points within 2σ"
            )
        if comparison is not None:
            feats = comparison["features"]
            error = f"error {feats['error']:.2f} σ, " if "error" in feats else ""
            print(
                f"compare with the new model: {error}{comparison['n_pass']}/"
                f"{comparison['n_cases']} cases pass; details in {comparison['folder']}/"
            )
    return 0


def _compare(
    spec: ModelSpec, data: MeasurementSet, args: argparse.Namespace, service: object = None
) -> dict[str, Any]:
    """Re-run the comparison with the calibrated model into ``args.out/compare``; its summary."""
    from validation.compare import CompareSettings
    from validation.features import FeatureSettings
    from validation.workflow import compare_and_write

    folder = args.out / "compare"
    cmp, _report = compare_and_write(
        spec,
        data,
        folder,
        CompareSettings(
            default_rel_uncertainty=args.uncertainty,
            features=FeatureSettings(rel_floor=args.model_error, eta_rel_sigma=args.uncertainty),
        ),
        service=service,
    )
    return {
        "n_pass": cmp.summary["n_pass"],
        "n_cases": cmp.summary["n_cases"],
        "passed": {c.case.case_id: c.passed for c in cmp.cases},
        "features": cmp.summary.get("features", {}),
        "folder": str(folder),
    }
