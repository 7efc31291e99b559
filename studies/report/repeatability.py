"""Sections of the HTML report for a repeatability folder (``hingelab repeatability``).

The folder holds ``repeatability.json`` (one entry per hinge: σ, θ = arcsin(6σ/L) with
their intervals, the normality tests, the readings' rounding), ``repeatability.csv``,
a histogram per hinge and, with η for two or more hinges, ``eta_theta.png``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from studies.report.parts import Html, Section, cards, fmt, join, link, table, tag
from studies.report.parts import figures as figure_grid
from studies.report.sections import ReportBody, read_json


def _interval(ci: Mapping[str, Any] | None, lo: str = "lo", hi: str = "hi") -> str:
    ci = ci or {}
    return f"[{fmt(ci.get(lo))}, {fmt(ci.get(hi))}]"


def _hinge_rows(hinges: list[Mapping[str, Any]]) -> list[list[object]]:
    rows = []
    for h in hinges:
        sw, ad = h.get("shapiro_wilk") or {}, h.get("anderson_darling") or {}
        rows.append(
            [
                h.get("hinge"),
                h.get("n"),
                h.get("sigma_um"),
                _interval(h.get("sigma_ci_um")),
                h.get("six_sigma_um"),
                h.get("theta_rad"),
                _interval(h.get("theta_ci_rad")),
                h.get("eta"),
                sw.get("p_value"),
                "rejects" if sw.get("rejects_normal") else "does not reject",
                ad.get("statistic"),
                "rejects" if ad.get("rejects_normal") else "does not reject",
            ]
        )
    return rows


def _correlation(doc: Mapping[str, Any]) -> Html:
    c = doc.get("correlation")
    if not c:
        return tag("p", f"no η–θ correlation: {doc.get('correlation_reason') or '—'}", cls="note")
    change = c.get("relative_change") or {}
    return join(
        [
            cards(
                [
                    ("slope dθ/dη [rad]", fmt(c.get("slope_rad"))),
                    ("Pearson r", fmt(c.get("pearson_r"))),
                    ("p-value", fmt(c.get("p_value"))),
                    ("relative change of η / θ", f"{fmt(change.get('eta'))} / {fmt(change.get('theta'))}"),
                ]
            ),
            tag("p", c.get("note") or "", cls="note"),
        ]
    )  # fmt: skip


def repeatability_report(folder: Path, report_dir: Path) -> ReportBody:
    """Read a ``hingelab repeatability`` folder (repeatability.json, .csv, histograms)."""
    doc = read_json(folder / "repeatability.json")
    hinges = list(doc["hinges"])
    confidence = doc.get("confidence")
    pct = f"{100 * confidence:g} %" if isinstance(confidence, int | float) else "—"
    heads = ["hinge", "n", "σ [µm]", f"σ {pct} interval", "6σ [µm]", "θ [rad]"]
    heads += [f"θ {pct} interval", "η", "Shapiro–Wilk p", "", "Anderson–Darling A²", ""]
    notes = [h["resolution"]["note"] for h in hinges if (h.get("resolution") or {}).get("note")]
    names = {Path(str(v)).name for v in (doc.get("files") or {}).values()}
    histograms = sorted(n for n in names if n.startswith("histogram_") and n.endswith(".png"))
    run: list[tuple[str, object]] = [
        ("command", "hingelab repeatability READINGS.csv --length-mm L --out DIR"),
        ("readings", doc.get("readings_file", "—")),
        ("label", doc.get("label", "—")),
        ("axis-to-sensor distance L [mm]", doc.get("length_mm")),
        ("interval coverage", pct),
        ("normality tests at α", doc.get("normality_alpha")),
        ("formula", doc.get("formula", "—")),
    ]
    sections = [
        Section(
            "theta",
            "Repeatability θ per hinge",
            join(
                [
                    table(heads, _hinge_rows(hinges)),
                    join(tag("p", n, cls="note") for n in notes),
                    tag("p", doc.get("eq14_note") or "", cls="note"),
                ]
            ),
        ),
        Section(
            "histograms",
            "Readings and fitted normal laws",
            figure_grid((folder / n, n) for n in histograms)
            or tag("p", "no histograms", cls="note"),
        ),
        Section(
            "eta-theta",
            "η and θ",
            join(
                [
                    _correlation(doc),
                    figure_grid([(folder / "eta_theta.png", "eta_theta.png — θ against η")]),
                ]
            ),
        ),
        Section(
            "files",
            "Files",
            join(
                tag("p", link(folder / n, report_dir))
                for n in ("repeatability.json", "repeatability.csv", *histograms)
            ),
        ),
    ]
    return ReportBody("Repeatability", run, sections)
