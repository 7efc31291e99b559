"""The time of a model's loop: from the protocol's force rate, or from a measured record.

A model's cycle is a sequence of force targets; it carries no clock of its own. An effect
that depends on time (``fe.effects.base.History``) is evaluated at

* the protocol's time (``protocol_time``): the force ramps at the stated rate
  ``CycleSettings.force_rate_n_per_s``, so ``t_k = Σ |ΔF| / rate`` (a point inserted at
  the same force, e.g. the free play crossed at F = 0, takes no time); or
* a measured record's time (``time_from_reference``): each point of the model's path
  takes the time at which the record passed the same force on the same ramp, so a
  record loaded at a varying rate (a sine, a hold) gives the model the same rate history.

>>> import numpy as np
>>> protocol_time(np.array([0.0, 10.0, 20.0, 0.0]), 10.0).tolist()
[0.0, 1.0, 2.0, 4.0]
"""

from __future__ import annotations

import itertools

import numpy as np
import numpy.typing as npt

from cad.errors import DataError, check_range

FloatArray = npt.NDArray[np.float64]

TURN_FRACTION = 0.2
"""A record turns when its force has come back this fraction of its largest |F| from the
running extreme (noise on a load cell is far below it; a real reversal far above)."""


def protocol_time(force_n: npt.ArrayLike, rate_n_per_s: float) -> FloatArray:
    """Return the time of each point of a force path ramped at a constant rate.

    Args:
        force_n: Force along the path, shape (n,) [N].
        rate_n_per_s: Force rate [N/s], > 0.

    Returns:
        Time from the first point, shape (n,) [s].
    """
    check_range("force_rate_n_per_s", rate_n_per_s, 0.0, 1e9, lo_open=True)
    F = np.asarray(force_n, dtype=np.float64)
    return np.concatenate([[0.0], np.cumsum(np.abs(np.diff(F)))]) / rate_n_per_s


def monotone_stages(force_n: FloatArray) -> list[slice]:
    """Split a model's force path into its ramps (the turning points end one and start the next).

    Returns:
        Slices into ``force_n``; consecutive slices share their turning point.
    """
    dF = np.diff(force_n)
    sign = np.sign(dF)
    cuts = [0]
    last = 0.0
    for k, s in enumerate(sign):
        if s == 0.0:
            continue
        if last != 0.0 and s != last:
            cuts.append(k)
        last = s
    cuts.append(len(force_n) - 1)
    return [slice(a, b + 1) for a, b in itertools.pairwise(cuts)]


def record_turns(force_n: FloatArray, fraction: float = TURN_FRACTION) -> list[int]:
    """Indices where a noisy record starts and turns: [0, first extreme, next extreme, …, n−1].

    A turn is confirmed once the force has come back ``fraction`` of the largest |F|
    from the running extreme.
    """
    F = np.asarray(force_n, dtype=np.float64)
    h = fraction * float(np.max(np.abs(F))) if F.size else 0.0
    turns = [0]
    direction = 0
    ext = 0
    for k in range(1, F.size):
        if direction == 0:
            if abs(F[k] - F[0]) > h:
                direction = 1 if F[k] > F[0] else -1
                ext = k
            continue
        if direction * (F[k] - F[ext]) > 0:
            ext = k
        elif direction * (F[ext] - F[k]) > h:
            turns.append(ext)
            direction = -direction
            ext = k
    turns.append(F.size - 1)
    return turns


def time_from_reference(
    force_n: npt.ArrayLike, ref_force_n: npt.ArrayLike, ref_time_s: npt.ArrayLike
) -> FloatArray:
    """Return the time of each point of a model's path, taken from a measured record.

    The model's path (0 → +Fg → −Fg → +Fg …) is split into its ramps and so is the record
    (``record_turns``); the model's first ramp is matched with the record's first and its
    last ramps with the record's last ones (a record may hold more cycles). The first ramp
    starts where the record last passed the model's start force before its first turn (a
    dwell at zero before the loading is not part of it). On each ramp the record's force
    is made monotone (its running maximum, or minimum going down: noise does not turn
    time back) and the model's forces are looked up on it.

    Args:
        force_n: The model's force path, shape (n,) [N], from the unloaded start.
        ref_force_n: The record's force, shape (m,) [N].
        ref_time_s: The record's time, shape (m,) [s], increasing.

    Returns:
        Time from the model's first point, non-decreasing, shape (n,) [s].

    Raises:
        DataError: If the record has fewer ramps than the model's path, or the shapes differ.
    """
    F = np.asarray(force_n, dtype=np.float64)
    Fr = np.asarray(ref_force_n, dtype=np.float64)
    tr = np.asarray(ref_time_s, dtype=np.float64)
    if Fr.shape != tr.shape or Fr.ndim != 1:
        raise DataError(f"record force {Fr.shape} and time {tr.shape} must be one (m,) shape")
    stages = monotone_stages(F)
    turns = record_turns(Fr)
    n_ref = len(turns) - 1
    if n_ref < len(stages):
        raise DataError(
            f"the record has {n_ref} load ramp(s), the model's path {len(stages)}: "
            "cannot take the model's time from it"
        )
    pick = [0, *range(n_ref - len(stages) + 1, n_ref)]
    t = np.zeros_like(F)
    for st, r in zip(stages, pick, strict=True):
        f_model = F[st]
        sign = 1.0 if f_model[-1] >= f_model[0] else -1.0
        start = turns[r]
        if r == 0:  # the ramp starts where the record last left the model's start force
            below = np.flatnonzero(sign * Fr[turns[0] : turns[1] + 1] <= sign * f_model[0])
            start += int(below[-1]) if below.size else 0
        seg = slice(start, turns[r + 1] + 1)
        f_seg, t_seg = Fr[seg], tr[seg]
        envelope = np.maximum.accumulate(sign * f_seg)
        t[st] = np.interp(sign * f_model, envelope, t_seg)
    t = np.maximum.accumulate(t)
    return np.asarray(t - t[0], dtype=np.float64)
