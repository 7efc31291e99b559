"""What the data could detect: the smallest common relative error the χ² test sees.

:func:`sensitivity` gives, per feature column, the relative model error that the χ²
test of ``validation.diagnose`` detects with a given power; it decides the
``cannot_tell`` verdict and is reported with every diagnosis (:func:`power_words`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from scipy import stats

from validation.candidate_fit import MeasuredFeatures

SENSITIVITY_NAMES = ("delta_max", "loop_area_or_eta", "opening")
"""Names of the three feature columns in a sensitivity statement (column 1 is W for a loop
and η for an η-only row: at a given δ_max a relative error of one is one of the other)."""


def sensitivity(meas: MeasuredFeatures, alpha: float, power: float) -> dict[str, float | None]:
    """Smallest common relative error of each feature the χ² test would detect.

    A model error that scales one feature by (1 + e) at every design point gives residuals
    ``e·v_i/σ_i`` and makes χ² noncentral with ``λ = e² Σ (v_i/σ_i)²`` over the
    informative features. The test (χ² above its (1 − α) quantile on N degrees of freedom)
    detects it with probability ``power`` when λ reaches λ* with
    ``P(χ²_N(λ*) > limit) = power``; so ``e_min = √(λ* / Σ (v_i/σ_i)²)``.

    Returns:
        Column name (``SENSITIVITY_NAMES``) → e_min (relative, e.g. 0.3 = 30 %), or None
        where that feature carries no information at all.
    """
    from scipy import optimize

    n = meas.n_obs
    out: dict[str, float | None] = dict.fromkeys(SENSITIVITY_NAMES)
    if n == 0:
        return out
    limit = float(stats.chi2.ppf(1.0 - alpha, n))
    lam = optimize.brentq(lambda x: stats.ncx2.sf(limit, n, x) - power, 1e-9, 1e6 + 100 * n)
    info = meas.informative
    with np.errstate(invalid="ignore", divide="ignore"):
        snr2 = np.where(info, (meas.values / meas.sigma) ** 2, 0.0)
    for j, name in enumerate(SENSITIVITY_NAMES):
        total = float(np.sum(snr2[:, j]))
        out[name] = math.sqrt(lam / total) if total > 0 else None
    return out


def power_words(sens: Mapping[str, float | None], alpha: float, power: float) -> str:
    """Say :func:`sensitivity`'s result in words, as the verdicts report it."""
    parts = [
        f"{name.replace('_', ' ')} {'—' if e is None else f'{e:.0%}'}" for name, e in sens.items()
    ]
    return (
        f"smallest relative error these data detect with {power:.0%} power at α = {alpha:g}: "
        + ", ".join(parts)
    )
