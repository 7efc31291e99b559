"""The bearing hinge's cycle with ``hertz`` balls (fe.bearing.system, fe.bearing.cycle).

Two kinds of check:

* the ball model and the solver against the independent closed forms of ``fe.bearing.pair``
  (Jones' equation for a preloaded pair) and ``fe.bearing.rings`` (5-DOF ring equilibrium),
  with the structure made rigid (``W = 0``), where they must agree to solver precision;
* the condensed FE structure (coarse mesh): equilibrium, rigid grip, zero dissipation, a
  loop without area, and what the structure's compliance adds to the balls'.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cad.bearing import make_bearing_hinge, without_balls
from cad.bearing_geometry import BearingHingeParams
from cad.errors import ConvergenceError, ParameterError
from fe.bearing.balls import GRIP_X, ball_law, solve_state
from fe.bearing.cycle import run_bearing_cycle
from fe.bearing.loading import preload_step
from fe.bearing.pair import axial_state_from_load, bearing_from_params
from fe.bearing.rings import pair_from_params, solve_ring
from fe.bearing.system import BearingSystem, build_bearing_system
from fe.cycle.protocol import CycleSettings
from fe.cycle.result import CycleResult
from fe.kinds import hinge_kind
from mesh.build import mesh_hinge

COARSE = {"size_mm": 4.0, "contact_size_mm": 0.8, "part_sizes_mm": (("ring", 1.2),)}
"""A 40k-node structure built in ~7 s (the default mesh: 62k nodes, ~12 s)."""


@pytest.fixture(scope="module")
def system() -> BearingSystem:
    p = BearingHingeParams()
    mesh, _ = mesh_hinge(
        without_balls(make_bearing_hinge(p)),
        hinge_kind("bearing").mesh_settings(**COARSE),
    )
    return build_bearing_system(mesh, p)


@pytest.fixture(scope="module")
def rigid(system: BearingSystem) -> BearingSystem:
    """The same balls in a rigid structure: only the closed-form ball law remains."""
    return dataclasses.replace(system, W=np.zeros_like(system.W))


@pytest.mark.parametrize("fp", [50.0, 100.0, 200.0])
def test_rigid_preload_matches_jones_pair(rigid: BearingSystem, fp: float) -> None:
    """Plate travel = 2 δ_a(F_p) and the contact angle of Jones' equation (independent code)."""
    pre = preload_step(rigid, fp)
    jones = axial_state_from_load(bearing_from_params(rigid.params), fp)
    assert pre.plate_travel_mm == pytest.approx(2 * jones.axial_deflection_mm, rel=1e-7)
    assert pre.balls.angle_deg == pytest.approx(jones.contact_angle_deg, abs=1e-6)
    assert pre.balls.load_n == pytest.approx(jones.ball_load_n, rel=1e-7)
    # the pin floats down by half the plate travel (both bearings alike)
    assert pre.axial_float_mm == pytest.approx(-jones.axial_deflection_mm, rel=1e-7)


@pytest.mark.parametrize(("fp", "fg"), [(0.0, 400.0), (100.0, 400.0), (200.0, -250.0)])
def test_rigid_radial_load_matches_ring_equilibrium(
    rigid: BearingSystem, fp: float, fg: float
) -> None:
    """δ_x and every ball load at a radial force equal the 5-DOF ring solution of the pair."""
    pre = preload_step(rigid, fp)
    st = solve_state(rigid, pre.balls.v_mm, pre.balls.alpha, (GRIP_X,), np.array([fg]),
                     ref_load_n=abs(fg))  # fmt: skip
    ring = solve_ring(
        pair_from_params(dataclasses.replace(rigid.params, preload_n=fp)),
        [fg, 0.0, 0.0, 0.0, 0.0],
    )
    assert st.alpha[GRIP_X] == pytest.approx(ring.displacement[0], rel=1e-6)
    Q_ring = np.concatenate([b.load_n for b in ring.balls])
    assert st.load_n == pytest.approx(Q_ring, rel=1e-6, abs=1e-6 * abs(fg))


def test_grip_moves_the_clevis_pin_and_inner_rings_rigidly(system: BearingSystem) -> None:
    u = system.fields[:, GRIP_X].reshape(-1, 3)
    for part in ("clevis", "pin", "inner_ring_0", "inner_ring_1"):
        nodes = system.mesh.part_nodes(part)
        assert u[nodes] == pytest.approx(np.tile([1.0, 0.0, 0.0], (len(nodes), 1)), abs=1e-9)
    for part in ("tang", "outer_ring_0", "outer_ring_1", "preload_plate"):
        assert np.abs(u[system.mesh.part_nodes(part)]).max() < 1e-12


def test_condensed_compliance_is_symmetric_positive_definite(system: BearingSystem) -> None:
    assert np.linalg.eigvalsh(system.W).min() > 0
    # the structure matters: its compliance is of the order of the balls' at the preload
    q = 30.0
    hertz = (q / system.balls.k_n) ** (2 / 3) / (1.5 * q)
    assert 0.05 * hertz < np.median(np.diag(system.W)) < 20 * hertz


def test_condensed_compliance_is_the_patch_rows_through_the_whole_solve(
    system: BearingSystem,
) -> None:
    """W from the solutions' rows at the DOFs the patches touch = ``B K⁻¹ Bᵀ`` from whole ones."""
    B_free = (system.B @ system.ties.T).tocsr()[:, system.free]
    X = system.factor.solve(B_free.T.toarray())  # every row of every solution
    W = np.asarray(B_free @ X)
    W = 0.5 * (W + W.T)
    np.testing.assert_allclose(system.W, W, rtol=0, atol=1e-12 * np.abs(W).max())


@pytest.fixture(scope="module")
def cycle_100(system: BearingSystem):  # type: ignore[no-untyped-def]
    return run_bearing_cycle(system, CycleSettings(amplitude_n=400.0), 100.0)


def test_ball_forces_balance_the_applied_load(system: BearingSystem, cycle_100) -> None:  # type: ignore[no-untyped-def]
    """Σ ball forces on the inner rings = the clevis force in x at every increment.

    In y and z the grip holds the clevis after the preload. In y the hinge is symmetric
    (only the mesh is not): the reaction is round-off of the mesh. In z it is not (the plate
    above, the tang's lip below): a radial load leaves a small axial reaction (1 % measured).
    """
    theta = system.balls.theta
    for inc, st in zip(cycle_100.result.increments, cycle_100.result.states, strict=True):
        f = ball_law(system.balls.d0, np.asarray(st.w[:, 1:]), system.balls.k_n)[0]
        assert np.sum(f[:, 0] * np.cos(theta)) == pytest.approx(inc.force_n, abs=1e-6)
        assert abs(np.sum(f[:, 0] * np.sin(theta))) < 1e-3 * 400.0
        assert abs(np.sum(f[:, 1])) < 3e-2 * 400.0


def test_preload_is_carried_by_both_bearings(cycle_100) -> None:  # type: ignore[no-untyped-def]
    pre = cycle_100.preload.balls
    n = len(pre.load_n) // 2
    sin_a = np.sin(np.radians(pre.angle_deg))
    assert np.sum(pre.load_n[n:] * sin_a[n:]) == pytest.approx(100.0, rel=1e-8)
    assert np.sum(pre.load_n[:n] * sin_a[:n]) == pytest.approx(100.0, rel=1e-8)
    assert cycle_100.preload.dissipation_Nmm == 0.0


def test_bonded_hertz_hinge_has_no_loop(cycle_100) -> None:  # type: ignore[no-untyped-def]
    """Nothing can dissipate: the loop area is quadrature error, tiny next to U_max."""
    m = cycle_100.result.metrics()
    assert abs(m["W_cycle_Nmm"]) < 1e-4 * m["U_max_Nmm"]
    assert m["friction_work_Nmm"] == 0.0
    assert abs(m["loop_closure_mm"]) < 1e-12


def test_no_preload_loop_area_converges_to_zero(system: BearingSystem) -> None:
    """Without preload F ∝ δ^{3/2} near 0; the refined crossing keeps the spurious area small
    and it falls with more increments (a quadrature error, not a dissipation)."""
    areas = []
    for n in (10, 40):
        c = run_bearing_cycle(system, CycleSettings(amplitude_n=300.0, increments_per_stage=n), 0.0)
        m = c.result.metrics()
        areas.append(abs(m["W_cycle_Nmm"]) / m["U_max_Nmm"])
    assert areas[0] < 1e-3
    assert areas[1] < areas[0] / 2


def test_response_is_not_linear_and_stiffens_with_preload(system: BearingSystem) -> None:
    """Hertz contacts break the homogeneity of the zero-clearance general hinge."""
    k = {}
    for fp in (0.0, 200.0):
        for fg in (100.0, 400.0):
            m = run_bearing_cycle(system, CycleSettings(amplitude_n=fg), fp).result.metrics()
            k[fp, fg] = m["secant_stiffness_N_per_mm"]
    assert k[0.0, 400.0] > 1.1 * k[0.0, 100.0]
    assert k[200.0, 100.0] > 1.2 * k[0.0, 100.0]


def test_preload_out_of_range_is_refused(system: BearingSystem) -> None:
    with pytest.raises(ParameterError, match=r"preload_n must be in \[0, 500\], got 600"):
        preload_step(system, 600.0)


def test_nonconverged_preload_names_the_step_iteration_and_residual(
    system: BearingSystem,
) -> None:
    with pytest.raises(ConvergenceError, match=r"preload step .* \(increment 0, iteration 2"):
        preload_step(system, 100.0, CycleSettings(max_iter=2))


def test_nonconverged_increment_is_cut_back_then_raises_with_the_partial_loop(
    system: BearingSystem, monkeypatch: pytest.MonkeyPatch
) -> None:
    import fe.bearing.cycle as cycle

    real = cycle.solve_state
    calls = []

    def failing_below_minus_200(*args, **kwargs):  # type: ignore[no-untyped-def]
        if args[3] == (GRIP_X,) and args[4][0] < -200.0:
            calls.append(args[4][0])
            raise ConvergenceError("forced", increment=-1, iteration=7, residual=1.0)
        return real(*args, **kwargs)

    monkeypatch.setattr(cycle, "solve_state", failing_below_minus_200)
    with pytest.raises(ConvergenceError, match=r"after 2 cut-backs.*iteration 7") as err:
        run_bearing_cycle(system, CycleSettings(amplitude_n=400.0, max_cutbacks=2), 100.0)
    partial = err.value.partial
    assert isinstance(partial, CycleResult)
    assert min(i.force_n for i in partial.increments) > -200.0
    assert len(partial.increments) > 10
    assert partial.preload_state is not None
    assert len(calls) == 3  # the full step, then halved twice, each failing below −200 N
