"""Hertz balls between groove centres: the law, its Newton solve, the stored energy.

The ``hertz`` ball model of the bearing hinge (``fe.bearing.system``): each ball is a Hertz
contact along the line of its groove centres, ``Q = K_n ⟨|d_0 + v| − |d_0|⟩^{3/2}``, and a
state solves, by Newton with a backtracking line search, for the balls' relative
displacements ``v`` (radial, axial per ball) and the unknown load parameters::

    v + W f(v) − G α = 0          (compatibility: the structure's response to the balls)
    G_Uᵀ f(v) = e_U               (equilibrium of the unknown parameters: F, 0, F_p)

with ``f`` the gradient of the balls' Hertz energy ``Σ (2/5) K_n ⟨|d_0 + v| − |d_0|⟩^{5/2}``.
The law and the Newton step are shared by the frictional fits (``fe.bearing.fit_cycle``)
and the meshed balls (``fe.bearing.full_cycle``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import ConvergenceError
from fe.bearing.system import PARAMS, BearingSystem
from fe.contact.law import ContactStatus
from fe.contact.state import ContactState

FloatArray = npt.NDArray[np.float64]

GRIP_X, GRIP_Z, PRELOAD = range(len(PARAMS))

REG_FRACTION = 1e-3
"""Approach below which a ball's tangent stiffness is taken at this fraction of the
reference approach (Hertz: dQ/dΔ = 0 at Δ = 0, so an unloaded pair has no tangent)."""


@dataclass(frozen=True)
class BallState:
    """The balls in one converged state.

    Attributes:
        load_n: Ball load Q (the same on the inner and the outer contact), shape (n_b,) [N].
        approach_mm: Hertz approach Δ (negative: unloaded, gap), shape (n_b,) [mm].
        angle_deg: Loaded contact angle against the radial plane, shape (n_b,) [deg].
        v_mm: Relative displacement inner − outer groove centre (radial, axial),
            shape (n_b, 2) [mm].
        alpha: Load parameters δ_x, δ_z, σ, shape (3,) [mm].
        iterations: Newton iterations.
    """

    load_n: FloatArray
    approach_mm: FloatArray
    angle_deg: FloatArray
    v_mm: FloatArray
    alpha: FloatArray
    iterations: int

    def as_contact_state(self) -> ContactState:
        """The state in ``fe.contact``'s layout, one point per ball (for the result store).

        ``p = [Q, 0, 0]``, ``w = [Δ, v_r, v_z]``, status closed (STICK) or OPEN.
        """
        m = len(self.load_n)
        p = np.zeros((m, 3))
        p[:, 0] = self.load_n
        w = np.column_stack([self.approach_mm, self.v_mm])
        status = np.where(self.load_n > 0, ContactStatus.STICK, ContactStatus.OPEN)
        return ContactState(p, w, status.astype(np.int8), self.alpha)


def contact_angles(d0: FloatArray, v: FloatArray) -> FloatArray:
    """Loaded contact angle of each ball against the radial plane, shape (n_b,) [deg].

    Args:
        d0: Unloaded groove-centre vectors (radial, axial), shape (n_b, 2) [mm].
        v: Their relative displacements, shape (n_b, 2) [mm].
    """
    d = d0 + v
    return np.asarray(np.degrees(np.arctan2(np.abs(d[:, 1]), d[:, 0])))


def ball_state_of(system: BearingSystem, state: ContactState) -> BallState:
    """Rebuild a ``BallState`` from its stored ``ContactState``.

    A ``full``-ball state also stores each ball's force (``p[:, 1:]``, radial and axial;
    ``fe.bearing.full_cycle``): the contact angle of a loaded ball is then that force's.
    """
    v = np.asarray(state.w[:, 1:])
    angle = contact_angles(system.balls.d0, v)
    f = np.asarray(state.p[:, 1:])
    loaded = np.linalg.norm(f, axis=1) > 0.0
    angle[loaded] = np.degrees(np.arctan2(np.abs(f[loaded, 1]), f[loaded, 0]))
    return BallState(
        np.asarray(state.p[:, 0]), np.asarray(state.w[:, 0]), angle, v, np.asarray(state.alpha), 0
    )


def ball_law(
    d0: FloatArray, v: FloatArray, k_n: float, reg_mm: float = 0.0
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Hertz balls between groove centres: forces, loads, approaches and tangents.

    Args:
        d0: Unloaded groove-centre vectors, shape (n_b, 2) [mm].
        v: Relative displacements, shape (n_b, 2) [mm].
        k_n: Hertz constant [N/mm^1.5].
        reg_mm: Approach at which the tangent of an (almost) unloaded ball is taken [mm].

    Returns:
        (f (n_b, 2) [N]: force on the inner ring's centre, ∂E/∂v; Q (n_b,) [N];
        Δ (n_b,) [mm]; H (n_b, 2, 2) [N/mm]: ∂f/∂v, with the regularised normal term).
    """
    d = d0 + v
    length = np.linalg.norm(d, axis=1)
    e = d / length[:, None]
    approach = length - np.linalg.norm(d0, axis=1)
    pos = np.maximum(approach, 0.0)
    Q = k_n * pos**1.5
    f = Q[:, None] * e
    kn = 1.5 * k_n * np.sqrt(np.where(approach > -reg_mm, np.maximum(pos, reg_mm), 0.0))
    ee = e[:, :, None] * e[:, None, :]
    H = kn[:, None, None] * ee + (Q / length)[:, None, None] * (np.eye(2) - ee)
    return f, Q, approach, H


def block_diag(H: FloatArray) -> FloatArray:
    """Per-ball 2 × 2 blocks (n_b, 2, 2) as one block-diagonal matrix (2 n_b, 2 n_b)."""
    n = H.shape[0]
    out = np.zeros((2 * n, 2 * n))
    for j in range(n):
        out[2 * j : 2 * j + 2, 2 * j : 2 * j + 2] = H[j]
    return out


def newton_scales(system: BearingSystem, ref_load_n: float) -> tuple[float, float, float]:
    """Scales of the ball Newton iteration for a state carrying about ``ref_load_n``.

    Returns:
        (ref_mm: the Hertz approach of a ball at the mean load [mm]; reg: the approach at
        which an unloaded ball's tangent is taken, ``REG_FRACTION · ref_mm`` [mm]; c: the
        compliance that weighs equilibrium residuals as displacements in the merit [mm/N]).
    """
    q_ref = max(ref_load_n, 1.0) / system.n_balls
    ref_mm = (q_ref / system.balls.k_n) ** (2.0 / 3.0)
    c = float(np.mean(np.diag(system.W))) + ref_mm / q_ref
    return ref_mm, REG_FRACTION * ref_mm, c


def newton_step(
    W: FloatArray, GU: FloatArray, H: FloatArray, r1: FloatArray, r2: FloatArray
) -> FloatArray:
    """The Newton step of the ball equations ``v + W f(v) − G α = 0``, ``G_Uᵀ f(v) = e_U``.

    Args:
        W: Ball compliance, shape (2 n_b, 2 n_b) [mm/N].
        GU: Columns of the unknown load parameters, shape (2 n_b, k).
        H: Ball tangents ∂f/∂v, shape (n_b, 2, 2) [N/mm].
        r1: Compatibility residual, shape (2 n_b,) [mm].
        r2: Equilibrium residual, shape (k,) [N].

    Returns:
        (Δv, Δα_U), shape (2 n_b + k,); least squares where the Jacobian is singular.
    """
    n2, k = W.shape[0], GU.shape[1]
    Hb = block_diag(H)
    J = np.zeros((n2 + k, n2 + k))
    J[:n2, :n2] = np.eye(n2) + W @ Hb
    J[:n2, n2:] = -GU
    J[n2:, :n2] = GU.T @ Hb
    rhs = -np.concatenate([r1, r2])
    try:
        return np.asarray(np.linalg.solve(J, rhs))
    except np.linalg.LinAlgError:
        return np.asarray(np.linalg.lstsq(J, rhs, rcond=None)[0])


def solve_state(
    system: BearingSystem,
    v0: FloatArray,
    alpha0: FloatArray,
    unknown: tuple[int, ...],
    targets: FloatArray,
    *,
    tol: float = 1e-10,
    max_iter: int = 60,
    ref_load_n: float = 1.0,
) -> BallState:
    """Solve one state from a starting guess.

    Args:
        system: The condensed structure.
        v0: Starting relative displacements, shape (n_b, 2) [mm].
        alpha0: Load parameters; the known ones are held, shape (3,) [mm].
        unknown: Indices of the load parameters solved for.
        targets: Their generalised forces (grip force, axial float force, plate preload),
            shape (len(unknown),) [N].
        tol: Relative tolerance on compatibility [mm] and equilibrium [N].
        max_iter: Newton iterations.
        ref_load_n: A load of the state's size, to scale the tolerance and tangent [N].

    Raises:
        ConvergenceError: If Newton does not converge (increment −1: set by the caller).
    """
    n = system.n_balls
    W, G = system.W, system.G
    GU = G[:, list(unknown)]
    d0, k_n = system.balls.d0, system.balls.k_n
    ref_mm, reg, c = newton_scales(system, ref_load_n)
    v = np.array(v0, dtype=float).ravel()
    alpha = np.array(alpha0, dtype=float)

    def residual(v: FloatArray, alpha: FloatArray) -> tuple[FloatArray, FloatArray]:
        f = ball_law(d0, v.reshape(n, 2), k_n)[0].ravel()
        return v + W @ f - G @ alpha, GU.T @ f - targets

    def merit(r1: FloatArray, r2: FloatArray) -> float:
        return float(np.sqrt(r1 @ r1 + (c * c) * (r2 @ r2)))

    r1, r2 = residual(v, alpha)
    it = 0
    while True:
        it += 1
        if it > max_iter:
            raise ConvergenceError(
                "bearing ball equilibrium did not converge",
                increment=-1,
                iteration=max_iter,
                residual=merit(r1, r2),
            )
        scale_v = tol * max(np.abs(v).max(), ref_mm)
        if np.abs(r1).max() <= scale_v and np.abs(r2).max(initial=0.0) <= tol * max(
            ref_load_n, 1.0
        ):
            break
        _, _, _, H = ball_law(d0, v.reshape(n, 2), k_n, reg)
        step = newton_step(W, GU, H, r1, r2)
        m0, t = merit(r1, r2), 1.0
        for _ in range(40):
            v_try = v + t * step[: 2 * n]
            a_try = alpha.copy()
            a_try[list(unknown)] += t * step[2 * n :]
            s1, s2 = residual(v_try, a_try)
            if merit(s1, s2) < (1.0 - 1e-4 * t) * m0:
                break
            t *= 0.5
        v, alpha, r1, r2 = v_try, a_try, s1, s2
    _, Q, approach, _ = ball_law(d0, v.reshape(n, 2), k_n)
    angle = contact_angles(d0, v.reshape(n, 2))
    return BallState(Q, approach, angle, v.reshape(n, 2), alpha, it - 1)


def grip_stiffness(system: BearingSystem, s: BallState) -> float:
    """Tangent dF/dδ_x of a converged state with σ and δ_z held [N/mm] (0: no ball loaded)."""
    n = system.n_balls
    _, _, _, H = ball_law(system.balls.d0, s.v_mm, system.balls.k_n)
    Hb = block_diag(H)
    g = system.G[:, GRIP_X]
    dv = np.linalg.solve(np.eye(2 * n) + system.W @ Hb, g)  # I + W H: W SPD, H PSD
    return float(g @ Hb @ dv)


def elastic_energy(system: BearingSystem, s: BallState) -> float:
    """Strain energy of the structure plus the balls' Hertz energy [N·mm]."""
    f = ball_law(system.balls.d0, s.v_mm, system.balls.k_n)[0].ravel()
    balls = 0.4 * system.balls.k_n * np.maximum(s.approach_mm, 0.0) ** 2.5
    return float(0.5 * f @ system.W @ f + balls.sum())
