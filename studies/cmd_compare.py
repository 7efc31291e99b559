"""``hingelab compare``: run a model file at every measured design point and judge it.

``hingelab compare MODEL.toml DATA_DIR --out DIR [--json]`` reads the model
(``validation.model_file``) and the measurements (``validation.measurements``), runs
the cycle once per (clearance, amplitude) — one mesh and one factorisation per
clearance, reused for every amplitude — compares (``validation.compare``) and writes
into DIR: ``comparison.json``, the model loops as ``model_loops/*.csv`` and the
pictures (``loops/<case>.png``, ``error_map.png``, ``residuals.png``,
``fingerprint.png``). The exit status is 0 whether cases pass or fail (the verdict is
in the output); 1 only for bad input.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cad.errors import DataError, ParameterError
from studies.pipeline import dumps
from validation.compare import METRIC_LABELS, METRICS, CompareSettings, Comparison, ModelResult
from validation.measurements import Case, Loop
from validation.model_file import ModelSpec


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
        help="relative uncertainty of cases without replicates (default 0.05)",
    )
    p.add_argument(
        "--without-free-play",
        action="store_true",
        help="compare with the model loop without the 4Δr free play (the test machine sees it)",
    )
    p.add_argument("--no-plots", action="store_true", help="skip the pictures")
    p.set_defaults(func=run)


def _check_cases(spec: ModelSpec, cases: Sequence[Case]) -> None:
    if spec.kind != "general":
        raise ParameterError(
            f"compare supports hinge kind 'general' only for now, got {spec.kind!r}"
        )
    for c in cases:
        if c.hinge != "general":
            raise DataError(
                f"case {c.case_id!r}: hinge {c.hinge!r}; compare supports the general hinge only for now"
            )
        if c.preload_n != 0.0:
            raise DataError(
                f"case {c.case_id!r}: preload_N = {c.preload_n:g}, but the general hinge has no preload"
            )


def run_model_for_cases(
    spec: ModelSpec, cases: Sequence[Case], *, with_free_play: bool = True
) -> tuple[dict[str, ModelResult], dict[tuple[float, float], Any]]:
    """Run the model's cycle at every (clearance, amplitude) of the cases.

    One mesh, one factorisation and one pair of condensed configurations per clearance,
    reused for every amplitude there; replicates share one run. The model's effects
    (``spec.effects``, e.g. written by ``hingelab calibrate``) are switched on.

    Returns:
        (case_id → ModelResult, (clearance, amplitude) → CycleResult).
    """
    from cad.general import make_general_hinge
    from fe.effects import run_cycle_with_effects
    from fe.hinge.cycle import run_cycle
    from fe.hinge.system import build_system
    from mesh.build import mesh_hinge
    from validation.model_file import with_clearance

    runs: dict[tuple[float, float], Any] = {}
    for clearance in sorted({c.clearance_mm for c in cases}):
        model = make_general_hinge(with_clearance(spec, clearance))
        mesh, _ = mesh_hinge(model, spec.mesh)
        system = build_system(mesh)
        configs = None
        for amp in sorted({c.amplitude_n for c in cases if c.clearance_mm == clearance}):
            settings = dataclasses.replace(spec.cycle, amplitude_n=amp)
            if spec.effects:  # the model's effects act on the base configurations
                with_effects = run_cycle_with_effects(
                    system, clearance, settings, spec.effects, configs=configs
                )
                result, configs = with_effects.result, with_effects.base_configs
            else:
                result = run_cycle(system, clearance, settings, configs=configs)
                configs = result.configs
            runs[(clearance, amp)] = result
    out = {}
    for c in cases:
        r = runs[(c.clearance_mm, c.amplitude_n)]
        # a stated η (an η-only table, like the paper's) excludes the free play, as
        # `hingelab cycle` reports it; a measured loop includes it (the grips see it)
        free_play = with_free_play and c.loop is not None
        F, d = r.machine_path() if free_play else r.loop_arrays()[:2]
        source = f"model: Δr = {c.clearance_mm:g} mm, Fg = {c.amplitude_n:g} N"
        out[c.case_id] = ModelResult(Loop(F, d, None, source), r.metrics())
    return out, runs


def _write_model_loops(
    runs: dict[tuple[float, float], Any], out: Path, free_play: bool
) -> list[str]:
    folder = out / "model_loops"
    folder.mkdir(parents=True, exist_ok=True)
    files = []
    for (clearance, amp), r in runs.items():
        F, d = r.machine_path() if free_play else r.loop_arrays()[:2]
        path = folder / f"clearance_{clearance:g}mm_F{amp:g}N.csv"
        np.savetxt(
            path,
            np.column_stack([F, d]),
            delimiter=",",
            header="force_N,displacement_mm",
            comments="",
            fmt="%.10g",
        )
        files.append(str(path))
    return files


def compare_and_write(
    spec: ModelSpec,
    data: Any,
    out: Path,
    settings: CompareSettings,
    *,
    free_play: bool = True,
    plots: bool = True,
) -> tuple[Comparison, dict[str, Any]]:
    """Run the model at every case, compare, write ``out/comparison.json``, loops and pictures.

    Args:
        spec: The model (with its effects).
        data: The measurement set (``validation.measurements.MeasurementSet``).
        out: Output folder (created).
        settings: Pass/fail settings.
        free_play: Compare with the model loop including the 4Δr free play traverse.
        plots: Draw the pictures.

    Returns:
        (the comparison, the report written to ``comparison.json``).
    """
    from validation.compare import compare

    t0 = time.perf_counter()
    _check_cases(spec, data.cases)
    models, runs = run_model_for_cases(spec, data.cases, with_free_play=free_play)
    cmp = compare(models, data, settings)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Any] = {"model_loops": _write_model_loops(runs, out, free_play)}
    if plots:
        from validation.plots import write_comparison_plots

        files.update({k: str(v) for k, v in write_comparison_plots(cmp, out).items()})
    files["comparison_json"] = str(out / "comparison.json")
    report = {
        **cmp.to_dict(),
        "model_loop_free_play": free_play,
        "files": files,
        "wall_s": time.perf_counter() - t0,
    }
    (out / "comparison.json").write_text(dumps(report))
    return cmp, report


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab compare``."""
    from validation.measurements import read_measurement_set
    from validation.model_file import read_model

    spec = read_model(args.model)
    data = read_measurement_set(args.data)
    settings = CompareSettings(k=args.k, default_rel_uncertainty=args.uncertainty)
    cmp, report = compare_and_write(
        spec,
        data,
        args.out,
        settings,
        free_play=not args.without_free_play,
        plots=not args.no_plots,
    )
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
    return 0


def _fmt(slope: float) -> str:
    return f"{0.0 if abs(slope) < 0.005 else slope:.2f}"


def format_table(cmp: Comparison) -> str:
    """Return the per-case table and the overall line (errors in %, * where |e| > kσ)."""
    heads = [
        "case",
        "Δr mm",
        "Fg N",
        *(METRIC_LABELS[m].split(" ")[0] for m in METRICS),
        "σ",
        "verdict",
    ]
    rows = [heads]
    for c in cmp.cases:
        cells = [c.case.case_id, f"{c.case.clearance_mm:g}", f"{c.case.amplitude_n:g}"]
        for m in METRICS:
            if m in c.errors:
                mark = "*" if m in c.failed else ""
                cells.append(f"{c.errors[m] * 100:+.1f}%{mark}")
            else:
                cells.append("—")
        sig = {f"{v * 100:.1f}%" for v in c.uncertainty.values()}
        cells.append(
            ("/".join(sorted(sig)) if len(sig) < 3 else "replicates")
            + ("" if c.uncertainty_source == "stated" else " (rep)")
        )
        cells.append("pass" if c.passed else "FAIL")
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
        "RMS is the loop distance / δ_max)"
    )
    if fp:
        lines.append(f"fingerprint — {fp}")
    return "\n".join(lines)
