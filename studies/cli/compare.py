"""``hingelab compare``: run a model file at every measured design point and judge it.

``hingelab compare MODEL.toml DATA_DIR --out DIR [--json]`` reads the model
(``model.file``) and the measurements (``validation.measurements``), runs
the cycle once per (clearance, amplitude) — one mesh and one factorisation per
clearance, reused for every amplitude; with ``--workers``/``--scheduler`` as Dask tasks,
a worker running the clearances it holds first; kept in ``DIR/results``, so a rerun reads them back —
compares (``validation.compare``) and writes
into DIR: ``comparison.json``, the model loops as ``model_loops/*.csv`` and the
pictures (``loops/<case>.png``, ``error_map.png``, ``residuals.png``,
``fingerprint.png``). The exit status is 0 whether cases pass or fail (the verdict is
in the output) unless ``--fail-on-mismatch`` asks for 2 when any case fails; 1 for bad
input.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from model.jsonio import dumps
from studies.cluster_options import CLUSTER_OPTIONS, add_cluster_arguments, model_service
from studies.outputs import check_writable_dir

if TYPE_CHECKING:
    from validation.compare import CaseComparison, Comparison


FIELD_OPTIONS = {
    "k": ("--k",),
    "default_rel_uncertainty": ("--uncertainty",),
    "eta_rel_sigma": ("--uncertainty",),
    **CLUSTER_OPTIONS,
}
"""Field → the options that set it: ``main`` words a refusal in the option the user typed."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``compare`` subcommand."""
    p = sub.add_parser(
        "compare",
        help="run MODEL.toml at every measured case; errors, pass/fail, plots",
    )
    p.add_argument("model", type=Path, metavar="MODEL.toml", help="the model file")
    p.add_argument("data", type=Path, metavar="DATA_DIR", help="measurement folder (cases.csv)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--k", type=float, default=2.0, metavar="K", help="pass when |error| ≤ K σ (default 2)"
    )
    p.add_argument(
        "--uncertainty",
        type=float,
        default=0.05,
        metavar="U",
        help="stated relative σ of η-only cases and of the loop distance (default 0.05); loop "
        "metrics use the record's noise ⊕ model floor ⊕ replicates, as diagnose",
    )
    p.add_argument(
        "--without-free-play",
        action="store_true",
        help="compare with the model loop without the 4Δr free play (the test machine sees it)",
    )
    p.add_argument("--no-plots", action="store_true", help="skip the pictures")
    add_cluster_arguments(p)
    p.add_argument(
        "--fail-on-mismatch",
        action="store_true",
        help="exit 2 when any case fails (for CI pipelines; default: exit 0 whatever the verdict)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab compare``."""
    from model.file import read_model
    from validation.compare import CompareSettings
    from validation.measurements import read_measurement_set
    from validation.workflow import compare_and_write

    data = read_measurement_set(args.data)
    from validation.stroke_fit import is_displacement_set

    if is_displacement_set(data):  # a rig drove ±δ: the model follows its displacement
        from studies.cli.stroke import run_compare

        return run_compare(args, data)
    spec = read_model(args.model)
    from validation.features import FeatureSettings

    settings = CompareSettings(
        k=args.k,
        default_rel_uncertainty=args.uncertainty,
        features=FeatureSettings(eta_rel_sigma=args.uncertainty),
    )
    check_writable_dir(args.out, "--out")  # before the model runs, not after
    with model_service(args, args.out / "results") as service:
        cmp, report = compare_and_write(
            spec,
            data,
            args.out,
            settings,
            free_play=not args.without_free_play,
            plots=not args.no_plots,
            service=service,
        )
    report["n_computed"] = service.n_computed
    report = {"model_file": str(args.model), "data": str(args.data), **report}
    (args.out / "comparison.json").write_text(dumps(report))
    if args.json:
        print(dumps(report))
    else:
        print(format_table(cmp))
        print(
            f"results in {args.out}/ (comparison.json, loops/, error_map.png, residuals.png, "
            f"fingerprint.png)   {report['wall_s']:.1f} s"
        )
    n_fail = sum(not c.passed for c in cmp.cases)
    if args.fail_on_mismatch and n_fail:
        print(
            f"hingelab compare: {n_fail} of {len(cmp.cases)} cases fail (--fail-on-mismatch)",
            file=sys.stderr,
        )
        return 2
    return 0


def _fmt(slope: float) -> str:
    return f"{0.0 if abs(slope) < 0.005 else slope:.2f}"


def _error_cell(c: CaseComparison, m: str) -> str:
    """A metric's error in %, ``n/m`` where not measurable, ``Δ…`` where judged absolutely."""
    mark = "*" if m in c.failed else ""
    if m in c.errors:
        return f"{c.errors[m] * 100:+.1f}%{mark}"
    j = c.judgements.get(m)
    if j is None:
        return "—"
    if m in c.not_measurable:
        return "n/m"
    return f"Δ{j.difference:+.3g}{mark}"


def _sigma_text(c: CaseComparison) -> str:
    """η's σ: relative where η is judged relatively, else absolute (never a % of ~0)."""
    if "eta" in c.uncertainty:
        return f"{c.uncertainty['eta'] * 100:.1f}%"
    j = c.judgements.get("eta")
    return "—" if j is None else f"±{j.sigma_abs:.2g}"


def _hysteresis_notes(cmp: Comparison) -> list[str]:
    """One line per case whose W or η is not measurable or fails absolutely, and what was cut."""
    from validation.compare import METRIC_LABELS

    notes = []
    for c in cmp.cases:
        cut = " (free play removed)" if c.free_play_removed else ""
        for m, j in c.judgements.items():
            if not j.relative:
                what = "not measurable" if m in c.not_measurable else "FAIL"
                notes.append(f"{c.case.case_id}: {METRIC_LABELS[m]}{cut} {what}: {j.reason}")
    if any(c.free_play_removed for c in cmp.cases):
        notes.append("with clearance, W and η are those of the loop without the free play")
    return notes


def format_table(cmp: Comparison) -> str:
    """Return the per-case table and the overall line (errors in %, * where |e| > kσ)."""
    from validation.compare import METRIC_LABELS, METRICS

    heads = [
        "case",
        "design",
        "Fg N",
        *(METRIC_LABELS[m].split(" ")[0] for m in METRICS),
        "σ",
        "verdict",
    ]
    rows = [heads]
    for c in cmp.cases:
        cells = [c.case.case_id, c.case.describe() or "—", f"{c.case.amplitude_n:g}"]
        cells += [_error_cell(c, m) for m in METRICS]
        src = c.uncertainty_source
        tag = "rep" if "replicates" in src else ("record" if src.startswith("record") else "stated")
        cells.append(f"η {_sigma_text(c)} ({tag})")
        nm = ", ".join(METRIC_LABELS[m] for m in c.not_measurable)
        cells.append(("pass" if c.passed else "FAIL") + (f" ({nm} n/m)" if nm else ""))
        rows.append(cells)
    widths = [max(len(r[i]) for r in rows) for i in range(len(heads))]
    lines = [
        "  ".join(
            cell.rjust(w) if i else cell.ljust(w)
            for i, (cell, w) in enumerate(zip(r, widths, strict=True))
        )
        for r in rows
    ]
    s = cmp.summary
    fp = "; ".join(
        f"{f.group}: W slope {_fmt(f.slope_W_measured)} measured / {_fmt(f.slope_W_model)} model, "
        f"η slope {_fmt(f.slope_eta_measured)} / {_fmt(f.slope_eta_model)}"
        for f in cmp.fingerprint
    )
    lines.append(
        f"{s['n_pass']}/{s['n_cases']} cases pass (|error| ≤ {cmp.settings.k:g}σ; * marks the failing metrics; "
        "RMS is the loop distance / δ_max; n/m: not measurable, neither pass nor fail)"
    )
    lines += _hysteresis_notes(cmp)
    feats = s.get("features", {})
    if "error" in feats:  # the number calibrate's ledger reports (validation.feature_misfit)
        lines.append(
            f"feature error {feats['error']:.2f} σ (δ_max, W, opening; χ² {feats['chi2']:.4g} over "
            f"{feats['n_obs']}), {feats['n_fitted']}/{feats['n_points']} design points within "
            f"{feats['k']:g}σ: the calibrate ledger's measure"
        )
    if fp:
        lines.append(f"fingerprint — {fp}")
    return "\n".join(lines)
