"""The turning points of a loop record and the metrics of its last loop.

``validation.loops`` finds the stages of a record (``Stages``) and calls ``loop_metrics``
on it; the formulas are described in that module's docstring (step 3, Metrics).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Stages:
    """Turning points of a record (indices into its samples).

    Attributes:
        start: First sample of the protocol: after the initial zero run, or for a record
            cut mid-cycle its upward zero crossing (``validation.loops.loading_start``).
        peak_first: The +Fg turning point that opens the last loop.
        trough: The −Fg turning point of the last loop.
        peak_last: The +Fg turning point that closes the last loop.
        n_cycles: Closed loops −Fg → +Fg found in the record.
    """

    start: int
    peak_first: int
    trough: int
    peak_last: int
    n_cycles: int

    @property
    def last_loop(self) -> slice:
        """Samples of the last loop +Fg → −Fg → +Fg (inclusive of both peaks)."""
        return slice(self.peak_first, self.peak_last + 1)


@dataclass(frozen=True)
class LoopMetrics:
    """What ``loop_metrics`` measures on one loop (names as in ``fe.general.cycle`` metrics).

    Attributes:
        f_max_n: Half peak-to-peak force of the last loop [N].
        disp_at_peak_mm: δ(+Fg) at the closing peak, from the start [mm].
        disp_at_minus_peak_mm: δ(−Fg) [mm].
        delta_max_mm: (δ(+Fg) − δ(−Fg))/2 [mm].
        W_cycle_Nmm: Loop area, closed by the chord [N·mm].
        U_max_Nmm: ½ F_max δ_max [N·mm].
        eta: W_cycle / (2π U_max).
        secant_stiffness_N_per_mm: F_max / δ_max [N/mm].
        closure_mm: δ(end) − δ(start) of the last loop, the gap the chord closes [mm].
        n_samples: Samples in the last loop.
    """

    f_max_n: float
    disp_at_peak_mm: float
    disp_at_minus_peak_mm: float
    delta_max_mm: float
    W_cycle_Nmm: float
    U_max_Nmm: float
    eta: float
    secant_stiffness_N_per_mm: float
    closure_mm: float
    n_samples: int

    def as_dict(self) -> dict[str, float]:
        """Return the metrics as a plain dict (JSON-ready)."""
        return {k: float(v) for k, v in vars(self).items()}


def loop_area(force_n: FloatArray, displacement_mm: FloatArray) -> float:
    """Return ∮ F dδ of a polygon closed by the chord from the last point to the first [N·mm].

    ``W = Σ ½ (F_i + F_{i+1}) (δ_{i+1} − δ_i)`` over the samples and the closing chord;
    for a closed polygon this is the shoelace area, independent of constant offsets.

    Args:
        force_n: Force along the loop, shape (n,) [N].
        displacement_mm: Displacement along the loop, shape (n,) [mm].
    """
    F = np.append(np.asarray(force_n, dtype=np.float64), force_n[0])
    d = np.append(np.asarray(displacement_mm, dtype=np.float64), displacement_mm[0])
    return float(np.sum(0.5 * (F[1:] + F[:-1]) * np.diff(d)))


def loop_metrics(force_n: FloatArray, displacement_mm: FloatArray, stages: Stages) -> LoopMetrics:
    """Measure the last loop of an offset-free record (see the module docstring).

    Args:
        force_n: Force, offset removed, shape (n,) [N].
        displacement_mm: Displacement from the start, shape (n,) [mm].
        stages: Its turning points.
    """
    F = np.asarray(force_n, dtype=np.float64)
    d = np.asarray(displacement_mm, dtype=np.float64)
    sl = stages.last_loop
    W = loop_area(F[sl], d[sl])
    f_max = 0.5 * float(F[stages.peak_last] - F[stages.trough])
    d_plus, d_minus = float(d[stages.peak_last]), float(d[stages.trough])
    delta_max = 0.5 * (d_plus - d_minus)
    U = 0.5 * f_max * delta_max
    return LoopMetrics(
        f_max_n=float(f_max),
        disp_at_peak_mm=d_plus,
        disp_at_minus_peak_mm=d_minus,
        delta_max_mm=delta_max,
        W_cycle_Nmm=W,
        U_max_Nmm=U,
        eta=W / (2 * math.pi * U) if U > 0 else math.nan,
        secant_stiffness_N_per_mm=f_max / delta_max if delta_max > 0 else math.nan,
        closure_mm=float(d[stages.peak_last] - d[stages.peak_first]),
        n_samples=sl.stop - sl.start,
    )
