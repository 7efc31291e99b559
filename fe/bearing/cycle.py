"""The bearing hinge's load cycle with ``hertz`` balls: preload, then 0 → +Fg → −Fg → +Fg.

Step 1 (preload): outer ring 1 is set down toward ring 0 by σ until the plate force is
F_p, with the pin and inner rings free to float axially (δ_z; the hinge is not clamped
yet) and the grip force zero. Step 2: σ and δ_z are held (the bond cured, the hinge
clamped) and the clevis force follows the paper's cycle through the grip displacement δ_x.

Each state solves, by Newton with a backtracking line search, for the balls' relative
displacements ``v`` (radial, axial per ball; ``fe.bearing.system``) and the unknown load
parameters::

    v + W f(v) − G α = 0          (compatibility: the structure's response to the balls)
    G_Uᵀ f(v) = e_U               (equilibrium of the unknown parameters: F, 0, F_p)

with ``f`` the gradient of the balls' Hertz energy ``Σ (2/5) K_n ⟨|d_0 + v| − |d_0|⟩^{5/2}``.
The energy is convex, the structure linear: the solution is unique, and it is elastic —
with bonded interfaces and free-rolling balls nothing dissipates, so the loop has no area
(``docs/bearing_model.md``).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.bearing_geometry import BallModel
from cad.errors import ConvergenceError, ParameterError
from fe.bearing.system import PARAMS, BearingSystem
from fe.contact import ContactState
from fe.contact.law import ContactStatus
from fe.hinge.protocol import CycleSettings, stage_targets, with_cutbacks
from fe.hinge.result import CycleResult, Increment

logger = logging.getLogger(__name__)

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


@dataclass(frozen=True)
class PreloadResult:
    """The preload step's own result.

    Attributes:
        preload_n: Plate force F_p [N].
        plate_travel_mm: Shift σ of outer ring 1 toward ring 0 [mm].
        axial_float_mm: Axial float δ_z of pin and inner rings [mm].
        balls: The balls after the preload.
        elastic_energy_Nmm: Stored energy [N·mm].
        dissipation_Nmm: Friction work of the step [N·mm] (0: nothing can slip).
    """

    preload_n: float
    plate_travel_mm: float
    axial_float_mm: float
    balls: BallState
    elastic_energy_Nmm: float
    dissipation_Nmm: float = 0.0


def preload_step(
    system: BearingSystem, preload_n: float, settings: CycleSettings | None = None
) -> PreloadResult:
    """Set the pair down to the plate force F_p (step 1).

    Raises:
        ParameterError: If ``preload_n`` is outside [0, 500] N.
        ConvergenceError: With increment 0 (the preload step), the iteration and residual.
    """
    if not 0.0 <= preload_n <= 500.0:
        raise ParameterError(f"preload_n must be in [0, 500] N, got {preload_n!r}")
    s = settings or CycleSettings()
    n = system.n_balls
    if preload_n == 0.0:
        zero = BallState(np.zeros(n), np.zeros(n), contact_angles(system.balls.d0, np.zeros((n, 2))),
                         np.zeros((n, 2)), np.zeros(3), 0)  # fmt: skip
        return PreloadResult(0.0, 0.0, 0.0, zero, 0.0)
    # start from the rigid-structure Hertz guess: each bearing's balls share F_p axially
    sin_a = np.abs(system.balls.d0[:, 1]) / np.linalg.norm(system.balls.d0, axis=1)
    q = preload_n / (n / 2) / sin_a
    guess = (q / system.balls.k_n) ** (2.0 / 3.0)
    e = system.balls.d0 / np.linalg.norm(system.balls.d0, axis=1)[:, None]
    try:
        st = solve_state(
            system,
            e * guess[:, None],
            np.zeros(3),
            (GRIP_X, GRIP_Z, PRELOAD),
            np.array([0.0, 0.0, preload_n]),
            tol=s.tol,
            max_iter=s.max_iter,
            ref_load_n=preload_n,
        )
    except ConvergenceError as err:
        raise ConvergenceError(
            f"the preload step (F_p = {preload_n:g} N) did not converge",
            increment=0,
            iteration=err.iteration,
            residual=err.residual,
        ) from err
    return PreloadResult(
        preload_n, float(st.alpha[PRELOAD]), float(st.alpha[GRIP_Z]), st, elastic_energy(system, st)
    )


@dataclass(frozen=True)
class BearingCycle:
    """A bearing-hinge cycle: the common result, the preload step and the ball states.

    Attributes:
        result: The cycle, as for the general hinge (``CycleResult``).
        preload: The preload step.
    """

    result: CycleResult
    preload: PreloadResult


def run_bearing_cycle(
    system: BearingSystem,
    settings: CycleSettings,
    preload_n: float,
    *,
    progress: Callable[[int, int], None] | None = None,
) -> BearingCycle:
    """Preload, then cycle the clevis force 0 → +Fg → −Fg → +Fg.

    With ``system.params.ball_model = "full"`` the balls are the meshed-ball law
    (:func:`fe.bearing.full_cycle.run_full_cycle`, its rig at the default level).

    Raises:
        ConvergenceError: With the increment, iteration and residual; ``partial`` holds the
            increments that converged (cut back ``settings.max_cutbacks`` times first).
    """
    if system.params.ball_model is BallModel.FULL:
        from fe.bearing.full_cycle import run_full_cycle

        return run_full_cycle(system, settings, preload_n, progress=progress).cycle
    t0 = time.perf_counter()
    pre = preload_step(system, preload_n, settings)
    t_pre = time.perf_counter() - t0
    incs: list[Increment] = []
    states: list[ContactState] = []
    total = sum(n for _, _, n in settings.stages())
    state = pre.balls

    def partial() -> CycleResult:
        return bearing_result(
            settings, incs, states, pre.balls.as_contact_state(), {"preload": t_pre}
        )

    t1 = time.perf_counter()
    f_prev = 0.0
    for stage, (f_from, f_to, n) in enumerate(settings.stages()):
        for target in with_zero_crossing(
            stage_targets(f_from, f_to, n, settings.grading), f_from, preload_n
        ):
            state = _advance(system, state, f_prev, float(target), settings, preload_n, len(incs),
                             partial)  # fmt: skip
            f_prev = float(target)
            e_new = elastic_energy(system, state)
            incs.append(
                Increment(
                    stage=stage,
                    force_n=f_prev,
                    disp_mm=float(state.alpha[GRIP_X]),
                    side=1,
                    iterations=state.iterations,
                    n_open=int(np.sum(state.load_n <= 0)),
                    n_stick=int(np.sum(state.load_n > 0)),
                    n_slip=0,
                    friction_work=0.0,
                    normal_work=0.0,
                    elastic_energy=e_new,
                    stiffness_n_per_mm=grip_stiffness(system, state),
                )
            )
            states.append(state.as_contact_state())
            if progress is not None:
                progress(len(incs), total)
    return BearingCycle(
        bearing_result(
            settings,
            incs,
            states,
            pre.balls.as_contact_state(),
            {"preload": t_pre, "cycle": time.perf_counter() - t1},
        ),
        pre,
    )


ZERO_REFINE = 8
"""Halvings of the force toward F = 0 on each side of a crossing without preload."""


def with_zero_crossing(
    targets: FloatArray,
    f_from: float,
    preload_n: float,
    *,
    at_zero: bool = True,
    halvings: int = ZERO_REFINE,
) -> FloatArray:
    """The targets with F = 0 added where the stage crosses it.

    Unpreloaded Hertz balls make F(δ) ∝ |δ|^{3/2} around F = 0 (no stiffness at zero
    load), which no polynomial quadrature integrates well: a step across it counted a
    spurious 1e-3 N·mm. Without preload the crossing is therefore refined geometrically
    toward 0 (``ZERO_REFINE`` halvings on each side: the error falls as h^{5/2}).
    """
    t = np.asarray(targets, dtype=float)
    path = np.concatenate([[f_from], t])
    cross = np.flatnonzero(path[:-1] * path[1:] < 0)
    if len(cross) == 0:
        return t
    j = int(cross[0])
    before, after = path[j], path[j + 1]
    if preload_n > 0:
        middle = np.array([0.0] if at_zero else [])
    else:
        halves = 0.5 ** np.arange(1, halvings + 1)
        zero = [0.0] if at_zero else []
        middle = np.concatenate([before * halves, zero, after * halves[::-1]])
    return np.concatenate([t[:j], middle, t[j:]])


def _advance(
    system: BearingSystem,
    state: BallState,
    f_from: float,
    f_to: float,
    settings: CycleSettings,
    preload_n: float,
    increment: int,
    partial: Callable[[], CycleResult],
) -> BallState:
    """Reach the force ``f_to`` from ``state``, halving the step on failure."""
    if f_to == 0.0 and preload_n == 0.0:
        # The unloaded pair at zero force: the exact state (Newton converges only
        # linearly there, every ball's tangent being zero).
        n = system.n_balls
        v0 = np.zeros((n, 2))
        return BallState(np.zeros(n), np.zeros(n), contact_angles(system.balls.d0, v0), v0,
                         state.alpha * [0.0, 1.0, 1.0], 0)  # fmt: skip
    ref = max(abs(f_to), abs(f_from), preload_n, settings.amplitude_n * 1e-3)

    def attempt(steps: int) -> BallState:
        s = state
        for j in range(1, steps + 1):
            f = f_from + (f_to - f_from) * j / steps
            s = solve_state(
                system,
                s.v_mm,
                s.alpha,
                (GRIP_X,),
                np.array([f]),
                tol=settings.tol,
                max_iter=settings.max_iter,
                ref_load_n=ref,
            )
        return s

    what = f"the cycle at F = {f_to:g} N"
    return with_cutbacks(
        attempt, settings.max_cutbacks, increment=increment, what=what, partial=partial
    )


def bearing_result(
    settings: CycleSettings,
    incs: list[Increment],
    states: list[ContactState],
    preload: ContactState,
    timings: dict[str, float],
) -> CycleResult:
    """The cycle result of a bearing hinge (no clearance, no free play, one configuration)."""
    return CycleResult(
        settings=settings,
        clearance_mm=0.0,
        increments=tuple(incs),
        free_play_mm=0.0,
        states=tuple(states),
        configs={},
        timings_s=timings,
        preload_state=preload,
    )
