"""Hertz line contact: the FE + contact stack against the closed form (plane strain).

A cylinder of radius R is pressed on a flat by a force P' per unit length, frictionless
(μ = 0). Hertz (Johnson, *Contact Mechanics*, 1985, §4.2, eqs 4.43–4.45)::

    a  = sqrt(4 P' R / (π E*)),   p0 = 2 P' / (π a),   p(x) = p0 sqrt(1 − x²/a²),
    1/E* = (1 − ν1²)/E1 + (1 − ν2²)/E2.

Model (tests/fe/contact_meshes.py): two bodies, one element thick in z with u_z = 0 on
every node, which is exactly plane strain (all nodes lie on the two end faces). The
cylinder body's bottom face lies on the circle; the flat's top face is the exact Plane
master. The cylinder's top is a rigid grip driven by the force P (force control through
the rigid amplitude of ``solve_increment``), the flat's bottom is clamped.

Half-space assumption: R/a = 50 (or 20) and both bodies span |x| <= 20 a (15 a) and are
20 a (15 a) tall. Resolution: a uniform x grid of h = a/20.4 over |x| <= 1.5 a (about 41
slave nodes across 2a); 20.4 rather than 20 so the Hertz edge does not sit on a node,
which would flatter the edge bracket below.

Measurements (from the z = 0 row of slave nodes; the z = h row is identical):

* Nodal pressure ``p_i = p_n,i / A_i`` with ``A_i`` the slave nodal area. The nodal force
  is the consistent ``∫ p N_i dA``, so at the centre ``p_n/A`` differs from the point
  value p0 only by the local curvature term ≈ (h/a)²/12 ≈ 0.02 %.
* Peak pressure: the largest nodal pressure (the centre node).
* Half-width, two ways. (1) The ellipse fit: ``p² = p0² − (p0²/a²) x²`` is linear in x²,
  so a least-squares line through (x_i², p_i²) over the closed nodes gives a. The
  outermost closed node on each side is left out: its nodal force integrates the square-
  root edge and is not a point value. With ~37 nodes the fit averages out node-level
  scatter; its error is that of the FE pressure itself. (2) The discrete edge: on each
  side the edge lies between the last closed node x_c (p_n > 0) and the first open node
  x_o; we take the midpoint, whose own resolution error is at most h/2 = 2.5 % of a,
  half the 5 % tolerance.

Measured (41 closed nodes per row): steel on aluminium, R = 50 mm: p0 +0.09 % (fit
+0.11 %), a −0.22 % (fit), +0.49 % (edge midpoint); steel on steel, R = 20 mm: p0 +0.15 %
(fit +0.17 %), a −0.31 % (fit), +0.49 % (edge midpoint). About 3 s per case.
"""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from cad.materials import Material
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState
from fe.structure.twobody import displacement, external_response, free_gap
from tests.fe.contact_meshes import CylinderOnFlat, plane_strain_modulus, press_rig

STEEL = Material("steel", 210_000.0, 0.30)
ALUMINIUM = Material("aluminium", 71_000.0, 0.33)
A_HERTZ_MM = 1.0  # the load is chosen so that the Hertz half-width is 1 mm
TOL = 0.05


def hertz_line(load_n_per_mm: float, radius_mm: float, e_star_mpa: float) -> tuple[float, float]:
    """Return (a [mm], p0 [MPa]) of the plane-strain Hertz line contact."""
    a = np.sqrt(4.0 * load_n_per_mm * radius_mm / (np.pi * e_star_mpa))
    return float(a), float(2.0 * load_n_per_mm / (np.pi * a))


def ellipse_fit(x: np.ndarray, p: np.ndarray) -> tuple[float, float]:
    """Least-squares (a, p0) from p² = p0² (1 − x²/a²) over the given nodes."""
    A = np.column_stack([np.ones_like(x), x**2])
    (c0, c1), *_ = np.linalg.lstsq(A, p**2, rcond=None)
    return float(np.sqrt(-c0 / c1)), float(np.sqrt(c0))


def check_displacement_control(rig, state):
    """Prescribing the grip displacement found under force control gives the same forces.

    Also checks that the recovered displacement field reproduces the contact gaps.
    """
    u = displacement(rig.system, rig.cond, state.p, fields=rig.grip[:, 1:], alpha=state.alpha)
    w = free_gap(rig.cond, np.ravel(u))
    np.testing.assert_allclose(w[:, 0], state.w[:, 0], rtol=0, atol=1e-9 * np.ptp(state.w[:, 0]))
    fixed_y = np.isin(rig.system.fixed, 3 * rig.mesh.set_nodes("cyl_top") + 1)
    u_ext = external_response(rig.system, u_fixed=np.where(fixed_y, state.alpha[0], 0.0))
    res = solve_increment(
        rig.cond.W,
        free_gap(rig.cond, u_ext),
        ContactState.initial(len(rig.x)),
        ContactSettings(mu=0.0),
    )
    np.testing.assert_allclose(res.state.p, state.p, rtol=0, atol=1e-7 * state.p[:, 0].max())


CASES = {
    "steel-on-aluminium-R50": (50.0, 20.0, STEEL, ALUMINIUM),
    "steel-on-steel-R20": (20.0, 15.0, STEEL, STEEL),
}


@pytest.mark.parametrize("case", CASES.values(), ids=CASES.keys())
def test_hertz_line_contact_size_and_peak_pressure(case):
    radius, size, cyl_mat, flat_mat = case
    a_h = A_HERTZ_MM
    h = a_h / 20.4
    params = CylinderOnFlat(
        radius_mm=radius,
        h_mm=h,
        fine_half_width_mm=1.5 * a_h,
        fine_depth_mm=0.5 * a_h,
        half_width_mm=size * a_h,
        height_mm=size * a_h,
        contact_half_width_mm=2.0 * a_h,
        growth=1.15,
        cylinder=cyl_mat,
        flat=flat_mat,
    )
    e_star = plane_strain_modulus(cyl_mat, flat_mat)
    load = np.pi * e_star * a_h**2 / (4.0 * radius)  # P' [N/mm]
    a_ref, p0_ref = hertz_line(load, radius, e_star)
    assert a_ref == pytest.approx(a_h, rel=1e-12)
    with threadpool_limits(1, user_api="blas"):
        rig = press_rig(params)
        m = len(rig.x)
        res = solve_increment(
            rig.cond.W,
            rig.cond.w0,
            ContactState.initial(m, 1),
            ContactSettings(mu=0.0),
            G=rig.G[:, 1:],  # vertical grip only: frictionless, no x stiffness
            e=np.array([load * h]),  # the slice is h thick
        )
        check_displacement_control(rig, res.state)
    p_n = res.state.p[:, 0]
    assert p_n.sum() == pytest.approx(load * h, rel=1e-9)

    row = np.flatnonzero(rig.z == 0.0)
    row = row[np.argsort(rig.x[row])]
    x, pressure = rig.x[row], p_n[row] / rig.cond.geo.area_mm2[row]
    closed = np.flatnonzero(pressure > 0.0)
    assert np.all(np.diff(closed) == 1), "the contact must be one connected patch"
    # a connected patch symmetric about x = 0 (both rows of the slice see the same pressure)
    np.testing.assert_allclose(pressure, pressure[::-1], rtol=1e-6, atol=1e-9 * p0_ref)

    p0_fe = float(pressure.max())
    a_fit, p0_fit = ellipse_fit(x[closed[1:-1]], pressure[closed[1:-1]])
    edge_right = 0.5 * (x[closed[-1]] + x[closed[-1] + 1])
    edge_left = -0.5 * (x[closed[0]] + x[closed[0] - 1])
    assert p0_fe == pytest.approx(p0_ref, rel=TOL)
    assert p0_fit == pytest.approx(p0_ref, rel=TOL)
    assert a_fit == pytest.approx(a_ref, rel=TOL)
    assert edge_right == pytest.approx(a_ref, rel=TOL)
    assert edge_left == pytest.approx(a_ref, rel=TOL)
