r"""Fit quality as the paper defines it (Eqs. 7-12), plus leave-one-out checks it lacks.

With ``y_i`` the sample responses, ``ỹ_i`` the surface at the samples, ``M``
the number of points and ``N`` the number of coefficients (the constant
included; 15 for the paper's quartic in two variables):

* relative error per point, Eq. 7: ``RE_i = (ỹ_i - y_i) / y_i``
* ``SSE = Σ (y_i - ỹ_i)²`` (Eq. 12), ``SST = Σ (y_i - ȳ)²`` (Eq. 11)
* ``R² = 1 - SSE / SST`` (Eq. 8)
* ``R²_adj = 1 - (M - 1) / (M - N) · (1 - R²)`` (Eq. 9)
* ``RMSE = sqrt(SSE / (M - N - 1))`` (Eq. 10). This follows the paper exactly,
  including its ``M - N - 1``: since ``N`` already counts the constant, the usual
  residual degrees of freedom would be ``M - N``. With M = 25, N = 15 the divisor
  is 9.

Not in the paper:

* leave-one-out residuals ``e_(i) = e_i / (1 - h_ii)`` with ``h_ii`` the
  leverage, ``PRESS = Σ e_(i)²`` and ``Q² = 1 - PRESS / SST``. These equal
  refitting without point ``i`` and predicting it, without refitting.
* an over-fitting diagnosis: a surface is flagged when ``R² - Q²`` exceeds
  ``Q2_GAP_LIMIT`` or when there are fewer than ``MIN_POINTS_PER_COEFFICIENT``
  points per coefficient.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rsm.polynomial import ResponseSurface, predict

FloatArray = npt.NDArray[np.float64]

Q2_GAP_LIMIT = 0.1
"""Flag a fit whose leave-one-out Q² falls more than this below its R²."""

MIN_POINTS_PER_COEFFICIENT = 1.5
"""Flag a fit with fewer sample points per coefficient than this (the paper has 25/15 ≈ 1.67)."""

_LEVERAGE_ONE = 1.0 - 1e-10


class OverfitWarning(UserWarning):
    """A response surface looks over-fitted; the message says why."""


@dataclass(frozen=True)
class FitMetrics:
    """Quality of a response surface at its own sample points.

    Attributes:
        n_points: M, the number of sample points.
        n_terms: N, the number of coefficients (constant included).
        relative_error: RE_i (Eq. 7), shape (n_points,), dimensionless (not percent).
        sse: Sum of squared residuals (Eq. 12), response units squared.
        sst: Total sum of squares about the mean (Eq. 11).
        r2: R² (Eq. 8).
        r2_adj: R²_adj (Eq. 9); NaN when M ≤ N.
        rmse: RMSE with the paper's divisor M - N - 1 (Eq. 10); NaN when M ≤ N + 1.
        max_abs_re_percent: max |RE_i| in percent.
        loo_residuals: e_(i), shape (n_points,); ±inf where a point has leverage 1.
        press: Σ e_(i)² (inf when any point has leverage 1).
        q2: 1 - PRESS / SST (-inf when PRESS is inf).
        condition_number: Of the scaled design matrix that was solved.
        overfit_reasons: Empty, or one sentence per reason the fit looks over-fitted.
    """

    n_points: int
    n_terms: int
    relative_error: FloatArray
    sse: float
    sst: float
    r2: float
    r2_adj: float
    rmse: float
    max_abs_re_percent: float
    loo_residuals: FloatArray
    press: float
    q2: float
    condition_number: float
    overfit_reasons: tuple[str, ...]

    def summary(self) -> dict[str, float]:
        """Return the headline numbers under the names the command line prints."""
        return {
            "R2": self.r2,
            "R2_adj": self.r2_adj,
            "RMSE": self.rmse,
            "max_abs_RE_percent": self.max_abs_re_percent,
            "Q2": self.q2,
            "PRESS": self.press,
            "condition_number": self.condition_number,
        }


def r2_adjusted(r2: float, n_points: int, n_terms: int) -> float:
    """Return R²_adj by the paper's Eq. 9, NaN when M ≤ N."""
    if n_points <= n_terms:
        return math.nan
    return 1.0 - (n_points - 1) / (n_points - n_terms) * (1.0 - r2)


def rmse_paper(sse: float, n_points: int, n_terms: int) -> float:
    """Return RMSE by the paper's Eq. 10, ``sqrt(SSE / (M - N - 1))``; NaN when M ≤ N + 1."""
    dof = n_points - n_terms - 1
    return math.sqrt(sse / dof) if dof > 0 else math.nan


def loo_residuals(residuals: npt.ArrayLike, leverage: npt.ArrayLike) -> FloatArray:
    """Return leave-one-out residuals ``e_i / (1 - h_ii)``.

    Args:
        residuals: ``y_i - ỹ_i``, shape (n_points,).
        leverage: Hat-matrix diagonal ``h_ii``, shape (n_points,).

    Returns:
        Shape (n_points,); ±inf (or NaN for a zero residual) where ``h_ii`` is 1,
        i.e. where the point alone determines a coefficient and cannot be predicted
        without it.
    """
    e = np.asarray(residuals, dtype=np.float64)
    h = np.asarray(leverage, dtype=np.float64)
    denom = 1.0 - h
    out = np.full_like(e, math.inf)
    ok = h < _LEVERAGE_ONE
    out[ok] = e[ok] / denom[ok]
    return out


def overfit_reasons(n_points: int, n_terms: int, r2: float, q2: float) -> tuple[str, ...]:
    """Explain why a fit looks over-fitted, or return an empty tuple.

    Args:
        n_points: M.
        n_terms: N.
        r2: R².
        q2: Leave-one-out Q².

    Returns:
        One sentence per criterion that fails.
    """
    reasons = []
    ratio = n_points / n_terms
    if ratio < MIN_POINTS_PER_COEFFICIENT:
        reasons.append(
            f"only {n_points} points for {n_terms} coefficients ({ratio:.2f} per coefficient, "
            f"fewer than {MIN_POINTS_PER_COEFFICIENT})"
        )
    if not q2 >= r2 - Q2_GAP_LIMIT:
        reasons.append(
            f"leave-one-out Q2 = {q2:.4g} is far below R2 = {r2:.4g} "
            f"(gap more than {Q2_GAP_LIMIT}): the surface predicts its own points "
            "much better than points it has not seen"
        )
    return tuple(reasons)


def fit_metrics(surface: ResponseSurface, *, warn: bool = True) -> FitMetrics:
    """Compute the paper's fit metrics and the leave-one-out checks.

    Args:
        surface: The fitted surface (it carries its sample points and leverages).
        warn: Emit an :class:`OverfitWarning` when the fit looks over-fitted.

    Returns:
        The metrics.

    Warns:
        OverfitWarning: If ``warn`` and ``overfit_reasons`` is not empty.
    """
    y = surface.y
    y_fit = predict(surface, surface.x)
    resid = y - y_fit
    with np.errstate(divide="ignore", invalid="ignore"):
        re = np.where(y != 0.0, (y_fit - y) / y, np.nan)
    sse = float(resid @ resid)
    sst = float(np.sum((y - y.mean()) ** 2))
    m, n = surface.n_points, surface.n_terms
    r2 = 1.0 - sse / sst
    loo = loo_residuals(resid, surface.leverage)
    press = float(loo @ loo) if np.all(np.isfinite(loo)) else math.inf
    q2 = 1.0 - press / sst
    reasons = overfit_reasons(m, n, r2, q2)
    if warn and reasons:
        warnings.warn(
            f"response surface for {surface.y_name!r} looks over-fitted: " + "; ".join(reasons),
            OverfitWarning,
            stacklevel=2,
        )
    re.setflags(write=False)
    loo.setflags(write=False)
    return FitMetrics(
        n_points=m,
        n_terms=n,
        relative_error=re,
        sse=sse,
        sst=sst,
        r2=r2,
        r2_adj=r2_adjusted(r2, m, n),
        rmse=rmse_paper(sse, m, n),
        max_abs_re_percent=float(100.0 * np.nanmax(np.abs(re)))
        if np.any(np.isfinite(re))
        else math.nan,
        loo_residuals=loo,
        press=press,
        q2=q2,
        condition_number=surface.condition_number,
        overfit_reasons=reasons,
    )
