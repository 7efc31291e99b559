"""Effects registry: zero strength is the baseline, each effect does what its mechanism says.

Coarse mesh, 6 increments per stage; the fingerprint table in ``fe.effects`` is checked by
the slow test at the end (40 increments per stage).
"""

from __future__ import annotations

import dataclasses
import hashlib
import re

import numpy as np
import pytest

from cad.errors import ParameterError
from cad.general import make_general_hinge
from cad.general_params import GeneralHingeParams
from fe.cycle.protocol import CycleSettings
from fe.effects.base import EffectContext
from fe.effects.cycle import run_cycle_with_effects
from fe.effects.registry import (
    REGISTRY,
    apply_effects,
    effect_ranges,
    post_process,
    validate_effects,
)
from fe.general.cycle import configurations, run_cycle
from fe.general.system import build_system
from mesh.build import mesh_hinge
from mesh.settings import MeshSettings

COARSE = MeshSettings.coarse()
FG = 400.0


def settings(amp=FG, n=6):
    return CycleSettings(amplitude_n=amp, mu=0.2, increments_per_stage=n, clearance_increments=n)


def _system(clearance):
    mesh, _ = mesh_hinge(make_general_hinge(GeneralHingeParams(clearance_mm=clearance)), COARSE)
    system = build_system(mesh)
    return system, configurations(system, clearance)


@pytest.fixture(scope="module")
def tight():
    return _system(0.0)


@pytest.fixture(scope="module")
def loose():
    return _system(0.1)


@pytest.fixture(scope="module")
def base_tight(tight):
    system, configs = tight
    return run_cycle(system, 0.0, settings(), configs=configs)


def _fingerprint(configs):
    h = hashlib.sha256()
    for side in sorted(configs):
        c = configs[side]
        for a in (c.W, c.G, c.w0, c.geo.g0, c.geo.area_mm2, c.C.data):
            h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


GENERAL = [n for n in REGISTRY if REGISTRY[n].applies_to("general")]
"""The effects of the general hinge (the bearing hinge's are in tests/fe/bearing)."""


def _strength(name, factor=1.0):
    return {name: {p.name: p.default * factor for p in REGISTRY[name].params}}


@pytest.mark.parametrize("name", GENERAL, ids=GENERAL)
def test_zero_strength_changes_nothing(name, tight, base_tight):
    system, configs = tight
    r = run_cycle_with_effects(system, 0.0, settings(), _strength(name, 0.0), configs=configs)
    F0, d0, _ = base_tight.loop_arrays()
    F1, d1, _ = r.loop_arrays()
    np.testing.assert_array_equal(F1, F0)
    np.testing.assert_allclose(d1, d0, rtol=0, atol=1e-12 * np.abs(d0).max())
    m0, m1 = base_tight.metrics(), r.metrics()
    assert m1["eta"] == pytest.approx(m0["eta"], rel=1e-12)


@pytest.mark.parametrize("name", GENERAL, ids=GENERAL)
def test_effects_never_modify_their_inputs(name, tight):
    system, configs = tight
    before = _fingerprint(configs)
    out = apply_effects(configs, _strength(name), EffectContext(system, settings()))
    assert _fingerprint(configs) == before
    assert out is not configs
    assert out[1] is out[-1]  # Δr = 0: one shared configuration stays shared
    F = np.linspace(0.0, 100.0, 5)
    d = np.linspace(0.0, 1e-3, 5)
    F_copy, d_copy = F.copy(), d.copy()
    post_process(F, d, _strength(name))
    np.testing.assert_array_equal(F, F_copy)
    np.testing.assert_array_equal(d, d_copy)


def test_frame_compliance_shears_the_loop_exactly(tight, base_tight):
    system, configs = tight
    c_f = 3e-5
    r = run_cycle_with_effects(
        system, 0.0, settings(), {"frame_compliance": {"compliance_mm_per_n": c_f}}, configs=configs
    )
    np.testing.assert_array_equal(r.result.configs[1].W, configs[1].W)  # W unchanged
    m0, m1 = base_tight.metrics(), r.metrics()
    assert m1["disp_at_peak_mm"] - m0["disp_at_peak_mm"] == pytest.approx(c_f * FG, rel=1e-9)
    assert m1["W_cycle_Nmm"] == pytest.approx(m0["W_cycle_Nmm"], rel=1e-9)
    ratio = m0["delta_max_mm"] / (m0["delta_max_mm"] + c_f * FG)  # U_max grows, W does not
    assert m1["eta"] == pytest.approx(m0["eta"] * ratio, rel=1e-9)
    assert m1["energy_balance_rel_err"] < 1e-9


@pytest.mark.parametrize(
    ("name", "components"),
    [("roughness_softening", (0,)), ("tangential_compliance", (1, 2))],
    ids=["normal", "tangential"],
)
def test_interface_compliance_changes_only_the_diagonal(name, components, tight, base_tight):
    system, configs = tight
    out = apply_effects(configs, _strength(name), EffectContext(system, settings()))
    W0, W1 = configs[1].W, out[1].W
    m = len(configs[1].geo.slave)
    dW = W1 - W0
    idx = np.concatenate([3 * np.arange(m) + k for k in components])
    c = REGISTRY[name].params[0].default
    for k in components:
        np.testing.assert_allclose(
            np.diag(dW)[3 * np.arange(m) + k], c / configs[1].geo.area_mm2, rtol=1e-12
        )
    dW[idx, idx] = 0.0
    assert not dW.any()  # nothing else changed
    r = run_cycle_with_effects(system, 0.0, settings(), _strength(name), configs=configs)
    m0, m1 = base_tight.metrics(), r.metrics()
    assert m1["disp_at_peak_mm"] > m0["disp_at_peak_mm"]  # softer
    assert m1["secant_stiffness_N_per_mm"] < m0["secant_stiffness_N_per_mm"]
    assert m1["energy_balance_rel_err"] < 0.02


@pytest.fixture(scope="module")
def interference_400(tight):
    system, configs = tight
    return run_cycle_with_effects(
        system, 0.0, settings(), _strength("interference"), configs=configs
    )


def test_interference_stiffens_the_initial_response_and_converges(interference_400, base_tight):
    r = interference_400
    F0, d0, _ = base_tight.loop_arrays()
    F1, d1, _ = r.loop_arrays()
    assert F1[1] == F0[1]
    assert d1[1] < 0.7 * d0[1]  # first increment from the prestressed zero: stiffer
    m0, m1 = base_tight.metrics(), r.metrics()
    assert m1["disp_at_peak_mm"] < m0["disp_at_peak_mm"]
    assert m1["energy_balance_rel_err"] < 0.02
    assert abs(m1["loop_closure_mm"]) < 0.02 * m1["delta_max_mm"]  # measured 1.1 %: see docstring


def test_interference_breaks_homogeneity(tight, interference_400):
    """The clamp does not scale with Fg: η now depends on the amplitude (baseline: constant)."""
    system, configs = tight
    eff = _strength("interference")
    lo = run_cycle_with_effects(system, 0.0, settings(100.0), eff, configs=configs).metrics()
    hi = interference_400.metrics()
    assert hi["eta"] > 3 * lo["eta"]


def test_interference_refused_with_clearance(loose):
    system, configs = loose
    with pytest.raises(
        ParameterError, match=r"interference_mm = 0.001 mm .* clearance_mm must be 0"
    ):
        run_cycle_with_effects(system, 0.1, settings(), _strength("interference"), configs=configs)


def test_clearance_with_roughness_runs_and_reuses_the_condensation(loose):
    system, configs = loose
    eff = _strength("roughness_softening")
    r = run_cycle_with_effects(system, 0.1, settings(), eff, configs=configs)
    assert r.base_configs[1] is configs[1]
    assert r.result.configs[1] is not configs[1]
    assert r.result.configs[1].C is configs[1].C  # the same operators, no new condensation
    assert r.metrics()["free_play_mm"] == pytest.approx(0.4)


@pytest.fixture(scope="module")
def face_100(tight):
    system, configs = tight
    return run_cycle_with_effects(
        system, 0.0, settings(100.0), _strength("face_friction"), configs=configs
    )


@pytest.fixture(scope="module")
def face_400(tight):
    system, configs = tight
    return run_cycle_with_effects(
        system, 0.0, settings(400.0), _strength("face_friction"), configs=configs
    )


def test_face_friction_clamp_equals_the_parameter(tight, face_400):
    """At F = 0 (the prestressed zero's state) each face carries the clamp force."""
    from fe.general.faces import face_normal_forces, unloaded_state

    cond = face_400.result.configs[1]
    state = unloaded_state(cond, EffectContext(tight[0], settings()).contact())
    clamp = REGISTRY["face_friction"].params[0].default
    for side, force in face_normal_forces(cond, np.asarray(state.p)).items():
        assert force == pytest.approx(clamp, rel=0.01), side


def test_face_friction_sticks_at_low_force_and_stiffens(face_100, tight):
    system, configs = tight
    base = run_cycle(system, 0.0, settings(100.0), configs=configs).metrics()
    m = face_100.metrics()
    assert m["secant_stiffness_N_per_mm"] > base["secant_stiffness_N_per_mm"]  # measured ×1.16
    cond, state = face_100.result.configs[1], face_100.result.states[-1]
    faces = np.asarray(cond.geo.pair) < 0
    p = np.asarray(state.p)[faces]
    stuck = np.linalg.norm(p[:, 1:], axis=1) < 0.2 * p[:, 0] * (1 - 1e-6)
    assert stuck.any()  # some face points stick at +Fg


def test_face_friction_closes_the_energy_balance_and_the_pin_floats(face_400, tight):
    from fe.general.system import displacement, support_reaction

    system, _ = tight
    m = face_400.metrics()
    assert m["energy_balance_rel_err"] < 1e-8
    cond = face_400.result.configs[1]
    for state in face_400.result.states:
        p, a = np.asarray(state.p), np.asarray(state.alpha)
        u = displacement(system, cond, p, a)
        assert support_reaction(system, cond, p, u) < 1e-8 * FG


def test_face_friction_breaks_homogeneity(face_100, face_400):
    """The clamp does not scale with Fg: η now depends on the amplitude (baseline: constant)."""
    assert face_400.metrics()["eta"] > 1.5 * face_100.metrics()["eta"]  # measured 1.86


def test_face_friction_without_friction_makes_no_loop(tight, base_tight):
    system, configs = tight
    r = run_cycle_with_effects(
        system,
        0.0,
        dataclasses.replace(settings(), mu=0.0),
        _strength("face_friction"),
        configs=configs,
    )
    assert all(i.friction_work == 0.0 for i in r.result.increments)
    assert r.metrics()["eta"] < 0.1 * base_tight.metrics()["eta"]  # open/close work only


@pytest.mark.parametrize(
    ("effects", "match"),
    [
        (
            {"bolt_preload": {}},
            r"unknown effect\(s\) \['bolt_preload'\]; known effects: frame_compliance",
        ),
        (
            {"frame_compliance": {"stiffness": 1.0}},
            r"effect 'frame_compliance': unknown parameter\(s\) \['stiffness'\]; allowed: compliance_mm_per_n",
        ),
        (
            {"frame_compliance": {"compliance_mm_per_n": 1e-3}},
            r"effects.frame_compliance.compliance_mm_per_n must be in \[0, 0.0001\] mm/N, got 0.001",
        ),
        (
            {"interference": {"interference_mm": -1e-3}},
            r"effects.interference.interference_mm must be in \[0, 0.01\] mm, got -0.001",
        ),
        (
            {"roughness_softening": {"compliance_mm3_per_n": float("nan")}},
            r"compliance_mm3_per_n must be in .* got nan",
        ),
    ],
    ids=["unknown-effect", "unknown-param", "too-large", "negative", "nan"],
)
def test_validation_names_effect_param_value_range(effects, match):
    with pytest.raises(ParameterError, match=match):
        validate_effects(effects)


def test_validation_fills_defaults_in_registry_order():
    out = validate_effects({"interference": {}, "frame_compliance": {"compliance_mm_per_n": 1e-5}})
    assert list(out) == ["frame_compliance", "interference"]
    assert out["interference"]["interference_mm"] == REGISTRY["interference"].params[0].default
    with pytest.raises(TypeError):
        out["interference"]["interference_mm"] = 1.0  # type: ignore[index]


def test_every_effect_is_documented():
    for name, effect in REGISTRY.items():
        doc = type(effect).__doc__ or ""
        assert "MECHANISM" in doc, name
        assert "FINGERPRINT" in doc, name
        assert "η vs amplitude" in doc, name
        assert "TABLE_" not in doc, name
        for p in effect.params:
            assert p.lo == 0.0
            assert p.lo <= p.default <= p.hi
    assert effect_ranges()["frame_compliance"] == {"compliance_mm_per_n": (0.0, 1e-4)}


def test_model_file_reads_effects_against_the_registry(tmp_path):
    from model.file import read_model, write_model

    path = tmp_path / "MODEL.toml"
    path.write_text(
        '[hinge]\nkind = "general"\n\n[effects.frame_compliance]\ncompliance_mm_per_n = 2e-5\n'
    )
    spec = read_model(path, REGISTRY)
    assert dict(spec.effects["frame_compliance"]) == {"compliance_mm_per_n": 2e-5}
    assert read_model(write_model(spec, tmp_path / "again.toml"), REGISTRY) == spec
    path.write_text('[hinge]\nkind = "general"\n\n[effects.interference]\ninterference_mm = 0.5\n')
    with pytest.raises(ParameterError, match=r"effects.interference.interference_mm"):
        read_model(path, REGISTRY)


# --------------------------------------------------------------------------- fingerprints

ROW = re.compile(r"^\s*(0|0\.1)\s+(100|400)\s+(-?[\d.]+)\s+(-?[\d.]+)\s+([\d.]+)\s+([\d.]+)\s*$")


def fingerprint_table(n=40):
    """(effect, Δr, Fg) → (η base, η effect, δ(+Fg) base µm, δ(+Fg) effect µm), as in the docstrings."""
    rows = {}
    for clearance in (0.0, 0.1):
        system, configs = _system(clearance)
        for amp in (100.0, 400.0):
            base = run_cycle(system, clearance, settings(amp, n), configs=configs).metrics()
            for name in GENERAL:
                if REGISTRY[name].zero_clearance_reason and clearance > 0:
                    continue
                m = run_cycle_with_effects(
                    system, clearance, settings(amp, n), _strength(name), configs=configs
                ).metrics()
                rows[(name, clearance, amp)] = (
                    base["eta"],
                    m["eta"],
                    base["disp_at_peak_mm"] * 1e3,
                    m["disp_at_peak_mm"] * 1e3,
                )
    return rows


@pytest.mark.slow
def test_docstring_fingerprints_are_measured():
    rows = fingerprint_table()
    for name in GENERAL:
        effect = REGISTRY[name]
        documented = {}
        for line in (type(effect).__doc__ or "").splitlines():
            hit = ROW.match(line)
            if hit:
                documented[(name, float(hit[1]), float(hit[2]))] = tuple(
                    map(float, hit.groups()[2:])
                )
        assert documented, name
        for key, values in documented.items():
            np.testing.assert_allclose(rows[key], values, rtol=0.02, atol=1.5e-5, err_msg=str(key))


def test_result_is_a_cycle_result_with_consistent_metrics(tight):
    from fe.cycle.result import CycleResult

    system, configs = tight
    r = run_cycle_with_effects(
        system, 0.0, settings(), _strength("frame_compliance"), configs=configs
    )
    assert isinstance(r.result, CycleResult)
    _, d, _ = r.loop_arrays()
    assert d[0] == 0.0
    sl = r.result.last_loop()
    assert r.metrics()["disp_at_peak_mm"] == d[sl][-1]
    assert "effects" in r.result.timings_s
