"""The misfit of a model to measured features, in words (``validation.diagnose``, step 5).

:func:`residual_pattern` says where and how the model as it is misses the data
(stiffness, η level, trends with amplitude and clearance, the largest residuals), for the
diagnosis' ``pattern`` and its ``unexplained`` verdict.
"""

from __future__ import annotations

import math

import numpy as np

from validation.candidate_fit import (
    FloatArray,
    MeasuredFeatures,
    design_text,
    eta_without_free_play,
    residuals,
)
from validation.features import FEATURES, derived


def residual_pattern(model: FloatArray, meas: MeasuredFeatures) -> list[str]:
    """Describe the baseline's misfit in words (stiffness, η level and trends).

    Rules, per quantity q ∈ {δ_max, η} with relative error e = (model − measured)/measured
    (for δ_max relative to its elastic part, the free play 2Δr taken off) and its σ from
    the features: "at all amplitudes" when every design point's error has
    the same sign beyond 2σ; "grows with amplitude" when, within a clearance, |e| at the
    largest amplitude exceeds |e| at the smallest by more than 2σ; likewise for clearance.
    """
    amps_all = meas.amplitudes
    clear_all = np.array([p[0] for p in meas.points])
    dm, em = derived(model, amps_all)
    dd, ed = derived(meas.values, amps_all)
    eta_rows = meas.eta_rows
    ed = np.where(eta_rows, meas.values[:, 1], ed)  # η-only rows state η itself …
    em = np.where(eta_rows, eta_without_free_play(model, meas), em)  # … without free play
    elastic = np.maximum(np.abs(dd - 2.0 * clear_all), 1e-12)  # δ_max without the free play 2Δr
    s_delta_all = meas.sigma[:, 0] / elastic
    s_eta_all = meas.sigma[:, 1] / np.abs(meas.values[:, 1])
    words = []
    with np.errstate(invalid="ignore", divide="ignore"):
        quantities = (
            ("δ", (dm - dd) / elastic, s_delta_all, "too soft", "too stiff"),
            ("η", em / ed - 1.0, s_eta_all, "η too high", "η too low"),
        )
    for label, e_all, s_all, hi_word, lo_word in quantities:
        keep = np.isfinite(e_all) & np.isfinite(s_all)  # δ is not measured in η-only rows
        if not np.any(keep):
            continue
        e, s, amps, clear = e_all[keep], s_all[keep], amps_all[keep], clear_all[keep]
        if np.all(e > 2 * s):
            words.append(
                f"{hi_word} at all amplitudes ({label} error {np.min(e):+.0%} … {np.max(e):+.0%})"
            )
        elif np.all(e < -2 * s):
            words.append(
                f"{lo_word} at all amplitudes ({label} error {np.max(e):+.0%} … {np.min(e):+.0%})"
            )
        for c in sorted(set(clear)):
            sel = np.flatnonzero(clear == c)
            if len(sel) < 2:
                continue
            i_lo, i_hi = sel[np.argmin(amps[sel])], sel[np.argmax(amps[sel])]
            grow = abs(e[i_hi]) - abs(e[i_lo])
            if abs(grow) > 2 * math.hypot(s[i_hi], s[i_lo]):
                trend = "grows" if grow > 0 else "shrinks"
                words.append(
                    f"{label} error {trend} with amplitude at {design_text(meas, c)} "
                    f"({e[i_lo]:+.0%} at {amps[i_lo]:g} N → {e[i_hi]:+.0%} at {amps[i_hi]:g} N)"
                )
        if len(set(clear)) >= 2:
            by_c = {c: float(np.mean(np.abs(e[clear == c]))) for c in sorted(set(clear))}
            cs = list(by_c)
            if abs(by_c[cs[-1]] - by_c[cs[0]]) > 2 * float(np.mean(s)):
                trend = "grows" if by_c[cs[-1]] > by_c[cs[0]] else "shrinks"
                words.append(f"{label} error {trend} with {meas.design_variable}")
    return words + _largest_residuals(model, meas) or ["no residual beyond 2σ"]


def _largest_residuals(model: FloatArray, meas: MeasuredFeatures, k: int = 3) -> list[str]:
    """Describe the largest residuals beyond 2σ (feature, σ, sign, design point); [] if none."""
    r = residuals(model, meas)
    big = [
        (abs(float(r[i, j])), i, j)
        for i in range(r.shape[0])
        for j in range(r.shape[1])
        if abs(r[i, j]) > 2.0 and abs(r[i, j]) < 1e3
    ]
    if not big:
        return []
    out = []
    for _, i, j in sorted(big, reverse=True)[:k]:
        c, a = meas.points[i]
        name = "η" if meas.eta_rows[i] else FEATURES[j]
        sign = "model above data" if r[i, j] > 0 else "model below data"
        out.append(f"{name} {r[i, j]:+.1f}σ at {design_text(meas, c)}, Fg = {a:g} N ({sign})")
    out.append(f"{len(big)} of {meas.n_obs} features beyond 2σ")
    return out
