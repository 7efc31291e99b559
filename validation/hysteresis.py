"""The hysteresis of a loop, with the free play taken out, and whether a record measures it.

With clearance the grips cross the free play 4Δr at (nearly) zero force on each branch.
That travel carries no loop area, but a force noise σ_F on every sample of it gives the
loop area W a noise ``≈ ½ σ_F √(Σ Δδ²)`` that dwarfs the hysteresis of the hinge itself,
and it inflates δ_max (hence deflates η) by 2Δr. So ``compare`` judges a clearance case
on the loop **without the free play** (``hysteresis`` with ``remove_free_play``):

* on each branch of the last loop (in time order) the part inside the zero band
  ``|F| < b`` is cut out: from where the branch first enters the band to where it last
  leaves it, both cut points interpolated at exactly ``±b`` (so a noise-free model loop
  and a noisy record are cut at the same forces). ``b`` is the band that
  ``validation.loops.zero_band_n`` gives for the measured record: four force-noise σ, at
  least 2 % of F_max;
* ``W' = Σ ½ (F_i + F_{i+1}) (δ_{i+1} − δ_i)`` over the segments that are kept and the
  chord that closes the loop: the area of the loop without the crossings (the crossing
  at zero force contributes nothing to the true area, only noise);
* the free play travel ``J`` of a branch is the displacement between its two cut
  points (descending J_d < 0, ascending J_a > 0), and
  ``δ'_max = δ_max − ¼ (J_a − J_d)`` is the half span of the loop without it;
* ``η' = W' / (π F_max δ'_max)``, as ``fe``'s η without the free play. The band's own
  elastic travel (about 2b / F_max of δ_max) goes with the cut, on both loops alike, so
  η' reads ~2 % above ``fe``'s η (0.00161 against 0.00157 at Δr 0.1 mm, 300 N).

The **noise** σ of W' is the first-order propagation of white force and displacement
noise (``validation.loops.noise_level``) through that sum: ``var W' = σ_F² Σ_i
(∂W'/∂F_i)² + σ_d² Σ_i (∂W'/∂δ_i)²`` (for the whole closed loop this is
``validation.loops.area_noise_sigma``); that of δ'_max is ``σ_d √¾`` (a peak, a trough
and four cut points) ⊕ ``δ'_max / F_max · σ_F`` (peaks picked on a noisy force).

A metric is **measurable** (``judge``) when the record tells it from zero, ``|v| > k
σ_noise``, and its whole σ (noise ⊕ model floor ⊕ replicates) does not exceed
``max_rel_sigma · |v|`` (the rule ``diagnose`` uses to leave out uninformative features).
A measurable metric is judged on its relative error; one that is not is **not
measurable** — neither pass nor fail — unless the model lies more than ``k σ`` away from
it in absolute terms (the model shows a hysteresis the record would have shown: a fail).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np
import numpy.typing as npt

from validation.features import FeatureSettings
from validation.loops import ProcessedLoop, noise_level, zero_band_n

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Hysteresis:
    """The hysteresis of one loop, free play removed or not (module docstring).

    Attributes:
        W_Nmm: Loop area W' [N·mm].
        delta_max_mm: Half span δ'_max [mm].
        eta: η' = W' / (π F_max δ'_max); NaN where δ'_max ≤ 0.
        free_play_mm: Mean free-play travel ½ (J_a − J_d) taken out [mm]; 0 when not removed.
        sigma_W_noise: Noise σ of W' [N·mm].
        sigma_delta_noise: Noise σ of δ'_max [mm].
        f_max_n: F_max of the loop [N].
    """

    W_Nmm: float
    delta_max_mm: float
    eta: float
    free_play_mm: float
    sigma_W_noise: float
    sigma_delta_noise: float
    f_max_n: float

    def sigma_eta(self, sigma_W: float, sigma_delta: float) -> float:
        """Absolute σ of η' from absolute σ of W' [N·mm] and δ'_max [mm] (no division by W')."""
        u = math.pi * self.f_max_n * self.delta_max_mm
        if not u > 0.0:
            return math.inf
        return math.hypot(sigma_W / u, abs(self.eta) * sigma_delta / self.delta_max_mm)


def _cut(F: FloatArray, d: FloatArray, sign: int, band: float) -> tuple[int, int, float, float]:
    """Where one branch (time order, starting at sign·F_max) enters and last leaves |F| < band.

    Returns:
        (i0, i1, δ at the entry cut, δ at the exit cut): samples ``[:i0]`` lie before the
        entry cut (on segment i0−1 → i0), samples ``[i1 + 1:]`` after the exit cut (on
        segment i1 → i1+1).
    """
    s = sign * F
    i0 = int(np.flatnonzero(s <= band)[0])
    i1 = int(np.flatnonzero(s >= -band)[-1])
    i0, i1 = max(i0, 1), min(i1, len(F) - 2)  # the peaks lie beyond the band (band ≤ ½ F_max)

    def at(a: int, level: float) -> float:
        fa, fb = s[a], s[a + 1]
        t = 0.0 if fb == fa else (level - fa) / (fb - fa)
        return float(d[a] + min(max(t, 0.0), 1.0) * (d[a + 1] - d[a]))

    return i0, i1, at(i0 - 1, band), at(i1, -band)


def _kept_polygon(
    loop: ProcessedLoop, band: float
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]:
    """The last loop with its crossings cut: (F (m,), δ (m,), kept (m,) bool per segment k→k+1).

    Segment m−1 is the closing chord from the last point back to the first.
    """
    s = loop.stages
    F, d = loop.force_n, loop.displacement_mm
    pieces_F: list[FloatArray] = []
    pieces_d: list[FloatArray] = []
    gaps = []
    n = 0
    for a, b, sign in ((s.peak_first, s.trough, 1), (s.trough, s.peak_last, -1)):
        Fb, db = F[a : b + 1], d[a : b + 1]
        i0, i1, d_in, d_out = _cut(Fb, db, sign, band)
        first = 0 if sign > 0 else 1  # the trough already ends the descending branch
        before_F = np.append(Fb[first:i0], sign * band)
        after_F = np.insert(Fb[i1 + 1 :], 0, -sign * band)
        pieces_F += [before_F, after_F]
        pieces_d += [np.append(db[first:i0], d_in), np.insert(db[i1 + 1 :], 0, d_out)]
        n += before_F.size
        gaps.append(n - 1)  # the segment from the entry cut to the exit cut
        n += after_F.size
    Fk, dk = np.concatenate(pieces_F), np.concatenate(pieces_d)
    kept = np.ones(Fk.size, dtype=bool)
    kept[gaps] = False
    return Fk, dk, kept


def _area_and_noise(
    F: FloatArray, d: FloatArray, kept: npt.NDArray[np.bool_], s_F: float, s_d: float
) -> tuple[float, float]:
    """Σ over kept segments (closing chord included) of ½(F_k + F_{k+1})(δ_{k+1} − δ_k), and its σ."""
    nxt = np.roll(np.arange(F.size), -1)
    f_mid = np.where(kept, 0.5 * (F + F[nxt]), 0.0)  # (m,)
    dd = np.where(kept, d[nxt] - d, 0.0)  # (m,)
    W = float(np.sum(f_mid * dd))
    g_F = 0.5 * dd + 0.5 * np.roll(dd, 1)  # ∂W/∂F_i: half of each kept segment touching i
    g_d = np.roll(f_mid, 1) - f_mid  # ∂W/∂δ_i: + end of segment i−1, − start of segment i
    var = s_F**2 * float(np.sum(g_F**2)) + s_d**2 * float(np.sum(g_d**2))
    return W, math.sqrt(var)


def hysteresis(loop: ProcessedLoop, band_n: float, *, remove_free_play: bool) -> Hysteresis:
    """Measure the hysteresis of a processed loop (module docstring).

    Args:
        loop: The processed loop (measured or model).
        band_n: Half-width b of the zero band cut out [N], ``0 < b ≤ ½ F_max``
            (``validation.loops.zero_band_n`` of the measured record).
        remove_free_play: Cut the crossings out (a case with clearance); else W, δ_max and
            η are the loop's own metrics.

    Returns:
        The hysteresis with its noise σ.
    """
    m = loop.metrics
    F, d = loop.force_n, loop.displacement_mm
    s_F, s_d = noise_level(F), noise_level(d)
    if remove_free_play and 0.0 < band_n < m.f_max_n:
        Fk, dk, kept = _kept_polygon(loop, band_n)
        W, s_W = _area_and_noise(Fk, dk, kept, s_F, s_d)
        gap_d = dk[np.roll(np.arange(Fk.size), -1)] - dk
        J_d, J_a = (float(v) for v in gap_d[~kept])
        free_play = 0.5 * (J_a - J_d)
        delta = m.delta_max_mm - 0.5 * free_play
        s_delta_d = s_d * math.sqrt(0.75)
    else:
        sl = loop.stages.last_loop
        Fl, dl = F[sl], d[sl]
        W, s_W = _area_and_noise(Fl, dl, np.ones(Fl.size, dtype=bool), s_F, s_d)
        W, free_play, delta = m.W_cycle_Nmm, 0.0, m.delta_max_mm
        s_delta_d = s_d / math.sqrt(2.0)
    u = math.pi * m.f_max_n * delta
    eta = W / u if u > 0.0 and math.isfinite(u) else math.nan
    slope = abs(delta) / m.f_max_n * s_F if m.f_max_n > 0.0 else math.inf
    return Hysteresis(W, delta, eta, free_play, s_W, math.hypot(s_delta_d, slope), m.f_max_n)


HYSTERESIS_METRICS = ("W_cycle_Nmm", "eta")
"""The metrics ``compare`` judges on the hysteresis (``judge``), in ``compare.METRICS`` names."""


def hysteresis_sigma(
    h: Hysteresis, features: FeatureSettings, replicates: dict[str, float]
) -> dict[str, tuple[float, float]]:
    """Absolute σ of W' and η': metric → (noise ⊕ model floor ⊕ replicates, noise alone).

    The floor is ``features``' (as ``validation.features.feature_sigma``): ``rel_floor ·
    |W'| + eta_floor · π F_max δ'_max`` for W', ``rel_floor · δ'_max`` for δ'_max.

    Args:
        h: The measured hysteresis.
        features: The model floor.
        replicates: Metric → relative replicate scatter (absent: none).
    """
    f = features
    u = math.pi * h.f_max_n * h.delta_max_mm
    floor_W = f.rel_floor * abs(h.W_Nmm) + f.eta_floor * abs(u)
    s_W = math.hypot(h.sigma_W_noise, floor_W, replicates.get("W_cycle_Nmm", 0.0) * abs(h.W_Nmm))
    s_delta = math.hypot(h.sigma_delta_noise, f.rel_floor * h.delta_max_mm)
    rep_eta = replicates.get("eta", 0.0) * abs(h.eta) if math.isfinite(h.eta) else 0.0
    return {
        "W_cycle_Nmm": (s_W, h.sigma_W_noise),
        "eta": (
            math.hypot(h.sigma_eta(s_W, s_delta), rep_eta),
            h.sigma_eta(h.sigma_W_noise, h.sigma_delta_noise),
        ),
    }


def judge_loops(
    measured: ProcessedLoop,
    model: ProcessedLoop,
    remove_free_play: bool,
    replicates: dict[str, float],
    features: FeatureSettings,
    stated_rel: float | None,
    *,
    k: float,
    max_rel_sigma: float,
    min_rel_sigma: float,
    names: Mapping[str, str],
) -> tuple[dict[str, Judgement], Hysteresis, Hysteresis]:
    """Judge W and η of a model loop against a measured one, both cut at the same zero band.

    Args:
        measured: The measured loop.
        model: The model's loop.
        remove_free_play: Judge the loops without the free play (a case with clearance).
        replicates: Metric → relative replicate scatter (absent: none).
        features: The model floor.
        stated_rel: A stated relative σ that replaces noise ⊕ floor ⊕ replicates where no
            replicate gives one (``Uncertainty.STATED``), or None.
        k: Coverage factor.
        max_rel_sigma: Largest relative σ of a measurable metric.
        min_rel_sigma: Floor on the relative σ.
        names: Metric → its name in reasons.

    Returns:
        (metric → judgement, measured hysteresis, model hysteresis).
    """
    band = zero_band_n(measured, model)
    hm = hysteresis(measured, band, remove_free_play=remove_free_play)
    hmod = hysteresis(model, band, remove_free_play=remove_free_play)
    sigmas = hysteresis_sigma(hm, features, replicates)
    values = {"W_cycle_Nmm": (hm.W_Nmm, hmod.W_Nmm), "eta": (hm.eta, hmod.eta)}
    out = {}
    for m in HYSTERESIS_METRICS:
        v, u = values[m]
        sig, noise = sigmas[m]
        if stated_rel is not None:
            sig = replicates.get(m, stated_rel) * abs(v)
        out[m] = judge(
            v,
            u,
            sig,
            noise,
            k=k,
            max_rel_sigma=max_rel_sigma,
            min_rel_sigma=min_rel_sigma,
            name=names.get(m, m),
        )
    return out, hm, hmod


class Status(Enum):
    """The verdict on one metric."""

    PASS = "pass"
    FAIL = "fail"
    NOT_MEASURABLE = "not measurable"


@dataclass(frozen=True)
class Judgement:
    """One metric judged (``judge``).

    Attributes:
        status: Pass, fail or not measurable.
        relative: True when judged on the relative error (a measurable metric).
        error: (model − measured)/|measured| where relative, else None.
        sigma: The relative σ used where relative, else None.
        difference: model − measured [the metric's unit].
        sigma_abs: The absolute σ (noise ⊕ floor ⊕ replicates) [the metric's unit].
        sigma_noise_abs: Its noise part [the metric's unit].
        reason: Why the metric is not measurable (or fails absolutely); "" otherwise.
    """

    status: Status
    relative: bool
    error: float | None
    sigma: float | None
    difference: float
    sigma_abs: float
    sigma_noise_abs: float
    reason: str = ""

    def as_dict(self) -> dict[str, object]:
        """Return the judgement as a JSON-ready dict."""
        return {**vars(self), "status": self.status.value}


def judge(
    measured: float,
    model: float,
    sigma_abs: float,
    sigma_noise_abs: float,
    *,
    k: float,
    max_rel_sigma: float,
    min_rel_sigma: float,
    name: str = "value",
) -> Judgement:
    """Judge one hysteresis metric: relative where measurable, else absolute or not measurable.

    Args:
        measured: The measured value v.
        model: The model's value u.
        sigma_abs: σ of v: noise ⊕ model floor ⊕ replicates (absolute).
        sigma_noise_abs: The noise part of it (absolute).
        k: Coverage factor.
        max_rel_sigma: Largest relative σ a measurable metric may have.
        min_rel_sigma: Floor on the relative σ (``CompareSettings.min_rel_uncertainty``).
        name: The metric's name in the reason text.
    """
    v, u = float(measured), float(model)
    diff = u - v if math.isfinite(u) and math.isfinite(v) else math.nan
    base: dict[str, Any] = {
        "difference": diff,
        "sigma_abs": sigma_abs,
        "sigma_noise_abs": sigma_noise_abs,
    }
    if not math.isfinite(v) or not math.isfinite(sigma_abs):
        why = f"measured {name} has no value ({v:.3g}, σ {sigma_abs:.3g})"
        return Judgement(Status.NOT_MEASURABLE, False, None, None, reason=why, **base)
    if abs(v) > k * sigma_noise_abs and sigma_abs <= max_rel_sigma * abs(v):
        err = diff / abs(v) if math.isfinite(diff) else math.nan
        sig = max(sigma_abs / abs(v), min_rel_sigma)
        ok = math.isfinite(err) and abs(err) <= k * sig
        return Judgement(Status.PASS if ok else Status.FAIL, True, err, sig, **base)
    if abs(v) <= k * sigma_noise_abs:
        why = f"{name} = {_g(v)} lies within {k:g}σ of zero for the record's noise ({_g(k * sigma_noise_abs)})"
    else:
        why = (
            f"its σ {_g(sigma_abs)} (noise {_g(sigma_noise_abs)} ⊕ model floor) exceeds its "
            f"value {_g(v)}"
        )
    if not math.isfinite(diff) or abs(diff) > k * sigma_abs:
        why = f"model {_g(u)} lies beyond {k:g}σ = {_g(k * sigma_abs)} of measured {_g(v)}; {why}"
        return Judgement(Status.FAIL, False, None, None, reason=why, **base)
    return Judgement(Status.NOT_MEASURABLE, False, None, None, reason=why, **base)


def _g(x: float) -> str:
    """Three significant digits."""
    return f"{x:.3g}"
