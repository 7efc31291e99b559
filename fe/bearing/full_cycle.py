"""The bearing hinge's cycle with ``full`` balls: the meshed-ball law in every ball.

The structure, its condensation on the balls' patch coordinates ``v`` and the load
sequence are those of the ``hertz`` cycle (:mod:`fe.bearing.cycle`); only the ball law
changes. Each ball is the condensed meshed one-ball rig (:mod:`fe.bearing.ball_rig`)
with Coulomb friction on its two contacts, solved by displacement control
(:class:`fe.bearing.meshed_ball.MeshedBallLaw`): path dependent, so every ball keeps its
own rig contact state, committed only when the whole increment has converged. Each state
solves, by Newton with the same backtracking line search as the ``hertz`` cycle::

    v + W f(v) − G α = 0,      G_Uᵀ f(v) = e_U

where ``f_j(v_j)`` is ball j's frictional contact step from its committed state and
``∂f_j/∂v_j`` its exact tangent for the converged active set (balls below the regularised
Hertz tangent of :mod:`fe.bearing.balls` get that one, so Newton sees a ball it is about
to load). The local solves
warm-start from the last iterate; a ball with a gap everywhere costs no solve.

Preload: solved frictionless (μ = 0 on the ball contacts): the pair is set down while
its balls can still roll into place, and the patches' friction history starts from the
preloaded state (the fits of :mod:`fe.bearing.fit_cycle` make the same choice). The
step therefore dissipates nothing by that choice, not by a result.

Energy: the local works are the trapezoidal ones of :mod:`fe.contact` (twice the half
rig's), the structure's and the rigs' stored energies are exact, and the loop is
integrated with the trapezoid (no Hermite tangent: the tangent jumps at reversals), so
``W_cycle = ΔE + Σ (friction + normal work)`` holds to the solver tolerance.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from threadpoolctl import threadpool_limits

from cad.bearing_geometry import MAX_PRELOAD_N
from cad.errors import ConvergenceError, ParameterError, check_range
from fe.bearing.ball_rig import load_or_build_rig
from fe.bearing.balls import (
    GRIP_X,
    GRIP_Z,
    PRELOAD,
    BallState,
    ball_law,
    newton_scales,
    newton_step,
)
from fe.bearing.loading import (
    BearingCycle,
    PreloadResult,
    bearing_result,
    preload_step,
    with_zero_crossing,
)
from fe.bearing.meshed_ball import BallStep, MeshedBallLaw, check_converged, rig_maps
from fe.bearing.system import BearingSystem
from fe.contact.law import ContactStatus
from fe.contact.memo import start_afresh
from fe.contact.state import ContactState
from fe.cycle.driver import Recorded, Target, drive
from fe.cycle.protocol import CycleSettings, stage_targets, with_cutbacks
from fe.cycle.result import CycleResult, Increment
from mesh.ball_block import BallBlockGrid

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]

FULL_TOL = 1e-8
"""Relative tolerance of the ball equilibrium with meshed balls (the local contact solves
converge to 1e-10 of their own scale, so a tighter global tolerance would only chase
their round-off)."""

MAX_OUTER = 40
"""Newton iterations on the ball coordinates per state."""

FULL_HALVINGS = 3
"""Halvings of the force toward zero at a crossing without preload (no point at F = 0:
there every ball may be unloaded and the state is not unique)."""


@dataclass(frozen=True)
class FullState:
    """A converged state of the pair with meshed balls.

    Attributes:
        balls: The balls' summary (load Q = |f|, geometric approach, angle of f, v, α).
        rigs: Each ball's rig contact state (half model), length n_b.
        force_n: Ball forces on the inner rings (radial, axial), shape (n_b, 2) [N].
        friction_work: Friction work of the step from the last committed state [N·mm].
        normal_work: Open/close work of the step [N·mm].
        ball_energy: Strain energy of all balls and their raceway blocks [N·mm].
        n_open: Open rig points, summed over the balls (half model).
        n_stick: Sticking rig points. n_slip: Slipping rig points.
        local_iterations: Contact Newton iterations of the accepted local solves.
    """

    balls: BallState
    rigs: tuple[ContactState, ...]
    force_n: FloatArray
    friction_work: float
    normal_work: float
    ball_energy: float
    n_open: int
    n_stick: int
    n_slip: int
    local_iterations: int

    def summary(self) -> ContactState:
        """One point per ball, as the ``hertz`` cycle stores it, with the force kept.

        ``p = [Q, f_r, f_z]``, ``w = [Δ, v_r, v_z]``, status closed (STICK) or OPEN.
        """
        b = self.balls
        p = np.column_stack([b.load_n, self.force_n])
        w = np.column_stack([b.approach_mm, b.v_mm])
        status = np.where(b.load_n > 0, ContactStatus.STICK, ContactStatus.OPEN)
        return ContactState(p, w, status.astype(np.int8), b.alpha)


def force_angles(f: FloatArray) -> FloatArray:
    """Contact angle of each ball from its force (radial, axial), shape (n_b,) [deg]."""
    return np.asarray(np.degrees(np.arctan2(np.abs(f[:, 1]), f[:, 0])))


def _state(
    system: BearingSystem, v: FloatArray, alpha: FloatArray, steps: list[BallStep], it: int
) -> FullState:
    """Assemble a ``FullState`` from the balls' steps at ``v`` (n_b, 2)."""
    f = np.array([s.force_n for s in steps])
    d = system.balls.d0 + v
    approach = np.linalg.norm(d, axis=1) - np.linalg.norm(system.balls.d0, axis=1)
    Q = np.array([s.load_n for s in steps])
    angle = np.where(Q > 0, force_angles(f), np.degrees(np.arctan2(np.abs(d[:, 1]), d[:, 0])))
    stat = [np.asarray(s.state.status) for s in steps]
    return FullState(
        balls=BallState(Q, approach, angle, v, alpha, it),
        rigs=tuple(s.state for s in steps),
        force_n=f,
        friction_work=float(sum(s.friction_work for s in steps)),
        normal_work=float(sum(s.normal_work for s in steps)),
        ball_energy=float(sum(s.energy for s in steps)),
        n_open=int(sum(np.sum(x == ContactStatus.OPEN) for x in stat)),
        n_stick=int(sum(np.sum(x == ContactStatus.STICK) for x in stat)),
        n_slip=int(sum(np.sum(x == ContactStatus.SLIP) for x in stat)),
        local_iterations=int(sum(s.iterations for s in steps)),
    )


def solve_full_state(
    system: BearingSystem,
    law: MeshedBallLaw,
    committed: FullState,
    v0: FloatArray,
    alpha0: FloatArray,
    unknown: tuple[int, ...],
    targets: FloatArray,
    *,
    max_iter: int = MAX_OUTER,
    ref_load_n: float = 1.0,
) -> FullState:
    """Solve one state with meshed balls from the committed state ``committed``.

    Args:
        system: The condensed structure.
        law: The meshed-ball law.
        committed: The last converged state (each ball's slip reference and works).
        v0: Starting ball coordinates, shape (n_b, 2) [mm].
        alpha0: Load parameters; the known ones are held, shape (3,) [mm].
        unknown: Indices of the load parameters solved for.
        targets: Their generalised forces, shape (len(unknown),) [N].
        max_iter: Newton iterations.
        ref_load_n: A load of the state's size, to scale the tolerance [N].

    Raises:
        ConvergenceError: If Newton or a local contact solve does not converge
            (increment −1: set by the caller).
        ParameterError: If a converged ball's contact reaches the edge of the rig's window.
    """
    n = system.n_balls
    W, G = system.W, system.G
    GU = G[:, list(unknown)]
    d0, k_n = system.balls.d0, system.balls.k_n
    ref_mm, reg, c = newton_scales(system, ref_load_n)
    v = np.array(v0, dtype=float).ravel()
    alpha = np.array(alpha0, dtype=float)
    prev = committed.rigs

    def evaluate(v: FloatArray, starts: tuple[ContactState, ...]) -> list[BallStep]:
        out = []
        for j in range(n):
            s = law.solve(j, v[2 * j : 2 * j + 2], prev[j], starts[j], tangent=False)
            check_converged(s, j)
            out.append(s)
        return out

    def residual(steps: list[BallStep], v: FloatArray, a: FloatArray) -> tuple[FloatArray, ...]:
        f = np.concatenate([s.force_n for s in steps])
        return v + W @ f - G @ a, GU.T @ f - targets

    def merit(r1: FloatArray, r2: FloatArray) -> float:
        return float(np.sqrt(r1 @ r1 + (c * c) * (r2 @ r2)))

    steps = evaluate(v, prev)
    r1, r2 = residual(steps, v, alpha)
    it = 0
    while True:
        if np.abs(r1).max() <= FULL_TOL * max(np.abs(v).max(), ref_mm) and np.abs(r2).max(
            initial=0.0
        ) <= FULL_TOL * max(ref_load_n, 1.0):
            break
        it += 1
        if it > max_iter:
            raise ConvergenceError(
                "bearing ball equilibrium with meshed balls did not converge",
                increment=-1,
                iteration=max_iter,
                residual=merit(r1, r2),
            )
        H = np.array([law.tangent_of(j, s, prev[j]) for j, s in enumerate(steps)])
        # Where a ball's tangent is below the regularised Hertz one (unloaded, or touching
        # at a point or two with no stiffness yet), the Hertz tangent shows Newton the
        # ball it is about to load.
        H_reg = ball_law(d0, v.reshape(n, 2), k_n, reg)[3]
        idle = np.trace(H, axis1=1, axis2=2) < np.trace(H_reg, axis1=1, axis2=2)
        H[idle] = H_reg[idle]
        step = newton_step(W, GU, H, r1, r2)
        m0, t = merit(r1, r2), 1.0
        starts = tuple(s.state for s in steps)
        for _ in range(30):
            v_try = v + t * step[: 2 * n]
            a_try = alpha.copy()
            a_try[list(unknown)] += t * step[2 * n :]
            s_try = evaluate(v_try, starts)
            q1, q2 = residual(s_try, v_try, a_try)
            if merit(q1, q2) < (1.0 - 1e-4 * t) * m0:
                break
            t *= 0.5
        v, alpha, steps, r1, r2 = v_try, a_try, s_try, q1, q2
    for j, s in enumerate(steps):
        if np.any(s.state.p[law.rig.rim, 0] > 0.0):
            raise ParameterError(
                f"ball {j}'s contact reaches the edge of the rig's contact window at "
                f"Q = {s.load_n:.4g} N, contact angle {force_angles(s.force_n[None])[0]:.2f}°: "
                "widen fine_x/fine_y of the rig's grid"
            )
    return _state(system, v.reshape(n, 2), alpha, steps, it)


def elastic_energy_full(system: BearingSystem, s: FullState) -> float:
    """Strain energy of the structure plus the meshed balls' [N·mm]."""
    f = s.force_n.ravel()
    return float(0.5 * f @ system.W @ f + s.ball_energy)


def full_preload(
    system: BearingSystem,
    law: MeshedBallLaw,
    preload_n: float,
    settings: CycleSettings,
    *,
    friction_steps: int = 0,
) -> tuple[PreloadResult, FullState]:
    """Set the pair down to the plate force F_p with meshed balls (step 1).

    Frictionless by default (module docstring); starts from the ``hertz`` preload state.
    With ``friction_steps = n > 0`` the plate force is instead raised in n equal steps
    with the balls' friction on (the first step seats them: a ball that was unloaded
    re-seats frictionless), to measure what a frictional preload would dissipate.

    Raises:
        ParameterError: If ``preload_n`` is outside [0, ``MAX_PRELOAD_N``] N.
        ConvergenceError: With increment 0 (the preload step).
    """
    n = system.n_balls
    hertz = preload_step(system, preload_n, settings)  # validates preload_n
    start = law.initial_state()
    st = FullState(hertz.balls, (start,) * n, np.zeros((n, 2)), 0.0, 0.0, 0.0, 0, 0, 0, 0)
    if preload_n == 0.0:
        return PreloadResult(0.0, 0.0, 0.0, hertz.balls, 0.0), st
    pre_law = law if friction_steps > 0 else law.with_mu(0.0)
    fric = 0.0
    try:
        for j in range(1, max(friction_steps, 1) + 1):
            f = preload_n * j / max(friction_steps, 1)
            st = solve_full_state(
                system,
                pre_law,
                st,
                hertz.balls.v_mm * (j / max(friction_steps, 1)) ** (2.0 / 3.0),
                hertz.balls.alpha * (j / max(friction_steps, 1)) ** (2.0 / 3.0),
                (GRIP_X, GRIP_Z, PRELOAD),
                np.array([0.0, 0.0, f]),
                ref_load_n=f,
            )
            fric += st.friction_work
    except ConvergenceError as err:
        raise ConvergenceError(
            f"the preload step with meshed balls (F_p = {preload_n:g} N) did not converge",
            increment=0,
            iteration=err.iteration,
            residual=err.residual,
        ) from err
    if pre_law is not law:
        law.n_solves += pre_law.n_solves
        law.n_skipped += pre_law.n_skipped
    pre = PreloadResult(
        preload_n,
        float(st.balls.alpha[PRELOAD]),
        float(st.balls.alpha[GRIP_Z]),
        st.balls,
        elastic_energy_full(system, st),
        fric,
    )
    return pre, st


@dataclass(frozen=True)
class FullCycle:
    """A cycle with meshed balls: the common result and what only this model has.

    Attributes:
        cycle: The result and the preload step, as the ``hertz`` cycle returns them.
        final: The last converged state (every ball's rig state).
        local_solves: Local contact solves done. skipped: Local steps skipped (unloaded).
        outer_iterations: Newton iterations on v per increment.
        rig_dof: DOFs of the rig's mesh. rig_points: Its contact points (half model).
        rig_timings_s: The rig's build times (as built, also when read from the cache).
    """

    cycle: BearingCycle
    final: FullState
    local_solves: int
    skipped: int
    outer_iterations: tuple[int, ...]
    rig_dof: int
    rig_points: int
    rig_timings_s: dict[str, float]


def meshed_ball_law(
    system: BearingSystem, mu: float, grid: BallBlockGrid | None = None
) -> MeshedBallLaw:
    """The meshed-ball law of the system's bearing (the rig from the cache or built)."""
    rig = load_or_build_rig(grid, system.params)
    return MeshedBallLaw(rig, rig_maps(system.params, system.balls), mu)


def run_full_cycle(
    system: BearingSystem,
    settings: CycleSettings,
    preload_n: float,
    *,
    grid: BallBlockGrid | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> FullCycle:
    """Preload, then cycle the clevis force 0 → +Fg → −Fg → +Fg, with meshed balls.

    Args:
        system: The condensed structure (``interfaces = "bonded"``).
        settings: The protocol (``settings.mu`` acts on the ball contacts).
        preload_n: Plate force F_p [N].
        grid: The rig's mesh grid (``fe.bearing.ball_rig.DEFAULT_RIG_LEVEL`` when None).
        progress: Called as ``progress(done, total)`` after each load target.

    Raises:
        ParameterError: If ``preload_n`` is outside [0, ``MAX_PRELOAD_N``] N.
        ConvergenceError: With the increment, iteration and residual; ``partial`` holds
            the increments that converged.
    """
    check_range("preload_n", preload_n, 0.0, MAX_PRELOAD_N)
    start_afresh()  # nothing learnt by earlier cycles on this system's W
    t0 = time.perf_counter()
    law = meshed_ball_law(system, settings.mu, grid)
    t_rig = time.perf_counter() - t0
    # one BLAS thread (settings.blas_threads) for the thousands of small local solves (two are
    # slower: benchmarks/bench_bearing_full.txt, 'run_full_cycle'); the rig's build above keeps them
    with threadpool_limits(limits=settings.blas_threads, user_api="blas"):
        pre, state = full_preload(system, law, preload_n, settings)
        t_pre = time.perf_counter() - t0 - t_rig
        step = FullStep(system, law, settings, preload_n, state)
        timings = {"rig": t_rig, "preload": t_pre}
        result = drive(step, settings, progress, timings_s=timings)
    outer = tuple(i.iterations for i in result.increments)  # Newton iterations on v
    return FullCycle(BearingCycle(result, pre), step.state, law.n_solves, law.n_skipped, outer,
                     law.rig.n_dof, law.rig.n_points, law.rig.timings_s)  # fmt: skip


class FullStep:
    """The bearing hinge's increment with meshed balls, for ``fe.cycle.driver.drive``.

    Each target is one state of the balls at the clevis force (σ and δ_z held), solved
    from the last committed state (``solve_full_state``) and halved on failure
    (``_advance``). Where a stage crosses F = 0 without preload the targets approach it
    by ``FULL_HALVINGS`` halvings on each side, without a point at F = 0 (there every ball
    may be unloaded and the state is not unique); with preload F = 0 is a target.
    """

    def __init__(
        self,
        system: BearingSystem,
        law: MeshedBallLaw,
        settings: CycleSettings,
        preload_n: float,
        preload: FullState,
    ) -> None:
        """Start from the preloaded state ``preload`` (plate force ``preload_n`` [N])."""
        self.system = system
        self.law = law
        self.settings = settings
        self.preload_n = preload_n
        self.preload = preload.summary()
        self.state = preload

    def targets(self, f_from: float, f_to: float, n: int) -> FloatArray:
        """The graded targets of the stage, refined toward F = 0 where it is crossed [N]."""
        targets = stage_targets(f_from, f_to, n, self.settings.grading)
        return with_zero_crossing(
            targets, f_from, self.preload_n, at_zero=self.preload_n > 0.0, halvings=FULL_HALVINGS
        )

    def advance(self, target: Target, partial: Callable[[], CycleResult]) -> Iterator[Recorded]:
        """Reach ``target.f_to``: one increment, the balls' rig states committed."""
        s = _advance(self.system, self.law, self.state, target.f_from, target.f_to,
                     self.settings, self.preload_n, target.index, partial)  # fmt: skip
        self.state = s
        inc = Increment(
            stage=target.stage,
            force_n=target.f_to,
            disp_mm=float(s.balls.alpha[GRIP_X]),
            side=1,
            iterations=s.balls.iterations,
            n_open=s.n_open,
            n_stick=s.n_stick,
            n_slip=s.n_slip,
            friction_work=s.friction_work,
            normal_work=s.normal_work,
            elastic_energy=elastic_energy_full(self.system, s),
        )
        yield inc, s.summary()

    def result(
        self,
        increments: tuple[Increment, ...],
        states: tuple[ContactState, ...],
        timings_s: dict[str, float],
    ) -> CycleResult:
        """The cycle of these increments, with the preloaded state (one point per ball)."""
        return bearing_result(self.settings, increments, states, self.preload, timings_s)


def _advance(
    system: BearingSystem,
    law: MeshedBallLaw,
    state: FullState,
    f_from: float,
    f_to: float,
    settings: CycleSettings,
    preload_n: float,
    increment: int,
    partial: Callable[[], CycleResult],
) -> FullState:
    """Reach the force ``f_to`` from ``state``, halving the step on failure.

    Sub-steps commit their rig states (the friction path is followed in smaller steps);
    the works are summed over them.
    """
    ref = max(abs(f_to), abs(f_from), preload_n, settings.amplitude_n * 1e-3)

    def attempt(steps: int) -> FullState:
        s = state
        fric = normal = 0.0
        iters = 0
        for j in range(1, steps + 1):
            f = f_from + (f_to - f_from) * j / steps
            s = solve_full_state(system, law, s, s.balls.v_mm, s.balls.alpha, (GRIP_X,),
                                 np.array([f]), ref_load_n=ref)  # fmt: skip
            fric += s.friction_work
            normal += s.normal_work
            iters += s.balls.iterations
        if steps == 1:
            return s
        b = s.balls
        balls = BallState(b.load_n, b.approach_mm, b.angle_deg, b.v_mm, b.alpha, iters)
        return FullState(balls, s.rigs, s.force_n, fric, normal, s.ball_energy, s.n_open,
                         s.n_stick, s.n_slip, s.local_iterations)  # fmt: skip

    what = f"the cycle with meshed balls at F = {f_to:g} N"
    return with_cutbacks(
        attempt, settings.max_cutbacks, increment=increment, what=what, partial=partial
    )
