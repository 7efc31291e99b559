"""The load protocol of a hysteresis cycle as data: 0 → +Fg → −Fg → +Fg, increments, solver options."""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from cad.errors import ConvergenceError, check_range
from fe.contact.state import ContactSettings

logger = logging.getLogger(__name__)

T = TypeVar("T")

FloatArray = npt.NDArray[np.float64]


DEFAULT_MU = 0.2
"""Default pin–hole friction coefficient. The paper gives none; 0.2 is a middle value for
steel on anodised aluminium with a dry-film lubricant, the usual state of a space hinge
(dry unlubricated pairs reach 0.4–0.6, MoS₂ films 0.05–0.15)."""


DEFAULT_FORCE_RATE = 20.0
"""Default force rate of the load ramps [N/s]: the synthetic test machine's
(``validation.synth.SynthSettings``); a 400 N loop then takes 100 s. Only a time-dependent
effect (``fe.effects.base.History``) sees it; set ``[cycle] force_rate_n_per_s`` to the rate
of the test the model is compared with."""


@dataclass(frozen=True)
class CycleSettings:
    """Load protocol and solver options of a hysteresis cycle.

    Attributes:
        amplitude_n: Force amplitude Fg [N].
        mu: Coulomb friction coefficient of every contact pair.
        increments_per_stage: Increments from one force extreme to the next (the
            initial 0 → +Fg stage uses half as many).
        n_cycles: Closed loops −Fg → +Fg after the initial loading (the paper: 1).
        grading: Exponent of the increment spacing after a reversal (1 = uniform; > 1
            makes the first steps after each reversal smaller).
        max_cutbacks: Halvings of a failing increment before giving up.
        tol: Contact-solver tolerance on the scaled residual.
        max_iter: Contact Newton iterations per increment before a cut-back.
        clearance_increments: Increments per stage used instead of
            ``increments_per_stage`` when Δr > 0. Points that open or close inside an
            increment make the loop area first-order in the step; at Δr = 0.1 mm, 100 N
            (default mesh) η was 0.00107 / 0.00096 / 0.00093 with 20 / 40 / 80 increments,
            while at Δr = 0, 20 increments agree with 40 to 0.03 %.
        contact_window: With clearance, solve only for the points whose initial gap in
            the touching configuration is ≤ contact_window·Δr (0.5: about ±60° around
            the load line); the others are checked to stay open at every load peak, and
            the cycle stops with a clear error if one closed. 0 solves for every point.
        blas_threads: BLAS threads for the dense contact solves. Their matrices are a
            few hundred to a few thousand wide, where one thread is faster than two
            (benchmarks/bench_cycle.txt, 'CycleSettings.blas_threads').
        force_rate_n_per_s: Rate of the force ramps [N/s]: the protocol's clock
            (``fe.effects.history.protocol_time``), seen only by time-dependent effects;
            a measured record's own time replaces it where the model is compared with
            the record (``fe.effects.history.time_from_reference``).
    """

    amplitude_n: float = 400.0
    mu: float = DEFAULT_MU
    increments_per_stage: int = 20
    n_cycles: int = 1
    grading: float = 1.5
    max_cutbacks: int = 5
    tol: float = 1e-10
    max_iter: int = 60
    blas_threads: int = 1
    contact_window: float = 0.5
    clearance_increments: int = 60
    force_rate_n_per_s: float = DEFAULT_FORCE_RATE

    def __post_init__(self) -> None:
        check_range("amplitude_n", self.amplitude_n, 0.0, 1e6, lo_open=True)
        check_range("mu", self.mu, 0.0, 2.0)
        check_range("increments_per_stage", self.increments_per_stage, 2, 10_000)
        check_range("n_cycles", self.n_cycles, 1, 100)
        check_range("grading", self.grading, 1.0, 4.0)
        check_range("max_cutbacks", self.max_cutbacks, 0, 20)
        check_range("blas_threads", self.blas_threads, 1, 64)
        check_range("contact_window", self.contact_window, 0.0, 10.0)
        check_range("clearance_increments", self.clearance_increments, 2, 10_000)
        check_range("force_rate_n_per_s", self.force_rate_n_per_s, 0.0, 1e9, lo_open=True)

    def contact(self) -> ContactSettings:
        """The contact-solver settings of the cycle (μ, tolerance, iteration budget)."""
        return ContactSettings(mu=self.mu, tol=self.tol, max_iter=self.max_iter)

    def stages(self) -> list[tuple[float, float, int]]:
        """Return the stages as (F_from, F_to, increments) [N]."""
        F = self.amplitude_n
        out = [(0.0, F, max(2, self.increments_per_stage // 2))]
        for _ in range(self.n_cycles):
            out += [(F, -F, self.increments_per_stage), (-F, F, self.increments_per_stage)]
        return out


def stage_targets(f_from: float, f_to: float, n: int, grading: float) -> FloatArray:
    """Force targets of one stage, shape (n,) [N]: ``f_from + (f_to − f_from)·(k/n)^grading``."""
    s = (np.arange(1, n + 1) / n) ** grading
    return f_from + (f_to - f_from) * s


Cutback = tuple[int, int]
"""One increment recovered by cut-backs: (increment index, halvings it needed)."""

_TALLY: ContextVar[list[Cutback] | None] = ContextVar("cutback_tally", default=None)


@contextmanager
def counting_cutbacks() -> Iterator[list[Cutback]]:
    """Collect the cut-backs ``with_cutbacks`` recovers inside the block, in order.

    ``fe.cycle.driver.drive`` wraps a cycle in it, so every step that cuts back through
    ``with_cutbacks`` is counted without passing a counter through it. The list is filled
    as increments recover; a nested block has its own list (a context variable, so a
    thread or a Dask task counts only its own cycle).
    """
    tally: list[Cutback] = []
    token = _TALLY.set(tally)
    try:
        yield tally
    finally:
        _TALLY.reset(token)


def with_cutbacks(
    attempt: Callable[[int], T],
    max_cutbacks: int,
    *,
    increment: int,
    what: str,
    partial: Callable[[], object],
) -> T:
    """Run ``attempt(n_sub)`` with n_sub = 1, 2, 4, … sub-steps until one converges.

    A failed attempt and a recovery are logged at INFO (``-v``), not as warnings: a
    recovered increment is a correct increment. They are counted instead
    (``counting_cutbacks``), and the cycle's summary says what to change when there were
    many (``fe.cycle.checks``).

    Args:
        attempt: Solves the increment in ``n_sub`` equal sub-steps; raises ConvergenceError.
        max_cutbacks: Halvings before giving up.
        increment: Index of the increment, for messages.
        what: The increment in words (e.g. ``increment 3 (F 0 → 40 N)``), for messages.
        partial: Builds what is kept when the increment finally fails (the partial loop).

    Raises:
        ConvergenceError: ``"{what} failed after {max_cutbacks} cut-backs"`` with the last
            attempt's iteration and residual and ``partial()``.
    """
    last: ConvergenceError | None = None
    for level in range(max_cutbacks + 1):
        try:
            out = attempt(2**level)
        except ConvergenceError as err:
            last = err
            logger.info("%s failed, cutting back: %s", what, err)
            continue
        if level:
            logger.info("increment %d converged after %d cut-backs", increment, level)
            tally = _TALLY.get()
            if tally is not None:
                tally.append((increment, level))
        return out
    assert last is not None
    raise ConvergenceError(
        f"{what} failed after {max_cutbacks} cut-backs",
        increment=increment,
        iteration=last.iteration,
        residual=last.residual,
        partial=partial(),
    ) from last
