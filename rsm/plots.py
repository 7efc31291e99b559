"""Pictures of a response surface, written as PNG (matplotlib, no GUI, no pyplot state).

* :func:`plot_surface_3d` -- the surface over two variables with the sample points
  (the paper's Figs. 6 and 11);
* :func:`plot_contour` -- a contour map with the region beyond a threshold shaded
  and its boundary labelled (Fig. 14, "η < 0.05");
* :func:`plot_slices` -- 1-D cuts through the surface with the samples on each cut
  (Figs. 7, 8, 12, 13);
* :func:`plot_predicted_vs_actual` -- fitted and leave-one-out predictions against
  the samples, the worst points labelled with their trace id or table row.

Axis labels take the unit from the column name (``clearance_mm`` → "clearance [mm]").
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import numpy.typing as npt
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from cad.errors import ParameterError
from rsm.metrics import FitMetrics
from rsm.polynomial import ResponseSurface, predict
from rsm.query import threshold_region

FloatArray = npt.NDArray[np.float64]

_UNITS = {"mm": "mm", "N": "N", "MPa": "MPa", "s": "s", "deg": "°", "rad": "rad", "um": "µm"}
_RESPONSE_NAMES = {"eta": "loss factor η [–]", "eta_fe": "loss factor η [–]"}
DPI = 110


def axis_label(name: str) -> str:
    """Turn a column name into an axis label with its unit.

    Example:
        >>> axis_label("clearance_mm"), axis_label("amplitude_N"), axis_label("eta")
        ('clearance [mm]', 'amplitude [N]', 'loss factor η [–]')
    """
    if name in _RESPONSE_NAMES:
        return _RESPONSE_NAMES[name]
    stem, _, unit = name.rpartition("_")
    if stem and unit in _UNITS:
        return f"{stem.replace('_', ' ')} [{_UNITS[unit]}]"
    return name.replace("_", " ")


def value_text(name: str, value: float) -> str:
    """Write a variable's value with its unit.

    Example:
        >>> value_text("amplitude_N", 300.0)
        'amplitude = 300 N'
    """
    stem, _, unit = name.rpartition("_")
    if stem and unit in _UNITS:
        return f"{stem.replace('_', ' ')} = {value:g} {_UNITS[unit]}"
    return f"{name} = {value:g}"


def response_symbol(name: str) -> str:
    """Return the symbol for a response column (``eta`` → ``η``), else the name itself."""
    return "η" if name in _RESPONSE_NAMES else name


def _what(surface: ResponseSurface) -> str:
    what = axis_label(surface.y_name).split(" [")[0]
    return what[0].upper() + what[1:]


def _pair(surface: ResponseSurface, x_names: tuple[str, str] | None) -> tuple[int, int]:
    if surface.n_vars < 2:
        raise ParameterError(f"this plot needs two variables, the surface has {surface.n_vars}")
    names = x_names or (surface.x_names[0], surface.x_names[1])
    for n in names:
        if n not in surface.x_names:
            raise ParameterError(f"unknown variable {n!r}; variables are {surface.x_names}")
    return surface.x_names.index(names[0]), surface.x_names.index(names[1])


def _on_slice(
    surface: ResponseSurface, base: FloatArray, free: tuple[int, ...]
) -> npt.NDArray[np.bool_]:
    """Samples whose held variables equal the slice's values (to 1e-9 of their range)."""
    held = [i for i in range(surface.n_vars) if i not in free]
    if not held:
        return np.ones(surface.n_points, dtype=bool)
    tol = 1e-9 * (2 * surface.half_range[held])
    on: npt.NDArray[np.bool_] = np.all(np.abs(surface.x[:, held] - base[held]) <= tol, axis=1)
    return on


def _grid_values(
    surface: ResponseSurface, ia: int, ib: int, base: FloatArray, n: int = 81
) -> tuple[FloatArray, FloatArray, FloatArray]:
    ga = np.linspace(surface.lower[ia], surface.upper[ia], n)
    gb = np.linspace(surface.lower[ib], surface.upper[ib], n)
    aa, bb = np.meshgrid(ga, gb)  # (n, n), indexed [j_b, i_a]
    pts = np.tile(base, (aa.size, 1))
    pts[:, ia], pts[:, ib] = aa.ravel(), bb.ravel()
    return aa, bb, predict(surface, pts).reshape(aa.shape)


def _held_text(surface: ResponseSurface, base: FloatArray, free: tuple[int, ...]) -> str:
    held = [
        f"{axis_label(n)} = {base[i]:g}" for i, n in enumerate(surface.x_names) if i not in free
    ]
    return ("; " + ", ".join(held)) if held else ""


def plot_surface_3d(
    surface: ResponseSurface,
    path: str | Path,
    *,
    x_names: tuple[str, str] | None = None,
    fixed: Mapping[str, float] | None = None,
    title: str | None = None,
) -> Path:
    """Draw the surface over two variables with its sample points.

    Args:
        surface: The fitted surface.
        path: PNG to write.
        x_names: The two variables; default the first two.
        fixed: Values of the other variables; default the middle of their range.
        title: Figure title; a default names the response and the degree.

    Returns:
        The PNG path.
    """
    ia, ib = _pair(surface, x_names)
    base = _base(surface, fixed)
    aa, bb, zz = _grid_values(surface, ia, ib, base, 41)
    fig = Figure(figsize=(8.0, 6.2), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    surf = ax.plot_surface(aa, bb, zz, cmap="viridis", alpha=0.75, linewidth=0, antialiased=True)
    on = _on_slice(surface, base, (ia, ib))
    ax.scatter(
        surface.x[on, ia],
        surface.x[on, ib],
        surface.y[on],
        color="red",
        s=22,
        depthshade=False,
        label="sample points (FE)",
    )
    ax.set_xlabel(axis_label(surface.x_names[ia]))
    ax.set_ylabel(axis_label(surface.x_names[ib]))
    ax.set_zlabel(axis_label(surface.y_name))
    fig.colorbar(surf, ax=ax, shrink=0.6, pad=0.12, label=axis_label(surface.y_name))
    ax.legend(loc="upper left")
    ax.set_title(
        title
        or f"{_what(surface)}, degree-{surface.degree} response surface"
        f"{_held_text(surface, base, (ia, ib))}"
    )
    return _save(fig, path)


def _base(surface: ResponseSurface, fixed: Mapping[str, float] | None) -> FloatArray:
    base = surface.center.copy()
    for n, v in (fixed or {}).items():
        if n not in surface.x_names:
            raise ParameterError(f"unknown variable {n!r}; variables are {surface.x_names}")
        base[surface.x_names.index(n)] = v
    return base


def _save(fig: Figure, path: str | Path) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=DPI)
    return p


def plot_contour(
    surface: ResponseSurface,
    path: str | Path,
    *,
    threshold: float | None = None,
    below: bool = True,
    x_names: tuple[str, str] | None = None,
    fixed: Mapping[str, float] | None = None,
    title: str | None = None,
) -> Path:
    """Draw a contour map; shade the region beyond a threshold and label its boundary.

    Args:
        surface: The fitted surface.
        path: PNG to write.
        threshold: Level whose region is shaded (e.g. η = 0.05), or None.
        below: Shade ỹ < threshold (True) or ỹ > threshold.
        x_names: The two variables; default the first two.
        fixed: Values of the other variables; default the middle of their range.
        title: Figure title.

    Returns:
        The PNG path.
    """
    ia, ib = _pair(surface, x_names)
    base = _base(surface, fixed)
    aa, bb, zz = _grid_values(surface, ia, ib, base, 121)
    fig = Figure(figsize=(7.8, 7.0), layout="constrained")
    ax = fig.add_subplot()
    cf = ax.contourf(aa, bb, zz, levels=14, cmap="viridis")
    levels = np.asarray(cf.levels, dtype=np.float64)
    cl = ax.contour(aa, bb, zz, levels=levels[::2], colors="white", linewidths=0.6, alpha=0.7)
    ax.clabel(cl, fmt="%.3g", fontsize=7, colors="white")
    fig.colorbar(cf, ax=ax, label=axis_label(surface.y_name))
    handles = []
    if threshold is not None:
        handles += _shade_threshold(ax, surface, (ia, ib), base, threshold, below)
    on = _on_slice(surface, base, (ia, ib))
    handles.append(
        ax.scatter(
            surface.x[on, ia],
            surface.x[on, ib],
            c="black",
            s=16,
            clip_on=False,
            zorder=5,
            label="sample points",
        )
    )
    ax.set_xlabel(axis_label(surface.x_names[ia]))
    ax.set_ylabel(axis_label(surface.x_names[ib]))
    ax.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.11),
        ncol=2,
        fontsize=8,
        frameon=False,
    )
    ax.set_title(
        title
        or f"{_what(surface)}, degree-{surface.degree} surface{_held_text(surface, base, (ia, ib))}"
    )
    return _save(fig, path)


def _shade_threshold(
    ax: Axes,
    surface: ResponseSurface,
    pair: tuple[int, int],
    base: FloatArray,
    threshold: float,
    below: bool,
) -> list[Artist]:
    ia, ib = pair
    names = (surface.x_names[ia], surface.x_names[ib])
    held = {n: float(base[i]) for i, n in enumerate(surface.x_names) if i not in pair}
    region = threshold_region(surface, threshold, below=below, x_names=names, fixed=held)
    sym, sign = response_symbol(surface.y_name), "<" if below else ">"
    m = region.mask.astype(float)
    ax.contourf(region.grid_x, region.grid_y, m, levels=[0.5, 1.5], colors=["white"], alpha=0.35)
    ax.contourf(region.grid_x, region.grid_y, m, levels=[0.5, 1.5], colors="none", hatches=["///"])
    for curve in region.boundary:
        ax.plot(curve[:, 0], curve[:, 1], color="red", lw=2.2)
        mid = curve[len(curve) // 2]
        ax.annotate(
            f"{sym} = {threshold:g}",
            mid,
            xytext=(0, 14),
            textcoords="offset points",
            ha="center",
            color="red",
            fontsize=9,
            fontweight="bold",
            bbox={"facecolor": "white", "edgecolor": "red", "alpha": 0.9, "pad": 1.5},
        )
    if region.mask.any():
        extent = (
            f"{sign} {threshold:g} on {100 * region.area_fraction:.1f} % of the box"
            f"{f' in {region.n_parts} parts' if region.n_parts > 1 else ''}: "
            f"{axis_label(names[0])} {region.lower[0]:.4g}–{region.upper[0]:.4g}, "
            f"{axis_label(names[1])} {region.lower[1]:.4g}–{region.upper[1]:.4g}"
        )
    else:
        extent = f"{sign} {threshold:g} nowhere in the box"
    return [
        Patch(
            facecolor="white",
            alpha=0.6,
            hatch="///",
            edgecolor="black",
            label=f"region {sym} {extent}",
        ),
        Line2D([], [], color="red", lw=2.2, label=f"boundary {sym} = {threshold:g}"),
    ]


def default_slice_values(surface: ResponseSurface) -> dict[str, float]:
    """For each variable, the sampled level nearest the middle of its range.

    Holding the other variables at a sampled level puts sample points on each slice.
    """
    out = {}
    for i, n in enumerate(surface.x_names):
        levels = np.unique(surface.x[:, i])
        out[n] = float(levels[np.argmin(np.abs(levels - surface.center[i]))])
    return out


def plot_slices(
    surface: ResponseSurface,
    path: str | Path,
    *,
    at: Mapping[str, float] | None = None,
    title: str | None = None,
) -> Path:
    """Draw one 1-D cut per variable, the others held, with the samples lying on each cut.

    Args:
        surface: The fitted surface.
        path: PNG to write.
        at: Where to hold each variable while another varies; default
            :func:`default_slice_values`. The paper's Figs. 7 and 8 are
            ``at={"amplitude_N": 300, "clearance_mm": 0.3}``.
        title: Figure title.

    Returns:
        The PNG path.
    """
    values = default_slice_values(surface)
    values.update({k: float(v) for k, v in (at or {}).items()})
    base = _base(surface, values)
    n = surface.n_vars
    fig = Figure(figsize=(5.0 * n, 4.2), layout="constrained")
    for i, name in enumerate(surface.x_names):
        ax = fig.add_subplot(1, n, i + 1)
        g = np.linspace(surface.lower[i], surface.upper[i], 200)
        pts = np.tile(base, (g.size, 1))
        pts[:, i] = g
        ax.plot(
            g, predict(surface, pts), color="C0", lw=2, label=f"surface (degree {surface.degree})"
        )
        on = _on_slice(surface, base, (i,))
        ax.plot(surface.x[on, i], surface.y[on], "o", color="red", ms=6, label="sample points (FE)")
        ax.set_xlabel(axis_label(name))
        ax.set_ylabel(axis_label(surface.y_name))
        held = _held_text(surface, base, (i,)).lstrip("; ")
        ax.set_title(f"at {held}" if held else "", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return _save(fig, path)


def plot_predicted_vs_actual(
    surface: ResponseSurface, metrics: FitMetrics, path: str | Path, *, n_labels: int = 3
) -> Path:
    """Plot fitted and leave-one-out predictions against the sample values.

    Args:
        surface: The fitted surface.
        metrics: Its metrics (for the leave-one-out residuals and the summary).
        path: PNG to write.
        n_labels: Label this many worst points (largest |RE|) with their point label.

    Returns:
        The PNG path.
    """
    y = surface.y
    fit = predict(surface, surface.x)
    loo = y - metrics.loo_residuals
    fig = Figure(figsize=(6.2, 6.0), layout="constrained")
    ax = fig.add_subplot()
    finite = np.isfinite(loo)
    lo = float(min(y.min(), fit.min(), loo[finite].min() if finite.any() else y.min()))
    hi = float(max(y.max(), fit.max(), loo[finite].max() if finite.any() else y.max()))
    pad = 0.05 * (hi - lo)
    ax.plot(
        [lo - pad, hi + pad], [lo - pad, hi + pad], color="gray", lw=1, label="predicted = actual"
    )
    ax.plot(
        y[finite], loo[finite], "s", mfc="none", mec="C1", ms=7, label="leave-one-out prediction"
    )
    ax.plot(y, fit, "o", color="C0", ms=5, label="fitted surface")
    worst = np.argsort(-np.nan_to_num(np.abs(metrics.relative_error)))[:n_labels]
    for k in worst:
        ax.annotate(
            f"{surface.labels[k]} (RE {100 * metrics.relative_error[k]:+.2f} %)",
            (y[k], fit[k]),
            xytext=(8, -12),
            textcoords="offset points",
            fontsize=8,
        )
    ax.set_xlim(lo - pad, hi + pad)
    ax.set_ylim(lo - pad, hi + pad)
    ax.set_aspect("equal")
    ax.set_xlabel(f"actual (sample) {axis_label(surface.y_name)}")
    ax.set_ylabel(f"predicted {axis_label(surface.y_name)}")
    ax.text(
        0.03,
        0.97,
        f"R² = {metrics.r2:.5f}\nQ² (LOO) = {metrics.q2:.5f}\nRMSE = {metrics.rmse:.3g}\n"
        f"max |RE| = {metrics.max_abs_re_percent:.3g} %\n"
        f"M = {metrics.n_points}, N = {metrics.n_terms}",
        transform=ax.transAxes,
        va="top",
        fontsize=9,
        bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "0.8"},
    )
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title(f"Predicted vs actual, degree {surface.degree}")
    return _save(fig, path)


def plot_all(
    surface: ResponseSurface,
    metrics: FitMetrics,
    out_dir: str | Path,
    *,
    threshold: float | None = None,
    slice_at: Mapping[str, float] | None = None,
    prefix: str = "",
) -> dict[str, Path]:
    """Write every plot that applies to the surface into ``out_dir``.

    Args:
        surface: The fitted surface.
        metrics: Its metrics.
        out_dir: Folder for the PNGs (created if needed).
        threshold: Level for the contour map's shaded region, or None.
        slice_at: Where to hold variables in the 1-D slices.
        prefix: Prepended to each file name (e.g. ``general_``).

    Returns:
        Plot name → PNG path (``surface_3d`` and ``contour`` only with two or more variables).
    """
    d = Path(out_dir)
    out = {
        "slices": plot_slices(surface, d / f"{prefix}slices.png", at=slice_at),
        "predicted_vs_actual": plot_predicted_vs_actual(
            surface, metrics, d / f"{prefix}predicted_vs_actual.png"
        ),
    }
    if surface.n_vars >= 2:
        out["surface_3d"] = plot_surface_3d(surface, d / f"{prefix}surface_3d.png")
        out["contour"] = plot_contour(surface, d / f"{prefix}contour.png", threshold=threshold)
    return out
