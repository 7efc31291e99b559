"""Convergence a user can see: a cycle's findings in the user's words, and the doubled-increments check.

A finished cycle checks itself at no cost (``fe.cycle.checks``: the energy balance, the
recovered cut-backs); ``warning_lines`` says what was measured and which option or key to
raise. With clearance the balance closes to round-off even when the increments are far too
few (points open and close inside an increment; measured on the coarse mesh at Δr = 0.1 mm,
300 N: η 0.00157 / 0.00125 / 0.00116 / 0.00113 / 0.00112 with 12 / 20 / 40 / 60 / 120
increments per half cycle, balance ≤ 2e-13 throughout), so a sweep reruns one point with the
clearance increments doubled and reports the change of η (``doubled_check``). The point is
the clearance point of the largest amplitude: on that mesh the error at a given increment
count grows with the amplitude above 200 N (at 200 N, 12 increments are within 1 %).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from fe.cycle.checks import convergence_findings, increments_setting
from fe.cycle.result import CycleResult

if TYPE_CHECKING:
    from model.service import ModelService
    from model.spec import DesignPoint, ModelSpec

logger = logging.getLogger(__name__)

SETTING_HINTS = {
    "increments_per_stage": "--increments (MODEL.toml [cycle] increments_per_stage, "
    "a study's [solver] increments_per_stage)",
    "clearance_increments": "--increments (MODEL.toml [cycle] clearance_increments, "
    "a study's [solver] clearance_increments)",
}
"""A ``CycleSettings`` field → the option and keys a user sets it with."""

DOUBLED_TOL = 0.02
"""Relative change of η at doubled increments above which a sweep warns (2 %).

On the coarse mesh at Δr = 0.1 mm the default 60 clearance increments change η by 0.9 %
(300 N) and 0.6 % (400 N) when doubled; 40 change it by 2.5 % and 1.0 %, 12 by 26 % and 14 %."""


def warning_lines(result: CycleResult) -> list[str]:
    """The convergence warnings of a finished cycle, each naming the option to raise.

    Args:
        result: A complete cycle.

    Returns:
        One line per finding of ``fe.cycle.checks.convergence_findings`` (empty if none).
    """
    return [
        f"{f.text}; raise {SETTING_HINTS.get(f.setting, f.setting)} above {f.current}"
        for f in convergence_findings(result)
    ]


@dataclass(frozen=True)
class IncrementCheck:
    """One point run again at doubled increments.

    Attributes:
        label: The point (``model.spec.point_label``).
        setting: The ``CycleSettings`` field doubled.
        increments: Its value in the sweep.
        eta: η of the sweep's run.
        eta_doubled: η at twice the increments.
        wall_s: Wall time of the doubled run [s] (0 when read back from the store).
    """

    label: str
    setting: str
    increments: int
    eta: float
    eta_doubled: float
    wall_s: float

    @property
    def change_rel(self) -> float:
        """|η(2n) − η(n)| / |η(2n)| (NaN where η is not defined)."""
        if not (math.isfinite(self.eta) and math.isfinite(self.eta_doubled)):
            return math.nan
        return abs(self.eta_doubled - self.eta) / max(abs(self.eta_doubled), 1e-300)

    @property
    def converged(self) -> bool:
        """True where doubling the increments changed η by at most ``DOUBLED_TOL``."""
        return not self.change_rel > DOUBLED_TOL

    def message(self) -> str:
        """What was measured, and the option to raise where it is not converged."""
        text = (
            f"{self.label}: η {self.eta:.5g} with {self.increments} increments per half "
            f"cycle, {self.eta_doubled:.5g} with {2 * self.increments} "
            f"({100 * self.change_rel:.2g} % change, tolerance {100 * DOUBLED_TOL:g} %)"
        )
        if self.converged:
            return text
        hint = SETTING_HINTS.get(self.setting, self.setting)
        return f"{text}: the loss factors are not converged; raise {hint} above {self.increments}"

    def record(self) -> dict[str, object]:
        """The check as plain data (for convergence.json)."""
        return {
            **dataclasses.asdict(self),
            "change_rel": self.change_rel,
            "tolerance": DOUBLED_TOL,
            "converged": self.converged,
            "message": self.message(),
        }


def check_point(results: Sequence[tuple[DesignPoint, CycleResult]]) -> int | None:
    """Index of the point to check: the clearance point of the largest amplitude, or None.

    Of several at that amplitude, the last (a sweep runs level by level, so its geometry
    is the one the sweep's service still holds).
    """
    play = [k for k, (_, r) in enumerate(results) if r.clearance_mm > 0.0]
    if not play:
        return None
    return max(play, key=lambda k: (results[k][0].amplitude_n, k))


def doubled_check(
    service: ModelService, spec: ModelSpec, point: DesignPoint, result: CycleResult
) -> IncrementCheck:
    """Run ``point`` again with its increments per half cycle doubled and compare η.

    Args:
        service: The service of the sweep (its store keeps the doubled run by its own key).
        spec: The sweep's model.
        point: The point to check.
        result: Its cycle at the sweep's increments.

    Returns:
        The check; its ``message()`` says whether η moved by more than ``DOUBLED_TOL``.
    """
    from model.spec import point_label

    setting, n = increments_setting(result)
    doubled = dataclasses.replace(spec, cycle=dataclasses.replace(spec.cycle, **{setting: 2 * n}))
    t0 = time.perf_counter()
    again = service.run_point(doubled, point)
    check = IncrementCheck(
        point_label(spec, point),
        setting,
        n,
        result.metrics()["eta"],
        again.metrics()["eta"],
        time.perf_counter() - t0,
    )
    logger.info("convergence check: %s (%.1f s)", check.message(), check.wall_s)
    return check
