"""Quasi-static equilibrium of a rigid inner ring (or shaft) on angular-contact ball bearings.

Jones' five-degree-of-freedom analysis (Jones 1960; Harris & Kotzalas, 2007, Ch. 8) at
low speed: rigid rings, one load per ball on the line through its two groove centres.
The inner rings of all bearings move as one rigid body with ``x = (δ_x, δ_y, δ_z, θ_x,
θ_y)`` [mm, mm, mm, rad, rad] about the origin; each outer ring is fixed but for an
axial shift ``s`` (the preload). Ball k of a bearing sits at azimuth ψ_k = 2πk/Z; its
inner groove centre ``p = r_i e_r + z_i e_z`` with ``r_i = d_m/2 + (f_i − ½) D cos α0``,
``z_i = z_b + σ (f_i − ½) D sin α0`` (σ = ±1 the sign of the contact line's axial
direction, from ball centre toward the outer contact) moves by ``w = δ + θ × p``; the
groove-centre distance in the ball's meridional plane is::

    d = (BD cos α0 + w·e_r,  σ BD sin α0 + w_z − s),   A = |d|,   δ_n = A − BD,
    Q = K_n max(δ_n, 0)^{3/2},   tan α = |d_z| / d_r.

The balls push the inner ring with ``−Q d/A`` applied at ``p``; equilibrium with the
external load ``f = (F_x, F_y, F_z, M_x, M_y)`` [N, N·mm] is ``Σ Tᵀ Q d/A = f`` with
``T = ∂d/∂x`` (2 × 5), and the tangent ``S = Σ Tᵀ [Q' d̂d̂ᵀ + (Q/A)(I − d̂d̂ᵀ)] T`` is the
(symmetric) stiffness matrix of the ring. The solve is scipy's MINPACK hybrid method on a
scaled system, then Newton steps with S to round-off.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy.optimize import root

from cad.bearing_geometry import BearingHingeParams, race_geometry
from cad.errors import ConvergenceError, ParameterError, check_range
from fe.bearing.pair import (
    BallBearing,
    axial_state_from_load,
    bearing_from_params,
    contact_constants,
)

N_DOF = 5
"""Ring unknowns (δ_x, δ_y, δ_z, θ_x, θ_y)."""


@dataclass(frozen=True)
class MountedBearing:
    """A bearing in place on the shared inner ring.

    Attributes:
        bearing: The bearing.
        direction: σ = ±1, the axial sign of its contact lines (ball centre → outer contact).
        z_mm: Axial position of its ball-centre plane [mm].
        outer_shift_mm: Axial shift s of its outer ring (the preload) [mm].
    """

    bearing: BallBearing
    direction: float
    z_mm: float
    outer_shift_mm: float = 0.0

    def __post_init__(self) -> None:
        if self.direction not in (-1.0, 1.0):
            raise ParameterError(f"direction must be -1 or +1, got {self.direction!r}")
        check_range("z_mm", self.z_mm, -1e6, 1e6)
        check_range("outer_shift_mm", self.outer_shift_mm, -1.0, 1.0)


class BallLoads(NamedTuple):
    """Per-ball state of one bearing, balls in azimuth order ψ_k = 2πk/Z.

    Attributes:
        azimuth_rad: ψ_k, shape (Z,) float64 [rad].
        load_n: Q_k, the load on both the inner and the outer contact, shape (Z,) [N].
        contact_angle_deg: Loaded contact angle α_k, shape (Z,) [deg] (the same inner/outer).
        approach_mm: δ_n,k, both contacts together, shape (Z,) [mm] (negative: a gap).
    """

    azimuth_rad: npt.NDArray[np.float64]
    load_n: npt.NDArray[np.float64]
    contact_angle_deg: npt.NDArray[np.float64]
    approach_mm: npt.NDArray[np.float64]


class RingEquilibrium(NamedTuple):
    """The converged ring.

    Attributes:
        displacement: x = (δ_x, δ_y, δ_z [mm], θ_x, θ_y [rad]), shape (5,).
        balls: One BallLoads per mounted bearing, in their order.
        stiffness: S = ∂f/∂x, shape (5, 5) [N/mm, N, N·mm/rad].
        residual_n: max |Σ ball forces − f| over forces [N] and moments / pitch radius [N].
        iterations: Function evaluations of the hybrid method plus Newton steps.
    """

    displacement: npt.NDArray[np.float64]
    balls: tuple[BallLoads, ...]
    stiffness: npt.NDArray[np.float64]
    residual_n: float
    iterations: int


def pair_from_params(p: BearingHingeParams) -> tuple[MountedBearing, MountedBearing]:
    """Return the hinge's two bearings, with outer ring 1 shifted to give ``p.preload_n``.

    Outer ring 0 rests on the tang lip; the plate moves outer ring 1 toward it by 2 δ_p
    (δ_p each bearing's axial approach at the preload), so that at zero external load the
    inner rings settle at ``δ_z = σ_0 δ_p`` with both bearings at F_p.
    """
    b = bearing_from_params(p)
    delta_p = axial_state_from_load(b, p.preload_n).axial_deflection_mm
    out = []
    for k in (0, 1):
        g = race_geometry(p, k)
        sigma = math.copysign(1.0, g.direction[1])
        shift = -sigma * 2.0 * delta_p if k == 1 else 0.0
        out.append(MountedBearing(b, sigma, g.ball_center[1], shift))
    return out[0], out[1]


class _Balls(NamedTuple):
    """All balls of all bearings, flattened: positions and the constant geometry."""

    p: npt.NDArray[np.float64]  # (n, 3) inner groove centres [mm]
    e_r: npt.NDArray[np.float64]  # (n, 3) radial unit vectors
    d0: npt.NDArray[np.float64]  # (n, 2) unloaded d = BD (cos α0, σ sin α0)
    shift: npt.NDArray[np.float64]  # (n,) outer ring shifts [mm]
    bd: npt.NDArray[np.float64]  # (n,) BD [mm]
    k_n: npt.NDArray[np.float64]  # (n,) K_n [N/mm^1.5]
    counts: tuple[int, ...]


def _balls_of(mounted: Sequence[MountedBearing]) -> _Balls:
    parts: list[list[npt.NDArray[np.float64]]] = [[] for _ in range(6)]
    for m in mounted:
        b = m.bearing
        z, a0 = b.ball_count, b.free_angle_rad
        psi = 2.0 * np.pi * np.arange(z, dtype=np.float64) / z
        half = (b.inner_curvature_ratio - 0.5) * b.ball_diameter_mm
        r_i = 0.5 * b.pitch_diameter_mm + half * math.cos(a0)
        z_i = m.z_mm + m.direction * half * math.sin(a0)
        e_r = np.column_stack([np.cos(psi), np.sin(psi), np.zeros(z)])
        bd_mm = b.groove_distance_mm
        ones = np.ones(z, dtype=np.float64)
        parts[0].append(r_i * e_r + np.array([0.0, 0.0, z_i]))
        parts[1].append(e_r)
        free = [bd_mm * math.cos(a0), m.direction * bd_mm * math.sin(a0)]
        parts[2].append(np.tile(np.array(free, dtype=np.float64), (z, 1)))
        parts[3].append(m.outer_shift_mm * ones)
        parts[4].append(bd_mm * ones)
        parts[5].append(contact_constants(b).ball * ones)
    p, e_r, d0, shift, bd, k_n = (np.concatenate(x) for x in parts)
    return _Balls(p, e_r, d0, shift, bd, k_n, tuple(m.bearing.ball_count for m in mounted))


def _kinematics(balls: _Balls) -> npt.NDArray[np.float64]:
    """Return T = ∂d/∂x, shape (n, 2, 5): rows (e_r·∂w/∂x, ∂w_z/∂x), w = δ + θ × p."""
    n = balls.p.shape[0]
    dw = np.zeros((n, 3, N_DOF))  # ∂w/∂x per ball
    dw[:, :, :3] = np.eye(3)
    px, py, pz = balls.p.T
    dw[:, :, 3] = np.column_stack([np.zeros(n), -pz, py])  # ∂(θ × p)/∂θ_x
    dw[:, :, 4] = np.column_stack([pz, np.zeros(n), -px])  # ∂(θ × p)/∂θ_y
    t = np.empty((n, 2, N_DOF))
    t[:, 0, :] = np.einsum("ni,nij->nj", balls.e_r, dw)  # (n, 5)
    t[:, 1, :] = dw[:, 2, :]
    return t


def ring_forces(
    mounted: Sequence[MountedBearing], x: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], tuple[BallLoads, ...]]:
    """Return the balls' resultant on the ring, its stiffness and the per-ball loads.

    Args:
        mounted: The bearings on the ring.
        x: Ring displacement (δ_x, δ_y, δ_z, θ_x, θ_y), shape (5,) [mm, rad].

    Returns:
        (f, S, balls): f = Σ Tᵀ Q d/A, shape (5,) [N, N·mm], the load the ring carries at
        x; S = ∂f/∂x, shape (5, 5); one BallLoads per bearing.
    """
    balls = _balls_of(mounted)
    t = _kinematics(balls)
    d = balls.d0 + np.einsum("nij,j->ni", t, x)  # (n, 2)
    d[:, 1] -= balls.shift
    dist = np.hypot(d[:, 0], d[:, 1])
    dn = dist - balls.bd
    dn_pos = np.maximum(dn, 0.0)
    q = balls.k_n * dn_pos**1.5
    dq = 1.5 * balls.k_n * np.sqrt(dn_pos)
    u = d / dist[:, None]  # (n, 2) unit d̂
    f = np.einsum("nij,ni->j", t, q[:, None] * u)
    uu = np.einsum("ni,nj->nij", u, u)  # (n, 2, 2)
    h = dq[:, None, None] * uu + (q / dist)[:, None, None] * (np.eye(2) - uu)
    s = np.einsum("nia,nij,njb->ab", t, h, t)  # (5, 5)
    alpha = np.degrees(np.arctan2(np.abs(d[:, 1]), d[:, 0]))
    out, start = [], 0
    for z in balls.counts:
        sl = slice(start, start + z)
        psi = 2.0 * np.pi * np.arange(z, dtype=np.float64) / z
        out.append(BallLoads(psi, q[sl], alpha[sl], dn[sl]))
        start += z
    return f, s, tuple(out)


def _scales(mounted: Sequence[MountedBearing], load: npt.NDArray[np.float64]) -> tuple[
    npt.NDArray[np.float64], float, float
]:  # fmt: skip
    """Return (x scale (5,), force scale [N], pitch radius [mm]) for a well-scaled solve."""
    radius = max(0.5 * m.bearing.pitch_diameter_mm for m in mounted)
    force = max(float(np.max(np.abs(load[:3]))), float(np.max(np.abs(load[3:]))) / radius, 1.0)
    n_balls = sum(m.bearing.ball_count for m in mounted)
    k_n = max(contact_constants(m.bearing).ball for m in mounted)
    length = (force / (0.2 * n_balls * k_n)) ** (2.0 / 3.0)
    return np.array([length] * 3 + [length / radius] * 2), force, radius


def solve_ring(
    mounted: Sequence[MountedBearing],
    load: npt.ArrayLike,
    *,
    guess: npt.ArrayLike | None = None,
    tol_n: float = 1e-9,
    max_newton: int = 20,
) -> RingEquilibrium:
    """Find the ring displacement at which the balls carry the external load.

    Args:
        mounted: The bearings on the ring (at least one).
        load: f = (F_x, F_y, F_z [N], M_x, M_y [N·mm]) on the inner ring, shape (5,).
        guess: Starting x, shape (5,); default a translation along F of Hertzian size.
        tol_n: Convergence bound on forces and on moments / pitch radius [N].
        max_newton: Newton steps after the hybrid method.

    Returns:
        The converged ring, its ball loads and its stiffness matrix.

    Raises:
        ParameterError: No bearing, or a load of the wrong shape or not finite.
        ConvergenceError: The residual stayed above ``tol_n`` (iteration and residual).
    """
    if not mounted:
        raise ParameterError("mounted must hold at least one bearing, got none")
    f_ext = np.asarray(load, dtype=np.float64)
    if f_ext.shape != (N_DOF,) or not np.all(np.isfinite(f_ext)):
        raise ParameterError(f"load must be 5 finite numbers (Fx, Fy, Fz, Mx, My), got {load!r}")
    check_range("tol_n", tol_n, 0.0, math.inf, lo_open=True)
    x_scale, f_scale, radius = _scales(mounted, f_ext)
    weight = np.array([1.0, 1.0, 1.0, 1.0 / radius, 1.0 / radius])  # moments → N

    def scaled(
        y: npt.NDArray[np.float64],
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        f, s, _ = ring_forces(mounted, y * x_scale)
        return (f - f_ext) * weight / f_scale, s * weight[:, None] * x_scale / f_scale

    if guess is None:
        y0 = np.zeros(N_DOF)
        if np.any(f_ext[:3]):
            y0[:3] = f_ext[:3] / np.linalg.norm(f_ext[:3])
    else:
        y0 = np.asarray(guess, dtype=np.float64) / x_scale
    sol = root(scaled, y0, jac=True, method="hybr", options={"xtol": 1e-14})
    y, n_iter = sol.x, int(sol.nfev)
    for _ in range(max_newton):
        r, jac = scaled(y)
        if np.max(np.abs(r)) * f_scale <= tol_n:
            break
        y = y - np.linalg.lstsq(jac, r, rcond=None)[0]
        n_iter += 1
    f, s, per_bearing = ring_forces(mounted, y * x_scale)
    residual = float(np.max(np.abs((f - f_ext) * weight)))
    if not residual <= tol_n:
        raise ConvergenceError(
            f"ring equilibrium under load={f_ext.tolist()} did not converge to {tol_n:g} N",
            increment=0,
            iteration=n_iter,
            residual=residual,
        )
    return RingEquilibrium(y * x_scale, per_bearing, s, residual, n_iter)
