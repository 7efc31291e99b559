"""Questions asked of a fitted surface: value, gradient, extremes, threshold regions, best design.

All searches run over a box, by default the box the samples span (the surface
is not trusted outside it). They start from a dense grid and polish the best
grid points with a bounded gradient method, so a result is never worse than the
best grid point.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum

import contourpy
import numpy as np
import numpy.typing as npt
from scipy import ndimage, optimize

from cad.errors import ParameterError
from rsm.polynomial import ResponseSurface, gradient, predict

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

GRID_BUDGET = 200_000
"""Total number of grid points a search may evaluate before polishing."""


class Sense(Enum):
    """Direction of an optimisation."""

    MINIMIZE = "min"
    MAXIMIZE = "max"


@dataclass(frozen=True)
class PointValue:
    """The surface at one point.

    Attributes:
        x: The point, shape (n_vars,), physical units.
        value: ỹ(x).
        gradient: ∇ỹ(x), shape (n_vars,), response units per variable unit.
    """

    x: FloatArray
    value: float
    gradient: FloatArray


@dataclass(frozen=True)
class Extrema:
    """Smallest and largest value of the surface over a box."""

    minimum: PointValue
    maximum: PointValue


@dataclass(frozen=True)
class ThresholdRegion:
    """Where a two-variable surface lies below (or above) a threshold.

    Attributes:
        threshold: The level, response units.
        below: True for the region ỹ < threshold, False for ỹ > threshold.
        x_names: The two plotted variables (x along axis 0, y along axis 1 of ``mask``).
        fixed: Values held for every other variable, physical units.
        grid_x: Grid along the first variable, shape (n_grid,).
        grid_y: Grid along the second variable, shape (n_grid,).
        values: ỹ on the grid, shape (n_grid, n_grid), indexed [j_y, i_x].
        mask: Grid points inside the region, shape (n_grid, n_grid), indexed [j_y, i_x].
        boundary: Curves where ỹ equals the threshold, each of shape (n_vertices, 2)
            in physical units of (first, second) variable.
        area_fraction: Share of the box inside the region, in [0, 1].
        n_parts: Number of disconnected pieces of the region on the grid (the paper's
            modified hinge has two, its regions b)-1 and b)-3).
        lower: Smallest value of each of the two variables inside the region
            (NaN if the region is empty), shape (2,).
        upper: Largest such value, shape (2,).
    """

    threshold: float
    below: bool
    x_names: tuple[str, str]
    fixed: Mapping[str, float]
    grid_x: FloatArray
    grid_y: FloatArray
    values: FloatArray
    mask: BoolArray
    boundary: tuple[FloatArray, ...]
    area_fraction: float
    n_parts: int
    lower: FloatArray
    upper: FloatArray


def _point(surface: ResponseSurface, x: npt.ArrayLike) -> PointValue:
    xa = np.asarray(x, dtype=np.float64).reshape(surface.n_vars)
    return PointValue(
        x=xa,
        value=float(predict(surface, xa)[0]),
        gradient=gradient(surface, xa)[0],
    )


def value_and_gradient(surface: ResponseSurface, x: npt.ArrayLike) -> PointValue:
    """Evaluate the surface and its gradient at one point.

    Args:
        surface: The fitted surface.
        x: The point, shape (n_vars,), physical units.

    Returns:
        Value and gradient.

    Raises:
        ParameterError: If the point has the wrong length.
    """
    xa = np.asarray(x, dtype=np.float64)
    if xa.shape != (surface.n_vars,):
        raise ParameterError(f"x must have shape ({surface.n_vars},), got {xa.shape}")
    return _point(surface, xa)


def _box(
    surface: ResponseSurface, bounds: Mapping[str, tuple[float, float]] | None
) -> tuple[FloatArray, FloatArray]:
    lo, hi = surface.lower.copy(), surface.upper.copy()
    for name, (a, b) in (bounds or {}).items():
        if name not in surface.x_names:
            raise ParameterError(f"unknown variable {name!r}; variables are {surface.x_names}")
        if not a <= b:
            raise ParameterError(f"bounds for {name!r} must satisfy lower <= upper, got ({a}, {b})")
        i = surface.x_names.index(name)
        lo[i], hi[i] = a, b
    return lo, hi


def _grid(lo: FloatArray, hi: FloatArray, budget: int = GRID_BUDGET) -> FloatArray:
    free = int(np.sum(hi > lo))
    n_axis = 1 if free == 0 else max(3, min(201, int(budget ** (1.0 / free))))
    axes = [
        np.linspace(a, b, n_axis) if b > a else np.array([a]) for a, b in zip(lo, hi, strict=True)
    ]
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.column_stack([m.ravel() for m in mesh])  # (n_grid_points, n_vars)


def _polish(
    surface: ResponseSurface, x0: FloatArray, lo: FloatArray, hi: FloatArray, sign: float
) -> FloatArray:
    res = optimize.minimize(
        lambda z: sign * float(predict(surface, z)[0]),
        x0,
        jac=lambda z: sign * gradient(surface, z)[0],
        bounds=list(zip(lo, hi, strict=True)),
        method="L-BFGS-B",
        options={"ftol": 1e-15, "gtol": 1e-12},
    )
    return np.clip(np.asarray(res.x, dtype=np.float64), lo, hi)


def _optimum(
    surface: ResponseSurface, lo: FloatArray, hi: FloatArray, sign: float, n_starts: int = 5
) -> PointValue:
    grid = _grid(lo, hi)
    vals = sign * predict(surface, grid)
    best_x, best_v = grid[int(np.argmin(vals))], float(np.min(vals))
    for k in np.argsort(vals)[:n_starts]:
        x = _polish(surface, grid[k], lo, hi, sign)
        v = sign * float(predict(surface, x)[0])
        if v < best_v:
            best_x, best_v = x, v
    return _point(surface, best_x)


def extrema(
    surface: ResponseSurface, *, bounds: Mapping[str, tuple[float, float]] | None = None
) -> Extrema:
    """Find the minimum and maximum of the surface over a box.

    Args:
        surface: The fitted surface.
        bounds: Per-variable (lower, upper) overriding the sampled box; a
            variable given equal bounds is held fixed.

    Returns:
        Both extremes with their locations.

    Raises:
        ParameterError: If a bound names an unknown variable or is inverted.
    """
    lo, hi = _box(surface, bounds)
    return Extrema(minimum=_optimum(surface, lo, hi, 1.0), maximum=_optimum(surface, lo, hi, -1.0))


def _refine_on_level(
    surface: ResponseSurface, pts: FloatArray, level: float, lo: FloatArray, hi: FloatArray
) -> FloatArray:
    """Move points onto ỹ = level by Newton steps along the gradient, not off the box."""
    out = pts.copy()
    pinned = np.isclose(out, lo, rtol=0.0, atol=1e-12 * (hi - lo + 1.0)) | np.isclose(
        out, hi, rtol=0.0, atol=1e-12 * (hi - lo + 1.0)
    )
    for _ in range(4):
        g = np.where(pinned, 0.0, gradient(surface, out))  # (n_pts, n_vars)
        gg = np.sum(g * g, axis=1)
        step = np.where(gg > 0, (predict(surface, out) - level) / np.where(gg > 0, gg, 1.0), 0.0)
        out = np.clip(out - step[:, None] * g, lo, hi)
    return out


def threshold_region(
    surface: ResponseSurface,
    threshold: float,
    *,
    below: bool = True,
    x_names: Sequence[str] | None = None,
    fixed: Mapping[str, float] | None = None,
    n_grid: int = 201,
) -> ThresholdRegion:
    """Map the region where the surface is below (or above) a threshold, in two variables.

    This is the paper's Fig. 14 / Sec. V.A analysis: "η < 0.05 only in region a)-1".

    Args:
        surface: The fitted surface.
        threshold: The level, response units.
        below: Region ỹ < threshold if True, else ỹ > threshold.
        x_names: The two variables to map; default the first two.
        fixed: Values for every other variable; default the middle of its range.
        n_grid: Grid points per axis (at least 11).

    Returns:
        The region, its boundary curves (refined onto the level to round-off)
        and the range each variable takes inside it.

    Raises:
        ParameterError: If the surface has fewer than two variables, a name is
            unknown, or ``n_grid`` is too small.
    """
    if surface.n_vars < 2:
        raise ParameterError(
            f"a threshold map needs two variables, the surface has {surface.n_vars}"
        )
    if n_grid < 11:
        raise ParameterError(f"n_grid must be at least 11, got {n_grid}")
    pair = tuple(x_names) if x_names is not None else surface.x_names[:2]
    for name in pair:
        if name not in surface.x_names:
            raise ParameterError(f"unknown variable {name!r}; variables are {surface.x_names}")
    if len(pair) != 2 or pair[0] == pair[1]:
        raise ParameterError(f"x_names must name two different variables, got {pair}")
    ia, ib = surface.x_names.index(pair[0]), surface.x_names.index(pair[1])
    base = surface.center.copy()
    held = {n: float(base[i]) for i, n in enumerate(surface.x_names) if i not in (ia, ib)}
    for name, v in (fixed or {}).items():
        if name not in held:
            raise ParameterError(f"fixed may only name variables other than {pair}, got {name!r}")
        held[name] = float(v)
        base[surface.x_names.index(name)] = v
    lo, hi = base.copy(), base.copy()
    lo[[ia, ib]], hi[[ia, ib]] = surface.lower[[ia, ib]], surface.upper[[ia, ib]]
    gx = np.linspace(lo[ia], hi[ia], n_grid)
    gy = np.linspace(lo[ib], hi[ib], n_grid)
    xx, yy = np.meshgrid(gx, gy)  # (n_grid, n_grid), indexed [j_y, i_x]
    pts = np.tile(base, (xx.size, 1))
    pts[:, ia], pts[:, ib] = xx.ravel(), yy.ravel()
    z = predict(surface, pts).reshape(xx.shape)
    mask = z < threshold if below else z > threshold
    curves = []
    for raw in contourpy.contour_generator(gx, gy, z).lines(threshold):
        line = np.asarray(raw, dtype=np.float64)  # (n_vertices, 2) with the default line type
        full = np.tile(base, (len(line), 1))
        full[:, ia], full[:, ib] = line[:, 0], line[:, 1]
        full = _refine_on_level(surface, full, threshold, lo, hi)
        curves.append(np.column_stack([full[:, ia], full[:, ib]]))
    inside = [np.column_stack([xx[mask], yy[mask]]), *curves]
    allpts = np.concatenate(inside) if mask.any() else np.empty((0, 2))
    return ThresholdRegion(
        threshold=threshold,
        below=below,
        x_names=(pair[0], pair[1]),
        fixed=held,
        grid_x=gx,
        grid_y=gy,
        values=z,
        mask=mask,
        boundary=tuple(curves),
        area_fraction=float(np.mean(mask)),
        n_parts=int(ndimage.label(mask)[1]),
        lower=allpts.min(axis=0) if len(allpts) else np.full(2, math.nan),
        upper=allpts.max(axis=0) if len(allpts) else np.full(2, math.nan),
    )


@dataclass(frozen=True)
class ResponseLimit:
    """A constraint on the response: ``lower <= ỹ(x) <= upper`` (either side may be open)."""

    lower: float = -math.inf
    upper: float = math.inf


def best_design(
    surface: ResponseSurface,
    *,
    objective: str | None = None,
    sense: Sense = Sense.MINIMIZE,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    fixed: Mapping[str, float] | None = None,
    response_limit: ResponseLimit | None = None,
) -> PointValue:
    """Find the best design inside a box, optionally keeping the response within limits.

    Two kinds of question, e.g. for the paper's general hinge:
    "the smallest η with clearance at most 0.05 mm at 400 N"
    (``objective=None, bounds={"clearance_mm": (0, 0.05)}, fixed={"amplitude_N": 400}``),
    or "the smallest clearance for which η ≤ 0.05 at 100 N"
    (``objective="clearance_mm", fixed={"amplitude_N": 100},
    response_limit=ResponseLimit(upper=0.05)``).

    Args:
        surface: The fitted surface.
        objective: A variable name to optimise, or None for the response itself.
        sense: Minimise or maximise the objective.
        bounds: Per-variable (lower, upper) overriding the sampled box.
        fixed: Variables held at a value.
        response_limit: Limits the response must respect.

    Returns:
        The best feasible point found, with the surface value and gradient there.

    Raises:
        ParameterError: If a name is unknown or no grid point satisfies the limit.
    """
    merged = dict(bounds or {})
    for name, v in (fixed or {}).items():
        merged[name] = (float(v), float(v))
    lo, hi = _box(surface, merged)
    if objective is not None and objective not in surface.x_names:
        raise ParameterError(
            f"objective must be None or one of {surface.x_names}, got {objective!r}"
        )
    lim = response_limit or ResponseLimit()
    sign = 1.0 if sense is Sense.MINIMIZE else -1.0
    k_obj = None if objective is None else surface.x_names.index(objective)

    def f(z: FloatArray) -> float:
        return sign * (float(z[k_obj]) if k_obj is not None else float(predict(surface, z)[0]))

    grid = _grid(lo, hi)
    yg = predict(surface, grid)
    ok = (yg >= lim.lower) & (yg <= lim.upper)
    if not ok.any():
        raise ParameterError(
            f"no point of the box gives {surface.y_name} in [{lim.lower}, {lim.upper}]; "
            f"over the box it ranges over [{yg.min():.6g}, {yg.max():.6g}]"
        )
    fg = sign * (grid[:, k_obj] if k_obj is not None else yg)
    fg = np.where(ok, fg, np.inf)
    best = grid[int(np.argmin(fg))]
    cons = []
    if math.isfinite(lim.upper):
        cons.append({"type": "ineq", "fun": lambda z: lim.upper - float(predict(surface, z)[0])})
    if math.isfinite(lim.lower):
        cons.append({"type": "ineq", "fun": lambda z: float(predict(surface, z)[0]) - lim.lower})
    res = optimize.minimize(
        f,
        best,
        bounds=list(zip(lo, hi, strict=True)),
        constraints=cons,
        method="SLSQP",
        options={"ftol": 1e-14, "maxiter": 200},
    )
    cand = np.clip(np.asarray(res.x, dtype=np.float64), lo, hi)
    y_c = float(predict(surface, cand)[0])
    tol = 1e-9 * max(1.0, abs(lim.upper) if math.isfinite(lim.upper) else 1.0)
    if lim.lower - tol <= y_c <= lim.upper + tol and f(cand) <= f(best):
        best = cand
    return _point(surface, best)
