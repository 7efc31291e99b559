"""validation.diagnose: verdict rules without FE (fast), and end to end on synthetic sets (slow)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from validation.candidate_fit import CandidateFit, DiagnoseSettings, MeasuredFeatures
from validation.diagnose import _verdict
from validation.features import loop_features, noise_sigma
from validation.loops import process_loop
from validation.misfit import residual_pattern


def _meas(n=4):
    pts = tuple((0.0, a) for a in np.linspace(100.0, 400.0, n))
    amps = np.array([p[1] for p in pts])
    delta = 1e-5 * amps
    W = 0.013 * math.pi * amps * delta
    vals = np.column_stack([delta, W, 0.3 * delta])
    return MeasuredFeatures(pts, vals, 0.02 * np.abs(vals))


def _fit(name, c2, c0=400.0, counts=True, n=12):
    return CandidateFit(
        name,
        "p",
        1e-5,
        "mm/N",
        c2,
        c0 - c2,
        50.0,
        1e-6 if counts else 0.5,
        counts,
        c0,
        c2,
        counts,
        False,
        c2 + 2,
        c2 + math.log(n),
        np.zeros((4, 3)),
    )


def test_verdict_rules():
    m, s = _meas(), DiagnoseSettings()
    assert _verdict([], 10.0, 12, 26.0, m, s)[0] == "no_missing_effect"
    assert _verdict([], 400.0, 12, 26.0, m, s)[0] == "unexplained"
    v = _verdict([_fit("a", 11.0), _fit("b", 200.0)], 400.0, 12, 26.0, m, s)
    assert v[:2] == ("effect_missing", ("a",))
    v = _verdict([_fit("a", 11.0), _fit("b", 12.0)], 400.0, 12, 26.0, m, s)
    assert v[0] == "indistinguishable"
    assert set(v[1]) == {"a", "b"}
    assert v[3]
    v = _verdict([_fit("a", 300.0)], 400.0, 12, 26.0, m, s)  # explains 26 % of the excess
    assert v[0] == "unexplained"
    assert "explains only" in v[2]
    few = dataclasses.replace(_fit("a", 1.0, counts=False), p_value=0.004)
    v = _verdict([few], 240.0, 3, 11.3, m, s)  # fits, but not significant with N = 3
    assert v[0] == "unexplained"
    assert "add cases" in v[2]
    assert "N = 3" in v[2]


def test_residual_pattern_words():
    m = _meas()
    stiff = m.values * np.array([0.8, 0.8, 0.8])  # δ 20 % low, η unchanged
    assert any("too stiff at all amplitudes" in w for w in residual_pattern(stiff, m))
    grow = m.values.copy()
    grow[:, 1] *= 1.0 + np.linspace(0.0, 0.6, 4)  # η error 0 → +60 %
    assert any("η error grows with amplitude" in w for w in residual_pattern(grow, m))
    assert residual_pattern(m.values, m) == ["no residual beyond 2σ"]


def test_features_of_an_ellipse_and_noise_sigma():
    rng = np.random.default_rng(0)
    theta = np.linspace(0.0, 2 * math.pi, 400)[1:]
    up = np.linspace(0.0, 1.0, 100)
    F = np.concatenate([np.zeros(20), 300.0 * up, 300.0 * np.cos(theta)])
    d = np.concatenate([np.zeros(20), 2e-3 * up, 2e-3 * np.cos(theta - 0.1)])
    clean = loop_features(process_loop(F, d, "ellipse"))
    assert clean[0] == pytest.approx(2e-3 * math.cos(0.1), rel=1e-3)
    assert clean[1] == pytest.approx(math.pi * 300 * 2e-3 * math.sin(0.1), rel=2e-2)
    noisy = process_loop(F + rng.normal(0, 0.2, F.size), d + rng.normal(0, 5e-6, F.size), "n")
    s = noise_sigma(noisy)
    assert np.all(s > 0)
    assert s[0] < 1e-5
    assert abs(loop_features(noisy)[1] - clean[1]) < 5 * s[1] + 0.02 * clean[1]


def _eta_table(tmp_path, rows):
    from validation.measurements import read_eta_table

    path = tmp_path / "eta.csv"
    lines = ["clearance_mm,amplitude_N,eta"] + [f"{c:g},{a:g},{e:g}" for c, a, e in rows]
    path.write_text("\n".join(lines) + "\n")
    return read_eta_table(path)


def test_eta_only_rows_count_once_and_compare_eta(tmp_path):
    from validation.candidate_fit import chi2, measured_features, residuals
    from validation.features import FeatureSettings

    data = _eta_table(tmp_path, [(0.0, 100.0, 0.02), (0.0, 400.0, 0.02), (0.0, 400.0, 0.024)])
    meas = measured_features(data, FeatureSettings(eta_rel_sigma=0.05))
    assert meas.points == ((0.0, 100.0), (0.0, 400.0))
    assert meas.eta_rows.tolist() == [True, True]
    assert meas.n_obs == 2
    assert meas.values[1, 1] == pytest.approx(0.022)  # replicates averaged
    s_rep = np.std([0.02, 0.024], ddof=1)
    expected = math.sqrt(s_rep**2 + (0.05 * 0.022) ** 2 + (0.02 * 0.022 + 0.001) ** 2)
    assert meas.sigma[1, 1] == pytest.approx(expected)
    amps = meas.amplitudes
    delta = 1e-5 * amps
    model = np.column_stack([delta, 0.03 * math.pi * amps * delta, 0.3 * delta])  # η = 0.03
    r = residuals(model, meas)
    assert r[:, [0, 2]].tolist() == [[0.0, 0.0], [0.0, 0.0]]
    np.testing.assert_allclose(r[:, 1], (0.03 - meas.values[:, 1]) / meas.sigma[:, 1])
    assert chi2(model, meas) == pytest.approx(float(np.sum(r[:, 1] ** 2)))
    words = residual_pattern(model, meas)
    assert any("η too high at all amplitudes" in w for w in words), words
    assert not any(w.startswith("too s") for w in words)  # δ was not measured


def test_eta_only_residual_takes_the_free_play_off(tmp_path):
    """A stated η excludes the free play; the model features include it in δ_max (2Δr)."""
    from validation.candidate_fit import measured_features, residuals
    from validation.features import FeatureSettings

    meas = measured_features(_eta_table(tmp_path, [(0.1, 400.0, 0.02)]), FeatureSettings())
    elastic = 0.004  # mm
    W = 0.02 * math.pi * 400.0 * elastic  # η = 0.02 on the elastic δ
    model = np.array([[elastic + 2 * 0.1, W, 0.001]])
    assert residuals(model, meas)[0, 1] == pytest.approx(0.0, abs=1e-9)


def test_eta_only_tie_asks_for_the_loop_that_separates(tmp_path):
    data = _eta_table(tmp_path, [(0.0, 100.0, 0.01), (0.0, 400.0, 0.01)])
    from validation.candidate_fit import measured_features
    from validation.features import FeatureSettings

    meas = measured_features(data, FeatureSettings())
    amps = meas.amplitudes
    soft = 1e-5 * amps * 1.5  # a series spring: δ 50 % larger, same η
    stiff = 1e-5 * amps
    a, b = _fit("frame_compliance", 1.0, n=2), _fit("tangential_compliance", 1.2, n=2)
    a = dataclasses.replace(
        a, features=np.column_stack([soft, 0.01 * math.pi * amps * soft, 0.1 * soft])
    )
    b = dataclasses.replace(
        b, features=np.column_stack([stiff, 0.01 * math.pi * amps * stiff, 0.1 * stiff])
    )
    v = _verdict([a, b], 400.0, 2, 9.2, meas, DiagnoseSettings())
    assert v[0] == "indistinguishable"
    assert "measure the loop" in v[3], v[3]
    assert "differ by 33%" in v[3]  # 1 − 1/1.5: every loop feature scales with δ here


# --------------------------------------------------------------------------- end to end

DESIGN = ((0.0, (100.0, 400.0)), (0.1, (100.0, 400.0)))
FAST = DiagnoseSettings(
    grid_points=5, grid_decades=2.5, refine_iter=4, increments_per_stage=6, clearance_increments=12
)


@pytest.fixture(scope="module")
def spec():
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.spec import ModelSpec

    return ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(mu=0.2, increments_per_stage=8, clearance_increments=16),
    )


def test_eta_judged_without_free_play_is_the_cycles_reported_eta(spec, tmp_path):
    # An η-only row is compared with the model's η with the free play taken off δ_max
    # (δ_max − 2Δr of the machine path). That must be the η `hingelab cycle` reports
    # (its loop without the free play); a different δ or a 4Δr slip would bias every
    # η-only diagnosis with clearance.
    from fe.effects.cycle import run_cycle_with_effects
    from model.spec import DesignPoint
    from validation.candidate_fit import eta_without_free_play, measured_features
    from validation.evaluate import ModelEvaluator
    from validation.features import FeatureSettings, derived

    point = (0.1, 300.0)
    meas = measured_features(_eta_table(tmp_path, [(*point, 0.001)]), FeatureSettings())
    evaluator = ModelEvaluator(spec, [point])
    features = evaluator.features({})
    judged = float(eta_without_free_play(features, meas)[0])
    system = evaluator.service.prepare(
        spec, DesignPoint(point[1], {"clearance_mm": point[0]})
    ).system
    settings = dataclasses.replace(evaluator.cycle, amplitude_n=point[1])
    reported = run_cycle_with_effects(system, point[0], settings, {}).metrics()["eta"]
    # same loop, same δ; they differ only by how the loop is closed (chord vs last state)
    assert judged == pytest.approx(reported, rel=0.01)
    with_play = float(derived(features, meas.amplitudes)[1][0])
    assert with_play < 0.5 * reported  # the free play matters here: the test can tell


def synth_set(spec, hidden, out, seed, design=DESIGN):
    from validation.measurements import read_measurement_set
    from validation.synth import SynthSettings, design_cases, synthesize

    synthesize(spec, hidden, design_cases(design), SynthSettings(seed=seed), out)
    return read_measurement_set(out)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_no_hidden_effect_gives_no_missing_effect(spec, tmp_path, seed):
    from validation.diagnose import diagnose

    d = diagnose(spec, synth_set(spec, {}, tmp_path, seed), FAST)
    assert d.verdict == "no_missing_effect", d.text()


@pytest.mark.slow
def test_hidden_frame_compliance_is_named_first_and_calibration_cuts_the_error(spec, tmp_path):
    from validation.calibrate import calibrate
    from validation.diagnose import diagnose

    data = synth_set(spec, {"frame_compliance": {"compliance_mm_per_n": 2e-5}}, tmp_path, 3)
    d = diagnose(spec, data, FAST)
    assert d.verdict == "effect_missing", d.text()
    assert d.effects == ("frame_compliance",)
    assert d.candidates[0].value == pytest.approx(2e-5, rel=0.15)
    _, rows = calibrate(spec, data, ["frame_compliance"], FAST)
    _assert_error_falls_to_the_noise(rows)


def _assert_error_falls_to_the_noise(rows):
    """The ledger's error must fall at least five-fold and end near the noise level."""
    assert rows[0].error >= 5 * rows[-1].error, rows
    assert rows[-1].error < 2.0, rows  # RMS feature residual in σ: ≈ 1 at the noise level


def _error_falls_to_the_noise(spec, data, name):
    """Calibrate ``name``: the error must fall at least five-fold and end near the noise."""
    from validation.calibrate import calibrate

    _assert_error_falls_to_the_noise(calibrate(spec, data, [name], FAST)[1])


@pytest.mark.slow
def test_hidden_roughness_softening_is_named_first(spec, tmp_path):
    from validation.diagnose import diagnose

    data = synth_set(spec, {"roughness_softening": {"compliance_mm3_per_n": 2e-4}}, tmp_path, 4)
    d = diagnose(spec, data, FAST)
    assert d.verdict == "effect_missing", d.text()
    assert d.effects == ("roughness_softening",)
    _error_falls_to_the_noise(spec, data, "roughness_softening")


@pytest.mark.slow
def test_hidden_interference_is_named_first(spec, tmp_path):
    from validation.diagnose import diagnose

    design = ((0.0, (100.0, 250.0, 400.0)),)  # an interference is refused with clearance
    data = synth_set(spec, {"interference": {"interference_mm": 1e-3}}, tmp_path, 5, design)
    d = diagnose(spec, data, FAST)
    assert d.verdict == "effect_missing", d.text()
    assert d.effects == ("interference",)
    _error_falls_to_the_noise(spec, data, "interference")


@pytest.mark.slow
def test_mu_is_calibrated_and_the_error_falls(spec, tmp_path):
    """The data come from μ = 0.3 (finer mesh); the model starts at μ = 0.05.

    At Δr = 0, η(μ) on the coarse model is 0.0055 / 0.0143 / 0.0167 at μ = 0.05 / 0.2 / 0.3:
    from 0.2 the misfit is within the noise (error 0.8 σ, measured), so the start is far off.
    """
    import dataclasses

    from validation.calibrate import calibrate

    truth = dataclasses.replace(spec, cycle=dataclasses.replace(spec.cycle, mu=0.3))
    spec = dataclasses.replace(spec, cycle=dataclasses.replace(spec.cycle, mu=0.05))
    design = ((0.0, (100.0, 250.0, 400.0)),)
    data = synth_set(truth, {}, tmp_path, 10, design)
    fitted, rows = calibrate(spec, data, [], FAST, fit_mu=True)
    assert [r.step for r in rows] == ["baseline", "+mu"]
    assert fitted.cycle.mu == pytest.approx(0.3, rel=0.1)
    _assert_error_falls_to_the_noise(rows)


def play_operator(force_n, slip_n):
    """Return the play (backlash) operator of a force history: x moves only when |F − x| > slip."""
    out = np.zeros_like(force_n)
    x = 0.0
    for i, f in enumerate(force_n):
        x = min(max(x, f - slip_n), f + slip_n)
        out[i] = x
    return out


@pytest.mark.slow
def test_effect_outside_the_registry_is_unexplained(spec, tmp_path):
    """A spring–slider (Jenkins) element in series, added to the data only: extra hysteresis
    that no registry effect makes (W grows with δ in a non-homogeneous way)."""
    from validation.diagnose import diagnose
    from validation.measurements import read_measurement_set

    design = ((0.0, (100.0, 250.0, 400.0)),)
    synth_set(spec, {}, tmp_path, 6, design)
    for path in (tmp_path / "loops").glob("*.csv"):
        t, F, d = np.loadtxt(path, delimiter=",", skiprows=1).T
        d = d + play_operator(F, 30.0) / 2e5  # slip 30 N, spring 2e5 N/mm
        np.savetxt(
            path,
            np.column_stack([t, F, d]),
            delimiter=",",
            header="time_s,force_N,displacement_mm",
            comments="",
            fmt="%.9g",
        )
    d = diagnose(spec, read_measurement_set(tmp_path), FAST)
    assert d.verdict == "unexplained", d.text()
    assert d.effects == ()


@pytest.mark.slow
def test_two_hidden_effects_are_found_in_two_rounds(spec, tmp_path):
    from validation.calibrate import calibrate
    from validation.diagnose import diagnose

    hidden = {
        "frame_compliance": {"compliance_mm_per_n": 2e-5},
        "roughness_softening": {"compliance_mm3_per_n": 2e-4},
    }
    data = synth_set(spec, hidden, tmp_path, 8)
    first = diagnose(spec, data, FAST)
    assert first.verdict == "effect_missing", first.text()
    assert first.effects[0] in hidden
    spec2, rows = calibrate(spec, data, list(first.effects), FAST)
    second = diagnose(spec2, data, FAST)
    assert second.verdict == "effect_missing", second.text()
    assert set(first.effects + second.effects) == set(hidden)
    _, rows3 = calibrate(spec2, data, list(second.effects), FAST)
    assert rows[0].error >= 5 * rows3[-1].error


@pytest.mark.slow
def test_eta_only_cases_cannot_tell_a_series_spring_from_shear_compliance(spec, tmp_path):
    """At Δr = 0 the model is positively homogeneous: a frame compliance and a tangential
    interface compliance both lower η by an amplitude-independent factor, so η-only cases
    cannot separate them; the loop (δ_max) can, and the diagnosis must say so."""
    from validation.diagnose import diagnose
    from validation.loops import process_loop
    from validation.measurements import read_eta_table, read_measurement_set

    # five amplitudes: with three η values the F test (1 and N − 1 = 2 dof) cannot call even
    # a perfect fit significant at α/m (measured: p = 0.004 > 0.002, verdict unexplained)
    design = ((0.0, (100.0, 175.0, 250.0, 325.0, 400.0)),)
    loops = tmp_path / "loops_set"
    synth_set(spec, {"frame_compliance": {"compliance_mm_per_n": 2e-5}}, loops, 9, design)
    rows = ["clearance_mm,amplitude_N,eta"]
    for case in read_measurement_set(loops).cases:
        m = process_loop(case.loop.force_n, case.loop.displacement_mm, case.case_id).metrics
        rows.append(f"{case.values['clearance_mm']:g},{case.amplitude_n:g},{m.eta:.6g}")
    (tmp_path / "eta.csv").write_text("\n".join(rows) + "\n")
    d = diagnose(spec, read_eta_table(tmp_path / "eta.csv"), FAST)
    assert d.verdict == "indistinguishable", d.text()
    assert {"frame_compliance", "tangential_compliance"} <= set(d.effects), d.text()
    assert "measure the loop" in d.separating_test, d.text()


def test_held_out_folds_keep_every_clearance_in_training():
    from validation.candidate_fit import holdout_folds

    pts = [(0.0, 100.0), (0.0, 400.0), (0.1, 100.0), (0.1, 400.0)]
    folds = holdout_folds(pts)
    assert [f.tolist() for f in folds] == [[True, False, True, False], [False, True, False, True]]
    single = holdout_folds(
        [(0.0, 100.0), (0.1, 100.0)]
    )  # one amplitude each: leave a clearance out
    assert [f.tolist() for f in single] == [[True, False], [False, True]]
