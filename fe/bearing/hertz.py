"""Hertz point contact between two curved bodies, and ball–raceway curvatures.

Two bodies I and II touch at a point; their principal planes coincide (always true when
one body is a ball). ``ρ_I1, ρ_I2, ρ_II1, ρ_II2`` are the principal curvatures [1/mm] in
planes 1 and 2, positive for a convex surface, negative for a concave one, zero for a
flat. Following Harris & Kotzalas (*Rolling Bearing Analysis*, 5th ed., 2007, Ch. 6)::

    Σρ    = ρ_I1 + ρ_I2 + ρ_II1 + ρ_II2                 (curvature sum)
    F(ρ)  = |(ρ_I1 − ρ_I2) + (ρ_II1 − ρ_II2)| / Σρ       (curvature difference, [0, 1))
    1/R_1 = ρ_I1 + ρ_II1,  1/R_2 = ρ_I2 + ρ_II2          (relative radii, Σρ = 1/R_1 + 1/R_2)

The contact ellipse has its major semi-axis ``a`` across the plane of the larger relative
curvature. Its ellipticity ``κ = a/b ≥ 1`` solves (m = 1 − 1/κ², K and E the complete
elliptic integrals of the first and second kind with parameter m)::

    F(ρ) = [(κ² + 1) E(m) − 2 K(m)] / [(κ² − 1) E(m)]

and with ``1/E* = (1 − ν_I²)/E_I + (1 − ν_II²)/E_II`` and ``c = (3 Q / (2 Σρ E*))^{1/3}``::

    a = (2 κ² E/π)^{1/3} c,   b = (2 E/(π κ))^{1/3} c,   δ = (2 K/π)(π/(2 κ² E))^{1/3} c² Σρ/2,
    p_max = 3 Q / (2 π a b),  Q = K_c δ^{3/2},  K_c = (4√2/3) E* / (δ*^{3/2} √Σρ),

with ``δ* = (2 K/π)(π/(2 κ² E))^{1/3}``. A sphere (radius R) on a plane gives κ = 1,
K = E = π/2 and the circular formulas ``a = (3 Q R/(4 E*))^{1/3}``, ``δ = a²/R``,
``K_c = (4/3) E* √R`` exactly. δ is the mutual approach of distant points of both bodies.

Hamrock & Brewe (*J. Lubr. Technol.* 105, 1983, 171–177) replace κ, K, E by explicit
functions of ``α_r = R_y/R_x ≥ 1`` (R_x the smaller relative radius)::

    κ̄ = α_r^{2/π},   Ē = 1 + (π/2 − 1)/α_r,   K̄ = π/2 + (π/2 − 1) ln α_r

measured here over 1 ≤ α_r ≤ 100 within 3.8 % (κ̄, worst near α_r ≈ 8), 2.1 % (K̄) and
0.91 % (Ē) of the exact values; a, b, δ within 2.7, 1.2, 4.1 % (tests/fe/bearing/test_hertz.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

from scipy.optimize import brentq
from scipy.special import ellipe, ellipkm1

from cad.errors import ConvergenceError, ParameterError, check_range
from cad.materials import Material

SERIES_LIMIT = 1e-3
"""Below this F(ρ), κ comes from the series F = 3m/8 + 3m²/16 + 111m³/1024 + O(m⁴)
(m = 1 − 1/κ²): the exact ratio loses digits to cancellation as κ → 1 (its numerator is
O(m²)), while the series' truncation is O(m⁴) ≈ 5e-11 relative there."""

MAX_ELLIPTICITY = 1e6
"""Upper end of the bracket of κ; F(ρ) = 1 − O(1e-11) there (an almost line contact)."""


class EllipseMethod(Enum):
    """How the ellipticity and the elliptic integrals are obtained."""

    EXACT = "exact"
    HAMROCK_BREWE = "hamrock_brewe"


class Race(Enum):
    """Which raceway a ball touches."""

    INNER = "inner"
    OUTER = "outer"


@dataclass(frozen=True)
class Curvatures:
    """Principal curvatures of two touching bodies in common principal planes [1/mm].

    Attributes:
        body_1: (ρ_I1, ρ_I2) of body I; convex > 0, concave < 0, flat 0.
        body_2: (ρ_II1, ρ_II2) of body II.
    """

    body_1: tuple[float, float]
    body_2: tuple[float, float]

    def __post_init__(self) -> None:
        for name, pair in (("body_1", self.body_1), ("body_2", self.body_2)):
            for rho in pair:
                if not math.isfinite(rho):
                    raise ParameterError(f"{name} curvatures must be finite, got {pair!r}")
        for plane, inv_r in (("1", self.relative_1), ("2", self.relative_2)):
            if inv_r <= 0.0:
                raise ParameterError(
                    f"relative curvature in plane {plane} must be > 0 (the bodies must touch "
                    f"at a point, not conform or cross), got {inv_r!r} from "
                    f"body_1={self.body_1!r}, body_2={self.body_2!r}"
                )

    @property
    def relative_1(self) -> float:
        """Relative curvature 1/R_1 = ρ_I1 + ρ_II1 in plane 1 [1/mm]."""
        return self.body_1[0] + self.body_2[0]

    @property
    def relative_2(self) -> float:
        """Relative curvature 1/R_2 = ρ_I2 + ρ_II2 in plane 2 [1/mm]."""
        return self.body_1[1] + self.body_2[1]

    @property
    def curvature_sum(self) -> float:
        """Σρ [1/mm]."""
        return self.relative_1 + self.relative_2

    @property
    def curvature_difference(self) -> float:
        """F(ρ) in [0, 1)."""
        return abs(self.relative_1 - self.relative_2) / self.curvature_sum

    @property
    def radius_ratio(self) -> float:
        """α_r = R_y/R_x ≥ 1, the larger relative radius over the smaller."""
        big, small = max(self.relative_1, self.relative_2), min(self.relative_1, self.relative_2)
        return big / small


class EllipticFactors(NamedTuple):
    """Ellipticity and complete elliptic integrals of one contact.

    Attributes:
        ellipticity: κ = a/b ≥ 1.
        first_kind: K(m), m = 1 − 1/κ² (Harris's ℱ, Hamrock's F).
        second_kind: E(m) (Harris's ℰ, Hamrock's E).
    """

    ellipticity: float
    first_kind: float
    second_kind: float


class ContactEllipse(NamedTuple):
    """Hertz solution at one normal load.

    Attributes:
        load_n: Normal load Q [N].
        semi_major_mm: a [mm], across the plane of larger relative curvature.
        semi_minor_mm: b [mm].
        approach_mm: Mutual approach δ of distant points [mm].
        max_pressure_mpa: p_max = 3Q/(2πab) [MPa].
        stiffness_n_per_mm: dQ/dδ = (3/2) Q/δ [N/mm].
    """

    load_n: float
    semi_major_mm: float
    semi_minor_mm: float
    approach_mm: float
    max_pressure_mpa: float
    stiffness_n_per_mm: float


def effective_modulus(body_1: Material, body_2: Material) -> float:
    """Return E* [MPa] with 1/E* = (1 − ν_1²)/E_1 + (1 − ν_2²)/E_2."""
    inv = (1.0 - body_1.poisson**2) / body_1.young_mpa
    inv += (1.0 - body_2.poisson**2) / body_2.young_mpa
    return 1.0 / inv


def curvature_difference_from_ellipticity(kappa: float) -> float:
    """Return F(ρ) = [(κ²+1)E − 2K]/[(κ²−1)E] for an ellipticity κ > 1 (0 at κ = 1)."""
    check_range("kappa", kappa, 1.0, math.inf)
    if kappa == 1.0:
        return 0.0
    p = 1.0 / (kappa * kappa)
    k_m = float(ellipkm1(p))  # K(1 − p), accurate as m → 1
    e_m = float(ellipe(1.0 - p))
    return ((kappa**2 + 1.0) * e_m - 2.0 * k_m) / ((kappa**2 - 1.0) * e_m)


def _factors_of(kappa: float) -> EllipticFactors:
    p = 1.0 / (kappa * kappa)
    return EllipticFactors(kappa, float(ellipkm1(p)), float(ellipe(1.0 - p)))


def elliptic_factors_exact(curvature_difference: float) -> EllipticFactors:
    """Solve the Hertz equation for κ (Brent's method on ln κ) and return κ, K, E.

    Args:
        curvature_difference: F(ρ) in [0, 1).

    Returns:
        The exact factors; below SERIES_LIMIT κ solves the series (see there).

    Raises:
        ParameterError: F(ρ) outside [0, 1 − 1e-11].
        ConvergenceError: Brent's method did not converge (iteration and residual).
    """
    f_max = curvature_difference_from_ellipticity(MAX_ELLIPTICITY)
    check_range("curvature_difference", curvature_difference, 0.0, f_max)
    if curvature_difference < SERIES_LIMIT:
        return _factors_of(_ellipticity_from_series(curvature_difference))

    def residual(log_kappa: float) -> float:
        return curvature_difference_from_ellipticity(math.exp(log_kappa)) - curvature_difference

    lo = 0.5 * math.log(1.0 / (1.0 - 2.0 * SERIES_LIMIT))  # F(e^lo) < SERIES_LIMIT
    log_kappa, info = brentq(
        residual, lo, math.log(MAX_ELLIPTICITY), xtol=1e-15, rtol=1e-15, full_output=True
    )
    if not info.converged:
        raise ConvergenceError(
            f"ellipticity for curvature_difference={curvature_difference!r} did not converge",
            increment=0,
            iteration=info.iterations,
            residual=abs(residual(log_kappa)),
        )
    return _factors_of(math.exp(log_kappa))


def _ellipticity_from_series(curvature_difference: float) -> float:
    """Return κ from F = 3m/8 + 3m²/16 + 111m³/1024 (fixed point, contraction ≈ m)."""
    f = curvature_difference
    m = 8.0 * f / 3.0
    for _ in range(60):
        m_new = 8.0 / 3.0 * (f - 3.0 * m * m / 16.0 - 111.0 * m**3 / 1024.0)
        if abs(m_new - m) <= 1e-17:
            break
        m = m_new
    return 1.0 / math.sqrt(1.0 - m_new)


def elliptic_factors_hamrock_brewe(radius_ratio: float) -> EllipticFactors:
    """Return Hamrock & Brewe's κ̄ = α_r^{2/π}, K̄ = π/2 + q ln α_r, Ē = 1 + q/α_r (q = π/2 − 1).

    Args:
        radius_ratio: α_r = R_y/R_x ≥ 1.
    """
    check_range("radius_ratio", radius_ratio, 1.0, math.inf)
    q = 0.5 * math.pi - 1.0
    return EllipticFactors(
        radius_ratio ** (2.0 / math.pi),
        0.5 * math.pi + q * math.log(radius_ratio),
        1.0 + q / radius_ratio,
    )


def elliptic_factors(curv: Curvatures, method: EllipseMethod) -> EllipticFactors:
    """Return κ, K, E of a contact by the chosen method."""
    if method is EllipseMethod.EXACT:
        return elliptic_factors_exact(curv.curvature_difference)
    return elliptic_factors_hamrock_brewe(curv.radius_ratio)


def _dimensionless(fac: EllipticFactors) -> tuple[float, float, float]:
    """Return Harris's (a*, b*, δ*) of the factors."""
    kappa, k_m, e_m = fac
    a_star = (2.0 * kappa**2 * e_m / math.pi) ** (1.0 / 3.0)
    b_star = (2.0 * e_m / (math.pi * kappa)) ** (1.0 / 3.0)
    delta_star = (2.0 * k_m / math.pi) * (math.pi / (2.0 * kappa**2 * e_m)) ** (1.0 / 3.0)
    return a_star, b_star, delta_star


def load_deflection_constant(
    curv: Curvatures, e_star_mpa: float, method: EllipseMethod = EllipseMethod.EXACT
) -> float:
    """Return K_c [N/mm^1.5] with Q = K_c δ^{3/2}: K_c = (4√2/3) E* / (δ*^{3/2} √Σρ).

    Args:
        curv: The two bodies' curvatures.
        e_star_mpa: Effective modulus E* [MPa] (see :func:`effective_modulus`).
        method: Exact ellipticity or Hamrock–Brewe.
    """
    check_range("e_star_mpa", e_star_mpa, 0.0, math.inf, lo_open=True)
    delta_star = _dimensionless(elliptic_factors(curv, method))[2]
    denom = delta_star * math.sqrt(delta_star * curv.curvature_sum)  # δ*^{3/2} √Σρ
    return 4.0 * math.sqrt(2.0) / 3.0 * e_star_mpa / denom


def contact_ellipse(
    curv: Curvatures,
    e_star_mpa: float,
    load_n: float,
    method: EllipseMethod = EllipseMethod.EXACT,
) -> ContactEllipse:
    """Return the Hertz ellipse, approach, peak pressure and stiffness at load Q.

    Args:
        curv: The two bodies' curvatures.
        e_star_mpa: Effective modulus E* [MPa].
        load_n: Normal load Q ≥ 0 [N].
        method: Exact ellipticity or Hamrock–Brewe.

    Returns:
        The contact (all zeros but the load at Q = 0; stiffness 0 there, as dQ/dδ ∝ Q^{1/3}).
    """
    check_range("e_star_mpa", e_star_mpa, 0.0, math.inf, lo_open=True)
    check_range("load_n", load_n, 0.0, math.inf)
    if load_n == 0.0:
        return ContactEllipse(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    a_star, b_star, delta_star = _dimensionless(elliptic_factors(curv, method))
    s = curv.curvature_sum
    c = (3.0 * load_n / (2.0 * s * e_star_mpa)) ** (1.0 / 3.0)
    a, b = a_star * c, b_star * c
    delta = delta_star * c * c * s / 2.0
    return ContactEllipse(
        load_n, a, b, delta, 3.0 * load_n / (2.0 * math.pi * a * b), 1.5 * load_n / delta
    )


def race_curvatures(
    ball_diameter_mm: float,
    pitch_diameter_mm: float,
    contact_angle_deg: float,
    curvature_ratio: float,
    race: Race,
) -> Curvatures:
    """Return ball (body I) and raceway (body II) curvatures at a ball–race contact.

    Plane 1 is the rolling (circumferential) plane, plane 2 the groove cross-section.
    With γ = D cos α / d_m (Harris & Kotzalas, 2007, §6.2)::

        ball:  ρ_I1 = ρ_I2 = 2/D
        inner: ρ_II1 = (2/D) γ/(1 − γ),   ρ_II2 = −1/(f_i D)
        outer: ρ_II1 = −(2/D) γ/(1 + γ),  ρ_II2 = −1/(f_o D)

    Args:
        ball_diameter_mm: D [mm].
        pitch_diameter_mm: d_m [mm], > D.
        contact_angle_deg: α [deg], in [0, 90).
        curvature_ratio: f = groove radius / D, > 0.5.
        race: Inner or outer raceway.
    """
    check_range("ball_diameter_mm", ball_diameter_mm, 0.0, math.inf, lo_open=True)
    check_range("pitch_diameter_mm", pitch_diameter_mm, ball_diameter_mm, math.inf, lo_open=True)
    check_range("contact_angle_deg", contact_angle_deg, 0.0, 90.0, hi_open=True)
    check_range("curvature_ratio", curvature_ratio, 0.5, math.inf, lo_open=True)
    d = ball_diameter_mm
    gamma = d * math.cos(math.radians(contact_angle_deg)) / pitch_diameter_mm
    sign = 1.0 if race is Race.INNER else -1.0  # the inner race is convex, the outer concave
    rho_1 = sign * 2.0 / d * gamma / (1.0 - sign * gamma)
    return Curvatures((2.0 / d, 2.0 / d), (rho_1, -1.0 / (curvature_ratio * d)))
