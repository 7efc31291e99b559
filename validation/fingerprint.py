"""The fingerprint of a comparison: how W and η scale with the amplitude, measured and model.

``fingerprint`` fits ``log W = a + s_W log Fg`` and ``log η = b + s_η log Fg`` for each
group of cases that differ only in amplitude (``group_name``), for the measured and the
model values. A positively homogeneous model (Coulomb friction, linear elasticity, zero
clearance) has s_W = 2 and s_η = 0 exactly; measured slopes that differ point to the
missing physics. With clearance the values are those of the loop without the free play
(``validation.hysteresis``), as ``compare`` judges them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # compare imports this module: the case type is for annotations only
    from validation.compare import CaseComparison
    from validation.measurements import Case

JUDGED_KEYS = {"W_cycle_Nmm": "W_without_free_play_Nmm", "eta": "eta_without_free_play"}
"""The free-play-free value of a metric, where a case with clearance has one."""


@dataclass(frozen=True)
class FingerprintFit:
    """Log–log slopes of W and η against amplitude for one group of cases.

    Attributes:
        group: Label of the group (what is held fixed).
        amplitudes_n: The amplitudes fitted [N].
        slope_W_measured: d log W / d log Fg of the measurements (NaN for η-only data).
        slope_W_model: Same for the model.
        slope_eta_measured: d log η / d log Fg of the measurements.
        slope_eta_model: Same for the model.
    """

    group: str
    amplitudes_n: tuple[float, ...]
    slope_W_measured: float
    slope_W_model: float
    slope_eta_measured: float
    slope_eta_model: float


def _slope(x: list[float], y: list[float]) -> float:
    xa, ya = np.asarray(x), np.asarray(y)
    ok = (xa > 0) & (ya > 0) & np.isfinite(ya)
    if len(np.unique(xa[ok])) < 2:
        return math.nan
    return float(np.polyfit(np.log(xa[ok]), np.log(ya[ok]), 1)[0])


def judged_value(c: CaseComparison, side: str, key: str) -> float:
    """One metric of one side ("measured" or "model"), free play removed where it was; NaN if absent."""
    values = getattr(c, side)
    return float(values.get(JUDGED_KEYS.get(key, key), values.get(key, math.nan)))


def _values(members: list[CaseComparison], side: str, key: str) -> list[float]:
    """One metric of one side of each case (``judged_value``)."""
    return [judged_value(c, side, key) for c in members]


def group_name(case: Case) -> str:
    """The case's design point without its amplitude, e.g. ``general, Δr = 0.1 mm``."""
    return ", ".join(filter(None, [case.hinge, case.describe()]))


def fingerprint(cases: tuple[CaseComparison, ...]) -> tuple[FingerprintFit, ...]:
    """Fit log–log slopes of W and η against amplitude per design group (``group_name``).

    Groups with fewer than two distinct amplitudes are skipped.
    """
    groups: dict[str, list[CaseComparison]] = {}
    for c in cases:
        groups.setdefault(group_name(c.case), []).append(c)
    fits = []
    for group, members in groups.items():
        amps = [c.case.amplitude_n for c in members]
        if len(set(amps)) < 2:
            continue

        fits.append(
            FingerprintFit(
                group=group,
                amplitudes_n=tuple(sorted(set(amps))),
                slope_W_measured=_slope(amps, _values(members, "measured", "W_cycle_Nmm")),
                slope_W_model=_slope(amps, _values(members, "model", "W_cycle_Nmm")),
                slope_eta_measured=_slope(amps, _values(members, "measured", "eta")),
                slope_eta_model=_slope(amps, _values(members, "model", "eta")),
            )
        )
    return tuple(fits)
