"""Sections of the HTML report for the response surfaces fitted to a sweep or study.

The fits recorded in the trace (``rsm fit --trace``, ``hingelab study``), the plots of an
``rsm fit`` (``<table>_rsm/``) or of a study (``rsm/``), and, where a ``fit.json`` was
written next to them (``hingelab study``), the extremes and the threshold region.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from studies.report.parts import Html, Section, fmt, join, kv_table, link, table, tag
from studies.report.parts import figures as figure_grid

PLOTS = (
    ("contour", "contours; a shaded area is the threshold region (--threshold)"),
    ("surface_3d", "response surface"),
    ("slices", "slices through the surface"),
    ("predicted_vs_actual", "predicted vs actual"),
)
"""The plots ``rsm.plots.plot_all`` writes, with what they show."""


def _fits_table(fits: list[dict[str, Any]]) -> Html:
    rows = [
        [f["id"], f["y"], ", ".join(f["x"]), f["degree"], f["n"]]
        + [f["metrics"].get(k) for k in ("R2", "R2_adj", "Q2", "RMSE", "max_abs_RE_percent")]
        for f in fits
    ]
    heads = ["fit", "y", "x", "degree", "points", "R²", "R²adj", "Q²", "RMSE", "max |RE| %"]
    last = fits[-1]
    names = ", ".join(f"x{i} = {n}" for i, n in enumerate(last["x"], start=1))
    coef = table(
        ["term", "coefficient"],
        zip(last["terms"], last["coefficients"], strict=True),
        caption=f"Coefficients of fit {last['id']} (physical units; {names})",
    )
    return join([table(heads, rows), coef])


def _region(r: Mapping[str, Any] | None, y: str) -> Html:
    """The threshold region of a fit report, in words and as a bounding box."""
    if not r:
        return tag("p", "no threshold given (no threshold region)", cls="note")
    sign = "<" if r.get("below", True) else ">"
    share = r.get("area_fraction")
    area = f"{100.0 * share:.1f} %" if isinstance(share, int | float) else "—"
    rows = [
        [n, lo, hi]
        for n, lo, hi in zip(
            r.get("x") or [], r.get("lower") or [], r.get("upper") or [], strict=False
        )
    ]
    fixed = ", ".join(f"{k} = {fmt(v)}" for k, v in (r.get("fixed") or {}).items())
    text = f"{y} {sign} {fmt(r.get('threshold'))} on {area} of the box ({fmt(r.get('n_parts'))} part(s))"
    return join(
        [
            tag("p", text + (f"; held at {fixed}" if fixed else "")),
            table(["variable", "from", "to"], rows, caption="Bounding box of the threshold region"),
        ]
    )


def fit_json_block(path: Path) -> Html:
    """Extremes, threshold region and warnings of a ``fit.json`` (the JSON of ``rsm fit``)."""
    import json

    rep = json.loads(path.read_text(encoding="utf-8"))
    x, y = rep.get("x") or [], rep.get("y", "y")
    ext = [
        [what, *(e.get("x") or []), e.get("y")]
        for what, e in (
            ("minimum", rep.get("minimum") or {}),
            ("maximum", rep.get("maximum") or {}),
        )
    ]
    warn = [tag("li", w) for w in rep.get("warnings") or []]
    return join(
        [
            kv_table(
                [
                    ("surface", f"{y} = f({', '.join(x)}), degree {fmt(rep.get('degree'))}"),
                    (
                        "points / coefficients",
                        f"{fmt(rep.get('n_points'))} / {fmt(rep.get('n_terms'))}",
                    ),
                    *((k, v) for k, v in (rep.get("metrics") or {}).items()),
                ]
            ),
            table(["", *x, y], ext, caption="Extremes over the sampled box"),
            _region(rep.get("threshold_region"), y),
            tag("ul", join(warn), cls="note") if warn else "",
        ]
    )


def _whose(d: Path) -> str:
    """``rsm/``, and which fit of the trace its files are (a rerun rewrites them)."""
    import json

    try:
        fid = json.loads((d / "fit.json").read_text(encoding="utf-8")).get("trace_fit_id")
    except (OSError, ValueError, AttributeError):
        fid = None
    return f"{d.name}/" + (f": fit {fid} of the trace" if isinstance(fid, int) else "")


def rsm_fit_sections(folder: Path, fits: list[dict[str, Any]], report_dir: Path) -> list[Section]:
    """The response surfaces of a sweep or study: trace fits, fit.json and the plots."""
    out: list[Section] = []
    if fits:
        out.append(Section("fits", "Response-surface fits (trace)", _fits_table(fits)))
    folders = sorted(folder.glob("*_rsm")) + ([folder / "rsm"] if (folder / "rsm").is_dir() else [])
    for d in folders:
        plots = figure_grid((d / f"{n}.png", f"{d.name}/{n}.png — {what}") for n, what in PLOTS)
        fit = d / "fit.json"
        body = join(
            [
                join([fit_json_block(fit), tag("p", link(fit, report_dir, f"{d.name}/fit.json"))])
                if fit.is_file()
                else "",
                plots,
            ]
        )
        out.append(Section(f"rsm-{d.name}", f"Surfaces and threshold regions ({_whose(d)})", body))
    return out
