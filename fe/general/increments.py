"""Increments of the general hinge's cycle: solved under force control, recorded, checked.

Shared by the hinge's two cycle steps, ``fe.general.cycle.HingeStep`` (the pin changes sides
at F = 0) and ``fe.general.freeplay.SlidingStep`` (clamped faces slide it across the free
play): one force-controlled contact solve in a touching configuration, started on the
branch's extrapolation; an increment with its sub-steps summed after cut-backs; the
``Increment`` record of a contact solve; and the check, after the cycle, that no point
outside the contact window has closed.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from cad.errors import ConvergenceError
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState, IncrementResult
from fe.cycle.protocol import CycleSettings, with_cutbacks
from fe.cycle.result import CycleResult, Increment
from fe.general.system import GRIP, N_RIGID, HingeSystem, displacements, outside_gaps
from fe.structure.condensed import Condensed

FloatArray = npt.NDArray[np.float64]

Branch = tuple[float, ContactState]
"""A converged (force [N], state) on the current branch, before the last one."""


def branch_start(
    state: ContactState, f_from: float, f: float, previous: Branch | None
) -> tuple[FloatArray, FloatArray] | None:
    """Newton's start (p (m, 3) [N], α (k,)) at force ``f``, extrapolated along the branch.

    While the active set holds, the solution is linear in F, so the line through
    ``previous`` and ``state`` (converged at ``f_from``) predicts it at ``f``: one or two
    iterations instead of about ten. None (start from ``state``) without a previous point
    on the branch. The solution does not depend on it.
    """
    if previous is None or previous[0] == f_from:
        return None
    t = (f - f_from) / (f_from - previous[0])
    p, a = np.asarray(state.p), np.asarray(state.alpha)
    return (
        p + t * (p - np.asarray(previous[1].p)),
        a + t * (a - np.asarray(previous[1].alpha)),
    )


def solve_at_force(
    cond: Condensed,
    state: ContactState,
    force_n: float,
    contact: ContactSettings,
    index: int,
    start: tuple[FloatArray, FloatArray] | None,
) -> IncrementResult:
    """One contact solve of the configuration ``cond`` from ``state`` to the grip force F [N].

    Raises:
        ConvergenceError: If the contact Newton does not converge (``index`` named).
    """
    e = np.zeros(N_RIGID)
    e[GRIP] = -force_n  # clevis equilibrium: G_δᵀ p = −F
    return solve_increment(
        cond.W, cond.w0, state, contact, G=cond.G, e=e, increment=index, start=start
    )


def advance_force(
    cond: Condensed,
    state: ContactState,
    f_from: float,
    f_to: float,
    contact: ContactSettings,
    settings: CycleSettings,
    index: int,
    partial: Callable[[], CycleResult],
    previous: Branch | None = None,
) -> tuple[ContactState, IncrementResult]:
    """Go from force f_from to f_to, halving the step on failure up to max_cutbacks times.

    Args:
        cond: The configuration's condensed operators.
        state: Converged state at ``f_from``.
        f_from: Force at the start [N].
        f_to: Force to reach [N].
        contact: Contact-solver settings.
        settings: Cycle settings (cut-back limit).
        index: Increment index for error messages.
        partial: Builds the partial result attached to a final ConvergenceError.
        previous: The converged (force, state) before ``state`` on the same branch, if
            any: the first sub-step starts from the extrapolation (``branch_start``).

    Returns:
        The final state and the IncrementResult with works and iterations summed over
        the sub-steps (works as length-1 arrays).

    Raises:
        ConvergenceError: After ``settings.max_cutbacks`` halvings, with ``partial()``.
    """

    def attempt(n_sub: int) -> tuple[ContactState, IncrementResult]:
        s = state
        works = np.zeros(2)
        iters = 0
        for k in range(1, n_sub + 1):
            f = f_from + (f_to - f_from) * k / n_sub
            start = branch_start(s, f_from, f, previous) if k == 1 else None
            res = solve_at_force(cond, s, f, contact, index, start)
            works += [res.friction_work.sum(), res.normal_work.sum()]
            iters += res.iterations
            s = res.state
        summed = dataclasses.replace(
            res,
            friction_work=np.array([works[0]]),
            normal_work=np.array([works[1]]),
            iterations=iters,
        )
        return s, summed

    what = f"increment {index} (F {f_from:.4g} → {f_to:.4g} N)"
    return with_cutbacks(
        attempt, settings.max_cutbacks, increment=index, what=what, partial=partial
    )


def record_increment(
    stage: int, force_n: float, side: int, res: IncrementResult, cond: Condensed
) -> Increment:
    """The ``Increment`` of a converged contact solve at the grip force F [N] on ``side``."""
    p = np.ravel(res.state.p)
    # W p from the converged w = W p + G α + w0 (an exact product in solve_increment),
    # rather than another pass over W
    Wp = np.ravel(res.state.w - cond.w0) - cond.G @ np.asarray(res.state.alpha)
    return Increment(
        stage=stage,
        force_n=force_n,
        disp_mm=float(res.state.alpha[GRIP]),
        side=side,
        iterations=res.iterations,
        n_open=res.n_open,
        n_stick=res.n_stick,
        n_slip=res.n_slip,
        friction_work=float(np.sum(res.friction_work)),
        normal_work=float(np.sum(res.normal_work)),
        elastic_energy=0.5 * float(p @ Wp),
    )


def increment_displacements(
    system: HingeSystem, result: CycleResult, indices: Sequence[int]
) -> list[FloatArray]:
    """Displacement fields of chosen increments, shape (n_nodes, 3) each [mm], in one batch.

    One batch because a large mesh refactorises for every recovery
    (``HingeSystem.low_memory``).
    """
    return displacements(
        system,
        [
            (
                result.configs[result.increments[k].side],
                np.asarray(result.states[k].p),
                np.asarray(result.states[k].alpha),
            )
            for k in indices
        ],
    )


def stage_ends(increments: Sequence[Increment]) -> list[int]:
    """Indices of the last increment of every stage (the load peaks), in order."""
    n = len(increments)
    return [k for k in range(n) if k == n - 1 or increments[k + 1].stage != increments[k].stage]


def check_window(system: HingeSystem, result: CycleResult) -> None:
    """Raise if a point outside the contact window has closed (the window was too small).

    Checked at the stage ends (the load peaks), all at once after the cycle: recovering
    displacements needs the sparse factors, which a large mesh holds one at a time
    (``HingeSystem.low_memory``), so one batch costs one factorisation per part.

    Raises:
        ConvergenceError: Naming the point, the overlap and the force, with ``result``
            as its ``partial``.
    """
    peaks = [
        k
        for k in stage_ends(result.increments)
        if result.configs[result.increments[k].side].outside is not None
    ]
    if not peaks:
        return
    fields = increment_displacements(system, result, peaks)
    for k, u in zip(peaks, fields, strict=True):
        cond = result.configs[result.increments[k].side]
        gaps = outside_gaps(cond, u)
        i = int(np.argmin(gaps))
        if gaps[i] < 0.0 and cond.outside is not None:
            x = np.asarray(system.mesh.nodes)[cond.outside.slave[i]]
            theta = np.degrees(np.arctan2(x[1], x[0]))
            raise ConvergenceError(
                f"contact window too small: a point outside it (θ = {theta:.1f}°, "
                f"z = {x[2]:.2f} mm) closed by {-gaps[i] * 1e3:.3f} µm at "
                f"F = {result.increments[k].force_n:g} N; raise CycleSettings.contact_window",
                increment=k,
                iteration=0,
                residual=float(-gaps[i]),
                partial=result,
            )
