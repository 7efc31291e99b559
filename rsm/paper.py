"""The paper as an external check: refit its tables and compare with what it printed.

The paper (Sec. III-IV, V.A) prints, for each hinge, 25 finite-element sample
points (Tables 1 and 4), a quartic response surface fitted to them (Eqs. 6 and
13), the surface's value at each point with the relative error (Tables 2 and 5),
and a few conclusions drawn from the surfaces (extremes over the box, the
η < 0.05 region, the η values of Table 7). This module refits the tables with
:func:`rsm.polynomial.fit_response_surface` and checks each printed number
against the refit *at the number's printed precision*. Nothing is tuned to
agree: what does not reproduce is reported with the size of the disagreement.

The printed numbers (transcribed from the paper's text) and the shipped sample tables are
in ``rsm.paper_printed``; this module refits, compares and writes the report.

Tables 3 and 6 (the paper's R², R²_adj, RMSE) are missing from the text
extraction available to the project, so they cannot be compared; the report
gives the project's values for them.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from model.jsonio import dumps
from rsm.metrics import FitMetrics, fit_metrics
from rsm.paper_printed import (
    ETA_THRESHOLD,
    GENERAL,
    MODIFIED,
    PRINTED_CLEARANCE_FOR_THRESHOLD_MM,
    PRINTED_REDUCTION_PERCENT,
    PRINTED_TABLE7_ETA,
    TABLE7_POINT,
    HingeCase,
    half_unit,
    paper_table_path,
)
from rsm.polynomial import ResponseSurface, design_matrix, fit_response_surface, predict
from rsm.query import Extrema, ThresholdRegion, extrema, threshold_region
from rsm.tables import numeric_column, read_table, xy_from_table

__all__ = [
    "Check",
    "HingeComparison",
    "PaperComparison",
    "ReportFiles",
    "UnscaledFits",
    "compare_hinge",
    "compare_with_paper",
    "fit_paper_table",
    "report_json",
    "report_markdown",
    "write_report",
]


@dataclass(frozen=True)
class Check:
    """One printed number set beside the project's value.

    Attributes:
        hinge: ``general``, ``modified`` or ``both``.
        item: What is compared, e.g. ``Eq. 6 coefficient x1^2``.
        printed: The paper's value.
        ours: The project's value from its own fit of the paper's table.
        difference: ``ours - printed``.
        tolerance: The largest difference that rounding of the printed value explains.
        reproduced: ``|difference| <= tolerance``.
        note: How the project's value was obtained or why it differs.
    """

    hinge: str
    item: str
    printed: float
    ours: float
    difference: float
    tolerance: float
    reproduced: bool
    note: str = ""


def _check(hinge: str, item: str, printed: float, ours: float, tol: float, note: str = "") -> Check:
    diff = ours - printed
    return Check(hinge, item, printed, ours, diff, tol, bool(abs(diff) <= tol * (1 + 1e-9)), note)


def fit_paper_table(case: HingeCase, degree: int = 4) -> ResponseSurface:
    """Fit the paper's sample table of one hinge (η from the FE column)."""
    with paper_table_path(case.csv_name) as p:
        xy = xy_from_table(read_table(p), case.x_names, "eta_fe")
    return fit_response_surface(
        xy.x, xy.y, degree, x_names=xy.x_names, y_name="eta", labels=xy.labels
    )


@dataclass(frozen=True)
class HingeComparison:
    """Everything computed for one hinge."""

    case: HingeCase
    surface: ResponseSurface
    metrics: FitMetrics
    extrema: Extrema
    region: ThresholdRegion
    checks: tuple[Check, ...]
    unscaled: UnscaledFits


def _coefficient_checks(case: HingeCase, s: ResponseSurface) -> list[Check]:
    names = s.term_names
    return [
        _check(
            case.name,
            f"{case.equation} coefficient {name}",
            float(txt),
            float(b),
            half_unit(txt),
            f"printed as {txt}",
        )
        for name, txt, b in zip(names, case.printed_coefficients, s.coefficients, strict=True)
    ]


def _table_checks(case: HingeCase, s: ResponseSurface, m: FitMetrics) -> list[Check]:
    with paper_table_path(case.csv_name) as p:
        printed = numeric_column(read_table(p), case.approx_column)
    ours = predict(s, s.x)
    eq = design_matrix(s.x, s.exponents) @ np.array([float(t) for t in case.printed_coefficients])
    out = [
        _check(case.name, f"{case.table} approximation, point {k + 1}", float(a), float(b), 0.5e-7)
        for k, (a, b) in enumerate(zip(printed, ours, strict=True))
    ]
    # The paper's deviations follow from its rounded approximations (Eq. 7 applied to the
    # printed columns), so they are recomputed from those; the fit itself is checked above.
    with paper_table_path(case.csv_name) as p:
        y_fe = numeric_column(read_table(p), "eta_fe")
    re_printed = 100.0 * (printed - y_fe) / y_fe
    out += [
        _check(
            case.name,
            f"{case.table} deviation %, point {k + 1}",
            float(t),
            float(r),
            half_unit(t),
            f"Eq. 7 applied to the printed {case.table} columns",
        )
        for k, (t, r) in enumerate(zip(case.printed_deviation_percent, re_printed, strict=True))
    ]
    k_worst = int(np.argmax(np.abs(eq - printed)))
    out.append(
        _check(
            case.name,
            f"{case.equation} as printed vs {case.table} (worst point {k_worst + 1})",
            float(printed[k_worst]),
            float(eq[k_worst]),
            0.5e-7,
            f"the printed {case.equation} coefficients, used as they stand, at the table's points",
        )
    )
    out.append(
        _check(
            case.name,
            "max |RE| over the table, %",
            case.printed_max_re_percent,
            m.max_abs_re_percent,
            0.0005,
        )
    )
    return out


@dataclass(frozen=True)
class UnscaledFits:
    """How far two unscaled solutions of the same least-squares problem land from the QR fit.

    Attributes:
        normal_equations: Max |Δỹ| at the samples for Eq. 4 solved literally (LU on ΦᵀΦ).
        lstsq_default_cutoff: Max |Δỹ| for ``numpy.linalg.lstsq`` on the physical-unit Φ
            with its default singular-value cutoff, which drops singular values below
            ``max(M, N) · eps · σ_max``.
        lstsq_max_coefficient_rel_error: Largest relative coefficient error of that lstsq fit.
    """

    normal_equations: float
    lstsq_default_cutoff: float
    lstsq_max_coefficient_rel_error: float


def _unscaled_fits(s: ResponseSurface) -> UnscaledFits:
    phi = design_matrix(s.x, s.exponents)
    ref = predict(s, s.x)
    try:
        b_ne = np.linalg.solve(phi.T @ phi, phi.T @ s.y)
        ne = float(np.max(np.abs(phi @ b_ne - ref)))
    except np.linalg.LinAlgError:
        ne = math.inf
    b_ls = np.linalg.lstsq(phi, s.y, rcond=None)[0]
    return UnscaledFits(
        normal_equations=ne,
        lstsq_default_cutoff=float(np.max(np.abs(phi @ b_ls - ref))),
        lstsq_max_coefficient_rel_error=float(np.max(np.abs(b_ls / s.coefficients - 1.0))),
    )


def compare_hinge(case: HingeCase) -> HingeComparison:
    """Refit one hinge's table and check every printed number derived from it."""
    s = fit_paper_table(case)
    m = fit_metrics(s, warn=False)
    ext = extrema(s)
    region = threshold_region(s, ETA_THRESHOLD)
    checks = _coefficient_checks(case, s) + _table_checks(case, s, m)
    k_lo, k_hi = int(np.argmin(s.y)), int(np.argmax(s.y))
    checks.append(
        _check(
            case.name,
            "minimum η over the box",
            case.printed_min,
            ext.minimum.value,
            0.00005,
            f"at {_xfmt(ext.minimum.x)}; smallest table value {s.y[k_lo]:g} at {_xfmt(s.x[k_lo])}",
        )
    )
    checks.append(
        _check(
            case.name,
            "maximum η over the box",
            case.printed_max,
            ext.maximum.value,
            0.00005,
            f"at {_xfmt(ext.maximum.x)}; largest table value {s.y[k_hi]:g} at {_xfmt(s.x[k_hi])}",
        )
    )
    t7 = float(predict(s, np.array(TABLE7_POINT[case.name]))[0])
    checks.append(
        _check(
            case.name,
            "Table 7 η",
            PRINTED_TABLE7_ETA[case.name],
            t7,
            0.00005,
            f"surface at ({', '.join(case.x_names)}) = {TABLE7_POINT[case.name]}",
        )
    )
    return HingeComparison(case, s, m, ext, region, tuple(checks), _unscaled_fits(s))


@dataclass(frozen=True)
class PaperComparison:
    """Both hinges and the cross-hinge checks."""

    general: HingeComparison
    modified: HingeComparison
    cross_checks: tuple[Check, ...]

    @property
    def checks(self) -> tuple[Check, ...]:
        """Every check, general hinge first."""
        return self.general.checks + self.modified.checks + self.cross_checks


def compare_with_paper() -> PaperComparison:
    """Run every comparison with the paper.

    Returns:
        The fits, their metrics and one :class:`Check` per printed number.
    """
    g, mo = compare_hinge(GENERAL), compare_hinge(MODIFIED)
    gmin, gmax = g.extrema.minimum.value, g.extrema.maximum.value
    mmin, mmax = mo.extrema.minimum.value, mo.extrema.maximum.value
    t7g = float(predict(g.surface, np.array(TABLE7_POINT["general"]))[0])
    t7m = float(predict(mo.surface, np.array(TABLE7_POINT["modified"]))[0])
    # The paper's percentages follow from its 4-decimal η values; do the same.
    note = "from the project's η values rounded to 4 decimals, as the paper's are"
    cross = [
        _check(
            "both",
            "reduction of the minimum η, %",
            PRINTED_REDUCTION_PERCENT["min"],
            _reduction(gmin, mmin),
            0.005,
            note,
        ),
        _check(
            "both",
            "reduction of the maximum η, %",
            PRINTED_REDUCTION_PERCENT["max"],
            _reduction(gmax, mmax),
            0.005,
            note,
        ),
        _check(
            "both",
            "Table 7 reduction of η, %",
            PRINTED_REDUCTION_PERCENT["table7"],
            _reduction(t7g, t7m),
            0.005,
            note,
        ),
        _check(
            "general",
            "smallest clearance with η < 0.05, mm",
            PRINTED_CLEARANCE_FOR_THRESHOLD_MM,
            float(g.region.lower[0]),
            0.00005,
            f"the η = 0.05 boundary meets F_g = {g.region.lower[1]:g} N there",
        ),
    ]
    return PaperComparison(g, mo, tuple(cross))


def _xfmt(x: npt.NDArray[np.float64]) -> str:
    return "(" + ", ".join(f"{float(v):.5g}" for v in x) + ")"


def _reduction(general: float, modified: float) -> float:
    g, m = round(general, 4), round(modified, 4)
    return 100.0 * (g - m) / g


def _fmt(v: float) -> str:
    return f"{v:.6g}" if math.isfinite(v) else str(v)


def _summary_rows(checks: tuple[Check, ...], prefix: str) -> tuple[int, int, Check | None]:
    group = [c for c in checks if c.item.startswith(prefix)]
    ok = sum(c.reproduced for c in group)
    worst = max(group, key=lambda c: abs(c.difference) / c.tolerance, default=None)
    return ok, len(group), worst


def report_markdown(cmp: PaperComparison) -> str:
    """Write the comparison as a short Markdown report."""
    lines = [
        "# The paper's response surfaces, refitted",
        "",
        "Generated by `rsm.paper` from the paper's Tables 1 and 4 (values as printed). "
        "Each printed number is compared with the project's least-squares quartic "
        "(scaled variables, QR) at the number's printed precision; *tolerance* is half a unit "
        "in its last printed digit. Nothing is adjusted to agree.",
        "",
    ]
    for h in (cmp.general, cmp.modified):
        m, s = h.metrics, h.surface
        lines += [
            f"## {h.case.name.capitalize()} hinge ({h.case.equation}, {h.case.table})",
            "",
            f"Fit: M = {m.n_points} points, N = {m.n_terms} terms, R² = {m.r2:.6f}, "
            f"R²_adj = {m.r2_adj:.6f}, RMSE (Eq. 10, M−N−1) = {m.rmse:.4g}, "
            f"max |RE| = {m.max_abs_re_percent:.4f} %, Q² (LOO) = {m.q2:.5f}, "
            f"condition number {s.condition_number:.3g} scaled "
            f"({s.condition_number_unscaled:.3g} in physical units).",
            f"Unscaled solutions of the same problem: Eq. 4 solved literally (normal equations) "
            f"lands within {h.unscaled.normal_equations:.3g} of the QR fit at the samples, but "
            f"`numpy.linalg.lstsq` on the physical-unit Φ with its default cutoff lands "
            f"{h.unscaled.lstsq_default_cutoff:.3g} away, with coefficients off by up to "
            f"{100 * h.unscaled.lstsq_max_coefficient_rel_error:.3g} %.",
            "",
        ]
        for prefix, what in (
            (f"{h.case.equation} coefficient", f"{h.case.equation} coefficients"),
            (f"{h.case.table} approximation", f"{h.case.table} approximations (7 decimals)"),
            (f"{h.case.table} deviation", f"{h.case.table} deviations (3 decimals, %)"),
        ):
            ok, n, worst = _summary_rows(h.checks, prefix)
            tail = (
                ""
                if worst is None
                else (
                    f"; largest difference {worst.difference:+.3g} at {worst.item.split(', ')[-1]} "
                    f"(printed {_fmt(worst.printed)}, ours {_fmt(worst.ours)})"
                )
            )
            lines.append(f"- {what}: {ok} of {n} reproduce{tail}.")
        lines.append("")
    lines += [
        "## Single numbers",
        "",
        "| hinge | item | printed | ours | difference | reproduced |",
        "|---|---|---|---|---|---|",
    ]
    singles = [
        c
        for c in cmp.checks
        if not any(k in c.item for k in ("coefficient", "approximation, point", "deviation %"))
    ]
    for c in singles:
        mark = "yes" if c.reproduced else "**no**"
        note = f" ({c.note})" if c.note else ""
        lines.append(
            f"| {c.hinge} | {c.item}{note} | {_fmt(c.printed)} | {_fmt(c.ours)} | "
            f"{c.difference:+.3g} | {mark} |"
        )
    not_ok = [c for c in cmp.checks if not c.reproduced]
    lines += [
        "",
        f"**{len(cmp.checks) - len(not_ok)} of {len(cmp.checks)} printed numbers "
        f"reproduce; {len(not_ok)} do not:**",
        "",
    ]
    lines += [
        f"- {c.hinge}: {c.item}: printed {_fmt(c.printed)}, ours {_fmt(c.ours)} "
        f"(difference {c.difference:+.3g}, {_rel(c)})."
        for c in not_ok
    ]
    lines += [
        "",
        "Tables 3 and 6 (the paper's R², R²_adj, RMSE) are missing from the text the "
        "project has, so they are not compared.",
    ]
    return "\n".join(lines) + "\n"


def _rel(c: Check) -> str:
    return f"{100 * c.difference / c.printed:+.3g} % of the printed value" if c.printed else "—"


def report_json(cmp: PaperComparison) -> dict[str, object]:
    """Return the comparison as JSON-ready data (non-finite numbers become None)."""

    def clean(v: object) -> object:
        if isinstance(v, float) and not math.isfinite(v):
            return None
        return v

    out: dict[str, object] = {
        "checks": [{k: clean(v) for k, v in asdict(c).items()} for c in cmp.checks]
    }
    for h in (cmp.general, cmp.modified):
        out[h.case.name] = {
            "x_names": list(h.case.x_names),
            "terms": list(h.surface.term_names),
            "coefficients": [float(b) for b in h.surface.coefficients],
            "metrics": {k: clean(v) for k, v in h.metrics.summary().items()},
            "minimum": {"x": h.extrema.minimum.x.tolist(), "eta": h.extrema.minimum.value},
            "maximum": {"x": h.extrema.maximum.x.tolist(), "eta": h.extrema.maximum.value},
            "eta_below_0.05": {
                "lower": [clean(float(v)) for v in h.region.lower],
                "upper": [clean(float(v)) for v in h.region.upper],
                "area_fraction": h.region.area_fraction,
            },
        }
    out["n_checks"] = len(cmp.checks)
    out["n_reproduced"] = sum(c.reproduced for c in cmp.checks)
    return out


@dataclass(frozen=True)
class ReportFiles:
    """Paths written by :func:`write_report`."""

    markdown: Path
    json: Path


def write_report(cmp: PaperComparison, out_dir: str | Path) -> ReportFiles:
    """Write ``paper_comparison.md`` and ``paper_comparison.json`` into ``out_dir``."""
    d = Path(out_dir)
    d.mkdir(parents=True, exist_ok=True)
    md, js = d / "paper_comparison.md", d / "paper_comparison.json"
    md.write_text(report_markdown(cmp), encoding="utf-8")
    js.write_text(dumps(report_json(cmp)) + "\n", encoding="utf-8")
    return ReportFiles(md, js)
