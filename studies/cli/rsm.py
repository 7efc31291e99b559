"""``hingelab rsm``: fit response surfaces to tables, and check the paper's.

``hingelab rsm fit TABLE.csv --x COL,COL --y COL --degree 4 [--json]`` prints the
coefficients (physical units, paper term order, each named like ``x1^2*x2``),
the fit metrics, the worst points and the extremes over the box, and writes
the plots (default folder: ``<table stem>_rsm/`` next to the table).

``hingelab rsm paper --out DIR`` refits the paper's Tables 1 and 4, writes the
comparison report (Markdown and JSON) and the plots into DIR.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

from model.jsonio import dumps

if TYPE_CHECKING:  # the fit, plots and paper tables load scipy and matplotlib: only when used
    from rsm.metrics import FitMetrics
    from rsm.polynomial import ResponseSurface


FIELD_OPTIONS = {"degree": ("--degree",)}
"""Field → the options that set it: ``main`` words a refusal in the option the user typed."""


def register(subparsers: Any) -> None:
    """Add the ``rsm`` subcommand and its ``fit`` and ``paper`` actions."""
    p = subparsers.add_parser("rsm", help="fit and query polynomial response surfaces")
    sub = p.add_subparsers(dest="rsm_command", required=True, metavar="ACTION")

    f = sub.add_parser("fit", help="fit a polynomial surface to a CSV table")
    f.add_argument("table", type=Path, help="CSV table, one sample point per row")
    f.add_argument("--x", required=True, help="input columns, comma-separated (x1,x2,...)")
    f.add_argument("--y", required=True, help="response column")
    f.add_argument("--degree", type=int, default=4, help="total degree 1-4 (default 4)")
    f.add_argument("--json", action="store_true", help="print JSON instead of text")
    f.add_argument(
        "--out", type=Path, help="folder for plots (default <table stem>_rsm/ next to the table)"
    )
    f.add_argument("--no-plots", action="store_true", help="do not write plots")
    f.add_argument("--threshold", type=float, help="shade the region where y < THRESHOLD")
    f.add_argument("--above", action="store_true", help="with --threshold: shade y > THRESHOLD")
    f.add_argument("--trace", type=Path, help="record the fit in this trace database")
    f.add_argument("--study", help="with --trace: study the fit belongs to")
    f.set_defaults(func=run_fit)

    q = sub.add_parser("paper", help="refit the paper's tables; write the comparison report")
    q.add_argument(
        "--out", type=Path, default=Path("rsm_paper"), help="output folder (default rsm_paper)"
    )
    q.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    q.add_argument("--no-plots", action="store_true", help="write the report only")
    q.set_defaults(func=run_paper)


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _fit(args: argparse.Namespace) -> tuple[ResponseSurface, FitMetrics, list[str]]:
    from rsm.metrics import OverfitWarning, fit_metrics
    from rsm.polynomial import fit_response_surface
    from rsm.tables import read_xy

    x_names = [c.strip() for c in args.x.split(",") if c.strip()]
    xy = read_xy(args.table, x_names, args.y)
    s = fit_response_surface(
        xy.x, xy.y, args.degree, x_names=xy.x_names, y_name=xy.y_name, labels=xy.labels
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", OverfitWarning)
        m = fit_metrics(s)
    return s, m, [str(w.message) for w in caught]


def fit_report(
    s: ResponseSurface, m: FitMetrics, threshold: float | None, below: bool
) -> dict[str, Any]:
    """Collect everything ``rsm fit`` reports, as JSON-ready data."""
    from rsm.polynomial import predict, term_names
    from rsm.query import extrema, threshold_region

    names = term_names(s.exponents, s.x_names)
    fitted = predict(s, s.x)
    ext = extrema(s)
    out: dict[str, Any] = {
        "x": list(s.x_names),
        "y": s.y_name,
        "degree": s.degree,
        "n_points": s.n_points,
        "n_terms": s.n_terms,
        "coefficients": [
            {"term": t, "name": n, "coefficient": float(b)}
            for t, n, b in zip(s.term_names, names, s.coefficients, strict=True)
        ],
        "metrics": {k: _num(v) for k, v in m.summary().items()},
        "condition_number_unscaled": _num(s.condition_number_unscaled),
        "points": [
            {
                "label": s.labels[k],
                "x": s.x[k].tolist(),
                "y": float(s.y[k]),
                "fit": float(fitted[k]),
                "RE_percent": _num(100 * float(m.relative_error[k])),
                "loo_residual": _num(float(m.loo_residuals[k])),
            }
            for k in range(s.n_points)
        ],
        "minimum": {"x": ext.minimum.x.tolist(), "y": ext.minimum.value},
        "maximum": {"x": ext.maximum.x.tolist(), "y": ext.maximum.value},
        "threshold_region": None,
        "overfit_reasons": list(m.overfit_reasons),
    }
    if threshold is not None and s.n_vars >= 2:
        r = threshold_region(s, threshold, below=below)
        out["threshold_region"] = {
            "threshold": threshold,
            "below": below,
            "x": list(r.x_names),
            "fixed": dict(r.fixed),
            "area_fraction": r.area_fraction,
            "n_parts": r.n_parts,
            "lower": [_num(float(v)) for v in r.lower],
            "upper": [_num(float(v)) for v in r.upper],
        }
    return out


def _print_text(rep: dict[str, Any]) -> None:
    print(
        f"{rep['y']} = f({', '.join(rep['x'])}): degree {rep['degree']}, "
        f"{rep['n_points']} points, {rep['n_terms']} coefficients"
    )
    print("  x" + ", x".join(f"{i + 1} = {n}" for i, n in enumerate(rep["x"])))
    print("\nCoefficients (physical units, paper term order):")
    width = max(len(c["term"]) for c in rep["coefficients"])
    for c in rep["coefficients"]:
        name = "" if c["name"] == c["term"] else f"   {c['name']}"
        print(f"  {c['term']:<{width}}  {c['coefficient']: .6e}{name}")
    print("\nMetrics (paper Eqs. 7-10; RMSE divides by M - N - 1):")
    for k, v in rep["metrics"].items():
        print(f"  {k:<20} {'n/a' if v is None else f'{v:.6g}'}")
    worst = sorted(rep["points"], key=lambda p: -abs(p["RE_percent"] or 0.0))[:5]
    print("\nLargest relative errors (trace a 'point N' with: hingelab trace DB N):")
    for p in worst:
        re_txt = "n/a" if p["RE_percent"] is None else f"{p['RE_percent']:+.3f} %"
        print(
            f"  {p['label']:<12} x = {p['x']}  y = {p['y']:.6g}  fit = {p['fit']:.6g}  RE {re_txt}"
        )
    print("\nOver the sampled box:")
    print(f"  minimum {rep['minimum']['y']:.6g} at {[round(v, 6) for v in rep['minimum']['x']]}")
    print(f"  maximum {rep['maximum']['y']:.6g} at {[round(v, 6) for v in rep['maximum']['x']]}")
    r = rep["threshold_region"]
    if r is not None:
        sign = "<" if r["below"] else ">"
        ranges = ", ".join(
            f"{n} in [{_g(lo)}, {_g(hi)}]"
            for n, lo, hi in zip(r["x"], r["lower"], r["upper"], strict=True)
        )
        print(
            f"  {rep['y']} {sign} {r['threshold']:g} on {100 * r['area_fraction']:.2f} % "
            f"of the box ({r['n_parts']} part(s)); there {ranges}"
        )


def _g(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.6g}"


def run_fit(args: argparse.Namespace) -> int:
    """Fit, report, plot and optionally record a response surface."""
    from rsm import trace_store
    from rsm.plots import plot_all
    from studies.outputs import check_trace_db, check_writable_dir

    out_dir = args.out or args.table.parent / f"{args.table.stem}_rsm"
    if not args.no_plots:  # every output is checked before the fit
        check_writable_dir(out_dir, "--out")
    if args.trace is not None:
        check_trace_db(args.trace, "--trace")
    s, m, warns = _fit(args)
    rep = fit_report(s, m, args.threshold, not args.above)
    rep["warnings"] = warns
    if not args.no_plots:
        plots = plot_all(s, m, out_dir, threshold=args.threshold)
        rep["plots"] = {k: str(v) for k, v in plots.items()}
    if args.trace is not None:
        ids = [int(lbl.removeprefix("point ")) for lbl in s.labels if lbl.startswith("point ")]
        if len(ids) != s.n_points:
            print("hingelab rsm fit: --trace needs a point_id column in the table", file=sys.stderr)
            return 1
        rep["trace_fit_id"] = trace_store.record_fit(
            args.trace, surface=s, metrics=m, point_ids=ids, study=args.study
        )
    for w in warns:
        print(f"warning: {w}", file=sys.stderr)
    if args.json:
        print(dumps(rep))
    else:
        _print_text(rep)
        for k, v in rep.get("plots", {}).items():
            print(f"plot {k}: {v}")
    return 0


def run_paper(args: argparse.Namespace) -> int:
    """Refit the paper's tables, write the comparison report and the plots."""
    from rsm import paper as paper_mod
    from rsm.paper_printed import ETA_THRESHOLD
    from rsm.plots import plot_all

    cmp = paper_mod.compare_with_paper()
    files = paper_mod.write_report(cmp, args.out)
    slice_at = {
        "general": {"amplitude_N": 300.0, "clearance_mm": 0.3},
        "modified": {"amplitude_N": 200.0, "preload_N": 100.0},
    }  # the paper's Figs. 7-8, 12-13
    plots: dict[str, str] = {}
    for h in (cmp.general, cmp.modified) if not args.no_plots else ():
        for k, v in plot_all(
            h.surface,
            h.metrics,
            args.out,
            threshold=ETA_THRESHOLD,
            slice_at=slice_at[h.case.name],
            prefix=f"{h.case.name}_",
        ).items():
            plots[f"{h.case.name}_{k}"] = str(v)
    if args.json:
        data = paper_mod.report_json(cmp)
        data["files"] = {"markdown": str(files.markdown), "json": str(files.json), **plots}
        print(dumps(data))
    else:
        print(files.markdown.read_text(encoding="utf-8"))
        print(f"report: {files.markdown} and {files.json}")
        for k, path in plots.items():
            print(f"plot {k}: {path}")
    return 0
