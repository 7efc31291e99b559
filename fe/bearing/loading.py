"""The bearing hinge's loading: the preload step, the targets around F = 0, the result.

Step 1 (preload): outer ring 1 is set down toward ring 0 by σ until the plate force is
F_p, with the pin and inner rings free to float axially (δ_z; the hinge is not clamped
yet) and the grip force zero. Step 2: σ and δ_z are held (the bond cured, the hinge
clamped) and the clevis force follows the paper's cycle through the grip displacement δ_x,
its targets refined toward F = 0 where the balls may unload (``with_zero_crossing``).
Shared by the cycles with ``hertz`` balls (``fe.bearing.cycle``), meshed balls
(``fe.bearing.full_cycle``) and frictional fits (``fe.bearing.fit_cycle``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.bearing_geometry import MAX_PRELOAD_N
from cad.errors import ConvergenceError, check_range
from fe.bearing.balls import (
    GRIP_X,
    GRIP_Z,
    PRELOAD,
    BallState,
    contact_angles,
    elastic_energy,
    solve_state,
)
from fe.bearing.system import BearingSystem
from fe.contact.state import ContactState
from fe.cycle.protocol import CycleSettings
from fe.cycle.result import CycleResult, Increment

FloatArray = npt.NDArray[np.float64]


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
        ParameterError: If ``preload_n`` is outside [0, ``MAX_PRELOAD_N``] N.
        ConvergenceError: With increment 0 (the preload step), the iteration and residual.
    """
    check_range("preload_n", preload_n, 0.0, MAX_PRELOAD_N)
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


def bearing_result(
    settings: CycleSettings,
    incs: Sequence[Increment],
    states: Sequence[ContactState],
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
