"""Loop processing, the same for measured and model loops.

A record follows the protocol 0 → +Fg → −Fg → +Fg (more closed cycles −Fg → +Fg may
follow; the last one is used). Every loop, measured or computed, goes through
``process_loop``, so both sides of a comparison are measured with the same ruler:

1. **Stages** (``split_stages``): the record is cut into excursions where the force is
   above ``+h`` or below ``−h``, with ``h = ½ max|F|`` (a hysteresis threshold: noise far
   smaller than Fg/2 cannot create or hide a reversal). The excursions must alternate
   +, −, +, (−, +)…; within each, the extreme sample is the turning point. The last loop
   runs from the last-but-one positive peak through the last negative peak to the last
   positive peak.
2. **Offsets** (``loading_start``): the *initial zero* is the run of leading samples
   before the force or the displacement first moves away from its first sample by more
   than a band: four times its noise (estimated from the median absolute second
   difference, which a ramp does not change), capped at ``ZERO_FRACTION`` of its range
   (with clearance the grips first cross 2Δr at zero force: that is travel, not offset). A record that dwells
   at zero before loading (as a test machine records) gets its whole dwell; a
   noise-free record (the model) gets its first sample only. The force offset is the
   median force of that run (a load cell that reads non-zero at zero load), the
   displacement offset its median displacement (the loop starts at δ = 0).

   A record **cut mid-cycle** has no zero-load samples: its first force is not its zero.
   A load-cell offset shifts the zero and both peaks alike, so a record starts at rest
   when its initial zero lies at the midpoint of its peaks (within ``REST_FRACTION`` of
   the half peak-to-peak force plus ``NOISE_BANDS`` noise σ). Otherwise, if its force
   reverses, the protocol is sought inside it: it starts at the upward zero crossing
   before the first +Fg excursion that follows a sample at or below zero (what comes
   before is not used); the force zero is the midpoint of the peaks (a force-controlled
   test turns at ±Fg about its zero), the displacement zero the centre
   ``(δ(+peak) + δ(−peak))/2`` of that first full cycle (where a symmetric hinge stands
   unloaded: its virgin loading is not in the record).
3. **Metrics** (``loop_metrics``), on the last loop ``+Fg → −Fg → +Fg``:

   * ``F_max = (F(+peak) − F(−peak))/2``, the half peak-to-peak force (exactly Fg for
     the model);
   * ``δ_max = (δ(+Fg) − δ(−Fg))/2`` as in ``fe.general.cycle`` (the paper's Eq. 1 triangle);
   * ``U_max = ½ F_max δ_max`` and ``η = W_cycle / (2π U_max)``;
   * ``W_cycle = ∮ F dδ`` by the trapezoid rule along the samples, the loop being
     **closed by the straight chord from its last point back to its first** (shoelace
     formula). A loop that does not close (creep, drift, noise at the peaks) then gets
     the area of the closed polygon, and W does not depend on the force or
     displacement offsets;
   * the displacement at the (final) peak δ(+Fg) from the start, and the secant
     stiffness ``F_max / δ_max``.

``loop_distance`` resamples the descending and the ascending branch of two loops on a
common force grid and returns the RMS of the displacement differences [mm].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import DataError
from validation.loop_metrics import LoopMetrics, Stages, loop_metrics

FloatArray = npt.NDArray[np.float64]

ZERO_FRACTION = 0.05
"""The initial-zero band is at most this fraction of the force's rise to its peak."""

NOISE_BANDS = 4.0
"""The initial-zero band is this many force-noise standard deviations."""

REVERSAL_FRACTION = 0.5
"""Excursions are counted beyond ± this fraction of max|F| (hysteresis threshold)."""

REST_FRACTION = 0.02
"""A record starts at rest when its initial zero lies within this fraction of its half
peak-to-peak force (plus ``NOISE_BANDS`` noise σ) of the midpoint of its peaks."""

GRID_POINTS = 101
"""Force levels per branch on which ``loop_distance`` compares two loops."""


@dataclass(frozen=True, eq=False)
class ProcessedLoop:
    """A record with its offsets removed, its stages and its metrics.

    Attributes:
        force_n: Force with the offset removed, shape (n,) [N].
        displacement_mm: Displacement from the start, shape (n,) [mm].
        stages: Its turning points.
        metrics: Its metrics.
        force_offset_n: The force offset that was removed [N].
        displacement_offset_mm: The displacement offset that was removed [mm].
        source: Where the record came from (file name or ``model:<case>``).
        mid_cycle: The record starts mid-cycle (``LoadingStart.mid_cycle``): its
            displacement is measured from the centre of its first full cycle.
    """

    force_n: FloatArray
    displacement_mm: FloatArray
    stages: Stages
    metrics: LoopMetrics
    force_offset_n: float
    displacement_offset_mm: float
    source: str
    mid_cycle: bool = False

    def branches(self) -> tuple[tuple[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]:
        """Return ((F, δ) descending +Fg → −Fg, (F, δ) ascending −Fg → +Fg) of the last loop."""
        s = self.stages
        down = slice(s.peak_first, s.trough + 1)
        up = slice(s.trough, s.peak_last + 1)
        F, d = self.force_n, self.displacement_mm
        return (F[down], d[down]), (F[up], d[up])


def _check_arrays(force_n: FloatArray, displacement_mm: FloatArray, source: str) -> None:
    F = np.asarray(force_n)
    d = np.asarray(displacement_mm)
    if F.ndim != 1 or F.shape != d.shape:
        raise DataError(
            f"{source}: force and displacement must be 1-D of equal length, got shapes "
            f"{F.shape} and {d.shape}"
        )
    if F.size < 4:
        raise DataError(f"{source}: a loop needs at least 4 samples, got {F.size}")
    for name, a in (("force_N", F), ("displacement_mm", d)):
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise DataError(
                f"{source}: row {bad[0] + 1}, column {name}: not a finite number ({a[bad[0]]})"
            )


def noise_level(values: FloatArray) -> float:
    """Estimate the standard deviation of white noise on a piecewise-smooth signal.

    ``σ ≈ 1.4826 · MAD(Δ²x) / √6``: second differences cancel ramps, white noise of
    variance σ² gives them variance 6σ², and the median absolute deviation ignores the
    few samples at the turning points.

    Args:
        values: The signal, shape (n,).
    """
    d2 = np.diff(np.asarray(values, dtype=np.float64), 2)
    if d2.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def _first_departure(x: FloatArray) -> int | None:
    """Index of the first sample that leaves the first one by more than the zero band."""
    rise = float(np.max(np.abs(x - x[0])))
    band = min(NOISE_BANDS * noise_level(x), ZERO_FRACTION * rise)
    above = np.flatnonzero(np.abs(x - x[0]) > band)
    return int(above[0]) if above.size else None


def initial_zero(force_n: FloatArray, displacement_mm: FloatArray | None = None) -> int:
    """Return the length of the initial zero run (≥ 1 sample).

    Args:
        force_n: Raw force, shape (n,) [N].
        displacement_mm: Raw displacement, shape (n,) [mm]; when given, the run also ends
            where the crosshead first moves (with clearance the grips cross the first 2Δr
            of free play at zero force: that travel is displacement, not offset).

    Returns:
        Number of leading samples before the force (or the displacement) first differs
        from its first sample by more than ``min(NOISE_BANDS · noise, ZERO_FRACTION ·
        max|x − x₀|)``.
    """
    starts = [_first_departure(np.asarray(force_n, dtype=np.float64))]
    if displacement_mm is not None:
        starts.append(_first_departure(np.asarray(displacement_mm, dtype=np.float64)))
    found = [s for s in starts if s is not None]
    first = min(found) if found else 0
    return first if first > 0 else 1


def _excursions(F: FloatArray, h: float) -> list[npt.NDArray[np.int64]]:
    """The runs of consecutive samples beyond +h or beyond −h (indices into ``F``)."""
    level = np.sign(F).astype(np.int64) * (np.abs(F) > h)  # +1, −1 beyond ±h, else 0
    idx = np.flatnonzero(level)
    if idx.size == 0:
        return []
    return np.split(idx, np.flatnonzero(np.diff(level[idx])) + 1)


def split_stages(force_n: FloatArray, source: str, start: int | None = None) -> Stages:
    """Find the turning points of a 0 → +Fg → −Fg → +Fg (→ −Fg → +Fg …) record.

    Args:
        force_n: Force, shape (n,) [N] (offset removed or not: the threshold is ½ max|F|).
        source: Name of the record for error messages.
        start: First sample of the protocol (``LoadingStart.index``); None: the end of
            the initial zero run.

    Returns:
        The stages.

    Raises:
        DataError: If the excursions beyond ±½ max|F| do not alternate +, −, +, ….
    """
    F = np.asarray(force_n, dtype=np.float64)
    begin = initial_zero(F) if start is None else start
    h = REVERSAL_FRACTION * float(np.max(np.abs(F[begin:])))
    runs = [r + begin for r in _excursions(F[begin:], h)]  # each run: one excursion
    if not runs:
        raise DataError(f"{source}: the force never leaves zero")
    signs = [1 if F[r[0]] > 0 else -1 for r in runs]
    expected = [1 if k % 2 == 0 else -1 for k in range(len(signs))]
    if signs != expected or len(signs) < 3 or len(signs) % 2 == 0:
        found = ", ".join("+" if s > 0 else "−" for s in signs)
        raise DataError(
            f"{source}: expected the load sequence 0 → +Fg → −Fg → +Fg (excursions beyond "
            f"±{h:.4g} N: +, −, +), found {found}"
        )

    def extreme(run: npt.NDArray[np.int64], sign: int) -> int:
        return int(run[np.argmax(sign * F[run])])

    return Stages(
        start=begin,
        peak_first=extreme(runs[-3], 1),
        trough=extreme(runs[-2], -1),
        peak_last=extreme(runs[-1], 1),
        n_cycles=(len(runs) - 1) // 2,
    )


def remove_offsets(
    force_n: FloatArray, displacement_mm: FloatArray
) -> tuple[FloatArray, FloatArray, float, float]:
    """Subtract the force and displacement of the initial zero run (medians).

    A record at rest only: ``loading_start`` also finds the zero of a record cut mid-cycle.

    Returns:
        (force [N], displacement [mm], force offset [N], displacement offset [mm]); the
        inputs are not modified.
    """
    F = np.asarray(force_n, dtype=np.float64)
    d = np.asarray(displacement_mm, dtype=np.float64)
    n0 = initial_zero(F, d)
    f0 = float(np.median(F[:n0]))
    d0 = float(np.median(d[:n0]))
    return F - f0, d - d0, f0, d0


@dataclass(frozen=True)
class LoadingStart:
    """Where the protocol of a record begins and where its zero is (module docstring, step 2).

    Attributes:
        index: First sample of the protocol: the end of the initial zero run, or for a
            record cut mid-cycle its upward zero crossing before the first +Fg.
        force_offset_n: The force read at zero load [N].
        displacement_offset_mm: The displacement taken as δ = 0 [mm].
        mid_cycle: The record starts mid-cycle (its first force is not its zero).
        first_force_n: The record's first force [N] (for messages).
    """

    index: int
    force_offset_n: float
    displacement_offset_mm: float
    mid_cycle: bool
    first_force_n: float

    def describe(self) -> str:
        """Say how the zero was found, for messages."""
        if self.mid_cycle:
            return (
                f"the record starts mid-cycle at {self.first_force_n:.4g} N; its zero is the "
                f"midpoint of its peaks, {self.force_offset_n:.3g} N, and the load sequence "
                f"starts at its upward zero crossing, data row {self.index + 1}"
            )
        return f"offset {self.force_offset_n:.3g} N removed"


def loading_start(force_n: FloatArray, displacement_mm: FloatArray) -> LoadingStart:
    """Find where the protocol of a record starts, and its force and displacement zero.

    See the module docstring (step 2): at rest, the medians of the initial zero run; cut
    mid-cycle, the midpoint of the peaks and the centre of the first full cycle.

    Args:
        force_n: Raw force, shape (n,) [N].
        displacement_mm: Raw displacement, shape (n,) [mm].
    """
    F = np.asarray(force_n, dtype=np.float64)
    d = np.asarray(displacement_mm, dtype=np.float64)
    n0 = initial_zero(F, d)
    f_rest, d_rest = float(np.median(F[:n0])), float(np.median(d[:n0]))
    hi, lo = float(np.max(F)), float(np.min(F))
    centre, half = 0.5 * (hi + lo), 0.5 * (hi - lo)
    h = REVERSAL_FRACTION * max(hi, -lo)
    at_rest = abs(f_rest - centre) <= REST_FRACTION * half + NOISE_BANDS * noise_level(F)
    if at_rest or not (hi > h and lo < -h):  # a record that never reverses keeps its zero
        return LoadingStart(n0, f_rest, d_rest, False, float(F[0]))
    F0 = F - centre
    below = np.flatnonzero(F0 <= 0.0)
    runs = _excursions(F0, REVERSAL_FRACTION * half)
    ups = [k for k, r in enumerate(runs) if F0[r[0]] > 0 and r[0] > below[0]]
    if not ups:  # no +Fg after a zero: split_stages refuses it from the first crossing
        return LoadingStart(int(below[0]), centre, float(d[below[0]]), True, float(F[0]))
    k = ups[0]
    index = int(below[below < runs[k][0]][-1])
    d0 = float(d[index])
    if k + 1 < len(runs):  # the centre of the first full cycle +peak → −peak
        peak = runs[k][np.argmax(F0[runs[k]])]
        trough = runs[k + 1][np.argmin(F0[runs[k + 1]])]
        d0 = 0.5 * float(d[peak] + d[trough])
    return LoadingStart(index, centre, d0, True, float(F[0]))


REVERSED_ETA = -0.002
"""A loop whose η is below this, beyond ``REVERSED_SIGMAS`` noise σ of its area, runs
clockwise (a frictionless model loop has |η| ~ 1e-5; a weakly dissipative noisy record can
have W < 0 by noise alone, which is not refused)."""

REVERSED_SIGMAS = 4.0
"""Noise σ of the loop area a clockwise loop must exceed to be refused."""


def area_noise_sigma(force_n: FloatArray, displacement_mm: FloatArray, stages: Stages) -> float:
    """σ of the last loop's area from white noise on both channels [N·mm].

    First-order propagation through the shoelace sum:
    ``var W = ¼ Σ σ_d² (F_{i+1} − F_{i−1})² + ¼ Σ σ_F² (δ_{i+1} − δ_{i−1})²``.
    """
    s_F, s_d = noise_level(force_n), noise_level(displacement_mm)
    sl = stages.last_loop
    Fl, dl = force_n[sl], displacement_mm[sl]
    dF = Fl[2:] - Fl[:-2]
    dd = dl[2:] - dl[:-2]
    var_W = 0.25 * s_d**2 * float(np.sum(dF**2)) + 0.25 * s_F**2 * float(np.sum(dd**2))
    return math.sqrt(var_W)


def process_loop(force_n: FloatArray, displacement_mm: FloatArray, source: str) -> ProcessedLoop:
    """Find the loading start and zero, split the stages and measure the last loop of a record.

    Args:
        force_n: Raw force, shape (n,) [N].
        displacement_mm: Raw displacement, shape (n,) [mm].
        source: Name of the record for error messages.

    Raises:
        DataError: On non-finite samples, a record that is not 0 → +Fg → −Fg → +Fg, a
            displacement whose sign is reversed against the force (δ_max < 0), or a loop
            that runs the wrong way round (η < ``REVERSED_ETA``: a passive hinge dissipates).
    """
    _check_arrays(force_n, displacement_mm, source)
    start = loading_start(force_n, displacement_mm)
    F = np.asarray(force_n, dtype=np.float64) - start.force_offset_n
    d = np.asarray(displacement_mm, dtype=np.float64) - start.displacement_offset_mm
    try:
        stages = split_stages(F, source, start.index)
    except DataError as err:
        if not start.mid_cycle:
            raise
        raise DataError(f"{err} ({start.describe()})") from err
    metrics = loop_metrics(F, d, stages)
    if metrics.delta_max_mm < 0.0:
        raise DataError(
            f"{source}: the displacement falls as the force rises (δ(+Fg) − δ(−Fg) = "
            f"{2 * metrics.delta_max_mm:.4g} mm): its sign is reversed against the force "
            "(a tension force must give a positive displacement); flip the displacement column"
        )
    u = 2.0 * math.pi * metrics.U_max_Nmm
    if metrics.W_cycle_Nmm < REVERSED_ETA * u - REVERSED_SIGMAS * area_noise_sigma(F, d, stages):
        raise DataError(
            f"{source}: the loop runs the wrong way round (W = {metrics.W_cycle_Nmm:.4g} N·mm, "
            f"η = {metrics.eta:.4f}, beyond its noise): a passive hinge dissipates; the force and "
            "displacement channels are out of step (check their sign and time alignment)"
        )
    f0, d0 = start.force_offset_n, start.displacement_offset_mm
    return ProcessedLoop(F, d, stages, metrics, f0, d0, source, mid_cycle=start.mid_cycle)


def _side(F: FloatArray, d: FloatArray, positive: bool) -> tuple[FloatArray, FloatArray]:
    """The part of a branch (in time order) on one side of its zero-force crossing.

    With clearance the branch crosses its free play at F = 0 (δ jumps by 4Δr there), so
    δ(F) at a small positive force must come from the samples before (descending) or after
    (ascending) the crossing, never from the other side's end of it.
    """
    descending = F[0] > F[-1]
    if descending == positive:  # the side the branch starts on: up to the first crossing sample
        cross = np.flatnonzero(F <= 0.0) if positive else np.flatnonzero(F >= 0.0)
        end = int(cross[0]) if cross.size else len(F) - 1
        return F[: end + 1], d[: end + 1]
    cross = np.flatnonzero(F >= 0.0) if not positive else np.flatnonzero(F <= 0.0)
    start = int(cross[-1]) if cross.size else 0
    return F[start:], d[start:]


def _branch_on_grid(F: FloatArray, d: FloatArray, grid: FloatArray) -> FloatArray:
    """δ(F) of one branch on ``grid``, the samples sorted by force (noise makes F non-monotone).

    Positive and negative grid forces are interpolated on their own side of the zero-force
    crossing (``_side``).
    """
    out = np.empty(grid.shape)
    for positive, sel in ((True, grid > 0.0), (False, grid <= 0.0)):
        if not np.any(sel):
            continue
        Fs, ds = _side(F, d, positive)
        order = np.argsort(Fs, kind="stable")
        out[sel] = np.interp(grid[sel], Fs[order], ds[order])
    return out


ZERO_BAND_NOISE = 4.0
"""Half-width of the band around F = 0 left out of the loop distance, in force-noise σ."""

ZERO_BAND_FRACTION = 0.02
"""Least half-width of that band, as a fraction of F_max (a noise-free model loop)."""


def zero_band_n(measured: ProcessedLoop, model: ProcessedLoop) -> float:
    """Half-width of the band around F = 0 where the free play is crossed [N].

    ``ZERO_BAND_NOISE`` measured force-noise σ, at least ``ZERO_BAND_FRACTION`` and at most
    half of 0.98 × the smaller F_max.
    """
    f_c = 0.98 * min(measured.metrics.f_max_n, model.metrics.f_max_n)
    noise = ZERO_BAND_NOISE * noise_level(measured.force_n)
    return min(max(noise, ZERO_BAND_FRACTION * f_c), 0.5 * f_c)


def branch_residuals(
    measured: ProcessedLoop, model: ProcessedLoop, n_grid: int = GRID_POINTS
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Resample both branches of two loops on a common force grid and subtract.

    The grid spans ±0.98 of the smaller F_max, so both loops cover it, except a band
    around F = 0 of ``ZERO_BAND_NOISE`` times the measured force noise (at least
    ``ZERO_BAND_FRACTION`` of F_max): with clearance a branch crosses its free play there
    at zero force, where δ(F) is a vertical segment that a noisy force scrambles over the
    whole 4Δr. Each loop is centred on the midpoint (δ(+Fg) + δ(−Fg))/2 of its own peaks:
    the residual then measures the loop's shape (stiffness and width), not the start
    offset, which ``disp_at_peak_mm`` already measures.

    Returns:
        (force grid (n_grid,) [N], δ_model − δ_measured on the descending branch
        (n_grid,) [mm], same on the ascending branch (n_grid,) [mm]).
    """
    f_c = 0.98 * min(measured.metrics.f_max_n, model.metrics.f_max_n)
    band = zero_band_n(measured, model)
    half = np.linspace(band, f_c, n_grid // 2)
    grid = np.concatenate([-half[::-1], half])
    out = []
    for loop in (measured, model):
        centre = 0.5 * (loop.metrics.disp_at_peak_mm + loop.metrics.disp_at_minus_peak_mm)
        (Fd, dd), (Fu, du) = loop.branches()
        out.append((_branch_on_grid(Fd, dd, grid) - centre, _branch_on_grid(Fu, du, grid) - centre))
    return grid, out[1][0] - out[0][0], out[1][1] - out[0][1]


def loop_distance(a: ProcessedLoop, b: ProcessedLoop, n_grid: int = GRID_POINTS) -> float:
    """RMS displacement difference between two loops over both branches [mm].

    See ``branch_residuals`` for the grid and the centring.
    """
    _, r_down, r_up = branch_residuals(a, b, n_grid)
    return float(np.sqrt(np.mean(np.concatenate([r_down, r_up]) ** 2)))
