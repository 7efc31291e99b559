"""The HTML report of a ``hingelab paper`` folder: both hinges beside the paper's tables."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from studies.html_parts import Section, cards, figures, fmt, join, link, table, tag
from studies.html_sections import ReportBody, read_json

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
    ]
    ranges = []
    for name, label in (("general", "general η (points)"), ("modified", "modified η (points)")):
        if r.get(name):
            h = r[name]
            ranges.append((label, f"{fmt(h['eta_min_points'])} – {fmt(h['eta_max_points'])}"))
    summary = cards(ranges)
    sections.insert(0, Section("paper-summary", "Summary", summary))
    return ReportBody("The paper's study with hingelab's FE", run, sections)
