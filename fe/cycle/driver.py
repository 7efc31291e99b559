"""One driver for every hysteresis cycle: stages, targets, increments, partial result, progress.

A kind of hinge describes its increment as a ``CycleStep``; ``drive`` runs the protocol of
``CycleSettings.stages()`` through it::

    for each stage (F_from → F_to, n increments):
        for each target F of step.targets(F_from, F_to, n):
            record every (Increment, state) that step.advance(target, partial) yields
            progress(targets done, targets in the cycle)
    return step.result(increments, states, timings) + the recovered cut-backs

``partial()`` builds the result of the increments recorded so far; a step hands it to
``fe.cycle.protocol.with_cutbacks``, which attaches it to the ``ConvergenceError`` raised
when an increment fails after its cut-backs.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from fe.contact.state import ContactState
from fe.cycle.protocol import Cutback, CycleSettings, counting_cutbacks
from fe.cycle.result import CycleResult, Increment

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]

Recorded = tuple[Increment, ContactState]
"""One recorded increment and its final contact state (``CycleResult.states``)."""


@dataclass(frozen=True)
class Target:
    """One force target of the cycle, as the driver hands it to a step.

    Attributes:
        stage: Stage index (0: initial loading, then 1, 2, … alternating −/+).
        f_from: Force of the previous target [N] (0 before the first).
        f_to: Force to reach [N].
        index: Index the next recorded increment will have (for messages and errors).
        first: True for the first target of its stage: the load has just reversed (or
            starts), so a step that extrapolates along a branch starts a new one.
    """

    stage: int
    f_from: float
    f_to: float
    index: int
    first: bool


class CycleStep(Protocol):
    """What a kind of hinge supplies to ``drive``: its targets, its increment, its result.

    A step carries its own converged state from one target to the next; ``drive`` keeps
    the recorded increments and their contact states.
    """

    def targets(self, f_from: float, f_to: float, n: int) -> FloatArray:
        """Force targets of the stage ``f_from → f_to`` of ``n`` increments, shape (k,) [N].

        The last target is ``f_to``; a step may add targets (e.g. around F = 0).
        """
        ...

    def advance(self, target: Target, partial: Callable[[], CycleResult]) -> Iterator[Recorded]:
        """Reach ``target.f_to`` from the last converged state; yield each increment recorded.

        Yield in order, as each converges, so ``partial()`` holds every one of them if a
        later one fails; several may be recorded for one target (a crossing of F = 0, the
        steps of a slide, the sub-steps of a cut-back).

        Raises:
            ConvergenceError: If the target cannot be reached; its ``partial`` is ``partial()``.
        """
        ...

    def result(
        self,
        increments: tuple[Increment, ...],
        states: tuple[ContactState, ...],
        timings_s: dict[str, float],
    ) -> CycleResult:
        """The cycle result of these increments (also the partial result of a failed cycle)."""
        ...


def drive(
    step: CycleStep,
    settings: CycleSettings,
    progress: Callable[[int, int], None] | None = None,
    *,
    timings_s: Mapping[str, float] | None = None,
    phase: str = "cycle",
) -> CycleResult:
    """Run the load cycle of ``settings`` through ``step``.

    Args:
        step: The kind's increment (``CycleStep``), in its state before the first target.
        settings: The protocol: ``settings.stages()`` gives each stage's force range and
            increment count.
        progress: Called as ``progress(done, total)`` after each target, with ``total``
            the number of targets of the whole cycle.
        timings_s: Wall times of the phases before the cycle [s], kept in the result
            (also in a partial one).
        phase: The key of the cycle's own wall time in ``CycleResult.timings_s``.

    Returns:
        ``step.result`` of every recorded increment, timings ``{**timings_s, phase: t}``,
        and the increments recovered by cut-backs (``CycleResult.cutbacks``, counted by
        ``fe.cycle.protocol.counting_cutbacks``; one INFO line sums them up).

    Raises:
        ConvergenceError: As ``step.advance``; its ``partial`` holds the increments
            recorded before the failure (and the cut-backs recovered before it).
    """
    before = dict(timings_s or {})
    plan = [step.targets(f_from, f_to, n) for f_from, f_to, n in settings.stages()]
    total = sum(len(targets) for targets in plan)
    increments: list[Increment] = []
    states: list[ContactState] = []

    with counting_cutbacks() as cutbacks:

        def partial() -> CycleResult:
            result = step.result(tuple(increments), tuple(states), dict(before))
            return with_counted(result, cutbacks)

        t0 = time.perf_counter()
        done, f_prev = 0, 0.0
        for stage, targets in enumerate(plan):
            for k, f in enumerate(targets):
                target = Target(stage, f_prev, float(f), len(increments), k == 0)
                for increment, state in step.advance(target, partial):
                    increments.append(increment)
                    states.append(state)
                f_prev, done = float(f), done + 1
                if progress is not None:
                    progress(done, total)
        timings = {**before, phase: time.perf_counter() - t0}
        result = with_counted(step.result(tuple(increments), tuple(states), timings), cutbacks)
    if cutbacks:
        logger.info(
            "%d increments of %d converged only after cut-backs (%d halvings in all)",
            len(cutbacks), len(increments), result.n_cutbacks,
        )  # fmt: skip
    return result


def with_counted(result: CycleResult, cutbacks: list[Cutback]) -> CycleResult:
    """``result`` with the recovered cut-backs of its cycle added to its own (a step may count some)."""
    if not cutbacks:
        return result
    return dataclasses.replace(result, cutbacks=(*result.cutbacks, *cutbacks))
