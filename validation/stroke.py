"""Features of displacement-controlled cycles: what a rig that drives ±δ_a measures well.

Under displacement control the amplitude is set and the force answers, so the features
of a cycle +δ → −δ → +δ (``STROKE_FEATURES``) are forces and travels, not δ(±Fg):

* ``W_cycle_Nmm``: the energy per cycle ∮F dδ (the loop closed by its chord) [N·mm];
* ``force_mid_up_N`` / ``force_mid_down_N``: the mean force on the ascending /
  descending branch over mid-stroke, |δ − δ_c| ≤ ``StrokeSettings.mid_window``·δ_a
  (δ_c the mid-range): the slip force each way, averaged over the rig's ringing;
* ``travel_up_mm`` / ``travel_down_mm``: the travel from a stroke end until the force
  first reaches half the opposite mid-stroke force: the lost travel of the backlash and
  the compliance together ("the travel to reverse the force").

``EXTRA_FEATURES`` are reported, not fitted: the extreme forces (the ringing after each
reversal is the rig's dynamics, not the element's) and the secant stiffness between the
reversal points, (F(+δ) − F(−δ)) / (δ(+) − δ(−)).

The σ of a feature at a design point (``stroke_sigma``) combines in quadrature the
**scatter of the steady cycles** of the record (their sample standard deviation: the
cycles are replicates), the **record's noise** (force noise over the mid-stroke samples,
displacement noise for the travels, ``validation.loops.area_noise_sigma`` for W) and a
**model floor** ``rel_floor``·|value| (``rel_floor``·δ_a for the travels).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import DataError, check_range
from validation.loop_metrics import loop_area
from validation.loops import area_noise_sigma, noise_level
from validation.rig_cycles import displacement_stages

FloatArray = npt.NDArray[np.float64]

STROKE_FEATURES = (
    "W_cycle_Nmm",
    "force_mid_up_N",
    "force_mid_down_N",
    "travel_up_mm",
    "travel_down_mm",
)
"""The fitted features of a displacement-controlled cycle, in column order."""

EXTRA_FEATURES = ("force_peak_plus_N", "force_peak_minus_N", "secant_stiffness_N_per_mm")
"""Reported beside them, not fitted (module docstring)."""

STROKE_LABELS = {
    "W_cycle_Nmm": "W",
    "force_mid_up_N": "F_mid↑",
    "force_mid_down_N": "F_mid↓",
    "travel_up_mm": "travel↑",
    "travel_down_mm": "travel↓",
    "force_peak_plus_N": "F_max",
    "force_peak_minus_N": "F_min",
    "secant_stiffness_N_per_mm": "k_sec",
}
"""Short names for tables."""


@dataclass(frozen=True)
class StrokeSettings:
    """How displacement-controlled cycles are summarised and judged.

    Attributes:
        mid_window: Half-width of the mid-stroke window, a fraction of δ_a.
        rel_floor: Model floor, a fraction of each feature (of δ_a for the travels).
        k: Coverage factor: a feature passes when |model − measured| ≤ k σ.
    """

    mid_window: float = 0.25
    rel_floor: float = 0.02
    k: float = 2.0

    def __post_init__(self) -> None:
        check_range("mid_window", self.mid_window, 0.0, 1.0, lo_open=True)
        check_range("rel_floor", self.rel_floor, 0.0, 1.0)
        check_range("k", self.k, 0.0, 10.0, lo_open=True)


def _first_crossing(F: FloatArray, d: FloatArray, level: float, sign: float) -> float:
    """δ where sign·(F − level) first becomes ≥ 0 (linear between samples); the branch's end if never."""
    above = np.flatnonzero(sign * (F - level) >= 0.0)
    if above.size == 0:
        return float(d[-1])
    i = int(above[0])
    if i == 0:
        return float(d[0])
    t = (level - F[i - 1]) / (F[i] - F[i - 1])
    return float(d[i - 1] + t * (d[i] - d[i - 1]))


def stroke_features(
    force_n: npt.ArrayLike, disp_mm: npt.ArrayLike, settings: StrokeSettings | None = None
) -> dict[str, float]:
    """The features of one cycle +δ → −δ → +δ (module docstring), by name.

    Args:
        force_n: Force, shape (n,) [N].
        disp_mm: Displacement, shape (n,) [mm].
        settings: The mid-stroke window (default ``StrokeSettings()``).

    Raises:
        DataError: Not one cycle, or a mid-stroke window without samples.
    """
    s = settings or StrokeSettings()
    F = np.asarray(force_n, dtype=np.float64)
    d = np.asarray(disp_mm, dtype=np.float64)
    st = displacement_stages(d, "stroke features")
    down, up = slice(st.peak_first, st.trough + 1), slice(st.trough, st.peak_last + 1)
    amp = 0.5 * float(d.max() - d.min())
    centre = 0.5 * float(d.max() + d.min())
    mids = []
    for sl in (up, down):
        window = np.abs(d[sl] - centre) <= s.mid_window * amp
        if not np.any(window):
            raise DataError("stroke features: no sample at mid-stroke on a branch")
        mids.append(float(np.mean(F[sl][window])))
    f_up, f_down = mids
    travel_down = float(d[st.peak_first]) - _first_crossing(F[down], d[down], 0.5 * f_down, -1.0)
    travel_up = _first_crossing(F[up], d[up], 0.5 * f_up, 1.0) - float(d[st.trough])
    loop = slice(st.peak_first, st.peak_last + 1)
    span = float(d[st.peak_last] - d[st.trough])
    return {
        "W_cycle_Nmm": loop_area(F[loop], d[loop]),
        "force_mid_up_N": f_up,
        "force_mid_down_N": f_down,
        "travel_up_mm": travel_up,
        "travel_down_mm": travel_down,
        "force_peak_plus_N": float(F.max()),
        "force_peak_minus_N": float(F.min()),
        "secant_stiffness_N_per_mm": (float(F[st.peak_last] - F[st.trough]) / span)
        if span > 0
        else math.nan,
    }


def feature_vector(features: dict[str, float]) -> FloatArray:
    """The fitted features in ``STROKE_FEATURES`` order, shape (5,)."""
    return np.array([features[n] for n in STROKE_FEATURES])


def _noise(force_n: FloatArray, disp_mm: FloatArray, settings: StrokeSettings) -> FloatArray:
    """The record-noise part of the σ of one cycle's fitted features, shape (5,)."""
    F, d = np.asarray(force_n), np.asarray(disp_mm)
    st = displacement_stages(d, "stroke noise")
    amp = 0.5 * float(np.ptp(d))
    n_mid = max(
        1.0, 0.5 * float(np.count_nonzero(np.abs(d - d.mean()) <= settings.mid_window * amp))
    )
    s_f = noise_level(F) / math.sqrt(n_mid)
    s_d = noise_level(d)
    return np.array([area_noise_sigma(F, d, st), s_f, s_f, s_d, s_d])


def stroke_sigma(
    cycles: Sequence[tuple[FloatArray, FloatArray]], settings: StrokeSettings
) -> tuple[FloatArray, FloatArray]:
    """The mean fitted features of a design point's cycles and their σ, each shape (5,).

    Args:
        cycles: (F [N], δ [mm]) of each steady cycle (replicate), at least one.
        settings: The floor and the mid-stroke window.

    Returns:
        (mean features, σ): cycle scatter (ddof = 1) ⊕ noise ⊕ floor.
    """
    feats = np.array([feature_vector(stroke_features(F, d, settings)) for F, d in cycles])
    mean = feats.mean(axis=0)
    rep = feats.std(axis=0, ddof=1) if len(cycles) > 1 else np.zeros(mean.size)
    noise = np.mean([_noise(F, d, settings) for F, d in cycles], axis=0)
    amp = float(np.mean([0.5 * np.ptp(d) for _F, d in cycles]))
    scale = np.abs(mean)
    scale[3:] = amp
    sigma = np.sqrt(rep**2 + noise**2 + (settings.rel_floor * scale) ** 2)
    return mean, np.asarray(sigma, dtype=np.float64)
