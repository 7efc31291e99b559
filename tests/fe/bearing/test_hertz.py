"""Hertz point contact (fe.bearing.hertz) against closed forms and the elasticity integral.

Independent references:
* circular contacts (sphere–plane, sphere–sphere, crossed equal cylinders): Johnson,
  *Contact Mechanics*, 1985, §4.2: a = (3QR/(4E*))^{1/3}, δ = a²/R, p0 = 3Q/(2πa²);
* the Boussinesq integral: the Hertz pressure p0·sqrt(1 − x²/b² − y²/a²) must produce a
  surface approach u(x, y) = δ − x²/(2R_x) − y²/(2R_y) inside the ellipse,
  u = (1/(πE*)) ∬ p dA'/|r − r'|, integrated here numerically (polar rays about the
  point, the ray integral of the square root in closed form) — it checks κ, a, b, δ and
  the curvature bookkeeping at once, by a route that shares no formula with the module;
* Hamrock & Brewe (1983): κ̄, K̄, Ē within 3.9 / 2.2 / 1.0 % of the exact values (the
  errors measured over 1 ≤ α_r ≤ 100; a, b, δ within 2.7, 1.2, 4.1 %);
* the small-m series F = 3m/8 + … and the exact ratio meet at the switch.
"""

from __future__ import annotations

import math

import pytest
from scipy.integrate import quad

from cad.errors import ParameterError
from cad.materials import GCR15, STEEL_45
from fe.bearing.hertz import (
    SERIES_LIMIT,
    ContactEllipse,
    Curvatures,
    EllipseMethod,
    Race,
    contact_ellipse,
    curvature_difference_from_ellipticity,
    effective_modulus,
    elliptic_factors_exact,
    elliptic_factors_hamrock_brewe,
    load_deflection_constant,
    race_curvatures,
)

E_STAR = effective_modulus(GCR15, GCR15)


def circular(q: float, radius: float, e_star: float) -> tuple[float, float, float]:
    a = (3.0 * q * radius / (4.0 * e_star)) ** (1.0 / 3.0)
    return a, a * a / radius, 3.0 * q / (2.0 * math.pi * a * a)


CIRCULAR_CASES = {
    "sphere-plane": (Curvatures((1 / 5.0, 1 / 5.0), (0.0, 0.0)), 5.0),
    "sphere-sphere": (Curvatures((1 / 5.0, 1 / 5.0), (1 / 20.0, 1 / 20.0)), 4.0),
    "sphere-in-cup": (Curvatures((1 / 5.0, 1 / 5.0), (-1 / 20.0, -1 / 20.0)), 20.0 / 3.0),
    "crossed-cylinders": (Curvatures((1 / 5.0, 0.0), (0.0, 1 / 5.0)), 5.0),
}


@pytest.mark.parametrize("name", list(CIRCULAR_CASES), ids=list(CIRCULAR_CASES))
@pytest.mark.parametrize("method", list(EllipseMethod), ids=[m.value for m in EllipseMethod])
def test_circular_contacts_reduce_to_the_circular_hertz_formulas(name, method):
    curv, radius = CIRCULAR_CASES[name]
    c = contact_ellipse(curv, E_STAR, 150.0, method)
    a, delta, p0 = circular(150.0, radius, E_STAR)
    assert c.semi_major_mm == pytest.approx(a, rel=1e-13)
    assert c.semi_minor_mm == pytest.approx(a, rel=1e-13)
    assert c.approach_mm == pytest.approx(delta, rel=1e-13)
    assert c.max_pressure_mpa == pytest.approx(p0, rel=1e-13)
    k_c = load_deflection_constant(curv, E_STAR, method)
    assert k_c == pytest.approx(4.0 / 3.0 * E_STAR * math.sqrt(radius), rel=1e-13)


def test_effective_modulus_of_two_materials():
    e_star = effective_modulus(GCR15, STEEL_45)
    inv = (1 - 0.3**2) / 208_000.0 + (1 - 0.31**2) / 210_000.0
    assert e_star == pytest.approx(1.0 / inv, rel=1e-15)


def _ray_integral(c0: float, c1: float, c2: float) -> float:
    """∫_0^{s1} sqrt(c0 + c1 s − c2 s²) ds, s1 the positive root (c0 > 0, c2 > 0)."""
    centre = c1 / (2.0 * c2)
    r2 = c0 / c2 + centre * centre
    r = math.sqrt(r2)
    t0 = -centre

    def prim(t: float) -> float:
        return 0.5 * (t * math.sqrt(max(r2 - t * t, 0.0)) + r2 * math.asin(t / r))

    return math.sqrt(c2) * (prim(r) - prim(t0))


def boussinesq_approach(c: ContactEllipse, b_axis_x: bool, x0: float, y0: float) -> float:
    """u(x0, y0) = (1/(πE*)) ∬ p dA/|r − r0| of the Hertz pressure of ``c``."""
    bx, by = (c.semi_minor_mm, c.semi_major_mm) if b_axis_x else (c.semi_major_mm, c.semi_minor_mm)
    p0 = c.max_pressure_mpa
    c0 = 1.0 - x0 * x0 / bx**2 - y0 * y0 / by**2

    def along(theta: float) -> float:
        ct, st = math.cos(theta), math.sin(theta)
        c1 = -2.0 * (x0 * ct / bx**2 + y0 * st / by**2)
        c2 = ct * ct / bx**2 + st * st / by**2
        return _ray_integral(c0, c1, c2)

    val, _ = quad(along, 0.0, 2.0 * math.pi, epsabs=0.0, epsrel=1e-9, limit=400)
    return p0 * val / (math.pi * E_STAR)


ELLIPTIC_CASES = {
    "708C-inner": race_curvatures(3.969, 15.0, 15.0, 0.52, Race.INNER),
    "708C-outer": race_curvatures(3.969, 15.0, 15.0, 0.53, Race.OUTER),
    "torus-mild": Curvatures((1 / 4.0, 1 / 6.0), (1 / 30.0, -1 / 40.0)),
}


@pytest.mark.parametrize("name", list(ELLIPTIC_CASES), ids=list(ELLIPTIC_CASES))
def test_hertz_pressure_produces_the_hertz_surface_approach(name):
    curv = ELLIPTIC_CASES[name]
    c = contact_ellipse(curv, E_STAR, 200.0)
    b_axis_x = curv.relative_1 > curv.relative_2  # minor axis lies in the stiffer plane
    r_x, r_y = 1.0 / curv.relative_1, 1.0 / curv.relative_2
    assert boussinesq_approach(c, b_axis_x, 0.0, 0.0) == pytest.approx(c.approach_mm, rel=1e-7)
    for fx, fy in ((0.5, 0.0), (0.0, 0.5), (0.4, 0.4)):
        x0 = fx * (c.semi_minor_mm if b_axis_x else c.semi_major_mm)
        y0 = fy * (c.semi_major_mm if b_axis_x else c.semi_minor_mm)
        expected = c.approach_mm - x0 * x0 / (2 * r_x) - y0 * y0 / (2 * r_y)
        got = boussinesq_approach(c, b_axis_x, x0, y0)
        assert got == pytest.approx(expected, rel=1e-7), (fx, fy)


@pytest.mark.parametrize("method", list(EllipseMethod), ids=[m.value for m in EllipseMethod])
def test_scaling_laws_are_exact(method):
    curv = ELLIPTIC_CASES["708C-inner"]
    c1 = contact_ellipse(curv, E_STAR, 10.0, method)
    c8 = contact_ellipse(curv, E_STAR, 80.0, method)
    assert c8.semi_major_mm / c1.semi_major_mm == pytest.approx(2.0, rel=1e-14)
    assert c8.semi_minor_mm / c1.semi_minor_mm == pytest.approx(2.0, rel=1e-14)
    assert c8.approach_mm / c1.approach_mm == pytest.approx(4.0, rel=1e-14)
    assert c8.max_pressure_mpa / c1.max_pressure_mpa == pytest.approx(2.0, rel=1e-14)
    k_c = load_deflection_constant(curv, E_STAR, method)
    for c in (c1, c8):
        assert c.load_n == pytest.approx(k_c * c.approach_mm**1.5, rel=1e-13)
        assert c.stiffness_n_per_mm == pytest.approx(1.5 * k_c * c.approach_mm**0.5, rel=1e-13)


def test_stiffness_is_the_derivative_of_the_load_deflection_curve():
    curv = ELLIPTIC_CASES["708C-outer"]
    h = 1e-3
    lo, hi = (contact_ellipse(curv, E_STAR, 100.0 + s * h) for s in (-1, 1))
    mid = contact_ellipse(curv, E_STAR, 100.0)
    fd = 2 * h / (hi.approach_mm - lo.approach_mm)
    assert mid.stiffness_n_per_mm == pytest.approx(fd, rel=1e-8)


def test_total_load_is_the_integral_of_the_pressure():
    """The ellipsoidal pressure over the contact ellipse, integrated by quadrature, is the load.

    Independent of the closed form's 2/3 π a b p_max: scipy's adaptive quadrature over the
    ellipse of p = p_max √(1 − x²/a² − y²/b²).
    """
    from scipy import integrate

    c = contact_ellipse(ELLIPTIC_CASES["708C-inner"], E_STAR, 200.0)
    a, b, p0 = c.semi_major_mm, c.semi_minor_mm, c.max_pressure_mpa
    total, _err = integrate.dblquad(
        lambda y, x: p0 * math.sqrt(max(0.0, 1.0 - (x / a) ** 2 - (y / b) ** 2)),
        -a,
        a,
        lambda x: -b * math.sqrt(max(0.0, 1.0 - (x / a) ** 2)),
        lambda x: b * math.sqrt(max(0.0, 1.0 - (x / a) ** 2)),
        epsrel=1e-10,
    )
    assert total == pytest.approx(200.0, rel=1e-7)


@pytest.mark.parametrize("kappa", [1.0001, 1.5, 3.0, 10.0, 40.0, 500.0])
def test_exact_ellipticity_inverts_the_hertz_equation(kappa):
    f = curvature_difference_from_ellipticity(kappa)
    assert elliptic_factors_exact(f).ellipticity == pytest.approx(kappa, rel=1e-10)


def test_series_and_exact_branches_meet_at_the_switch():
    kappa_series = elliptic_factors_exact(SERIES_LIMIT * (1 - 1e-9)).ellipticity
    kappa_exact = elliptic_factors_exact(SERIES_LIMIT * (1 + 1e-9)).ellipticity
    assert kappa_exact - 1 == pytest.approx(kappa_series - 1, rel=1e-6)
    assert elliptic_factors_exact(0.0).ellipticity == 1.0
    assert elliptic_factors_exact(3e-7).ellipticity - 1 == pytest.approx(4e-7, rel=1e-5)


HB_MAX_ERROR = (0.039, 0.022, 0.010)
"""Largest |approx/exact − 1| of (κ̄, K̄, Ē) over 1 ≤ α_r ≤ 100, measured on 400 log-spaced
α_r (3.8 %, 2.1 %, 0.91 %, κ̄ worst near α_r ≈ 8); the derived a, b, δ, p_max, dQ/dδ: 2.7, 1.2, 4.1, 1.6, 4.3 %."""


@pytest.mark.parametrize("alpha_r", [1.0, 2.0, 5.0, 8.0, 10.0, 35.0, 100.0])
def test_hamrock_brewe_within_their_measured_accuracy(alpha_r):
    curv = Curvatures((1.0, 1.0 / alpha_r), (0.0, 0.0))
    exact = elliptic_factors_exact(curv.curvature_difference)
    approx = elliptic_factors_hamrock_brewe(alpha_r)
    for got, ref, tol in zip(approx, exact, HB_MAX_ERROR, strict=True):
        assert abs(got / ref - 1) < tol
    ce = contact_ellipse(curv, E_STAR, 100.0)
    ca = contact_ellipse(curv, E_STAR, 100.0, EllipseMethod.HAMROCK_BREWE)
    for got, ref in zip(ca[1:], ce[1:], strict=True):
        assert abs(got / ref - 1) < 0.045


def test_race_curvatures_of_a_deep_groove_bearing():
    # α = 0: the inner race's rolling radius is d_m/2 − D/2, the outer's d_m/2 + D/2.
    inner = race_curvatures(10.0, 50.0, 0.0, 0.52, Race.INNER)
    outer = race_curvatures(10.0, 50.0, 0.0, 0.52, Race.OUTER)
    assert inner.body_2 == pytest.approx((1 / 20.0, -1 / 5.2), rel=1e-14)
    assert outer.body_2 == pytest.approx((-1 / 30.0, -1 / 5.2), rel=1e-14)
    assert inner.curvature_sum > outer.curvature_sum


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"curvature_ratio": 0.5}, "curvature_ratio"),
        ({"contact_angle_deg": 90.0}, "contact_angle_deg"),
        ({"pitch_diameter_mm": 3.0}, "pitch_diameter_mm"),
    ],
    ids=["f=0.5", "alpha=90", "dm<D"],
)
def test_bad_race_parameters_name_themselves(kwargs, name):
    args = {
        "ball_diameter_mm": 3.969,
        "pitch_diameter_mm": 15.0,
        "contact_angle_deg": 15.0,
        "curvature_ratio": 0.52,
        "race": Race.INNER,
    } | kwargs
    with pytest.raises(ParameterError, match=name):
        race_curvatures(**args)


def test_conforming_bodies_are_refused():
    with pytest.raises(ParameterError, match="relative curvature in plane 2"):
        Curvatures((0.2, 0.2), (0.0, -0.25))


def test_negative_load_is_refused():
    with pytest.raises(ParameterError, match="load_n"):
        contact_ellipse(ELLIPTIC_CASES["708C-inner"], E_STAR, -1.0)
