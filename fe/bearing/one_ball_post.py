"""Measurements of a meshed Hertz contact: footprint semi-axes, half-space displacement.

Helpers of :mod:`fe.bearing.one_ball` (see there for how they are used):

* :func:`footprint_semi_axes` — semi-axes of an elliptic contact from the nodal forces on
  a structured grid, by force moments, an ellipsoid fit and the discrete edge;
* :func:`halfspace_axis_displacement` — the Boussinesq displacement on the contact axis
  at a depth under the Hertz pressure, to compare an approach measured at finite depth;
* :func:`fit_contact_constant` — ``δ = K^{-2/3} Q^{2/3} + c Q`` over several loads.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from fe.bearing.hertz import ContactEllipse

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


class SemiAxes(NamedTuple):
    """Semi-axes of one footprint [mm] and its largest nodal pressure [MPa].

    Attributes:
        a_moment: From ``a² = 5 (<x²> − h_x²/6)`` with the force-weighted mean.
        b_moment: From ``b² = 5 (<y²> − h_y²/6)``.
        a_fit: From the least-squares ellipsoid fit of ``p²`` (nan if not closed).
        b_fit: Same for b.
        a_edge: Midway between the last closed and first open node on y = 0.
        b_edge: Same on x = 0.
        p_max: Largest nodal pressure ``F/A``.
    """

    a_moment: float
    b_moment: float
    a_fit: float
    b_fit: float
    a_edge: float
    b_edge: float
    p_max: float


def _grid_index(v: FloatArray) -> tuple[FloatArray, IntArray]:
    vals = np.unique(np.round(v, 9))
    return vals, np.searchsorted(vals, np.round(v, 9)).astype(np.int64)


def footprint_semi_axes(
    x: FloatArray, y: FloatArray, force: FloatArray, area: FloatArray, h_x: float, h_y: float
) -> SemiAxes:
    """Return the semi-axes of a half footprint (y ≥ 0, y = 0 a symmetry line).

    For the Hertz pressure ``p0 sqrt(1 − x²/a² − y²/b²)``, ``<x²> = a²/5``; consistent
    nodal forces integrate the bilinear interpolant of x², which exceeds x² by ``h²/6``
    on average over a uniform grid of size h, hence the correction. The fit uses the
    closed nodes whose four grid neighbours (mirrored across y = 0) are closed.

    Args:
        x: Node positions across the footprint (major axis), shape (n,) [mm].
        y: Node positions along the minor axis, ≥ 0, shape (n,) [mm]; the nodes must
            form a tensor grid (x values × y values).
        force: Normal nodal forces, shape (n,) [N].
        area: Nodal areas, shape (n,) [mm²].
        h_x: Uniform grid size in x over the footprint [mm].
        h_y: Same in y [mm].
    """
    total = force.sum()
    a_m = math.sqrt(5.0 * (float(force @ x**2) / total - h_x**2 / 6.0))
    b_m = math.sqrt(5.0 * (float(force @ y**2) / total - h_y**2 / 6.0))
    xv, i = _grid_index(x)
    yv, j = _grid_index(y)
    pres = np.full((len(xv), len(yv)), np.nan)
    pres[i, j] = force / area
    closed = np.nan_to_num(pres) > 0.0
    pad = np.pad(closed, 1, constant_values=False)
    pad[1:-1, 0] = closed[:, 0]  # mirror: the node below y = 0 is the one above
    inner = closed & pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:]
    ii, jj = np.nonzero(inner)
    A = np.column_stack([np.ones(len(ii)), xv[ii] ** 2, yv[jj] ** 2])
    c, *_ = np.linalg.lstsq(A, pres[ii, jj] ** 2, rcond=None)
    a_f = math.sqrt(-c[0] / c[1]) if c[1] < 0 else math.nan
    b_f = math.sqrt(-c[0] / c[2]) if c[2] < 0 else math.nan
    i0, j0 = int(np.argmin(np.abs(xv))), 0
    row = np.flatnonzero(closed[:, j0])
    a_e = 0.25 * (xv[row[-1]] + xv[row[-1] + 1] - xv[row[0]] - xv[row[0] - 1])
    col = np.flatnonzero(closed[i0, :])
    b_e = 0.5 * (yv[col[-1]] + yv[col[-1] + 1])
    return SemiAxes(a_m, b_m, a_f, b_f, a_e, b_e, float(np.nanmax(pres)))


def halfspace_axis_displacement(
    ell: ContactEllipse, depth_mm: float, young_mpa: float, poisson: float, n: int = 4000
) -> float:
    """Return w(d): the Boussinesq normal displacement at depth d on the axis [mm].

    Half-space under the Hertz pressure ``p0 sqrt(1 − x²/a² − y²/b²)``; a point force P
    gives ``u_z = P/(4πG) [2(1 − ν)/ρ + d²/ρ³]`` at distance ρ. In the coordinates
    ``x = a sin φ cos θ, y = b sin φ sin θ`` the integrand is smooth (Gauss–Legendre in
    φ, the periodic trapezoid rule in θ). ``w(0)`` summed over both bodies is δ_H.

    Args:
        ell: Hertz contact (a, b, p_max).
        depth_mm: d ≥ 0 [mm].
        young_mpa: E of the body [MPa].
        poisson: ν of the body.
        n: Points in θ (the ellipse is slender: θ needs many points).
    """
    a, b, p0, d = ell.semi_major_mm, ell.semi_minor_mm, ell.max_pressure_mpa, depth_mm
    shear = young_mpa / (2.0 * (1.0 + poisson))
    phi_x, phi_w = np.polynomial.legendre.leggauss(200)
    phi = 0.25 * math.pi * (phi_x + 1.0)  # (0, π/2)
    theta = 2.0 * math.pi * np.arange(n) / n
    s = np.sqrt((a * np.cos(theta)) ** 2 + (b * np.sin(theta)) ** 2)  # (n,)
    sp, cp = np.sin(phi)[:, None], np.cos(phi)[:, None]
    rho = np.sqrt((sp * s[None, :]) ** 2 + d * d)
    kernel = 2.0 * (1.0 - poisson) * sp / rho + d * d * sp / rho**3  # sin φ from dA
    integrand = p0 * a * b * cp * cp * kernel
    total = float(np.sum(phi_w[:, None] * integrand)) * 0.25 * math.pi * (2.0 * math.pi / n)
    return total / (4.0 * math.pi * shear)


def fit_contact_constant(loads_n: FloatArray, approach_mm: FloatArray) -> tuple[float, float]:
    """Least-squares ``δ = K^{-2/3} Q^{2/3} + c Q``: return (K [N/mm^1.5], c [mm/N]).

    Args:
        loads_n: Loads Q, shape (n,), n ≥ 2 [N].
        approach_mm: Total approaches δ, shape (n,) [mm].
    """
    q = np.asarray(loads_n, dtype=np.float64)
    A = np.column_stack([q ** (2.0 / 3.0), q])
    (s, c), *_ = np.linalg.lstsq(A, np.asarray(approach_mm, dtype=np.float64), rcond=None)
    return float(s**-1.5), float(c)
