"""The bearing hinge's load cycle with ``hertz`` balls: preload, then 0 → +Fg → −Fg → +Fg.

The preload step and the load targets are those of ``fe.bearing.loading``; each state of
the cycle solves the ``hertz`` balls' equations of ``fe.bearing.balls`` (Newton on the
balls' relative displacements ``v`` and the grip displacement δ_x, σ and δ_z held). The
energy is convex, the structure linear: the solution is unique, and it is elastic — with
bonded interfaces and free-rolling balls nothing dissipates, so the loop has no area
(``docs/bearing_model.md``). ``run_bearing_cycle`` drives ``HertzStep`` through
``fe.cycle.driver.drive``, or runs the meshed-ball cycle (``fe.bearing.full_cycle``) when
the system asks for ``full`` balls.

The ball law is ``fe.bearing.balls``, the preload step ``fe.bearing.loading``.
"""

from __future__ import annotations

__all__ = [
    "HertzStep",
    "run_bearing_cycle",
]

import logging
import time
from collections.abc import Callable, Iterator

import numpy as np
import numpy.typing as npt

from cad.bearing_geometry import BallModel
from fe.bearing.balls import (
    GRIP_X,
    BallState,
    contact_angles,
    elastic_energy,
    grip_stiffness,
    solve_state,
)
from fe.bearing.full_cycle import run_full_cycle
from fe.bearing.loading import (
    BearingCycle,
    PreloadResult,
    bearing_result,
    preload_step,
    with_zero_crossing,
)
from fe.bearing.system import BearingSystem
from fe.contact.memo import start_afresh
from fe.contact.state import ContactState
from fe.cycle.driver import Recorded, Target, drive
from fe.cycle.protocol import CycleSettings, stage_targets, with_cutbacks
from fe.cycle.result import CycleResult, Increment

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]


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
        return run_full_cycle(system, settings, preload_n, progress=progress).cycle
    start_afresh()  # nothing learnt by earlier cycles on this system's W
    t0 = time.perf_counter()
    pre = preload_step(system, preload_n, settings)
    t_pre = time.perf_counter() - t0
    step = HertzStep(system, settings, preload_n, pre)
    return BearingCycle(drive(step, settings, progress, timings_s={"preload": t_pre}), pre)


class HertzStep:
    """The bearing hinge's increment with ``hertz`` balls, for ``fe.cycle.driver.drive``.

    Each target is one state of the balls at the clevis force (σ and δ_z held), reached
    from the last by Newton (``_advance``). The targets get F = 0 added where a stage
    crosses it (``with_zero_crossing``), and each increment carries the grip's tangent
    stiffness, so the elastic loop is integrated with the Hermite rule.
    """

    def __init__(
        self,
        system: BearingSystem,
        settings: CycleSettings,
        preload_n: float,
        preload: PreloadResult,
    ) -> None:
        """Start from the preloaded state ``preload`` (plate force ``preload_n`` [N])."""
        self.system = system
        self.settings = settings
        self.preload_n = preload_n
        self.preload = preload
        self.state = preload.balls

    def targets(self, f_from: float, f_to: float, n: int) -> FloatArray:
        """The graded targets of the stage, F = 0 added where it is crossed, shape (k,) [N]."""
        targets = stage_targets(f_from, f_to, n, self.settings.grading)
        return with_zero_crossing(targets, f_from, self.preload_n)

    def advance(self, target: Target, partial: Callable[[], CycleResult]) -> Iterator[Recorded]:
        """Reach ``target.f_to``: one increment."""
        s = _advance(self.system, self.state, target.f_from, target.f_to, self.settings,
                     self.preload_n, target.index, partial)  # fmt: skip
        self.state = s
        inc = Increment(
            stage=target.stage,
            force_n=target.f_to,
            disp_mm=float(s.alpha[GRIP_X]),
            side=1,
            iterations=s.iterations,
            n_open=int(np.sum(s.load_n <= 0)),
            n_stick=int(np.sum(s.load_n > 0)),
            n_slip=0,
            friction_work=0.0,
            normal_work=0.0,
            elastic_energy=elastic_energy(self.system, s),
            stiffness_n_per_mm=grip_stiffness(self.system, s),
        )
        yield inc, s.as_contact_state()

    def result(
        self,
        increments: tuple[Increment, ...],
        states: tuple[ContactState, ...],
        timings_s: dict[str, float],
    ) -> CycleResult:
        """The cycle of these increments, with the preloaded state."""
        preload = self.preload.balls.as_contact_state()
        return bearing_result(self.settings, increments, states, preload, timings_s)


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
