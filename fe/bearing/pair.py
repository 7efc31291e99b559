"""Angular-contact ball bearings under axial load, singly and as a preloaded pair.

The classical quasi-static analysis (Jones 1960; Harris & Kotzalas, *Rolling Bearing
Analysis*, 5th ed., 2007, Ch. 7–8): rigid rings, low speed (no centrifugal or gyroscopic
ball loads, so a ball's inner and outer contacts carry the same load on one line), Hertz
contacts. With ``B = f_i + f_o − 1`` the groove centres of a ball lie ``BD`` apart when
unloaded (zero clearance: the free contact angle α0 is the nominal one). Under an axial
displacement δ_a of the inner ring they lie ``A`` apart at a contact angle α::

    A sin α = BD sin α0 + δ_a,   A cos α = BD cos α0,   δ_n = A − BD,
    Q = K_n δ_n^{3/2},           F_a = Z Q sin α,

hence Jones' equation ``F_a / (Z K_n (BD)^{3/2}) = sin α (cos α0 / cos α − 1)^{3/2}``.
``K_n = [K_i^{−2/3} + K_o^{−2/3}]^{−3/2}`` joins the inner and outer contacts in series;
K_i and K_o are evaluated at α0: for the 708C the shift of γ = D cos α/d_m as α grows to
21° (400 N axial) changes K_i by +0.15 %, K_o by −0.11 % and K_n by +0.02 %, and keeping
them fixed makes every relation below exact and the same as in :mod:`fe.bearing.rings`.

A preloaded pair (face-to-face or back-to-back, identical bearings, rigid spacer): the
preload F_p gives each bearing the approach δ_p; an external axial force F_a on the inner
rings moves them by x, so one bearing is at δ_p + x and the other at δ_p − x::

    F_a = F(δ_p + x) − F(δ_p − x),   F(δ) = 0 for δ ≤ 0,

and the unloaded bearing lifts off at x = δ_p, i.e. at ``F_a = F(2 δ_p)``; with
F ∝ δ^{3/2} (small change of α) that is ``2^{3/2} F_p ≈ 2.83 F_p``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from scipy.optimize import brentq

from cad.bearing_geometry import BearingHingeParams
from cad.errors import ConvergenceError, ParameterError, check_range
from fe.bearing.hertz import (
    EllipseMethod,
    Race,
    load_deflection_constant,
    race_curvatures,
)


@dataclass(frozen=True)
class BallBearing:
    """One angular-contact ball bearing (rings and balls of one material).

    Attributes:
        ball_diameter_mm: D [mm].
        pitch_diameter_mm: d_m [mm].
        inner_curvature_ratio: f_i = inner groove radius / D, > 0.5.
        outer_curvature_ratio: f_o = outer groove radius / D, > 0.5.
        contact_angle_deg: Free (unloaded) contact angle α0 [deg], in [0, 45].
        ball_count: Z.
        young_mpa: E [MPa].
        poisson: ν.
    """

    ball_diameter_mm: float
    pitch_diameter_mm: float
    inner_curvature_ratio: float
    outer_curvature_ratio: float
    contact_angle_deg: float
    ball_count: int
    young_mpa: float
    poisson: float

    def __post_init__(self) -> None:
        check_range("ball_diameter_mm", self.ball_diameter_mm, 0.0, math.inf, lo_open=True)
        check_range(
            "pitch_diameter_mm", self.pitch_diameter_mm, self.ball_diameter_mm, math.inf,
            lo_open=True,
        )  # fmt: skip
        check_range("inner_curvature_ratio", self.inner_curvature_ratio, 0.5, 1.0, lo_open=True)
        check_range("outer_curvature_ratio", self.outer_curvature_ratio, 0.5, 1.0, lo_open=True)
        check_range("contact_angle_deg", self.contact_angle_deg, 0.0, 45.0)
        if isinstance(self.ball_count, bool) or not isinstance(self.ball_count, int):
            raise ParameterError(f"ball_count must be an integer, got {self.ball_count!r}")
        check_range("ball_count", self.ball_count, 3, 1000)
        check_range("young_mpa", self.young_mpa, 0.0, math.inf, lo_open=True)
        check_range("poisson", self.poisson, -1.0, 0.5, lo_open=True, hi_open=True)

    @property
    def free_angle_rad(self) -> float:
        """α0 [rad]."""
        return math.radians(self.contact_angle_deg)

    @property
    def groove_distance_mm(self) -> float:
        """BD = (f_i + f_o − 1) D, the unloaded distance between groove centres [mm]."""
        f_sum = self.inner_curvature_ratio + self.outer_curvature_ratio
        return (f_sum - 1.0) * self.ball_diameter_mm

    @property
    def effective_modulus_mpa(self) -> float:
        """E* = E / (2 (1 − ν²)) of two bodies of this material [MPa]."""
        return self.young_mpa / (2.0 * (1.0 - self.poisson**2))


def bearing_from_params(p: BearingHingeParams) -> BallBearing:
    """Return one bearing of the hinge's pair (both are identical).

    Args:
        p: Bearing hinge parameters (ball, pitch circle, grooves, angle, Z, material).
    """
    return BallBearing(
        ball_diameter_mm=p.ball_diameter_mm,
        pitch_diameter_mm=p.pitch_diameter_mm,
        inner_curvature_ratio=p.inner_curvature_ratio,
        outer_curvature_ratio=p.outer_curvature_ratio,
        contact_angle_deg=p.contact_angle_deg,
        ball_count=p.ball_count,
        young_mpa=p.bearing_material.young_mpa,
        poisson=p.bearing_material.poisson,
    )


class ContactConstants(NamedTuple):
    """Load–deflection constants of one ball [N/mm^1.5] (Q = K δ^{3/2}).

    Attributes:
        inner: K_i, ball on the inner race.
        outer: K_o, ball on the outer race.
        ball: K_n = [K_i^{−2/3} + K_o^{−2/3}]^{−3/2}, both contacts in series.
    """

    inner: float
    outer: float
    ball: float


def contact_constants(
    b: BallBearing, method: EllipseMethod = EllipseMethod.EXACT
) -> ContactConstants:
    """Return K_i, K_o and K_n at the free contact angle."""
    k = []
    for race, f in ((Race.INNER, b.inner_curvature_ratio), (Race.OUTER, b.outer_curvature_ratio)):
        curv = race_curvatures(
            b.ball_diameter_mm, b.pitch_diameter_mm, b.contact_angle_deg, f, race
        )
        k.append(load_deflection_constant(curv, b.effective_modulus_mpa, method))
    k_n = (k[0] ** (-2.0 / 3.0) + k[1] ** (-2.0 / 3.0)) ** -1.5
    return ContactConstants(k[0], k[1], k_n)


class AxialState(NamedTuple):
    """One bearing under a pure axial load (every ball alike).

    Attributes:
        axial_load_n: F_a [N].
        axial_deflection_mm: δ_a, inner ring relative to outer ring along the axis [mm].
        contact_angle_deg: Loaded contact angle α [deg].
        ball_load_n: Q per ball [N].
        normal_approach_mm: δ_n per ball (both contacts) [mm].
        stiffness_n_per_mm: dF_a/dδ_a [N/mm].
    """

    axial_load_n: float
    axial_deflection_mm: float
    contact_angle_deg: float
    ball_load_n: float
    normal_approach_mm: float
    stiffness_n_per_mm: float


def axial_state_from_deflection(b: BallBearing, axial_deflection_mm: float) -> AxialState:
    """Return the explicit state at an axial deflection δ_a (zero for δ_a ≤ 0: lift-off).

    ``dF_a/dδ_a = Z K_n [ (3/2) δ_n^{1/2} sin² α + δ_n^{3/2} cos² α / A ]``.
    """
    if not math.isfinite(axial_deflection_mm):
        raise ParameterError(f"axial_deflection_mm must be finite, got {axial_deflection_mm!r}")
    a0, bd = b.free_angle_rad, b.groove_distance_mm
    if axial_deflection_mm <= 0.0:
        return AxialState(0.0, axial_deflection_mm, b.contact_angle_deg, 0.0, 0.0, 0.0)
    k_n, z = contact_constants(b).ball, b.ball_count
    along, across = bd * math.sin(a0) + axial_deflection_mm, bd * math.cos(a0)
    dist = math.hypot(along, across)
    sin_a, cos_a = along / dist, across / dist
    dn = dist - bd
    q = k_n * dn * math.sqrt(dn)
    stiffness = z * k_n * (1.5 * math.sqrt(dn) * sin_a**2 + dn * math.sqrt(dn) * cos_a**2 / dist)
    alpha = math.degrees(math.atan2(along, across))
    return AxialState(z * q * sin_a, axial_deflection_mm, alpha, q, dn, stiffness)


def _jones_rhs(b: BallBearing, alpha: float) -> float:
    """Return the right side of Jones' equation, sin α (cos α0/cos α − 1)^{3/2}."""
    t = max(math.cos(b.free_angle_rad) / math.cos(alpha) - 1.0, 0.0)
    return math.sin(alpha) * t * math.sqrt(t)


def axial_state_from_load(b: BallBearing, axial_load_n: float) -> AxialState:
    """Solve Jones' equation for α at an axial load F_a (Brent's method), return the state.

    Raises:
        ParameterError: F_a < 0 (a single bearing carries axial load one way only).
        ConvergenceError: Brent's method did not converge.
    """
    check_range("axial_load_n", axial_load_n, 0.0, math.inf)
    if axial_load_n == 0.0:
        return axial_state_from_deflection(b, 0.0)
    bd = b.groove_distance_mm
    target = axial_load_n / (b.ball_count * contact_constants(b).ball * bd**1.5)
    lo, hi = b.free_angle_rad, 0.5 * (b.free_angle_rad + 0.5 * math.pi)
    while _jones_rhs(b, hi) < target:
        hi = 0.5 * (hi + 0.5 * math.pi)
        if hi > 0.5 * math.pi - 1e-12:
            raise ParameterError(f"axial_load_n too large for this bearing, got {axial_load_n!r}")
    alpha, info = brentq(
        lambda a: _jones_rhs(b, a) - target, lo, hi, xtol=1e-15, rtol=1e-15, full_output=True
    )
    if not info.converged:
        raise ConvergenceError(
            f"Jones' equation at axial_load_n={axial_load_n!r} did not converge",
            increment=0,
            iteration=info.iterations,
            residual=abs(_jones_rhs(b, alpha) - target),
        )
    a0 = b.free_angle_rad
    delta_a = bd * (math.cos(a0) * math.tan(alpha) - math.sin(a0))
    return axial_state_from_deflection(b, delta_a)


class PairAxialState(NamedTuple):
    """A preloaded pair under an external axial force on its inner rings.

    Attributes:
        preload_n: F_p [N].
        external_load_n: F_a ≥ 0 [N], pushing the inner rings toward bearing ``loaded``.
        displacement_mm: x, the inner rings' axial motion from the preloaded state [mm].
        loaded: The bearing whose load grows (approach δ_p + x).
        unloaded: The other bearing (approach δ_p − x; zero load once lifted off).
        stiffness_n_per_mm: dF_a/dx of the pair [N/mm].
        lifted_off: Whether the unloaded bearing carries nothing.
    """

    preload_n: float
    external_load_n: float
    displacement_mm: float
    loaded: AxialState
    unloaded: AxialState
    stiffness_n_per_mm: float
    lifted_off: bool


def liftoff_load(b: BallBearing, preload_n: float) -> float:
    """Return the external axial force F(2 δ_p) at which the unloaded bearing lifts off [N]."""
    delta_p = axial_state_from_load(b, preload_n).axial_deflection_mm
    return axial_state_from_deflection(b, 2.0 * delta_p).axial_load_n


def pair_axial(b: BallBearing, preload_n: float, external_load_n: float) -> PairAxialState:
    """Share an external axial force between the two bearings of a preloaded pair.

    Args:
        b: Either bearing (both identical).
        preload_n: F_p ≥ 0 [N].
        external_load_n: F_a ≥ 0 [N] (by symmetry the sign only swaps the bearings).

    Raises:
        ParameterError: A negative preload or load.
        ConvergenceError: Brent's method did not converge.
    """
    check_range("preload_n", preload_n, 0.0, math.inf)
    check_range("external_load_n", external_load_n, 0.0, math.inf)
    delta_p = axial_state_from_load(b, preload_n).axial_deflection_mm

    def net(x: float) -> float:
        up = axial_state_from_deflection(b, delta_p + x).axial_load_n
        return up - axial_state_from_deflection(b, delta_p - x).axial_load_n

    if external_load_n == 0.0:
        x = 0.0
    else:
        hi = max(delta_p, axial_state_from_load(b, external_load_n).axial_deflection_mm)
        x, info = brentq(
            lambda s: net(s) - external_load_n, 0.0, hi, xtol=1e-16, rtol=1e-15, full_output=True
        )
        if not info.converged:
            raise ConvergenceError(
                f"pair at preload_n={preload_n!r}, external_load_n={external_load_n!r} "
                "did not converge",
                increment=0,
                iteration=info.iterations,
                residual=abs(net(x) - external_load_n),
            )
    loaded = axial_state_from_deflection(b, delta_p + x)
    unloaded = axial_state_from_deflection(b, delta_p - x)
    return PairAxialState(
        preload_n,
        external_load_n,
        x,
        loaded,
        unloaded,
        loaded.stiffness_n_per_mm + unloaded.stiffness_n_per_mm,
        unloaded.axial_load_n == 0.0 and external_load_n > 0.0,
    )
