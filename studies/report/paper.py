"""The HTML report of a ``hingelab paper`` folder: both hinges beside the paper's tables."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from studies.report.parts import Section, cards, figures, fmt, join, link, table, tag
from studies.report.sections import ReportBody, read_json

HINGES = (
    ("general", "General hinge beside Table 1", ("clearance_mm", "amplitude_N")),
    ("modified", "Modified hinge beside Table 4", ("preload_N", "amplitude_N")),
)


def _hinge_section(folder: Path, name: str, title: str, xs: tuple[str, str], h: Any) -> Section:
    rows = [
        [
            p[xs[0]],
            p[xs[1]],
            p["eta_ours"],
            p["eta_paper"],
            (p["eta_ours"] / p["eta_paper"]) if p.get("eta_paper") else None,
        ]
        for p in h["points"]
    ]
    parts = [table([xs[0], xs[1], "η ours", "η paper", "ours / paper"], rows)]
    surf = h.get("surface")
    if surf:
        parts.append(
            tag(
                "p",
                f"Degree-{surf['degree']} surface: max |RE| {fmt(surf['max_abs_re_percent'])} %, "
                f"R² {fmt(surf['r2'])}, R²adj {fmt(surf['r2_adj'])}, RMSE {fmt(surf['rmse'])}, "
                f"Q² {fmt(surf['q2'])}; η from {fmt(h['eta_min'])} to {fmt(h['eta_max'])} on the "
                f"surface ({fmt(h['eta_min_points'])} to {fmt(h['eta_max_points'])} at the points).",
            )
        )
        parts.append(figures((folder / f, k) for k, f in surf["figures"].items()))
    return Section(f"paper-{name}", title, join(parts))


def _threshold_section(folder: Path, t: Any) -> Section:
    rows = []
    for name in ("general", "modified"):
        o, p = t[name]["ours"], t[name]["paper_fit"]
        rows.append(
            [
                name,
                None if o is None else 100 * o["fraction_below"],
                None if o is None else o["n_parts"],
                100 * p["fraction_below"],
                p["n_parts"],
            ]
        )
    sc = t["general"]["smallest_clearance_mm"]
    text = (
        f"Smallest clearance with η < 0.05: ours {fmt(sc['ours'])} mm, the paper's surface "
        f"{fmt(sc['paper_fit'])} mm, the paper's text {fmt(sc['paper_text'])} mm."
    )
    body = join(
        [
            table(["hinge", "ours below [%]", "pieces", "paper below [%]", "pieces"], rows),
            tag("p", text),
            figures([(folder / t["figure"], "η = 0.05 map")]),
        ]
    )
    return Section("paper-threshold", "Where η < 0.05 (Fig. 14)", body)


def _repeatability_section(rep: Any) -> Section:
    rows = [
        [
            r["hinge"],
            r["sigma_um"],
            r["theta_rad"],
            r["theta_rad_table7"],
            r["eta_table7"],
            r["eta_ours"],
        ]
        for r in rep["rows"]
    ]
    head = ["hinge", "σ [µm]", "θ = arcsin(6σ/L) [rad]", "θ Table 7", "η Table 7", "η ours"]
    return Section(
        "paper-repeatability",
        "Repeatability and η (Table 7)",
        join([table(head, rows), tag("p", rep["note"])]),
    )


def paper_study_report(folder: Path, report_dir: Path) -> ReportBody:
    """Read a ``hingelab paper`` folder (report.json, both sweeps, figures)."""
    r = read_json(folder / "report.json")
    study = r["study"]
    sections = []
    for name, title, xs in HINGES:
        if r.get(name):
            sections.append(_hinge_section(folder, name, title, xs, r[name]))
    if "reduction_percent" in r:
        red, paper = r["reduction_percent"], r["reduction_percent_paper"]
        body = join(
            [
                tag("p", f"Between the {r.get('reduction_basis', 'surface extremes')}."),
                table(
                    ["", "ours [%]", "paper [%]"],
                    [["η_min", red["min"], paper["min"]], ["η_max", red["max"], paper["max"]]],
                ),
            ]
        )
        sections.append(Section("paper-reduction", "What the bearing brings", body))
    if r.get("validation_points"):
        rows = [
            [v["hinge"], v["quantity"], v["paper_fe"], v["paper_test"], v["ours"]]
            for v in r["validation_points"]
        ]
        table_html = table(["hinge", "quantity (400 N)", "paper FE", "paper test", "ours"], rows)
        sections.append(
            Section("paper-validation-points", "The 400 N validation points", table_html)
        )
    if r.get("threshold"):
        sections.append(_threshold_section(folder, r["threshold"]))
    if r.get("repeatability"):
        sections.append(_repeatability_section(r["repeatability"]))
    loops = [(folder / "figures" / v, k) for k, v in (r.get("loops") or {}).items() if v]
    if loops:
        sections.append(Section("paper-loops", "Loops", figures(loops)))
    sections.append(
        Section(
            "paper-files",
            "Files",
            join(tag("p", link(folder / f, report_dir)) for f in ("report.md", "report.json")),
        )
    )
    flags = f"{' --quick' if study['quick'] else ''} --interfaces {study['interfaces']}"
    counts = [
        f"{n}: {s['ok'] + s['cached'] + s['skipped']} ok, {s['failed']} failed"
        for n, s in r["sweeps"].items()
    ]
    run: list[tuple[str, object]] = [
        ("command", f"hingelab paper{flags} --mu {study['mu']}"),
        ("points", ", ".join(counts)),
        ("wall time", f"{fmt(r['wall_s'])} s"),
        (
            "points computed in",
            ", ".join(f"{n} {fmt(s.get('compute_s'))} s" for n, s in r["sweeps"].items())
            + " (their own wall times when they ran, setup included)",
        ),
    ]
    ranges = []
    for name, label in (("general", "general η (points)"), ("modified", "modified η (points)")):
        if r.get(name):
            h = r[name]
            ranges.append((label, f"{fmt(h['eta_min_points'])} – {fmt(h['eta_max_points'])}"))
    summary = cards(ranges)
    sections.insert(0, Section("paper-summary", "Summary", summary))
    return ReportBody("The paper's study with hingelab's FE", run, sections)
