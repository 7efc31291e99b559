"""Sections of the HTML report for validation runs and the paper checks.

``compare`` (comparison.json, loops/, error_map.png, …), ``calibrate`` (ledger.json,
MODEL.toml, compare/), ``python -m studies.paper.validation`` (report.json,
compare_*/, diagnose_*.txt) and ``hingelab rsm paper`` (paper_comparison.json and the
surface plots). Nothing here writes files.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from studies.report.parts import (
    Html,
    Section,
    cards,
    figure,
    figures,
    fmt,
    join,
    kv_table,
    link,
    links,
    pct,
    scroll,
    table,
    tag,
    verdict,
)
from studies.report.sections import ReportBody, read_json

METRIC_LABELS = {
    "disp_at_peak_mm": "δ(+Fg)",
    "W_cycle_Nmm": "W_cycle",
    "eta": "η",
    "secant_stiffness_N_per_mm": "k_sec",
    "rms_loop": "RMS loop / δ_max",
}
"""The metrics ``validation.compare`` forms per case, in its report order."""


def _error_cell(case: Mapping[str, Any], metric: str) -> object:
    errors = case.get("errors") or {}
    if metric in (case.get("not_measurable") or []):
        return tag(
            "span", "n/m", cls="na", title="not measurable at this noise: neither pass nor fail"
        )
    if metric not in errors:
        return "—"
    text = pct(errors[metric])
    if metric in (case.get("failed") or []):
        return tag("span", text + " *", cls="fail")
    return Html(tag("span", text))


def _eta(loop: Mapping[str, Any] | None, case: Mapping[str, Any]) -> object:
    """η as ``compare`` judged it: without the free play where it was removed (marked ′)."""
    loop = loop or {}
    if case.get("free_play_removed"):
        value = loop.get("eta_without_free_play")
        return None if value is None else f"{value:.3g} ′"
    return loop.get("eta")


def _cases_table(cases: list[Mapping[str, Any]], report_dir: Path) -> Html:
    metrics = [
        m
        for m in METRIC_LABELS
        if any(m in (c.get("errors") or {}) or m in (c.get("not_measurable") or []) for c in cases)
    ]
    heads = ["case", "Δr [mm]", "Fg [N]", *(f"{METRIC_LABELS[m]} error" for m in metrics)]
    heads += ["η measured", "η model", "verdict", "measurement"]
    rows = []
    for c in cases:
        src = c.get("source")
        rows.append(
            [c.get("case_id"), c.get("clearance_mm"), c.get("amplitude_N")]
            + [_error_cell(c, m) for m in metrics]
            + [_eta(c.get("measured"), c), _eta(c.get("model"), c)]
            + [verdict(c.get("passed")), link(Path(src), report_dir) if src else "—"]
        )
    note = (
        "η′: the loop without the free play (as compare judges clearance cases); "
        "n/m: not measurable at the record's noise, neither pass nor fail"
    )
    return scroll(table(heads, rows, caption=note))


def _metric_summary(summary: Mapping[str, Any]) -> Html:
    rows = [
        [
            METRIC_LABELS.get(m, m),
            s.get("n"),
            pct(s.get("bias")),
            pct(s.get("rms")),
            pct(s.get("max_abs")),
            s.get("worst_case"),
            s.get("n_fail"),
        ]
        for m, s in (summary.get("metrics") or {}).items()
    ]
    heads = ["metric", "cases", "bias", "RMS", "max |error|", "worst case", "failing"]
    return table(heads, rows, caption="Error ledger per metric (relative errors)")


def _fingerprint(fp: list[Mapping[str, Any]]) -> Html:
    if not fp:
        return Html("")
    rows = [
        [
            f.get("group"),
            f.get("slope_W_measured"),
            f.get("slope_W_model"),
            f.get("slope_eta_measured"),
            f.get("slope_eta_model"),
        ]
        for f in fp
    ]
    heads = ["group", "W slope measured", "W slope model", "η slope measured", "η slope model"]
    return table(heads, rows, caption="Fingerprint: log-log slopes over the amplitude")


def compare_sections(folder: Path, report_dir: Path, prefix: str = "") -> list[Section]:
    """The sections of one ``compare`` folder (``prefix`` keeps anchors unique)."""
    c = read_json(folder / "comparison.json")
    summary = c.get("summary") or {}
    cases = c.get("cases") or []
    loops = sorted((folder / "loops").glob("*.png"))
    model_loops = sorted((folder / "model_loops").glob("*.csv"))
    k = (c.get("settings") or {}).get("k")
    head = cards(
        [
            ("cases passing", f"{fmt(summary.get('n_pass'))} / {fmt(summary.get('n_cases'))}"),
            ("criterion", f"|error| ≤ {fmt(k)} σ"),
            ("model loop with free play", fmt(c.get("model_loop_free_play"))),
        ]
    )
    note = tag(
        "p", "* marks a failing metric. Errors are (model − measured) / measured.", cls="note"
    )
    return [
        Section(
            f"{prefix}comparison",
            f"{prefix}Comparison table",
            join([head, note, _cases_table(cases, report_dir)]),
        ),
        Section(
            f"{prefix}ledger",
            f"{prefix}Errors per metric",
            join(
                [
                    _metric_summary(summary),
                    _fingerprint(c.get("fingerprint") or []),
                    figures(
                        (folder / f"{n}.png", f"{n}.png")
                        for n in ("error_map", "residuals", "fingerprint")
                    ),
                ]
            ),
        ),
        Section(
            f"{prefix}loops",
            f"{prefix}Loops: model and measurement",
            join(
                [
                    figures((p, f"loops/{p.name}") for p in loops)
                    or tag("p", "no loop pictures (an η-only table has no loops)", cls="note"),
                    tag(
                        "p",
                        join(
                            ["model loops: ", links(((p.name, p) for p in model_loops), report_dir)]
                        ),
                    ),
                ]
            ),
        ),
    ]


def _compare_run(c: Mapping[str, Any], command: str) -> list[tuple[str, object]]:
    s = c.get("settings") or {}
    return [
        ("command", command),
        ("model file", c.get("model_file", "—")),
        ("measurements", c.get("data", "—")),
        ("pass criterion k [σ]", s.get("k")),
        ("default relative uncertainty", s.get("default_rel_uncertainty")),
        ("wall time [s]", c.get("wall_s")),
    ]


def compare_report(folder: Path, report_dir: Path) -> ReportBody:
    """Read a ``hingelab compare`` folder."""
    c = read_json(folder / "comparison.json")
    return ReportBody(
        "Model vs measurement (compare)",
        _compare_run(c, "hingelab compare MODEL.toml DATA_DIR"),
        compare_sections(folder, report_dir),
    )


def calibrate_report(folder: Path, report_dir: Path) -> ReportBody:
    """Read a ``hingelab calibrate`` folder (ledger, calibrated MODEL.toml, compare/)."""
    ledger = read_json(folder / "ledger.json")
    rows = [
        [
            r.get("step"),
            ", ".join(f"{k} = {fmt(v)}" for k, v in (r.get("params") or {}).items()),
            r.get("n_params"),
            r.get("chi2"),
            r.get("error"),
            r.get("heldout_error"),
            r.get("aic"),
            r.get("bic"),
        ]
        for r in ledger
    ]
    heads = ["step", "parameters", "n", "χ²", "error [σ]", "held-out [σ]", "AIC", "BIC"]
    model = folder / "MODEL.toml"
    model_text = model.read_text(encoding="utf-8") if model.is_file() else "(no MODEL.toml)"
    sections = [
        Section(
            "ledger",
            "Error ledger",
            join([table(heads, rows), figure(folder / "ledger.png", "ledger.png", wide=True)]),
        ),
        Section(
            "model",
            "Calibrated model",
            join([tag("p", link(model, report_dir, "MODEL.toml")), scroll(tag("pre", model_text))]),
        ),
    ]
    if (folder / "compare" / "comparison.json").is_file():
        sections += compare_sections(folder / "compare", report_dir, prefix="Calibrated model: ")
    last = ledger[-1] if ledger else {}
    run: list[tuple[str, object]] = [
        ("command", "hingelab calibrate MODEL.toml DATA_DIR --effects …"),
        ("steps", " → ".join(str(r.get("step")) for r in ledger)),
        (
            "fitted parameters",
            ", ".join(f"{k} = {fmt(v)}" for k, v in (last.get("params") or {}).items()) or "—",
        ),
    ]
    return ReportBody("Calibration", run, sections)


def _diagnosis(folder: Path, label: str, d: Mapping[str, Any]) -> Html:
    rows = [
        [c.get("name"), c.get("param"), c.get("value"), c.get("unit"), c.get("chi2")]
        for c in d.get("candidates") or []
    ]
    txt = folder / f"{label}.txt"
    return join(
        [
            tag(
                "p", join([tag("b", f"verdict: {d.get('verdict')}"), f" — {d.get('message', '')}"])
            ),
            kv_table(
                [("χ² baseline", d.get("chi2_base")), ("χ² noise limit", d.get("chi2_noise_limit"))]
            ),
            table(["candidate", "parameter", "value", "unit", "χ²"], rows) if rows else Html(""),
            _signatures(d.get("signatures")),
            tag("pre", txt.read_text(encoding="utf-8")) if txt.is_file() else Html(""),
        ]
    )


def _signatures(sig: Mapping[str, Any] | None) -> Html:
    """The residual's signature table of an unexplained diagnosis (``validation.signatures``)."""
    if not sig:
        return Html("")
    rows = [
        [
            r.get("kind"),
            r.get("what"),
            r.get("size"),
            r.get("unit"),
            r.get("p_value"),
            r.get("word"),
        ]
        for r in sig.get("rows") or []
    ]
    return join(
        [
            tag("p", f"What kind of effect is missing (α = {fmt(sig.get('alpha'))}):"),
            table(["signature", "shape", "size", "unit", "p", "at α"], rows),
            tag("p", str(sig.get("summary", ""))),
        ]
    )


def paper_validation_report(folder: Path, report_dir: Path) -> ReportBody:
    """Read a ``python -m studies.paper.validation`` folder."""
    r = read_json(folder / "report.json")
    model = r.get("model") or {}
    mesh = model.get("mesh") or {}
    cases = [
        [
            c.get("clearance_mm"),
            c.get("amplitude_N"),
            c.get("eta_paper"),
            c.get("eta_model"),
            pct(c.get("eta_error"), 0),
        ]
        for key in ("compare_table1", "compare_test_point")
        for c in (r.get(key) or {}).get("cases", [])
    ]
    sections = [
        Section(
            "eta",
            "η: the paper against our model",
            table(["Δr [mm]", "Fg [N]", "η paper", "η model", "error"], cases),
        )
    ]
    for label in ("diagnose_zero_clearance", "diagnose_3x3"):
        if label in r:
            sections.append(
                Section(label, f"Diagnosis: {label}", _diagnosis(folder, label, r[label]))
            )
    for label in ("table1", "test_point"):
        sub = folder / f"compare_{label}"
        if (sub / "comparison.json").is_file():
            sections += compare_sections(sub, report_dir, prefix=f"compare_{label}: ")
    sections.append(
        Section(
            "files",
            "Files",
            links(
                [("report.md", folder / "report.md"), ("report.json", folder / "report.json")],
                report_dir,
            ),
        )
    )
    run: list[tuple[str, object]] = [
        ("command", "python -m studies.paper.validation"),
        ("model", "default general hinge (ModelSpec defaults)"),
        ("friction coefficient μ", model.get("mu")),
        ("mesh", ", ".join(f"{k} = {fmt(v)}" for k, v in mesh.items()) or "—"),
        ("wall time [s]", r.get("wall_s")),
    ]
    return ReportBody("Our model against the paper's published values", run, sections)


def _share(value: object) -> str:
    """Format a fraction (0.16) as an unsigned percentage (16.0 %)."""
    return f"{100.0 * value:.1f} %" if isinstance(value, int | float) else "—"


def _hinge_section(folder: Path, name: str, h: Mapping[str, Any]) -> Section:
    x = h.get("x_names") or []
    metrics = kv_table((k, v) for k, v in (h.get("metrics") or {}).items())
    ext = [
        [what, *(e.get("x") or []), e.get("eta")]
        for what, e in (("minimum", h.get("minimum") or {}), ("maximum", h.get("maximum") or {}))
    ]
    regions = [
        [
            key,
            ", ".join(
                f"{n} ∈ [{fmt(lo)}, {fmt(hi)}]"
                for n, lo, hi in zip(x, v.get("lower") or [], v.get("upper") or [], strict=False)
            ),
            _share(v.get("area_fraction")),
        ]
        for key, v in h.items()
        if key.startswith("eta_below") or key.startswith("eta_above")
    ]
    coef = table(
        ["term", "coefficient"],
        zip(h.get("terms") or [], h.get("coefficients") or [], strict=False),
    )
    plots = figures(
        (folder / f"{name}_{p}.png", f"{name}_{p}.png")
        for p in ("contour", "surface_3d", "slices", "predicted_vs_actual")
    )
    body = join(
        [
            metrics,
            table(["", *x, "η"], ext, caption="Extremes over the box"),
            table(["region", "bounding box", "area"], regions, caption="Threshold regions")
            if regions
            else "",
            plots,
            tag("h3", "Coefficients (physical units)"),
            coef,
        ]
    )
    return Section(f"hinge-{name}", f"{name} hinge: surface and threshold region", body)


def rsm_paper_report(folder: Path, report_dir: Path) -> ReportBody:
    """Read a ``hingelab rsm paper`` folder (paper_comparison.json and plots)."""
    r = read_json(folder / "paper_comparison.json")
    checks = r.get("checks") or []
    missed = [c for c in checks if not c.get("reproduced")]
    rows = [
        [
            c.get("hinge"),
            c.get("item"),
            c.get("printed"),
            c.get("ours"),
            c.get("difference"),
            c.get("tolerance"),
            c.get("note"),
        ]
        for c in missed
    ]
    heads = ["hinge", "item", "printed", "ours", "difference", "tolerance", "note"]
    sections = [
        Section(
            "checks",
            "What reproduces",
            join(
                [
                    cards(
                        [
                            (
                                "checks reproduced",
                                f"{fmt(r.get('n_reproduced'))} / {fmt(r.get('n_checks'))}",
                            )
                        ]
                    ),
                    table(heads, rows, caption="Checks that do not reproduce") if rows else "",
                ]
            ),
        )
    ]
    sections += [_hinge_section(folder, n, r[n]) for n in ("general", "modified") if n in r]
    sections.append(
        Section(
            "files",
            "Files",
            links(
                [
                    ("paper_comparison.md", folder / "paper_comparison.md"),
                    ("paper_comparison.json", folder / "paper_comparison.json"),
                ],
                report_dir,
            ),
        )
    )
    run: list[tuple[str, object]] = [
        ("command", "hingelab rsm paper (the paper's Tables 1 and 4 refitted)"),
        ("checks", r.get("n_checks")),
    ]
    return ReportBody("The paper's response surfaces refitted", run, sections)
