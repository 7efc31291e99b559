"""Displacement-controlled records: cycles, steady replicates, and one cycle as a loop.

A displacement-controlled rig drives a sine ±δ_a that ramps in and out. ``split_cycles``
cuts the record at its displacement peaks: excursions beyond ``±h`` around the record's
mid-range ``c = ½(max δ + min δ)`` alternate +, −, +, … (``h = max(NOISE_BANDS σ_δ,
CYCLE_BAND_FRACTION · max|δ − c|)``: a hysteresis threshold, as ``validation.loops``
uses on the force, so noise cannot create a reversal); each positive excursion's largest
sample is a peak and a cycle runs from one peak to the next (+δ → −δ → +δ). A cycle is
**steady** when its peak-to-peak ``p`` is within a tolerance ``τ`` of the steady
peak-to-peak ``p_s``, the median of the cycles with ``p ≥ (1 − τ) max p``; the ramp-in
and ramp-out cycles fall short of it and are dropped. At least ``MIN_STEADY_CYCLES`` must
be steady (a record whose amplitude only grows has no steady state).

In a measurement set (``validation.measurements``, ``control = displacement``) each
steady cycle is one loop file and one case, the cycles of one record being replicates;
``process_displacement_cycle`` measures it with the same ``Stages`` and ``LoopMetrics``
as a force-controlled loop, its turning points being the displacement's: +δ → −δ → +δ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import DataError
from validation.loop_files import Loop
from validation.loop_metrics import Stages, loop_area, loop_metrics
from validation.loops import (
    NOISE_BANDS,
    REVERSED_ETA,
    REVERSED_SIGMAS,
    ProcessedLoop,
    area_noise_sigma,
    noise_level,
)

FloatArray = npt.NDArray[np.float64]

CYCLE_BAND_FRACTION = 0.05
"""Least half-width of the band around the mid-range that a reversal must cross, as a
fraction of the largest excursion (ramp cycles below 5 % of the stroke merge into their
neighbours, whose peak-to-peak then still measures the larger one)."""

MIN_STEADY_CYCLES = 2
"""A record needs at least this many steady cycles (one alone cannot show it is steady)."""

AMPLITUDE_TOL_DISPLACEMENT = 0.05
"""A displacement-controlled loop file must reach its stated ±δ_a within this fraction."""


@dataclass(frozen=True)
class CycleSplit:
    """The cycles of a displacement-controlled record.

    Attributes:
        bounds: First and last sample of each cycle (both +δ peaks), shape (n_cycles, 2),
            int64.
        peak_to_peak_mm: Peak-to-peak displacement of each cycle, shape (n_cycles,) [mm].
        steady_peak_to_peak_mm: The steady peak-to-peak p_s [mm].
        steady: Whether each cycle is steady, shape (n_cycles,), bool.
        centre_mm: The record's mid-range c [mm].
        tolerance: The tolerance τ used.
    """

    bounds: npt.NDArray[np.int64]
    peak_to_peak_mm: FloatArray
    steady_peak_to_peak_mm: float
    steady: npt.NDArray[np.bool_]
    centre_mm: float
    tolerance: float

    @property
    def n_steady(self) -> int:
        """Number of steady cycles."""
        return int(np.count_nonzero(self.steady))


def cycle_peaks(displacement_mm: FloatArray) -> tuple[npt.NDArray[np.int64], float]:
    """Return the indices of the +δ peaks (one per positive excursion) and the mid-range.

    Args:
        displacement_mm: The record's displacement, shape (n,) [mm], finite.
    """
    x = np.asarray(displacement_mm, dtype=np.float64)
    c = 0.5 * float(x.max() + x.min())
    y = x - c
    h = max(NOISE_BANDS * noise_level(x), CYCLE_BAND_FRACTION * float(np.max(np.abs(y))))
    level = np.sign(y).astype(np.int64) * (np.abs(y) > h)  # +1, −1 beyond ±h, else 0
    idx = np.flatnonzero(level)
    if idx.size == 0:
        return np.zeros(0, dtype=np.int64), c
    runs = np.split(idx, np.flatnonzero(np.diff(level[idx])) + 1)  # alternating excursions
    peaks = [int(r[np.argmax(y[r])]) for r in runs if level[r[0]] > 0]
    return np.array(peaks, dtype=np.int64), c


def split_cycles(displacement_mm: FloatArray, tolerance: float, source: str) -> CycleSplit:
    """Cut a displacement-controlled record into cycles and find the steady ones.

    Args:
        displacement_mm: Displacement, shape (n,) [mm], finite.
        tolerance: τ, relative tolerance on the peak-to-peak (e.g. 0.02).
        source: What to name in errors (file and column).

    Raises:
        DataError: No full cycle +δ → −δ → +δ, or fewer than ``MIN_STEADY_CYCLES`` steady
            cycles (the message lists every cycle's peak-to-peak).
    """
    x = np.asarray(displacement_mm, dtype=np.float64)
    peaks, c = cycle_peaks(x)
    if peaks.size < 2:
        raise DataError(
            f"{source}: no full cycle +δ → −δ → +δ ({peaks.size} positive peak(s)); a "
            "displacement-controlled record needs at least two"
        )
    bounds = np.stack([peaks[:-1], peaks[1:]], axis=1)  # (n_cycles, 2)
    p2p = np.array([np.ptp(x[i : j + 1]) for i, j in bounds])
    top = p2p[p2p >= (1.0 - tolerance) * p2p.max()]
    steady_p2p = float(np.median(top))
    steady = np.abs(p2p - steady_p2p) <= tolerance * steady_p2p
    if np.count_nonzero(steady) < MIN_STEADY_CYCLES:
        shown = ", ".join(f"{p:.4g}" for p in p2p)
        raise DataError(
            f"{source}: no steady cycle: fewer than {MIN_STEADY_CYCLES} of its {p2p.size} "
            f"cycles have a peak-to-peak within ±{tolerance:.0%} of {steady_p2p:.4g} mm "
            f"(peak-to-peak: {shown} mm)"
        )
    return CycleSplit(bounds, p2p, steady_p2p, steady, c, tolerance)


def cycle_energies(
    force_n: FloatArray, displacement_mm: FloatArray, split: CycleSplit
) -> FloatArray:
    """Return the energy dissipated in each cycle, ∮ F dδ closed by the chord [N·mm].

    Args:
        force_n: Force, shape (n,) [N].
        displacement_mm: Displacement, shape (n,) [mm].
        split: Its cycles.

    Returns:
        Shape (n_cycles,) [N·mm].
    """
    return np.array(
        [loop_area(force_n[i : j + 1], displacement_mm[i : j + 1]) for i, j in split.bounds]
    )


def displacement_stages(displacement_mm: FloatArray, source: str) -> Stages:
    """Turning points of one displacement-controlled cycle +δ → −δ → +δ.

    The trough is the smallest displacement; the peaks are the largest before and after it.

    Raises:
        DataError: If the trough is at either end (the file is not one full cycle).
    """
    d = np.asarray(displacement_mm, dtype=np.float64)
    trough = int(np.argmin(d))
    if trough == 0 or trough == d.size - 1:
        raise DataError(
            f"{source}: not one cycle +δ → −δ → +δ: the smallest displacement is at the "
            f"{'first' if trough == 0 else 'last'} sample"
        )
    first = int(np.argmax(d[: trough + 1]))
    last = trough + int(np.argmax(d[trough:]))
    return Stages(start=0, peak_first=first, trough=trough, peak_last=last, n_cycles=1)


def check_displacement_amplitude(loop: Loop, amplitude_mm: float, where: str) -> None:
    """Check that a cycle's half peak-to-peak is ±δ_a within ``AMPLITUDE_TOL_DISPLACEMENT``.

    Raises:
        DataError: Naming the case, the stated and the reached amplitude.
    """
    half = 0.5 * float(np.ptp(loop.displacement_mm))
    if abs(half - amplitude_mm) > AMPLITUDE_TOL_DISPLACEMENT * amplitude_mm:
        raise DataError(
            f"{where}: the cycle's displacement amplitude {half:.4g} mm is not the stated "
            f"amplitude_mm = {amplitude_mm:g} within {AMPLITUDE_TOL_DISPLACEMENT:.0%}"
        )


def process_displacement_cycle(
    force_n: FloatArray, displacement_mm: FloatArray, source: str
) -> ProcessedLoop:
    """Measure one displacement-controlled cycle (offsets already removed on import).

    The metrics are ``validation.loop_metrics.loop_metrics`` at the displacement's turning points:
    ``F_max = ½(F(+δ) − F(−δ))`` (the force at the reversals), ``δ_max`` the half
    peak-to-peak displacement, W the loop area closed by the chord, η = W/(2π·½F_max δ_max).

    Raises:
        DataError: Not finite, not one cycle, or a loop that runs the wrong way round.
    """
    F = np.asarray(force_n, dtype=np.float64)
    d = np.asarray(displacement_mm, dtype=np.float64)
    for name, a in (("force_N", F), ("displacement_mm", d)):
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise DataError(f"{source}: row {bad[0] + 1}, column {name}: not a finite number")
    stages = displacement_stages(d, source)
    metrics = loop_metrics(F, d, stages)
    u = 2.0 * math.pi * abs(metrics.U_max_Nmm)
    if metrics.W_cycle_Nmm < REVERSED_ETA * u - REVERSED_SIGMAS * area_noise_sigma(F, d, stages):
        raise DataError(
            f"{source}: the loop runs the wrong way round (W = {metrics.W_cycle_Nmm:.4g} N·mm): "
            "a passive device dissipates; flip the force or the displacement in the mapping"
        )
    return ProcessedLoop(F, d, stages, metrics, 0.0, 0.0, source)
