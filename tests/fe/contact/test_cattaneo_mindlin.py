"""Cattaneo–Mindlin partial slip of a line contact: dissipation per tangential load cycle.

A cylinder (radius R) is pressed on a flat of the same material by a constant normal
force P' per unit length, then a tangential force Q' is cycled 0 → +Q* → −Q* → +Q*
with Q* = 0.5 μP' (force control on the cylinder's rigid grip; model and plane-strain
slice as in tests/fe/test_hertz.py and tests/fe/contact_meshes.py).

Closed form (identical materials, so the normal and tangential problems uncouple; Dundurs
β = 0). Cattaneo's 2-D solution (Johnson, *Contact Mechanics*, 1985, ch. 7, incipient
sliding of cylinders): the stick zone is |x| < c with ``(c/a)² = 1 − Q/(μP')``, the
shear ``q(x) = μ p0 [√(1 − x²/a²) − (c/a) √(1 − x²/c²)]`` (second term only for |x| < c),
and the half-plane kernel gives the relative slip in c < |x| < a (p0/(a E*) = 1/(2R))::

    s_c(x) = (μ / 2R) [ |x| √(x² − c²) − c² arccosh(|x|/c) ].

Mindlin–Deresiewicz (Johnson ch. 7, oscillating tangential force): reversing from Q* to
Q superposes a Cattaneo solution with 2μ and Q* − Q; at Q = −Q* the reverse stick zone
is c* again, so one half cycle dissipates ``D = 2 ∫_{c*}^{a} μ p(x) · 2 s_{c*}(x) dx`` and
the cycle ``ΔW = 2 D``. The familiar closed form (Mindlin & Deresiewicz 1953, quoted in
Johnson ch. 7) is for spheres and does not apply here; for the line contact it follows
from the nonlinear part of the grip displacement, ``δ_nl(Q) = (μP'/(πE*)) κ ln κ`` with
``κ = 1 − Q/(μP')`` (from ∫ q ln|x| dx; the part linear in Q, which depends on the body
size in 2-D, encloses no area), and Masing's rule ``ΔW = 4 Q* δ(Q*) − 8 ∫_0^{Q*} δ dQ``::

    ΔW / length = (2 μ² P'² / (π E*)) [2q − q² + 2 (1 − q) ln(1 − q)],   q = Q*/(μP'),

which tends to 2 Q*³ / (3 π E* μ P') for small q. ``test_closed_form_equals_slip_integral``
checks the two forms against each other by quadrature. ΔW does not depend on R or a, so
scaling P' and Q* by s scales it by s² exactly.

Measurements: ΔW_fe is the friction work ``Σ_points Σ_increments friction_work`` over the
closed loop +Q* → −Q* → +Q*; independently, the loop area ``∮ Q dδ`` from the grip's
tangential displacement δ = α_x (trapezoidal). The contact solver's trapezoidal works
satisfy the energy balance exactly when the loop closes, so the two agree to ~1e-6
(P' is constant and the normal grip displacement returns to within 1e-9 mm).

Resolution: h = a/40.8 over |x| <= 1.5 a (about 82 slave nodes across 2a, ~12 in each slip
zone at q = 0.5), bodies 40 a wide and tall, 20 force increments per quarter cycle.
Measured: ΔW_fe/ΔW = 0.9962 (s = 1) and 0.9961 (s = 2), so ΔW(2)/ΔW(1) = 4 × 0.9999;
friction work / loop area − 1 = 4e-6; stick half-width c +0.5 %. The same at 20 a:
0.991/0.988, at 10 a: 0.972/0.954 (the finite body, not the mesh, dominates and grows with a/L); at
h = a/20.4, 20 a: 1.0105/0.9928. Increments per quarter at h = a/20.4: 5/10/20/40 give
1.002/1.009/1.0105/1.0108.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest
from scipy.integrate import quad
from threadpoolctl import threadpool_limits

from cad.materials import Material
from fe.contact.law import ContactStatus
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState
from tests.fe.contact_meshes import CylinderOnFlat, PressRig, plane_strain_modulus, press_rig

STEEL = Material("steel", 210_000.0, 0.30)
RADIUS_MM = 50.0
A_HERTZ_MM = 1.0  # Hertz half-width at scale s = 1
MU = 0.3
Q_RATIO = 0.5  # Q* / (μ P')
H_MM = A_HERTZ_MM / 40.8
STEPS_PER_QUARTER = 20
E_STAR = plane_strain_modulus(STEEL, STEEL)
LOAD_N_PER_MM = np.pi * E_STAR * A_HERTZ_MM**2 / (4.0 * RADIUS_MM)  # P' at s = 1


def dissipation_closed_form(mu, load, q, e_star):
    """Mindlin–Deresiewicz ΔW per cycle per unit length of a line contact [N·mm/mm]."""
    return 2.0 * mu**2 * load**2 / (np.pi * e_star) * (2 * q - q**2 + 2 * (1 - q) * np.log(1 - q))


def dissipation_slip_integral(mu, load, q, e_star, radius):
    """The same ΔW by integrating μ p |Δs| over the slip zones (module docstring)."""
    a = np.sqrt(4.0 * load * radius / (np.pi * e_star))
    p0 = 2.0 * load / (np.pi * a)
    c = a * np.sqrt(1.0 - q)

    def work_density(x):
        slip = mu / radius * (x * np.sqrt(x * x - c * c) - c * c * np.arccosh(x / c))  # 2 s_c
        return mu * p0 * np.sqrt(1.0 - (x / a) ** 2) * slip

    half_cycle = 2.0 * quad(work_density, c, a)[0]  # both slip zones
    return 2.0 * half_cycle


@pytest.mark.parametrize("q", [0.1, 0.5, 0.9], ids=["q0.1", "q0.5", "q0.9"])
def test_closed_form_equals_slip_integral(q):
    closed = dissipation_closed_form(MU, LOAD_N_PER_MM, q, E_STAR)
    integral = dissipation_slip_integral(MU, LOAD_N_PER_MM, q, E_STAR, RADIUS_MM)
    assert closed == pytest.approx(integral, rel=1e-7)


class Cycle(NamedTuple):
    friction_work: float  # over the closed loop, summed over points [N·mm]
    loop_area: float  # ∮ Q dδ over the closed loop [N·mm]
    stick_half_width: float  # at +Q* on first loading [mm]
    normal_drift: float  # grip normal displacement change over the loop [mm]
    max_p_t2: float  # largest |p_t2| ever (locked plane-strain direction) [N]


def tangential_cycle(rig: PressRig, load: float, q: float, steps: int) -> Cycle:
    """Press with P = load·h, then cycle Q = 0 → Q* → −Q* → Q*, Q* = q μ P."""
    P = load * H_MM
    Q = q * MU * P
    m = len(rig.x)
    settings = ContactSettings(mu=MU)
    state = ContactState.initial(m, 2, w=rig.cond.w0)
    normal = [(0.0, P * k / 4) for k in range(1, 5)]
    tangential = np.concatenate(
        [
            np.linspace(0.0, Q, steps + 1)[1:],
            np.linspace(Q, -Q, 2 * steps + 1)[1:],
            np.linspace(-Q, Q, 2 * steps + 1)[1:],
        ]
    )
    history = [(Qk, P) for Qk in tangential]
    Qs, deltas, works, max_t2 = [], [], [], 0.0
    stick = None
    with threadpool_limits(1, user_api="blas"):
        for k, (Qk, Pk) in enumerate(normal + history):
            e = np.array([-Qk, Pk])  # Gᵀp = −(grip force on the cylinder)
            res = solve_increment(rig.cond.W, rig.cond.w0, state, settings, G=rig.G, e=e)
            state = res.state
            max_t2 = max(max_t2, float(np.abs(state.p[:, 2]).max()))
            i = k - len(normal)
            if i == steps - 1:  # +Q* on first loading
                stick = state.status == ContactStatus.STICK
            if i >= steps - 1:  # the closed loop starts at +Q*
                Qs.append(Qk)
                deltas.append(state.alpha)
                if i >= steps:
                    works.append(res.friction_work.sum())
    d = np.asarray(deltas)
    Qa = np.asarray(Qs)
    loop = float(np.sum(0.5 * (Qa[1:] + Qa[:-1]) * np.diff(d[:, 0])))
    return Cycle(
        friction_work=float(np.sum(works)),
        loop_area=loop,
        stick_half_width=_edge(rig, stick),
        normal_drift=float(d[-1, 1] - d[0, 1]),
        max_p_t2=max_t2,
    )


def _edge(rig: PressRig, inside: np.ndarray) -> float:
    """Half-width of a centred node set on the z = 0 row: midpoint to the next node out."""
    row = np.flatnonzero(rig.z == 0.0)
    row = row[np.argsort(rig.x[row])]
    idx = np.flatnonzero(inside[row])
    x = rig.x[row]
    return 0.25 * ((x[idx[-1]] + x[idx[-1] + 1]) - (x[idx[0]] + x[idx[0] - 1]))


@pytest.fixture(scope="module")
def rig():
    params = CylinderOnFlat(
        radius_mm=RADIUS_MM,
        h_mm=H_MM,
        fine_half_width_mm=1.5 * A_HERTZ_MM,
        fine_depth_mm=0.5 * A_HERTZ_MM,
        half_width_mm=40.0 * A_HERTZ_MM,
        height_mm=40.0 * A_HERTZ_MM,
        contact_half_width_mm=2.0 * A_HERTZ_MM,
        growth=1.15,
        cylinder=STEEL,
        flat=STEEL,
    )
    with threadpool_limits(1, user_api="blas"):
        return press_rig(params)


@pytest.fixture(scope="module")
def cycles(rig):
    return {
        s: tangential_cycle(rig, s * LOAD_N_PER_MM, Q_RATIO, STEPS_PER_QUARTER) for s in (1.0, 2.0)
    }


def test_dissipation_per_cycle_matches_mindlin_deresiewicz(cycles):
    cyc = cycles[1.0]
    expected = dissipation_closed_form(MU, LOAD_N_PER_MM, Q_RATIO, E_STAR) * H_MM
    assert cyc.friction_work == pytest.approx(expected, rel=0.10)
    assert cyc.loop_area == pytest.approx(expected, rel=0.10)


def test_friction_work_equals_loop_area(cycles):
    for cyc in cycles.values():
        assert cyc.friction_work == pytest.approx(cyc.loop_area, rel=0.02)
        assert abs(cyc.normal_drift) < 1e-6 * A_HERTZ_MM


def test_stick_zone_matches_cattaneo(cycles):
    c_expected = A_HERTZ_MM * np.sqrt(1.0 - Q_RATIO)
    # midpoint between the last sticking and first slipping node: resolution h/2 = 1.7 % of c
    assert cycles[1.0].stick_half_width == pytest.approx(c_expected, rel=0.05)


def test_plane_strain_direction_carries_no_force(cycles):
    for cyc in cycles.values():
        assert cyc.max_p_t2 == 0.0


def test_dissipation_scales_with_load_squared(cycles):
    ratio = cycles[2.0].friction_work / cycles[1.0].friction_work
    assert ratio == pytest.approx(4.0, rel=0.01)
