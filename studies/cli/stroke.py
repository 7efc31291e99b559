"""The displacement-controlled path of ``compare``, ``diagnose`` and ``calibrate``.

When every case of DATA_DIR is displacement-controlled (``control = displacement``, as
``hingelab import-records`` writes a rig's records), the three commands drive the model
by each record's own displacement (``validation.stroke_fit``; the kind must have a
``displacement_loop``, as ``joint`` has) and judge the features of
``validation.stroke``. The model file's ``[laws]`` (``validation.joint_laws``) give the
element's parameters per test condition; ``calibrate --fit TERMS`` fits them and writes
them back, ``--leave-one-out`` adds the leave-one-condition-out table. Not a subcommand
of its own: ``studies/cli/compare.py``, ``diagnose.py`` and ``calibrate.py`` call it.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from cad.errors import ParameterError
from model.jsonio import dumps
from studies.outputs import check_writable_dir


def _inputs(args: argparse.Namespace) -> tuple[Any, Any, Any]:
    from model.file import read_model
    from validation.joint_laws import read_laws

    spec = read_model(args.model)
    return spec, read_laws(args.model, spec), _settings(args)


def _settings(args: argparse.Namespace) -> Any:
    from validation.stroke import StrokeSettings

    return StrokeSettings(
        rel_floor=getattr(args, "model_error", 0.02), k=getattr(args, "k", 2.0) or 2.0
    )


def _write(path: Path, payload: Any) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(dumps(payload) + "\n")
    tmp.replace(path)


def run_compare(args: argparse.Namespace, data: Any) -> int:
    """``hingelab compare`` on a displacement-controlled set."""
    from validation.stroke_report import format_compare, stroke_compare

    spec, laws, settings = _inputs(args)
    check_writable_dir(args.out, "--out")
    report = stroke_compare(spec, laws, data, settings)
    report = {"model_file": str(args.model), "data": str(args.data), **report}
    args.out.mkdir(parents=True, exist_ok=True)
    _write(args.out / "comparison.json", report)
    print(dumps(report) if args.json else format_compare(report))
    if not args.json:
        print(f"results in {args.out}/comparison.json")
    failed = report["n_cases"] - report["n_pass"]
    return 2 if args.fail_on_mismatch and failed else 0


def run_diagnose(args: argparse.Namespace, data: Any) -> int:
    """``hingelab diagnose`` on a displacement-controlled set: each candidate term alone."""
    from validation.stroke_fit import parse_terms
    from validation.stroke_report import default_candidates, stroke_diagnosis

    spec, laws, settings = _inputs(args)
    params_type = spec.hinge_kind.params_type
    candidates = (
        parse_terms(args.candidates, params_type) if args.candidates else default_candidates(data)
    )
    result = stroke_diagnosis(spec, laws, data, candidates, settings)
    if args.json:
        print(dumps(result))
        return 0
    print(f"baseline χ² = {result['baseline_chi2']:.1f} over N = {result['n_obs']} features")
    print(f"{'candidate':44} {'χ²':>9} {'ΔBIC':>9} {'held-out χ²':>12}  needed")
    for c in result["candidates"]:
        print(
            f"{c['term']:44} {c['chi2']:9.1f} {c['delta_bic']:+9.1f} "
            f"{c['heldout_chi2']:12.1f}  {'yes' if c['needed'] else 'no'}"
        )
    print(f"best: {result['best'] or 'none needed'} (held-out: each record predicted unseen)")
    return 0


def run_calibrate(args: argparse.Namespace, data: Any) -> int:
    """``hingelab calibrate --fit TERMS`` on a displacement-controlled set."""
    from validation.calibrate import append_ledger, plot_ledger
    from validation.joint_laws import write_model_with_laws
    from validation.stroke_fit import parse_terms
    from validation.stroke_report import (
        format_compare,
        format_loo,
        loo_table,
        stroke_compare,
        stroke_ledger,
    )

    if args.effects or args.mu:
        raise ParameterError(
            "calibrate: displacement-controlled data fit the element's laws: give --fit "
            "TERMS (e.g. slip_force_n~band_tension_N), not --effects/--mu"
        )
    spec, laws, settings = _inputs(args)
    terms = parse_terms(args.fit or "", spec.hinge_kind.params_type)
    check_writable_dir(args.out, "--out")
    laws, rows, ho = stroke_ledger(spec, laws, data, terms, settings, hold_out=args.leave_one_out)
    model_out = write_model_with_laws(spec, laws, args.out / "MODEL.toml")
    every = append_ledger(args.out, rows)
    png = plot_ledger(every, args.out / "ledger.png")
    out: dict[str, Any] = {"model": str(model_out), "ledger": every, "plot": str(png)}
    if ho is not None:
        table = loo_table(ho)
        _write(args.out / "leave_one_out.json", table)
        out["leave_one_out"] = table
    if not args.no_compare:
        report = stroke_compare(spec, laws, data, settings)
        (args.out / "compare").mkdir(parents=True, exist_ok=True)
        _write(args.out / "compare" / "comparison.json", report)
        out["compare"] = {k: report[k] for k in ("n_pass", "n_cases", "W_rms_error")}
    if args.json:
        print(json.dumps(out, default=float))
        return 0
    for r in every:
        h = r["heldout_error"]  # null (NaN) in the strict-JSON ledger when not held out
        held = f"{h:8.2f} σ" if h is not None and h == h else "       —"
        print(f"{r['step']:44} error {r['error']:8.2f} σ  held-out {held}  BIC {r['bic']:9.1f}")
    for k, v in law_lines(laws):
        print(f"  {k} = {v:.6g}")
    if ho is not None:
        print(format_loo(out["leave_one_out"]))
    if not args.no_compare:
        print(format_compare(report))
    print(f"model written to {model_out}; ledger in {args.out}/ (ledger.json, .csv, .png)")
    return 0


def law_lines(laws: Any) -> list[tuple[str, float]]:
    """The laws' coefficients as (name, value) pairs, in the order written."""
    from validation.stroke_fit import law_coefficients

    return list(law_coefficients(laws).items())
