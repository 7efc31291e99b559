"""What a finished cycle says about its own convergence: the energy balance and the cut-backs.

Two checks cost nothing, because the cycle has computed what they need:

* the energy balance (``CycleResult.metrics()['energy_balance_rel_err']``): the friction and
  open/close work summed over every contact point against the loop area minus the change
  of elastic energy. A converged, well-resolved cycle closes it to round-off (the general
  hinge: about 1e-13) or to its load-step quadrature; a balance worse than
  ``ENERGY_BALANCE_TOL`` means the increments are too coarse for the loop (measured: the
  bearing hinge with frictional fits at F_p = 0 closes it to 2.9 % with 20 increments per
  half cycle, 0.6 % with 40);
* recovered cut-backs (``CycleResult.cutbacks``): each one is an increment that failed at
  its full size and was solved in halves. They do not make the result wrong, but many of
  them cost time and say that the steps are too large for the contact solver.

Each check gives a ``Finding`` naming the ``CycleSettings`` field to raise; the command
line turns it into a message with the option or key the user types.

What the energy balance cannot see: with clearance, too few increments change the path
(points open and close inside an increment) while the balance still closes to round-off
(measured at Δr = 0.1 mm: η off by 40 % with a balance of 1e-13). That needs a run at
more increments (``studies.convergence``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fe.cycle.result import CycleResult

ENERGY_BALANCE_TOL = 0.01
"""Relative energy-balance error above which a cycle is reported as under-resolved (1 %).

Between the bearing hinge with frictional fits at 20 increments (2.9 %) and at 40
(0.6 %); every other cycle of the project closes its balance to below 1e-6."""

MANY_CUTBACKS_FRACTION = 0.1
"""Share of the increments that may need cut-backs before the cycle says to raise the
increments (10 %: an occasional cut-back at a reversal is normal)."""


@dataclass(frozen=True)
class Finding:
    """One thing a cycle's user should know about its convergence.

    Attributes:
        kind: ``"energy_balance"`` or ``"cutbacks"``.
        setting: The ``CycleSettings`` field to raise (``increments_per_stage``, or
            ``clearance_increments`` for a cycle with clearance).
        current: Its value in this cycle.
        value: The measured quantity (the relative balance error, or the cut-backs).
        limit: The limit it exceeded.
        text: What was measured, in words, without the option to change.
    """

    kind: str
    setting: str
    current: int
    value: float
    limit: float
    text: str


def increments_setting(result: CycleResult) -> tuple[str, int]:
    """The ``CycleSettings`` field that set the cycle's increments per half cycle, and its value.

    ``clearance_increments`` replaces ``increments_per_stage`` where the hinge has a
    clearance (``CycleSettings``).
    """
    s = result.settings
    if result.clearance_mm > 0.0:
        return "clearance_increments", s.clearance_increments
    return "increments_per_stage", s.increments_per_stage


def convergence_findings(result: CycleResult) -> list[Finding]:
    """The findings of a finished cycle: energy balance worse than the tolerance, many cut-backs.

    Args:
        result: A complete cycle (with a closed loop).

    Returns:
        The findings, empty for a cycle that passes both checks.
    """
    setting, current = increments_setting(result)
    out = []
    err = result.metrics()["energy_balance_rel_err"]
    if math.isfinite(err) and err > ENERGY_BALANCE_TOL:
        out.append(
            Finding(
                "energy_balance",
                setting,
                current,
                err,
                ENERGY_BALANCE_TOL,
                f"the energy balance closes only to {100 * err:.2g} % "
                f"(tolerance {100 * ENERGY_BALANCE_TOL:g} %) with {current} increments per "
                "half cycle: the loss factor is not converged",
            )
        )
    n_inc = max(len(result.increments), 1)
    if len(result.cutbacks) > MANY_CUTBACKS_FRACTION * n_inc:
        out.append(
            Finding(
                "cutbacks",
                setting,
                current,
                float(result.n_cutbacks),
                MANY_CUTBACKS_FRACTION,
                f"{len(result.cutbacks)} of {len(result.increments)} increments converged "
                f"only after cut-backs ({result.n_cutbacks} halvings): the steps are too "
                "large for the contact solver (the result holds; smaller steps are faster)",
            )
        )
    return out
