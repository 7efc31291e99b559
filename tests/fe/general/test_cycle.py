"""The general hinge's hysteresis cycle: invariants that hold exactly, not regressions.

A coarse mesh keeps these fast; every property tested here holds at any mesh size.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cad.errors import ConvergenceError, ParameterError
from cad.general import make_general_hinge
from cad.general_params import GeneralHingeParams
from fe.cycle.protocol import CycleSettings
from fe.cycle.result import CycleResult
from fe.general.cycle import grip_force, run_cycle
from fe.general.system import build_system, displacement, support_reaction
from mesh.build import mesh_hinge
from mesh.settings import MeshSettings

COARSE = MeshSettings.coarse()


def system_for(clearance: float):
    mesh, _ = mesh_hinge(make_general_hinge(GeneralHingeParams(clearance_mm=clearance)), COARSE)
    return build_system(mesh)


@pytest.fixture(scope="module")
def tight():
    return system_for(0.0)


@pytest.fixture(scope="module")
def loose():
    return system_for(0.1)


def cycle(system, clearance=0.0, **kw) -> CycleResult:
    kw.setdefault("increments_per_stage", 8)
    kw.setdefault("clearance_increments", kw["increments_per_stage"])
    return run_cycle(system, clearance, CycleSettings(**kw))


@pytest.fixture(scope="module")
def tight_400(tight):
    return cycle(tight, amplitude_n=400.0, mu=0.2)


@pytest.fixture(scope="module")
def loose_400(loose):
    return cycle(loose, 0.1, amplitude_n=400.0, mu=0.2)


@pytest.mark.parametrize("which", ["tight_400", "loose_400"], ids=["clearance-0", "clearance-0.1"])
def test_energy_balance_friction_work_equals_loop_area(which, request):
    m = request.getfixturevalue(which).metrics()
    assert m["W_cycle_Nmm"] > 0
    # the trapezoidal identity is exact step by step: 2.7e-15 / 1.0e-14 reached (Δr 0 / 0.1)
    assert m["energy_balance_rel_err"] < 1e-12


def test_loop_closes_and_eta_is_the_papers_definition(tight_400):
    m = tight_400.metrics()
    assert abs(m["loop_closure_mm"]) < 1e-3 * m["delta_max_mm"]
    assert m["eta"] == pytest.approx(
        m["W_cycle_Nmm"] / (2 * math.pi * 0.5 * 400.0 * m["delta_max_mm"])
    )
    assert 0.0 < m["eta"] < 1.0


def test_no_friction_no_loop(tight, tight_400):
    frictionless = cycle(tight, amplitude_n=400.0, mu=0.0).metrics()
    assert frictionless["eta"] < 0.01 * tight_400.metrics()["eta"]


def test_eta_independent_of_amplitude_at_zero_clearance(tight, tight_400):
    # Zero clearance, Coulomb friction and linear elasticity are positively homogeneous:
    # scaling F scales every force and displacement, so η cannot change. Gaps taken from
    # the faceted mesh instead of the exact surfaces would break this.
    low = cycle(tight, amplitude_n=100.0, mu=0.2).metrics()
    assert low["eta"] == pytest.approx(tight_400.metrics()["eta"], rel=0.01)
    assert low["delta_max_mm"] == pytest.approx(tight_400.metrics()["delta_max_mm"] / 4, rel=0.01)


def test_eta_grows_with_friction(tight, tight_400):
    assert cycle(tight, amplitude_n=400.0, mu=0.1).metrics()["eta"] < tight_400.metrics()["eta"]


def test_force_control_and_pin_equilibrium(tight, tight_400):
    # The grip force recovered from the contact forces equals the prescribed F, and the
    # pin's 3-2-1 supports carry nothing: the pin really floats.
    cond = tight_400.configs[1]
    for inc, state in zip(tight_400.increments, tight_400.states, strict=True):
        assert grip_force(cond, np.asarray(state.p)) == pytest.approx(inc.force_n, abs=1e-6 * 400)
    state = tight_400.states[-1]
    u = displacement(tight, cond, np.asarray(state.p), np.asarray(state.alpha))
    assert support_reaction(tight, cond, np.asarray(state.p), u) < 1e-6 * 400.0
    strain = 0.5 * float(np.ravel(u) @ (tight.K @ np.ravel(u)))
    assert strain == pytest.approx(tight_400.increments[-1].elastic_energy, rel=1e-6)


def test_clearance_free_play_and_contact_near_the_load_line(loose_400):
    assert loose_400.free_play_mm == pytest.approx(0.4)
    _F, d_raw, _ = loose_400.loop_arrays(with_free_play=True)
    assert d_raw.max() - d_raw.min() > 0.4  # the raw loop spans the free play
    cond, state = loose_400.configs[1], loose_400.states[len(loose_400.increments) - 1]
    closed = np.asarray(state.p)[:, 0] > 0
    normals = cond.geo.frame[closed, 0]
    # tension: the pin bears on the tang's +x side and on the clevis' −x side, so every
    # contact normal (into the hole) has a clear x component
    assert np.all(np.abs(normals[:, 0]) > 0.5)


def test_clearance_lowers_eta(tight_400, loose_400):
    assert loose_400.metrics()["eta"] < tight_400.metrics()["eta"]


def test_more_cycles_report_shakedown(tight):
    res = cycle(tight, amplitude_n=400.0, mu=0.2, n_cycles=2, increments_per_stage=6)
    m = res.metrics()
    assert len(res.work_per_cycle()) == 2
    assert m["W_change_last_two_cycles_rel"] < 0.05
    assert m["reported_cycle"] == 2


def test_failed_increment_is_cut_back_then_raises_with_partial_loop(tight):
    with pytest.raises(ConvergenceError) as info:
        cycle(tight, amplitude_n=400.0, mu=0.2, max_iter=1, max_cutbacks=1)
    err = info.value
    assert isinstance(err.partial, CycleResult)
    assert err.increment == len(err.partial.increments)
    assert "increment" in str(err)
    assert "residual" in str(err)


@pytest.mark.parametrize(
    ("kw", "name"),
    [
        ({"amplitude_n": -5.0}, "amplitude_n"),
        ({"mu": -0.1}, "mu"),
        ({"increments_per_stage": 1}, "increments"),
    ],
    ids=["negative-amplitude", "negative-mu", "one-increment"],
)
def test_bad_settings_name_themselves(kw, name):
    with pytest.raises(ParameterError, match=name):
        CycleSettings(**kw)


def test_contact_window_changes_nothing_but_the_cost(loose, loose_400):
    windowed = cycle(loose, 0.1, amplitude_n=400.0, mu=0.2, contact_window=0.5)
    full = (
        loose_400
        if loose_400.settings.contact_window == 0
        else cycle(loose, 0.1, amplitude_n=400.0, mu=0.2, contact_window=0.0)
    )
    assert len(windowed.configs[1].geo.slave) < 0.6 * len(full.configs[1].geo.slave)
    assert windowed.metrics()["eta"] == pytest.approx(full.metrics()["eta"], rel=1e-6)
    assert windowed.metrics()["disp_at_peak_mm"] == pytest.approx(
        full.metrics()["disp_at_peak_mm"], rel=1e-6
    )


def test_too_small_contact_window_is_caught(loose):
    with pytest.raises(ConvergenceError, match="contact window too small") as info:
        cycle(loose, 0.1, amplitude_n=500.0, mu=0.2, contact_window=1e-5)
    assert isinstance(info.value.partial, CycleResult)
    assert info.value.residual > 0


def test_machine_path_crosses_the_free_play_at_zero_force(loose_400):
    # defect: a loop with the free play added but no zero-force traverse counted a
    # spurious F·4Δr trapezoid at every side change (35x the true work in compare)
    def work(F, d):
        return float(np.sum(0.5 * (F[1:] + F[:-1]) * np.diff(d)))

    F, d, _ = loose_400.loop_arrays()
    F_raw, d_raw = loose_400.machine_path()
    assert work(F_raw, d_raw) == pytest.approx(work(F, d), rel=1e-9)
    assert np.ptp(d_raw) > loose_400.free_play_mm
    assert np.all(
        F_raw[np.abs(np.diff(d_raw, prepend=d_raw[0])) > 0.5 * loose_400.free_play_mm] == 0.0
    )


def test_the_condensed_W_is_frozen_so_the_solver_checks_it_once(tight_400):
    """Nothing may write into the hinge's W (its caches trust it): read-only, owning its data."""
    from fe.contact.state import _unwritable

    W = tight_400.configs[1].W
    assert not W.flags.writeable
    assert _unwritable(W)
    with pytest.raises(ValueError, match="read-only"):
        W[0, 0] = 0.0
