"""validation.synth without FE: design parsing, the finer mesh rule, the machine path, sampling."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cad.errors import ParameterError
from fe.cycle.protocol import CycleSettings
from fe.cycle.result import CycleResult, Increment
from mesh.settings import MeshSettings
from validation.loop_files import Loop
from validation.loops import process_loop
from validation.measurements import check_amplitude
from validation.synth import (
    SynthSettings,
    default_design,
    design_cases,
    finer_mesh,
    machine_path,
    measure,
    parse_design,
)


def _ellipse_path(amp=300.0, d_amp=2e-3, n=80):
    """0 → +Fg, then one loop +Fg → −Fg → +Fg with a phase lag (a known area)."""
    up = np.linspace(0.0, 1.0, n // 4)
    theta = np.linspace(0.0, 2 * math.pi, n)[1:]
    F = np.concatenate([amp * up, amp * np.cos(theta)])
    d = np.concatenate([d_amp * up, d_amp * np.cos(theta - 0.1)])
    return F, d


def test_default_design_is_three_by_three():
    cases = design_cases(default_design("general"))
    assert len(cases) == 9
    assert {c.values for c in cases} == {(("clearance_mm", x),) for x in (0.0, 0.1, 0.2)}
    assert len({c.amplitude_n for c in cases}) == 3
    assert len({c.case_id for c in cases}) == 9


def test_parse_design():
    assert parse_design("0:100,400; 0.1:250") == ((0.0, (100.0, 400.0)), (0.1, (250.0,)))
    with pytest.raises(ParameterError, match=r"'0.1-250' is not clearance_mm:amplitude_N"):
        parse_design("0:100;0.1-250")
    with pytest.raises(ParameterError, match="amplitude_n must be in"):
        design_cases(parse_design("0:0"))
    with pytest.raises(ParameterError, match="repeated"):
        design_cases(parse_design("0:100,100"))


@pytest.mark.parametrize(
    "mesh",
    [MeshSettings.coarse(), MeshSettings(), MeshSettings(arc_grading=1.0)],
    ids=["coarse", "default", "uniform-arcs"],
)
def test_synth_mesh_is_finer_and_graded_differently(mesh):
    fine = finer_mesh(mesh)
    assert fine.contact_size_mm == pytest.approx(0.75 * mesh.contact_size_mm)
    assert fine.slave_mm < mesh.slave_mm
    assert fine.size_mm < mesh.size_mm
    assert fine.arc_grading != mesh.arc_grading


def _increment(stage, F, d, side):
    return Increment(stage, F, d, side, 1, 0, 0, 0, 0.0, 0.0, 0.0)


def test_machine_path_crosses_the_free_play_at_zero_force():
    incs = (
        _increment(0, 100.0, 1e-3, 1),
        _increment(1, 0.0, 2e-4, 1),
        _increment(1, -100.0, -1e-3, -1),
        _increment(2, 0.0, -2e-4, -1),
        _increment(2, 100.0, 1e-3, 1),
    )
    r = CycleResult(CycleSettings(amplitude_n=100.0), 0.05, incs, 0.2, (), {})
    F, d = machine_path(r)
    # from the centred pin (δ = 0) the grips first cross 2Δr at zero force
    np.testing.assert_array_equal(F, [0, 0, 100, 0, 0, -100, 0, 0, 100])
    np.testing.assert_allclose(
        d, [0.0, 0.1, 0.101, 0.1002, -0.1, -0.101, -0.1002, 0.1, 0.101], rtol=0, atol=1e-15
    )
    # the record the machine makes of it never moves faster than its crosshead limit
    quiet = SynthSettings(
        noise_force_n=0.0, noise_disp_mm=0.0, force_offset_n=0.0, disp_offset_mm=0.0
    )
    m = measure(F, d, quiet, 0)
    speed = np.abs(np.diff(m.displacement_mm)) / np.diff(m.time_s)
    assert speed.max() <= quiet.disp_rate_mm_per_s * (1 + 1e-9)
    assert m.displacement_mm[0] == 0.0


def test_measure_is_deterministic_by_seed_and_leaves_inputs_alone():
    F, d = _ellipse_path()
    F0, d0 = F.copy(), d.copy()
    a = measure(F, d, SynthSettings(seed=3), 0)
    b = measure(F, d, SynthSettings(seed=3), 0)
    c = measure(F, d, SynthSettings(seed=4), 0)
    e = measure(F, d, SynthSettings(seed=3), 1)
    np.testing.assert_array_equal(a.force_n, b.force_n)
    np.testing.assert_array_equal(a.displacement_mm, b.displacement_mm)
    assert not np.array_equal(a.force_n, c.force_n)
    assert not np.array_equal(a.force_n, e.force_n)  # each case its own stream
    np.testing.assert_array_equal(F, F0)
    np.testing.assert_array_equal(d, d0)


def test_measured_loop_is_realistic_and_keeps_the_area():
    F, d = _ellipse_path()
    s = SynthSettings(seed=1, noise_force_n=0.1, noise_disp_mm=1e-6)
    m = measure(F, d, s, 0)
    dt = np.diff(m.time_s)
    np.testing.assert_allclose(dt, 1 / s.sample_hz, rtol=1e-9)  # fixed clock
    n_dwell = int(np.sum(m.time_s < s.dwell_s))
    assert n_dwell == pytest.approx(s.dwell_s * s.sample_hz, abs=1)
    assert np.all(np.abs(m.force_n[:n_dwell] - m.force_offset_n) < 1.0)
    loop = Loop(m.force_n, m.displacement_mm, m.time_s, "synth")
    check_amplitude(loop, 300.0, "synth")
    measured = process_loop(m.force_n, m.displacement_mm, "synth").metrics
    truth = process_loop(F, d, "path").metrics
    assert measured.W_cycle_Nmm == pytest.approx(truth.W_cycle_Nmm, rel=0.03)
    assert measured.eta == pytest.approx(truth.eta, rel=0.03)


def test_free_play_is_sampled_at_the_crosshead_speed():
    F = np.array([0.0, 100.0, 0.0, 0.0, -100.0])
    d = np.array([0.0, 1e-3, 0.0, -0.2, -0.201])
    s = SynthSettings(noise_force_n=0.0, noise_disp_mm=0.0, force_offset_n=0.0, disp_offset_mm=0.0)
    m = measure(F, d, s, 0)
    in_play = (m.displacement_mm < -1e-3) & (m.displacement_mm > -0.199)
    assert np.all(m.force_n[in_play] == 0.0)
    assert in_play.sum() == pytest.approx(0.198 / s.disp_rate_mm_per_s * s.sample_hz, abs=2)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("seed", -1, "seed must be an integer"),
        ("sample_hz", 0.0, "sample_hz"),
        ("noise_force_n", -1.0, "noise_force_n"),
    ],
    ids=["seed", "sample_hz", "noise"],
)
def test_settings_refuse_bad_values(field, value, match):
    with pytest.raises(ParameterError, match=match):
        SynthSettings(**{field: value})


def test_true_model_passes_compare_on_synthetic_data_with_clearance(tmp_path):
    """No hidden effect, Δr = 0.1 mm: the record and the model start from the same centred
    pin, so δ(+Fg) agrees (it was −95 % off when the record jumped 2Δr at its start)."""
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.spec import ModelSpec
    from validation.compare import compare
    from validation.measurements import read_measurement_set
    from validation.synth import design_cases, synthesize
    from validation.workflow import run_model_for_cases

    spec = ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(increments_per_stage=6, clearance_increments=12),
    )
    synthesize(spec, {}, design_cases([(0.1, (300.0,))]), SynthSettings(seed=5), tmp_path)
    data = read_measurement_set(tmp_path)
    models, _ = run_model_for_cases(spec, data.cases)
    (case,) = compare(models, data).cases
    assert abs(case.errors["disp_at_peak_mm"]) < 0.05, case.errors


def _coarse_spec():
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.spec import ModelSpec

    return ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(increments_per_stage=6, clearance_increments=6),
    )


def test_synth_adapts_a_data_mesh_that_distorts_and_says_so(tmp_path):
    """On the coarse mesh at Δr = 0.3 mm the ×1.5 arc grading gives a scaled Jacobian of
    0.049: the data mesh is graded less there, the manifest says why, the set is complete."""
    from validation.synth import design_cases, synthesize

    out = tmp_path / "set"
    report = synthesize(
        _coarse_spec(), {}, design_cases([(0.3, (200.0,))]), SynthSettings(seed=1), out
    )
    assert "0.3" in report.manifest["mesh_adapted"]
    assert "scaled Jacobian" in report.manifest["mesh_adapted"]["0.3"]
    assert (out / "cases.csv").is_file()
    assert (out / "loops" / "dr0.3mm_F200N.csv").is_file()


class _PathService:
    """Stands in for ``model.service.ModelService``: one short stage path per point, no FE.

    The atomic write does not depend on what the cycle was (the FE path of synthesize is
    checked above on the coarse model); this keeps the failure test a fraction of a second
    instead of two finer-mesh cycles.
    """

    def run_summarized(self, pairs):
        out = []
        for _, point in pairs:
            a = point.amplitude_n
            incs = (
                _increment(0, a, 1e-3, 1),
                _increment(1, 0.0, 2e-4, 1),
                _increment(1, -a, -1e-3, -1),
                _increment(2, 0.0, -2e-4, -1),
                _increment(2, a, 1e-3, 1),
            )
            out.append((CycleResult(CycleSettings(amplitude_n=a), 0.0, incs, 0.0, (), {}), {}))
        return out


def test_a_failing_synth_leaves_no_partial_set(tmp_path, monkeypatch):
    import validation.synth as synth

    calls = []

    def fail_second(path, m):  # the first case's loop file is already written
        calls.append(path)
        if len(calls) == 2:
            assert path.parent.parent.name.endswith(".partial")  # beside out, not in it
            assert (path.parent / "dr0mm_F100N.csv").is_file()  # the first case is on disk
            raise synth.ParameterError("refused by the test")
        return real(path, m)

    real = synth.write_loop_csv
    monkeypatch.setattr(synth, "write_loop_csv", fail_second)
    out = tmp_path / "set"
    cases = synth.design_cases([(0.0, (100.0, 200.0))])
    with pytest.raises(synth.ParameterError, match="refused by the test"):
        synth.synthesize(_coarse_spec(), {}, cases, SynthSettings(), out, _PathService())
    assert len(calls) == 2
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(synth.ParameterError, match="not a synthetic set"):
        synth.synthesize(
            _coarse_spec(),
            {},
            synth.design_cases([(0.0, (100.0,))]),
            SynthSettings(),
            tmp_path / "mine",
            _PathService(),
        )
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep"
