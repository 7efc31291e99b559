"""The load-cycle driver (fe.cycle.driver) with a one-DOF friction element as its step.

The element: a linear spring k and a Coulomb slider of strength Fs acting together on one
displacement x under the grip force, ``F = k x + q`` with ``|q| ≤ Fs`` (the slider sticks
while ``|F − k x| < Fs``). (A spring and slider in series, the Jenkins element, cannot
carry more than Fs, so it has no state under force control at F > Fs; this pairing has
the same rigid-plastic slider and a loop under force control.) From +F the slider sticks
until the force has dropped by 2 Fs, then slips with ``x = (F + Fs)/k`` down to −F, and
back alike: the loop is a parallelogram of height 2 Fs and width ``2 (F − Fs)/k``::

    W_cycle = 4 Fs (F − Fs) / k,   δ_max = (F − Fs) / k,   η = W / (2π · ½ F δ_max) = 4 Fs / (π F)

The step records the point where slip starts as its own increment, so the trapezoidal
loop area is exact and must match the closed form to round-off.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from cad.errors import ConvergenceError
from fe.contact.law import ContactStatus
from fe.contact.state import ContactState
from fe.cycle.driver import Recorded, Target, drive
from fe.cycle.protocol import CycleSettings, stage_targets, with_cutbacks
from fe.cycle.result import CycleResult, Increment

K = 250.0  # [N/mm]
FS = 30.0  # [N]
F = 100.0  # [N]


class SliderStep:
    """Spring k and Coulomb slider Fs on one DOF (module docstring), solved exactly."""

    def __init__(self, settings: CycleSettings, fail_below_n: float = -math.inf) -> None:
        self.settings = settings
        self.fail_below_n = fail_below_n
        self.x = 0.0
        self.slip = 0  # direction of the last increment's slip (0: stuck)
        self.attempts: list[int] = []

    def targets(self, f_from: float, f_to: float, n: int) -> np.ndarray:
        return stage_targets(f_from, f_to, n, self.settings.grading)

    def advance(self, target: Target, partial: Callable[[], CycleResult]) -> Iterator[Recorded]:
        def attempt(n_sub: int) -> float:
            self.attempts.append(n_sub)
            if target.f_to < self.fail_below_n:
                raise ConvergenceError("forced", increment=-1, iteration=7, residual=0.5)
            return target.f_to

        f = with_cutbacks(
            attempt, self.settings.max_cutbacks, increment=target.index, what="slider",
            partial=partial,
        )  # fmt: skip
        q = f - K * self.x
        if abs(q) <= FS:
            self.slip = 0
            yield self.record(target.stage, f, self.x, 0, 0.0)
            return
        d = 1 if q > 0 else -1
        if self.slip != d:  # slip starts inside this target: its point is on the loop
            yield self.record(target.stage, K * self.x + d * FS, self.x, 0, 0.0)
        x = (f - d * FS) / K
        work = FS * abs(x - self.x)
        self.x, self.slip = x, d
        yield self.record(target.stage, f, x, d, work)

    def record(self, stage: int, f: float, x: float, slip: int, work: float) -> Recorded:
        status = ContactStatus.SLIP if slip else ContactStatus.STICK
        inc = Increment(
            stage=stage, force_n=f, disp_mm=x, side=1, iterations=1, n_open=0,
            n_stick=int(not slip), n_slip=int(bool(slip)), friction_work=work, normal_work=0.0,
            elastic_energy=0.5 * K * x * x,
        )  # fmt: skip
        state = ContactState(
            np.array([[f - K * x, 0.0, 0.0]]), np.array([[x, 0.0, 0.0]]),
            np.array([status], dtype=np.int8), np.array([x]),
        )  # fmt: skip
        return inc, state

    def result(
        self,
        increments: tuple[Increment, ...],
        states: tuple[ContactState, ...],
        timings_s: dict[str, float],
    ) -> CycleResult:
        return CycleResult(self.settings, 0.0, increments, 0.0, states, {}, timings_s)


def settings(**kw) -> CycleSettings:
    return CycleSettings(amplitude_n=F, **{"increments_per_stage": 10, **kw})


@pytest.mark.parametrize("n_cycles", [1, 3], ids=["one-cycle", "three-cycles"])
def test_loop_area_and_eta_of_the_slider_are_the_closed_form(n_cycles):
    result = drive(SliderStep(settings(n_cycles=n_cycles)), settings(n_cycles=n_cycles))
    m = result.metrics()
    assert m["W_cycle_Nmm"] == pytest.approx(4 * FS * (F - FS) / K, rel=1e-13)
    assert m["delta_max_mm"] == pytest.approx((F - FS) / K, rel=1e-13)
    assert m["eta"] == pytest.approx(4 * FS / (math.pi * F), rel=1e-13)
    assert m["energy_balance_rel_err"] < 1e-13
    assert result.work_per_cycle() == pytest.approx([4 * FS * (F - FS) / K] * n_cycles, rel=1e-13)


def test_increments_states_and_timings_are_recorded_in_order():
    s = settings()
    result = drive(SliderStep(s), s, timings_s={"setup": 1.5}, phase="loop")
    stages = [i.stage for i in result.increments]
    assert stages == sorted(stages)
    assert set(stages) == {0, 1, 2}
    assert len(result.states) == len(result.increments)
    for inc, state in zip(result.increments, result.states, strict=True):
        assert state.alpha[0] == inc.disp_mm
    peaks = [i.force_n for i in result.increments if abs(i.force_n) == F]
    assert peaks == [F, -F, F]
    assert set(result.timings_s) == {"setup", "loop"}
    assert result.timings_s["setup"] == 1.5


def test_progress_is_called_once_per_target_with_the_total():
    s = settings(increments_per_stage=6, n_cycles=2)
    calls: list[tuple[int, int]] = []
    drive(SliderStep(s), s, lambda done, total: calls.append((done, total)))
    total = sum(n for _, _, n in s.stages())  # 3 + 4 × 6 targets
    assert total == 27
    assert calls == [(k, total) for k in range(1, total + 1)]


def test_each_target_knows_its_stage_start_force_and_index():
    s = settings(increments_per_stage=4)
    seen: list[Target] = []

    class Spy(SliderStep):
        def advance(self, target, partial):
            seen.append(target)
            yield from super().advance(target, partial)

    result = drive(Spy(s), s)
    assert [t.first for t in seen] == [
        True,
        False,
        True,
        False,
        False,
        False,
        True,
        False,
        False,
        False,
    ]
    assert seen[0].f_from == 0.0
    for a, b in itertools.pairwise(seen):
        assert b.f_from == a.f_to
        assert b.index > a.index  # several increments may be recorded for one target
    assert seen[-1].f_to == F
    assert seen[-1].index < len(result.increments)


def test_a_failing_step_is_cut_back_then_raises_with_the_partial_loop():
    s = settings(max_cutbacks=3)
    step = SliderStep(s, fail_below_n=-0.5 * F)
    with pytest.raises(ConvergenceError, match=r"slider failed after 3 cut-backs") as err:
        drive(step, s)
    e = err.value
    assert step.attempts[-4:] == [1, 2, 4, 8]  # the target, then halved three times
    assert (e.iteration, e.residual) == (7, 0.5)
    partial = e.partial
    assert isinstance(partial, CycleResult)
    assert e.increment == len(partial.increments)  # the increment that failed is the next
    assert len(partial.increments) == len(partial.states) > 0
    assert min(i.force_n for i in partial.increments) >= -0.5 * F
    assert partial.increments[-1].stage == 1  # on the way down
    assert partial.timings_s == {}


def test_a_step_is_not_driven_past_its_failure():
    s = settings(max_cutbacks=0)
    step = SliderStep(s, fail_below_n=0.5 * F)  # the first target already fails
    with pytest.raises(ConvergenceError, match="after 0 cut-backs") as err:
        drive(step, s)
    assert err.value.increment == 0
    assert err.value.partial.increments == ()
    assert step.attempts == [1]


class HardStep(SliderStep):
    """The slider, whose targets in a force window converge only in ``needs`` sub-steps."""

    def __init__(self, settings: CycleSettings, window: tuple[float, float], needs: int) -> None:
        super().__init__(settings)
        self.window, self.needs = window, needs
        self.hard: list[int] = []

    def advance(self, target: Target, partial: Callable[[], CycleResult]) -> Iterator[Recorded]:
        lo, hi = self.window
        if lo <= target.f_to <= hi:
            self.hard.append(target.index)

            def attempt(n_sub: int) -> None:
                if n_sub < self.needs:
                    raise ConvergenceError("too big", increment=target.index, iteration=9,
                                           residual=1.0)  # fmt: skip

            with_cutbacks(attempt, self.settings.max_cutbacks, increment=target.index,
                          what="hard", partial=partial)  # fmt: skip
        yield from super().advance(target, partial)


def test_recovered_cutbacks_are_counted_and_logged_only_at_info(caplog):
    """Two halvings per hard target (1 and 2 sub-steps fail, 4 converge): each is counted
    by increment in the result, and nothing reaches WARNING (one line per cut-back)."""
    s = settings()
    step = HardStep(s, (-0.6 * F, -0.2 * F), needs=4)
    with caplog.at_level("INFO", logger="fe.cycle"):
        result = drive(step, s)
    assert len(step.hard) >= 2
    assert result.cutbacks == tuple((k, 2) for k in step.hard)
    assert result.n_cutbacks == 2 * len(step.hard)
    assert not [r for r in caplog.records if r.levelno >= 30]
    info = [r.getMessage() for r in caplog.records if r.levelno == 20]
    assert sum("cutting back" in m for m in info) == 2 * len(step.hard)
    assert any(f"{len(step.hard)} increments of {len(result.increments)}" in m for m in info)
    # the loop is that of the easy slider: cut-backs change the cost, not the result
    assert result.metrics()["eta"] == pytest.approx(4 * FS / (math.pi * F), rel=1e-13)
    assert drive(SliderStep(s), s).cutbacks == ()


def test_a_failure_after_recovered_cutbacks_keeps_them_in_the_partial_loop():
    s = settings(max_cutbacks=3)

    class Failing(HardStep):
        def advance(self, target, partial):
            if target.f_to < -0.8 * F:
                raise ConvergenceError("stop", increment=target.index, iteration=4, residual=2.0,
                                       partial=partial())  # fmt: skip
            yield from super().advance(target, partial)

    step = Failing(s, (-0.79 * F, 0.5 * F), needs=2)
    with pytest.raises(ConvergenceError, match=r"iteration 4, residual 2\.000e\+00") as err:
        drive(step, s)
    assert err.value.partial.cutbacks == tuple((k, 1) for k in step.hard)
    assert len(step.hard) >= 2
