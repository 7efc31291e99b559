"""Comparison on analytic loops: errors, replicate uncertainty, pass/fail, fingerprint, plots."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from cad.errors import DataError
from validation.compare import CompareSettings, ModelResult, Uncertainty, compare
from validation.loop_files import Loop
from validation.measurements import Case, MeasurementSet
from validation.plots import write_comparison_plots

PHI = 0.08
STATED = CompareSettings(uncertainty=Uncertainty.STATED)


def ellipse_loop(fg, d, *, n=80, phi=PHI, noise=0.0, seed=0, source="loop"):
    """0 → +Fg then an elliptic loop with η = tan φ (dense: n samples per loop)."""
    theta = math.pi / 2 + np.linspace(0, 2 * math.pi, n + 1)[1:]
    s = np.linspace(0, 1, n // 4 + 1)
    F = np.concatenate([np.zeros(10), fg * s, fg * np.sin(theta)])
    x = np.concatenate([np.zeros(10), d * math.cos(phi) * s, d * np.sin(theta - phi)])
    if noise:
        rng = np.random.default_rng(seed)
        F = F + rng.normal(0, noise * fg, F.size)
        x = x + rng.normal(0, noise * d, x.size)
    return Loop(F, x, None, source)


def case(cid, amp, loop=None, clearance=0.0, eta=None):
    return Case(cid, "general", {"clearance_mm": clearance}, amp, loop=loop, eta=eta)


def model(amp, d_per_n=1e-5, phi=PHI, n=12):
    """Model loops: coarse (n samples per loop), δ ∝ Fg (a homogeneous model)."""
    loop = ellipse_loop(amp, d_per_n * amp, n=n, phi=phi, source="model")
    return ModelResult(loop, {"eta": math.tan(phi)})


def test_identical_physics_passes_with_small_errors():
    ms = MeasurementSet(
        (
            case("a", 100.0, ellipse_loop(100.0, 1e-3, n=4000)),
            case("b", 300.0, ellipse_loop(300.0, 3e-3, n=4000)),
        ),
        Path("."),
    )
    cmp = compare({"a": model(100.0, n=400), "b": model(300.0, n=400)}, ms, STATED)
    assert cmp.passed
    for c in cmp.cases:
        assert c.uncertainty_source == "stated"
        assert c.uncertainty["eta"] == pytest.approx(0.05, rel=1e-12)
        for m in ("disp_at_peak_mm", "eta", "secant_stiffness_N_per_mm"):
            assert abs(c.errors[m]) < 1e-3, m
        assert c.errors["rms_loop"] < 1e-3
        assert c.model["fe_eta"] == pytest.approx(math.tan(PHI))
    assert cmp.summary["n_pass"] == 2


def test_wrong_displacement_scale_fails_on_displacement_not_eta():
    ms = MeasurementSet((case("a", 200.0, ellipse_loop(200.0, 1.3 * 2e-3, n=2000)),), Path("."))
    c = compare({"a": model(200.0, n=400)}, ms).cases[0]
    assert not c.passed
    assert c.errors["disp_at_peak_mm"] == pytest.approx(1 / 1.3 - 1, rel=1e-3)
    assert c.errors["secant_stiffness_N_per_mm"] == pytest.approx(0.3, rel=1e-3)
    assert {"disp_at_peak_mm", "W_cycle_Nmm", "secant_stiffness_N_per_mm", "rms_loop"} <= set(
        c.failed
    )
    assert "eta" not in c.failed  # scaling δ leaves η unchanged


def test_replicates_give_the_uncertainty():
    loops = [ellipse_loop(200.0, d, n=2000) for d in (2.0e-3, 2.1e-3, 1.9e-3)]
    ms = MeasurementSet(tuple(case(f"r{i}", 200.0, lp) for i, lp in enumerate(loops)), Path("."))
    cmp = compare({f"r{i}": model(200.0, n=400) for i in range(3)}, ms, STATED)
    c = cmp.cases[0]
    assert c.uncertainty_source == "replicates (n=3)"
    peaks = np.array([2.0e-3, 2.1e-3, 1.9e-3]) * math.cos(PHI)
    assert c.uncertainty["disp_at_peak_mm"] == pytest.approx(
        np.std(peaks, ddof=1) / np.mean(peaks), rel=1e-6
    )
    assert c.uncertainty["eta"] == 0.005  # identical η: the floor
    assert cmp.passed  # the model sits in the middle of the spread


def test_eta_only_cases_and_fingerprint():
    ms = MeasurementSet(
        tuple(case(f"e{a:g}", a, eta=0.05 * (a / 100.0) ** 0.5) for a in (100.0, 200.0, 400.0)),
        Path("."),
    )
    cmp = compare({f"e{a:g}": model(a) for a in (100.0, 200.0, 400.0)}, ms)
    assert all(set(c.errors) == {"eta"} for c in cmp.cases)
    (fit,) = cmp.fingerprint
    assert fit.slope_eta_measured == pytest.approx(0.5)
    assert fit.slope_eta_model == pytest.approx(0.0, abs=1e-12)
    assert fit.slope_W_model == pytest.approx(2.0)
    assert math.isnan(fit.slope_W_measured)
    assert cmp.summary["metrics"]["eta"]["n"] == 3


def test_missing_model_result_refused():
    ms = MeasurementSet((case("a", 100.0, ellipse_loop(100.0, 1e-3)),), Path("."))
    with pytest.raises(DataError, match=r"no model result for case\(s\) \['a'\]"):
        compare({}, ms)


def test_k_changes_the_verdict():
    ms = MeasurementSet((case("a", 200.0, ellipse_loop(200.0, 1.08 * 2e-3, n=2000)),), Path("."))
    models = {"a": model(200.0, n=400)}
    assert not compare(models, ms, CompareSettings(k=1.0, uncertainty=Uncertainty.STATED)).passed
    assert compare(models, ms, CompareSettings(k=2.0, uncertainty=Uncertainty.STATED)).passed


def test_record_uncertainty_follows_the_noise_of_the_record():
    """The default σ is the record's noise ⊕ the model floor: an 8 % δ error fails on a clean
    record (σ ≈ the 2 % floor) and passes on one whose noise hides it."""
    models = {"a": model(200.0, n=400)}
    clean = MeasurementSet((case("a", 200.0, ellipse_loop(200.0, 1.08 * 2e-3, n=2000)),), Path("."))
    noisy = MeasurementSet(
        (case("a", 200.0, ellipse_loop(200.0, 1.08 * 2e-3, n=2000, noise=0.05, seed=3)),), Path(".")
    )
    c_clean = compare(models, clean).cases[0]
    c_noisy = compare(models, noisy).cases[0]
    assert c_clean.uncertainty_source == "record ⊕ floor"
    assert c_clean.uncertainty["secant_stiffness_N_per_mm"] == pytest.approx(0.02, rel=0.05)
    assert "disp_at_peak_mm" in c_clean.failed
    assert (
        c_noisy.uncertainty["secant_stiffness_N_per_mm"]
        > 2 * c_clean.uncertainty["secant_stiffness_N_per_mm"]
    )
    assert "secant_stiffness_N_per_mm" not in c_noisy.failed


def test_eta_only_sigma_is_the_one_diagnose_uses():
    from validation.candidate_fit import measured_features
    from validation.features import FeatureSettings

    ms = MeasurementSet(
        tuple(case(f"e{a:g}", a, eta=0.02 + a * 1e-4) for a in (100.0, 400.0)), Path(".")
    )
    cmp = compare({c.case_id: model(c.amplitude_n) for c in ms.cases}, ms)
    meas = measured_features(ms, FeatureSettings())
    for c, (eta, s_eta) in zip(
        cmp.cases, zip(meas.values[:, 1], meas.sigma[:, 1], strict=True), strict=True
    ):
        assert c.uncertainty["eta"] == pytest.approx(s_eta / eta, rel=1e-12)


def test_to_dict_is_json_and_plots_are_written(tmp_path):
    cases = [
        case("a", 100.0, ellipse_loop(100.0, 1e-3, noise=0.003, n=1500)),
        case("b", 200.0, ellipse_loop(200.0, 2.6e-3, noise=0.003, seed=1, n=1500)),
        case("c", 300.0, ellipse_loop(300.0, 3e-3, noise=0.003, seed=2, n=1500), clearance=0.05),
        case("d", 300.0, eta=0.08),
    ]
    ms = MeasurementSet(tuple(cases), Path("."))
    cmp = compare({c.case_id: model(c.amplitude_n) for c in cases}, ms)
    d = json.loads(json.dumps(cmp.to_dict()))
    assert [c["passed"] for c in d["cases"]] == [True, False, True, True]
    files = write_comparison_plots(cmp, tmp_path)
    assert set(files) == {"loop_a", "loop_b", "loop_c", "error_map", "residuals", "fingerprint"}
    for path in files.values():
        assert path.read_bytes()[:4] == b"\x89PNG"
