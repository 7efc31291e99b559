"""Re-fit every effect parameter of a model jointly (``validation.calibrate``, each step).

A one-effect-at-a-time fit cannot undo an early wrong turn: an effect fitted first absorbs
what a later one owns (a friction fitted alone takes up part of a series compliance's
stiffness loss). So after each effect is added, ``joint_fit`` re-fits the **primary**
parameter (the first ``ParamSpec``, the one ``diagnose`` and the greedy step fit) of every
effect in the model together, from their previous values (the new effect from its greedy
value), with ``scipy.optimize.least_squares`` within the ``ParamSpec`` bounds, on the
residuals that give the ledger's χ² (``validation.candidate_fit.residuals``). Other
parameters of an effect keep their values.

The uncertainty of the fitted values comes from the Jacobian J (finite differences, in
units of each parameter's range) at the optimum: ``cov = s² (JᵀJ)⁺`` with the scale
``s² = max(1, χ²/(N − k))`` (the residuals are in σ; a misfit beyond the noise inflates
it), ``σ_i = sqrt(cov_ii)`` and the correlations ``cov_ij / (σ_i σ_j)``. A parameter whose
value moved by more than its σ from its previous value is **moved**: the earlier step's
value was biased by what this step's effect now explains.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from validation.candidate_fit import FloatArray, MeasuredFeatures, residuals
from validation.evaluate import ModelEvaluator

DIFF_STEP = 1e-3
"""Finite-difference step of the Jacobian, in units of each parameter's range."""

MAX_NFEV = 60
"""Model evaluations the joint fit may spend (each evaluates every design point)."""


@dataclass(frozen=True)
class JointFit:
    """Every effect's primary parameter fitted together (module docstring).

    Attributes:
        effects: The model's effects with the fitted values (name → parameter → value).
        values: ``effect.param`` → fitted value.
        sigma: ``effect.param`` → its σ (NaN where J does not determine it).
        correlation: ``effect.param`` → ``effect.param`` → correlation coefficient.
        moved: Parameters that moved by more than σ from their previous value.
        previous: ``effect.param`` → the start value (previous step's, or the greedy fit's).
        chi2: χ² at the fit.
        features: Model features at the fit, shape (n_points, 3).
    """

    effects: dict[str, dict[str, float]]
    values: dict[str, float]
    sigma: dict[str, float]
    correlation: dict[str, dict[str, float]]
    moved: tuple[str, ...]
    previous: dict[str, float]
    chi2: float
    features: FloatArray = field(repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dict (no arrays)."""
        return {
            "values": self.values,
            "sigma": self.sigma,
            "correlation": self.correlation,
            "moved": list(self.moved),
            "previous": self.previous,
        }


def joint_fit(
    evaluator: ModelEvaluator,
    effects: Mapping[str, Mapping[str, float]],
    meas: MeasuredFeatures,
    previous: Mapping[str, float] | None = None,
) -> JointFit:
    """Fit the primary parameter of every effect in ``effects`` jointly.

    Args:
        evaluator: The model's evaluator (its own effects are replaced by ``effects``).
        effects: Every effect of the model with its start values (name → param → value).
        meas: The measured features.
        previous: ``effect.param`` → the value before this step, for the ``moved`` flag
            (default: the start values).

    Returns:
        The joint fit.
    """
    from scipy import optimize

    from fe.effects.registry import REGISTRY

    start = {n: dict(p) for n, p in effects.items()}
    free = [(n, REGISTRY[n].params[0]) for n in start]
    lo = np.array([p.lo for _, p in free])
    span = np.array([max(p.hi - p.lo, 1e-300) for _, p in free])
    x0 = np.array([start[n].get(p.name, p.default) for n, p in free], dtype=np.float64)
    u0 = np.clip((x0 - lo) / span, 1e-6, 1.0 - 1e-6)  # least_squares needs an interior start
    informative = meas.informative

    def trial(u: FloatArray) -> dict[str, dict[str, float]]:
        out = {n: dict(p) for n, p in start.items()}
        for (n, p), v in zip(free, lo + span * np.asarray(u), strict=True):
            out[n][p.name] = float(v)
        return out

    def fun(u: FloatArray) -> FloatArray:
        return residuals(evaluator.features(trial(u)), meas)[informative]

    res = optimize.least_squares(
        fun, u0, bounds=(0.0, 1.0), diff_step=DIFF_STEP, max_nfev=MAX_NFEV, x_scale=1.0
    )
    fitted = trial(res.x)
    keys = [f"{n}.{p.name}" for n, p in free]
    values = {k: fitted[n][p.name] for k, (n, p) in zip(keys, free, strict=True)}
    chi2 = float(np.sum(res.fun**2))
    sigma, corr = _uncertainty(np.asarray(res.jac), chi2, meas.n_obs, span)
    prev = dict(previous) if previous is not None else dict(zip(keys, x0.tolist(), strict=True))
    moved = tuple(
        k
        for k, s in zip(keys, sigma, strict=True)
        if k in prev and math.isfinite(s) and abs(values[k] - prev[k]) > s
    )
    return JointFit(
        effects=fitted,
        values=values,
        sigma=dict(zip(keys, sigma.tolist(), strict=True)),
        correlation={
            a: {b: float(corr[i, j]) for j, b in enumerate(keys)} for i, a in enumerate(keys)
        },
        moved=moved,
        previous={k: float(v) for k, v in prev.items() if k in values},
        chi2=chi2,
        features=evaluator.features(fitted),
    )


def _uncertainty(
    jac: FloatArray, chi2: float, n_obs: int, span: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """(σ per parameter (k,), correlation matrix (k, k)) from J in range units (module docstring)."""
    k = jac.shape[1]
    scale = max(1.0, chi2 / max(n_obs - k, 1))
    cov_u = scale * np.linalg.pinv(jac.T @ jac)
    var = np.diag(cov_u)
    ok = var > 0.0
    sigma = np.where(ok, np.sqrt(np.where(ok, var, 0.0)), np.nan) * span
    with np.errstate(invalid="ignore", divide="ignore"):
        s_u = np.sqrt(np.where(ok, var, np.nan))
        corr = cov_u / np.outer(s_u, s_u)
    return sigma, np.asarray(corr, dtype=np.float64)
