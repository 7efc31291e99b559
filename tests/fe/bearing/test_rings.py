"""Five-DOF ring equilibrium (fe.bearing.rings) against closed forms and invariances.

* pure axial load on one bearing: the 1-D Jones solution of fe.bearing.pair (a separate
  code path: a scalar root of Jones' equation vs the vector equilibrium of all balls);
* pure radial load on a zero-clearance radial bearing (α0 = 0): δ_n(ψ) = δ_r cos ψ exactly,
  so F_r = K_n δ_r^{3/2} Σ_{cos ψ>0} cos^{5/2} ψ (Stribeck's sum; Z Q_max/F_r = 4.38 at Z = 10);
* conservation: the ball loads, resolved from (Q, α, ψ) alone, sum to the applied load;
* symmetry: rotating the load by 2π/Z rolls the ball loads by one ball, mirroring it about
  the x axis mirrors them; the stiffness matrix is symmetric and the derivative of f(x).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cad.bearing_geometry import BearingHingeParams
from cad.errors import ConvergenceError, ParameterError
from fe.bearing.pair import (
    axial_state_from_load,
    bearing_from_params,
    contact_constants,
    liftoff_load,
    pair_axial,
)
from fe.bearing.rings import MountedBearing, pair_from_params, ring_forces, solve_ring

B708 = bearing_from_params(BearingHingeParams())
PAIR_100 = pair_from_params(BearingHingeParams(preload_n=100.0))


def resultant_from_balls(mounted, eq):
    """Σ Q (cos α e_r + σ sin α e_z) and its moment about the origin, from ball data only."""
    total = np.zeros(5)
    for m, balls in zip(mounted, eq.balls, strict=True):
        b = m.bearing
        half = (b.inner_curvature_ratio - 0.5) * b.ball_diameter_mm
        r_i = 0.5 * b.pitch_diameter_mm + half * math.cos(b.free_angle_rad)
        z_i = m.z_mm + m.direction * half * math.sin(b.free_angle_rad)
        a = np.radians(balls.contact_angle_deg)
        psi = balls.azimuth_rad
        f = balls.load_n[:, None] * np.column_stack(
            [np.cos(a) * np.cos(psi), np.cos(a) * np.sin(psi), m.direction * np.sin(a)]
        )
        p = np.column_stack([r_i * np.cos(psi), r_i * np.sin(psi), np.full(psi.size, z_i)])
        total[:3] += f.sum(axis=0)
        total[3:] += np.cross(p, f).sum(axis=0)[:2]
    return total


@pytest.mark.parametrize("fa", [5.0, 100.0, 400.0])
def test_single_bearing_under_axial_load_matches_jones(fa):
    single = [MountedBearing(B708, 1.0, 0.0)]
    eq = solve_ring(single, [0.0, 0.0, fa, 0.0, 0.0])
    ref = axial_state_from_load(B708, fa)
    assert eq.displacement[2] == pytest.approx(ref.axial_deflection_mm, rel=1e-10)
    assert np.abs(eq.displacement[[0, 1, 3, 4]]).max() < 1e-12
    np.testing.assert_allclose(eq.balls[0].load_n, ref.ball_load_n, rtol=1e-10)
    np.testing.assert_allclose(eq.balls[0].contact_angle_deg, ref.contact_angle_deg, rtol=1e-10)
    assert eq.stiffness[2, 2] == pytest.approx(ref.stiffness_n_per_mm, rel=1e-8)


@pytest.mark.parametrize("fr", [50.0, 400.0])
def test_radial_bearing_matches_stribeck_sum(fr):
    radial = dataclasses.replace(B708, contact_angle_deg=0.0)
    eq = solve_ring([MountedBearing(radial, 1.0, 0.0)], [fr, 0.0, 0.0, 0.0, 0.0])
    z = radial.ball_count
    psi = 2 * np.pi * np.arange(z) / z
    cos_psi = np.cos(psi)
    s = np.sum(np.where(cos_psi > 0, np.clip(cos_psi, 0, None) ** 2.5, 0.0))
    k_n = contact_constants(radial).ball
    delta_r = (fr / (k_n * s)) ** (2 / 3)
    assert eq.displacement[0] == pytest.approx(delta_r, rel=1e-10)
    q_ref = k_n * np.clip(delta_r * cos_psi, 0, None) ** 1.5
    np.testing.assert_allclose(eq.balls[0].load_n, q_ref, rtol=1e-9, atol=1e-9 * fr)
    assert z * eq.balls[0].load_n.max() / fr == pytest.approx(z / s, rel=1e-9)
    assert z / s == pytest.approx(4.379, abs=1e-3)


LOADS = {
    "radial": [400.0, 0.0, 0.0, 0.0, 0.0],
    "axial": [0.0, 0.0, -150.0, 0.0, 0.0],
    "combined": [300.0, -120.0, 60.0, 900.0, -400.0],
}


@pytest.mark.parametrize("name", list(LOADS), ids=list(LOADS))
@pytest.mark.parametrize("fp", [0.0, 100.0], ids=["Fp=0", "Fp=100"])
def test_ball_loads_sum_to_the_applied_load(name, fp):
    mounted = pair_from_params(BearingHingeParams(preload_n=fp))
    eq = solve_ring(mounted, LOADS[name])
    got = resultant_from_balls(mounted, eq)
    np.testing.assert_allclose(got[:3], LOADS[name][:3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(got[3:], LOADS[name][3:], rtol=0, atol=1e-9 * 7.5)


def test_rotating_the_load_by_one_ball_pitch_rolls_the_ball_loads():
    load = np.array([300.0, 50.0, 20.0, 0.0, 0.0])
    turn = 2 * np.pi / B708.ball_count
    c, s = np.cos(turn), np.sin(turn)
    rotated = load.copy()
    rotated[:2] = [c * load[0] - s * load[1], s * load[0] + c * load[1]]
    a, b = solve_ring(PAIR_100, load), solve_ring(PAIR_100, rotated)
    for qa, qb in zip(a.balls, b.balls, strict=True):
        np.testing.assert_allclose(np.roll(qa.load_n, 1), qb.load_n, rtol=1e-9, atol=1e-9)


def test_load_along_x_loads_the_balls_symmetrically_about_x():
    eq = solve_ring(PAIR_100, [400.0, 0.0, 0.0, 0.0, 0.0])
    for balls in eq.balls:
        mirrored = np.roll(balls.load_n[::-1], 1)  # ψ → −ψ
        np.testing.assert_allclose(balls.load_n, mirrored, rtol=1e-9, atol=1e-9)
    # DF pair, load midway: both bearings alike, no tilt, inner rings stay at δ_z = σ_0 δ_p.
    np.testing.assert_allclose(eq.balls[0].load_n, eq.balls[1].load_n, rtol=1e-9)
    assert np.abs(eq.displacement[3:]).max() < 1e-12


@pytest.mark.parametrize("fp", [50.0, 100.0, 200.0])
def test_preloaded_pair_at_rest_matches_the_axial_pair(fp):
    mounted = pair_from_params(BearingHingeParams(preload_n=fp))
    eq = solve_ring(mounted, np.zeros(5))
    ref = axial_state_from_load(B708, fp)
    for balls in eq.balls:
        np.testing.assert_allclose(balls.load_n, ref.ball_load_n, rtol=1e-10)
    assert eq.displacement[2] == pytest.approx(mounted[0].direction * ref.axial_deflection_mm)
    assert eq.stiffness[2, 2] == pytest.approx(pair_axial(B708, fp, 0.0).stiffness_n_per_mm)


def test_external_axial_load_on_the_pair_matches_the_axial_pair_and_lifts_off():
    ref = pair_axial(B708, 100.0, 150.0)
    eq = solve_ring(PAIR_100, [0.0, 0.0, 150.0, 0.0, 0.0])
    at_rest = solve_ring(PAIR_100, np.zeros(5)).displacement[2]
    assert eq.displacement[2] - at_rest == pytest.approx(ref.displacement_mm, rel=1e-9)
    np.testing.assert_allclose(eq.balls[1].load_n, ref.loaded.ball_load_n, rtol=1e-9)
    np.testing.assert_allclose(eq.balls[0].load_n, ref.unloaded.ball_load_n, rtol=1e-9)
    lift = solve_ring(PAIR_100, [0.0, 0.0, liftoff_load(B708, 100.0), 0.0, 0.0])
    assert lift.balls[0].load_n.max() < 1e-9 * lift.balls[1].load_n.max()


def test_stiffness_is_symmetric_and_the_derivative_of_the_ball_forces():
    x = solve_ring(PAIR_100, LOADS["combined"]).displacement
    _, s, _ = ring_forces(PAIR_100, x)
    np.testing.assert_allclose(s, s.T, rtol=1e-12, atol=1e-12 * np.abs(s).max())
    steps = np.array([1e-7, 1e-7, 1e-7, 1e-8, 1e-8])
    fd = np.empty((5, 5))
    for j in range(5):
        e = np.zeros(5)
        e[j] = steps[j]
        fd[:, j] = (ring_forces(PAIR_100, x + e)[0] - ring_forces(PAIR_100, x - e)[0]) / (
            2 * steps[j]
        )
    np.testing.assert_allclose(s, fd, rtol=1e-6, atol=1e-6 * np.abs(s).max())


def test_bad_input_names_the_parameter():
    with pytest.raises(ParameterError, match="direction"):
        MountedBearing(B708, 0.0, 0.0)
    with pytest.raises(ParameterError, match="load"):
        solve_ring(PAIR_100, [1.0, 2.0])
    with pytest.raises(ParameterError, match="mounted"):
        solve_ring([], np.zeros(5))


def test_unreachable_tolerance_raises_with_iteration_and_residual():
    with pytest.raises(ConvergenceError, match="iteration") as err:
        solve_ring(PAIR_100, LOADS["combined"], tol_n=1e-30, max_newton=2)
    assert err.value.residual > 0.0
