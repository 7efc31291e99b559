"""What the data can tell: informative features, the power statement, cannot_tell (no FE)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from validation.candidate_fit import DiagnoseSettings, MeasuredFeatures, chi2
from validation.diagnose import Verdict, _verdict
from validation.misfit import residual_pattern
from validation.sensitivity import sensitivity


def _design(clearances=(0.0, 0.1, 0.2), amps=(100.0, 200.0, 300.0, 400.0)):
    return tuple((c, a) for c in clearances for a in amps)


def _features(points, w_rel_sigma_with_clearance=0.02):
    """Feature values of a homogeneous hinge; σ 2 % except W with clearance (free play noise)."""
    amps = np.array([p[1] for p in points])
    clear = np.array([p[0] for p in points])
    delta = 1e-5 * amps + 2 * clear
    W = 0.013 * math.pi * amps * 1e-5 * amps
    vals = np.column_stack([delta, W, 0.3e-5 * amps])
    sig = 0.02 * np.abs(vals)
    sig[clear > 0, 1] = w_rel_sigma_with_clearance * W[clear > 0]
    return vals, sig


def test_uninformative_features_leave_chi2_and_n():
    pts = _design()
    vals, sig = _features(pts, w_rel_sigma_with_clearance=30.0)
    noisy = MeasuredFeatures(pts, vals, sig, max_rel_sigma=1.0)
    every = MeasuredFeatures(pts, vals, sig)  # max_rel_sigma inf: all finite features count
    n_clear = sum(1 for c, _ in pts if c > 0)
    assert every.n_obs == 3 * len(pts)
    assert noisy.n_obs == 3 * len(pts) - n_clear
    # a model with 3x the loop area everywhere: the W features at Δr = 0 see it
    model = vals.copy()
    model[:, 1] /= 3.0
    c_noisy, c_every = chi2(model, noisy), chi2(model, every)
    assert c_noisy == pytest.approx(
        c_every - np.sum(((model - vals)[:, 1] / sig[:, 1])[[c > 0 for c, _ in pts]] ** 2)
    )
    limit_noisy = stats.chi2.ppf(0.99, noisy.n_obs)
    assert c_noisy > limit_noisy  # detected once the uninformative features stop diluting it


def test_sensitivity_matches_a_monte_carlo_of_the_test():
    """The formula's e_min is the error the χ² test detects with the stated power."""
    pts = _design(clearances=(0.0,), amps=(100.0, 200.0, 300.0, 400.0, 500.0))
    vals, sig = _features(pts)
    sig[:, 1] = 0.1 * vals[:, 1]  # a weaker W column
    meas = MeasuredFeatures(pts, vals, sig)
    alpha, power = 0.01, 0.8
    e = sensitivity(meas, alpha, power)["loop_area_or_eta"]
    assert e is not None
    rng = np.random.default_rng(7)
    limit = stats.chi2.ppf(1 - alpha, meas.n_obs)
    shift = np.zeros_like(vals)
    shift[:, 1] = e * vals[:, 1] / sig[:, 1]
    hits = [np.sum((shift + rng.standard_normal(vals.shape)) ** 2) > limit for _ in range(4000)]
    assert np.mean(hits) == pytest.approx(power, abs=0.025)
    # a feature with no information gives None, not a number
    sig_none = sig.copy()
    sig_none[:, 2] = np.inf
    assert sensitivity(MeasuredFeatures(pts, vals, sig_none), alpha, power)["opening"] is None


def test_verdict_separates_consistent_from_cannot_tell():
    s = DiagnoseSettings()
    pts = _design(clearances=(0.0,), amps=(100.0, 300.0))
    vals, sig = _features(pts)
    precise = MeasuredFeatures(pts, vals, sig)
    n = precise.n_obs
    limit = float(stats.chi2.ppf(1 - s.alpha, n))
    d = _verdict([], 0.8 * n, n, limit, precise, s)
    assert d.verdict is Verdict.NO_MISSING_EFFECT
    assert "detect" in d.message
    weak_sig = sig.copy()
    weak_sig[:, 1] = 0.8 * vals[:, 1]  # informative (σ < value) but far too weak for 50 %
    weak = MeasuredFeatures(pts, vals, weak_sig, max_rel_sigma=1.0)
    d = _verdict([], 0.8 * n, n, limit, weak, s)
    assert d.verdict is Verdict.CANNOT_TELL
    assert "cannot tell" in d.message
    nothing = MeasuredFeatures(pts, vals, np.full_like(sig, np.inf), max_rel_sigma=1.0)
    assert _verdict([], 0.0, 0, float("nan"), nothing, s).verdict is Verdict.CANNOT_TELL


def test_null_false_alarm_rate_on_feature_noise():
    """Null data (model + the stated noise) on 200 seeds: 'a misfit' no more often than α."""
    s = DiagnoseSettings()
    pts = _design()
    vals, sig = _features(pts, w_rel_sigma_with_clearance=30.0)
    meas0 = MeasuredFeatures(pts, vals, sig, max_rel_sigma=1.0)
    rng = np.random.default_rng(11)
    alarms = 0
    for _ in range(200):
        noisy = vals + sig * rng.standard_normal(vals.shape)
        meas = MeasuredFeatures(pts, noisy, sig, max_rel_sigma=1.0)
        if meas.n_obs != meas0.n_obs:  # a noisy W may flip informativeness: judge as the data say
            pass
        n = meas.n_obs
        limit = float(stats.chi2.ppf(1 - s.alpha, n))
        d = _verdict([], chi2(vals, meas), n, limit, meas, s)
        alarms += d.verdict not in (Verdict.NO_MISSING_EFFECT, Verdict.CANNOT_TELL)
    assert alarms / 200 <= 3 * s.alpha + 0.01


def test_pattern_names_the_largest_residuals():
    pts = _design(clearances=(0.0,), amps=(100.0, 300.0))
    vals, sig = _features(pts)
    meas = MeasuredFeatures(pts, vals, sig)
    model = vals.copy()
    model[0, 0] -= 13 * sig[0, 0]  # one strong δ_max residual, the rest exact
    model[1, 0] += 3 * sig[1, 0]  # and a weaker one of the other sign: no common sign
    words = residual_pattern(model, meas)
    assert any("delta_max_mm -13.0σ at Δr = 0 mm, Fg = 100 N" in w for w in words), words
    assert not any("no systematic pattern" in w for w in words)


def test_a_real_misfit_is_unexplained_even_when_power_is_low():
    """χ² above the noise limit with no candidate that explains it: a residual the data do
    show, so not 'cannot tell' (a lag outside the registry gave χ² 22 > 18.5 this way)."""
    s = DiagnoseSettings()
    pts = _design(clearances=(0.0,), amps=(100.0, 300.0))
    vals, sig = _features(pts)
    sig[:, 1] = 0.8 * vals[:, 1]  # weak on the loop area
    weak = MeasuredFeatures(pts, vals, sig, max_rel_sigma=1.0)
    n = weak.n_obs
    limit = float(stats.chi2.ppf(1 - s.alpha, n))
    assert _verdict([], 1.2 * limit, n, limit, weak, s).verdict is Verdict.UNEXPLAINED
