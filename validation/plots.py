"""Pictures of a comparison: loops with residuals, error map, residuals, fingerprint.

All functions draw on a bare ``Figure`` (Agg canvas, no pyplot state) into a PNG and return its path. Displacements
are shown in µm (hinge loops span a few µm to a few tens of µm).
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from fe.kinds import hinge_kind
from model.paths import file_stem, inside
from validation.compare import METRIC_LABELS, METRICS, CaseComparison, Comparison
from validation.fingerprint import group_name, judged_value
from validation.hysteresis import Status
from validation.loops import branch_residuals

UM_PER_MM = 1e3
AMPLITUDE = ("amplitude_n", "amplitude Fg [N]")

ERROR_MAP_LIMIT_PCT = 50.0
"""The error map's colour scale spans ±this many percent, fixed (beyond it: the end colours)."""

MARKERS = {Status.PASS: "o", Status.FAIL: "x", Status.NOT_MEASURABLE: "s"}
"""Marker of a case on the error map, by the verdict on the metric the map shows."""


GREY = (0.75, 0.75, 0.75, 1.0)
"""Colour of a case on the error map without a relative error (not measurable)."""


def error_colour(error_pct: float | None) -> tuple[float, float, float, float]:
    """RGBA of an error [%] on the map's fixed diverging scale ±``ERROR_MAP_LIMIT_PCT``; grey for None.

    Errors beyond the scale take its end colours: 0.0003 % stays white, +500 % is as red
    as +50 %.
    """
    if error_pct is None or not math.isfinite(error_pct):
        return GREY
    norm = Normalize(-ERROR_MAP_LIMIT_PCT, ERROR_MAP_LIMIT_PCT, clip=True)
    r, g, b, a = colormaps["RdBu_r"](float(norm(error_pct)))
    return (float(r), float(g), float(b), float(a))


def format_eta(eta: float | None) -> str:
    """η with three significant digits, in scientific notation when small (``1.38e-05``)."""
    if eta is None or not math.isfinite(eta):
        return "—"
    return f"{eta:.3g}"


def _variables(cmp: Comparison) -> list[tuple[str, str]]:
    """(name, axis label) of every design variable of the cases' kinds, then the amplitude."""
    out: dict[str, str] = {}
    for hinge in dict.fromkeys(c.case.hinge for c in cmp.cases):
        for v in hinge_kind(hinge).design_variables:
            out.setdefault(v.name, f"{v.word} {v.symbol} [{v.unit}]")
    return [*out.items(), AMPLITUDE]


def _value(c: CaseComparison, name: str) -> float:
    """A case's design value (0 where its kind has no such variable) or its amplitude."""
    if name == AMPLITUDE[0]:
        return c.case.amplitude_n
    return float(c.case.values.get(name, 0.0))


def _save(fig: Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path


def _title(c: CaseComparison) -> str:
    k = c.case
    verdict = "pass" if c.passed else "FAIL: " + ", ".join(METRIC_LABELS[m] for m in c.failed)
    if c.not_measurable:
        verdict += "; not measurable: " + ", ".join(METRIC_LABELS[m] for m in c.not_measurable)
    where = ", ".join(filter(None, [k.describe(), f"Fg = {k.amplitude_n:g} N"]))
    return f"{_short(k.case_id)}: {where}\n{verdict}"


def _short(text: str, n: int = 40) -> str:
    """``text`` cut to ``n`` characters (a case id from a file may be any length)."""
    return text if len(text) <= n else text[: n - 1] + "…"


def plot_case_loops(c: CaseComparison, path: Path) -> Path:
    """Overlay the measured and the model loop, with the residual along both branches below.

    Args:
        c: One case with a measured loop.
        path: PNG to write.

    Returns:
        ``path``.
    """
    fig = Figure(figsize=(7.0, 7.0), layout="constrained")
    ax, ax_r = fig.subplots(2, 1, height_ratios=(3, 1.4))
    mod = c.model_loop
    meas = c.measured_loop
    if meas is not None:
        ax.plot(
            meas.displacement_mm * UM_PER_MM,
            meas.force_n,
            ".",
            ms=2.5,
            color="0.45",
            label=f"measured ({meas.force_n.size} samples)",
        )
    ax.plot(
        mod.displacement_mm * UM_PER_MM,
        mod.force_n,
        "-o",
        ms=3,
        lw=1.4,
        color="C3",
        label="model",
    )
    ax.axhline(0, color="0.8", lw=0.6, zorder=0)
    ax.axvline(0, color="0.8", lw=0.6, zorder=0)
    ax.set_xlabel("displacement δ [µm]")
    ax.set_ylabel("force F [N]")
    text = [f"η: model {format_eta(c.model['eta'])}, measured {format_eta(c.measured['eta'])}"]
    if c.free_play_removed:
        text[0] += " (free play included)"
        text.append(
            f"η without free play: model {format_eta(judged_value(c, 'model', 'eta'))}, "
            f"measured {format_eta(judged_value(c, 'measured', 'eta'))}"
        )
    if "eta" in c.not_measurable:
        text.append(textwrap.fill(f"η not measurable: {c.not_measurable['eta']}", 70))
    if c.rms_loop_mm is not None:
        text.append(f"RMS loop distance {c.rms_loop_mm * UM_PER_MM:.3g} µm")
    ax.text(0.02, 0.97, "\n".join(text), transform=ax.transAxes, va="top", fontsize=9)
    ax.legend(loc="lower right", fontsize=9)
    ax.set_title(_title(c), fontsize=9.5)
    if meas is not None:
        grid, r_down, r_up = branch_residuals(meas, mod)
        ax_r.plot(grid, r_down * UM_PER_MM, color="C0", label="descending +Fg → −Fg")
        ax_r.plot(grid, r_up * UM_PER_MM, color="C1", label="ascending −Fg → +Fg")
        ax_r.axhline(0, color="0.6", lw=0.6)
        ax_r.legend(fontsize=8, loc="best")
    else:
        ax_r.text(0.5, 0.5, "η only: no measured loop", ha="center", transform=ax_r.transAxes)
    ax_r.set_xlabel("force F [N]")
    ax_r.set_ylabel("δ model − measured [µm]\n(each loop centred)", fontsize=8.5)
    return _save(fig, path)


def _design_axes(cmp: Comparison) -> tuple[str, str]:
    """The map's axes: amplitude, and the first design variable that varies (else the first)."""
    design = _variables(cmp)[:-1] or [AMPLITUDE]
    varying = [n for n, _ in design if len({_value(c, n) for c in cmp.cases}) > 1]
    return AMPLITUDE[0], (varying or [design[0][0]])[0]


@dataclass(frozen=True)
class MapPoint:
    """One case on the error map (``error_map_points``).

    Attributes:
        case_id: The case.
        x: Its amplitude [N].
        y: Its design value on the map's other axis.
        status: The verdict on the map's metric.
        marker: Matplotlib marker (``MARKERS``).
        error_pct: The relative error [%], or None (not measurable, or failed without a
            relative error).
        colour: Its fill, RGBA (``error_colour``).
        label: The text beside it.
    """

    case_id: str
    x: float
    y: float
    status: Status
    marker: str
    error_pct: float | None
    colour: tuple[float, float, float, float]
    label: str


def error_map_points(cmp: Comparison, metric: str = "eta") -> list[MapPoint]:
    """Decide marker, colour value and label of every case on the error map of ``metric``.

    The marker follows the verdict on ``metric`` itself (not the case's overall verdict):
    ○ within kσ, × outside kσ, □ not measurable. Cases without the metric are left out.
    """
    xk, yk = _design_axes(cmp)
    points = []
    for c in cmp.cases:
        j = c.judgements.get(metric)
        if metric in c.errors:
            status = Status.FAIL if metric in c.failed else Status.PASS
            error: float | None = c.errors[metric] * 100
            text = f"{error:+.1f} %"
        elif j is not None:
            status, error = j.status, None
            text = "n/m" if status is Status.NOT_MEASURABLE else f"Δ{j.difference:+.3g}"
        else:
            continue
        label = f"{text}\n{_short(c.case.case_id, 16)}"
        points.append(
            MapPoint(
                c.case.case_id,
                _value(c, xk),
                _value(c, yk),
                status,
                MARKERS[status],
                error,
                error_colour(error),
                label,
            )
        )
    return points


def plot_error_map(cmp: Comparison, path: Path, metric: str = "eta") -> Path:
    """Draw the error of one metric over the design space (amplitude × clearance or preload).

    Each case is a marker coloured by its error on a fixed scale ±``ERROR_MAP_LIMIT_PCT``
    (diverging, centred on 0; grey without a relative error) and shaped by the verdict on
    this metric (``error_map_points``); the label is the error in %.
    """
    xk, yk = _design_axes(cmp)
    points = error_map_points(cmp, metric)
    lim = ERROR_MAP_LIMIT_PCT
    fig = Figure(figsize=(7.0, 5.0), layout="constrained")
    ax = fig.subplots()
    for p in points:
        ax.scatter(p.x, p.y, s=260, color=[p.colour], edgecolors="none")
        if p.marker == "x":
            ax.scatter(p.x, p.y, s=420, marker="x", color="k", linewidths=1.5)
        else:
            ax.scatter(
                p.x, p.y, s=420, marker=p.marker, facecolors="none", edgecolors="k", linewidths=1.2
            )
        ax.annotate(
            p.label, (p.x, p.y), xytext=(0, 17), textcoords="offset points", ha="center", fontsize=8
        )
    fig.colorbar(
        ScalarMappable(Normalize(-lim, lim), colormaps["RdBu_r"]),
        ax=ax,
        extend="both",
        label=f"{METRIC_LABELS[metric]} error (model − measured)/measured [%], "
        f"scale fixed at ±{lim:g} %",
    )
    labels = dict(_variables(cmp))
    ax.set_xlabel(labels[xk])
    ax.set_ylabel(labels[yk])
    ax.margins(0.25)
    k = cmp.settings.k
    ax.set_title(
        f"{METRIC_LABELS[metric]} error over the design space\nmarkers: {METRIC_LABELS[metric]} "
        f"○ within {k:g}σ, × outside {k:g}σ, □ not measurable (grey: no relative error)",
        fontsize=9.5,
    )
    return _save(fig, path)


def plot_residuals(cmp: Comparison, path: Path) -> Path:
    """Draw every metric's error against each design variable that varies, with the ±kσ band."""
    variables = [
        (k, label) for k, label in _variables(cmp) if len({_value(c, k) for c in cmp.cases}) > 1
    ] or [AMPLITUDE]
    metrics = [m for m in METRICS if any(m in c.errors for c in cmp.cases)]
    fig = Figure(
        figsize=(max(3.6 * len(variables) + 1.0, 6.5), 1.9 * len(metrics) + 0.9),
        layout="constrained",
    )
    axes = fig.subplots(len(metrics), len(variables), squeeze=False, sharex="col")
    k = cmp.settings.k
    for i, m in enumerate(metrics):
        have = [c for c in cmp.cases if m in c.errors]
        e = np.array([c.errors[m] for c in have]) * 100
        band = np.array([k * c.uncertainty[m] for c in have]) * 100
        for j, (var, label) in enumerate(variables):
            ax = axes[i, j]
            x = np.array([_value(c, var) for c in have])
            ok = np.array([m not in c.failed for c in have])
            ax.errorbar(x, e, yerr=band, fmt="none", ecolor="0.6", capsize=3, lw=1)
            ax.plot(x[ok], e[ok], "o", color="C2", ms=5, label="within kσ")
            ax.plot(x[~ok], e[~ok], "X", color="C3", ms=7, label="outside kσ")
            ax.axhline(0, color="0.5", lw=0.7)
            ax.margins(x=0.15)
            if j == 0:
                ax.set_ylabel(f"{METRIC_LABELS[m]}\nerror [%]", fontsize=9)
            if i == len(metrics) - 1:
                ax.set_xlabel(label)
    axes[0, 0].legend(fontsize=7, loc="best")
    fig.suptitle(f"Errors (model − measured) against the design variables\nbars: ±{k:g}σ")
    return _save(fig, path)


def plot_fingerprint(cmp: Comparison, path: Path) -> Path:
    """Draw W and η against amplitude on log–log axes, measured and model, with fitted slopes."""
    n_groups = len({group_name(c.case) for c in cmp.cases})
    fig = Figure(figsize=(12.0, 4.6 + 0.2 * n_groups), layout="constrained")
    ax_w, ax_e = fig.subplots(1, 2)
    fits = {f.group: f for f in cmp.fingerprint}
    groups: dict[str, list[CaseComparison]] = {}
    for c in cmp.cases:
        groups.setdefault(group_name(c.case), []).append(c)
    hinges = {c.case.hinge for c in cmp.cases}

    def short(c: CaseComparison) -> str:
        """The group's name with the hinge left out when every group shares it (title)."""
        parts = [c.case.hinge] if len(hinges) > 1 else []
        return ", ".join([*parts, c.case.describe() or "all cases"])

    common = next(iter(hinges)) if len(hinges) == 1 else ""
    for g, (name, members) in enumerate(groups.items()):
        color = f"C{g % 10}"
        amps = np.array([c.case.amplitude_n for c in members])
        fit = fits.get(name)
        label = short(members[0])
        for ax, key, what in ((ax_w, "W_cycle_Nmm", "W"), (ax_e, "eta", "eta")):
            for side, marker, ls in (("measured", "o", ":"), ("model", "s", "-")):
                v = np.array([judged_value(c, side, key) for c in members])
                ok = np.isfinite(v) & (v > 0)
                if not ok.any():
                    continue
                slope = math.nan if fit is None else getattr(fit, f"slope_{what}_{side}")
                lab = f"{side}, {label}" + ("" if math.isnan(slope) else f": slope {_fmt(slope)}")
                ax.plot(
                    amps[ok],
                    v[ok],
                    marker,
                    color=color,
                    mfc="none" if side == "model" else color,
                    label=lab,
                )
                if not math.isnan(slope) and ok.sum() >= 2:
                    xs = np.sort(amps[ok])
                    c0 = np.mean(np.log(v[ok]) - slope * np.log(amps[ok]))
                    ax.plot(xs, np.exp(c0) * xs**slope, ls, color=color, lw=1)
    for ax, ylabel in ((ax_w, "loop area W_cycle [N·mm]"), (ax_e, "loss factor η")):
        _log_axes(ax)
        ax.set_xlabel("amplitude Fg [N]")
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", color="0.9")
        if ax.get_legend_handles_labels()[0]:  # nothing positive to draw (μ = 0): no legend
            # below the axes: inside, the legend of a 5-group design covered the points
            ax.legend(fontsize=7.5, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
        else:
            ax.text(0.5, 0.5, "no positive values", ha="center", transform=ax.transAxes)
    ax_w.set_title("W vs Fg (homogeneous model: slope 2)")
    ax_e.set_title("η vs Fg (homogeneous model: slope 0)")
    fig.suptitle(
        "Fingerprint: measured (filled, dotted fit) and model (open, solid fit)"
        + (f" — {common}" if common else "")
    )
    return _save(fig, path)


def _fmt(slope: float) -> str:
    """Slope with two decimals and no "-0.00"."""
    return f"{0.0 if abs(slope) < 0.005 else slope:.2f}"


def _log_axes(ax: Axes) -> None:
    """Make log–log axes that span at least a factor 4, ticks labelled as plain numbers.

    The minimum span keeps round-off (η constant to 1e-14) from looking like a trend.
    """
    ax.set_xscale("log")
    ax.set_yscale("log")
    for axis, (lo, hi), setter in (
        (ax.xaxis, ax.get_xlim(), ax.set_xlim),
        (ax.yaxis, ax.get_ylim(), ax.set_ylim),
    ):
        if hi / lo < 4.0:
            mid = math.sqrt(lo * hi)
            lo, hi = mid / 2.0, mid * 2.0
            setter(lo, hi)
        plain = FuncFormatter(lambda v, _: f"{v:.3g}")
        axis.set_major_formatter(plain)
        decades = math.log10(hi / lo)
        if decades < 1.5:
            subs = (2.0, 3.0, 4.0, 6.0, 8.0) if decades < 1.0 else (2.0, 5.0)
            axis.set_minor_locator(LogLocator(subs=subs))
            axis.set_minor_formatter(plain)
        else:
            axis.set_minor_formatter(NullFormatter())


def write_comparison_plots(cmp: Comparison, out: Path) -> dict[str, Path]:
    """Write every picture of a comparison under ``out``; return name → path."""
    files = {
        f"loop_{c.case.case_id}": plot_case_loops(
            c, inside(out, out / "loops" / f"{file_stem(c.case.case_id)}.png")
        )
        for c in cmp.cases
        if c.measured_loop is not None
    }
    files["error_map"] = plot_error_map(cmp, out / "error_map.png")
    files["residuals"] = plot_residuals(cmp, out / "residuals.png")
    files["fingerprint"] = plot_fingerprint(cmp, out / "fingerprint.png")
    return files
