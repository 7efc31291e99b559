"""The cycle of a hinge with clearance and clamped faces: the free play crossed by sliding.

With clearance and the clevis arms clamped onto the tang (``fe.general.faces``), the pin is
not the only load path: while the faces stick they hold the clevis wherever it is in the
free play. The pin changes sides only when the faces let go, at the force ``F_slide``
where every face point slips (about ``μ`` times the clamp on both faces); then the clevis
slides rigidly across the free play at that force until the pin touches the other side.
The loop therefore crosses the free play at ``F = ±F_slide``, not at 0, and the crossing
is a rectangle of area ``F_slide × travel``: real dissipation at the faces.

How it is computed (``SlidingStep``, which ``fe.general.cycle.run_cycle`` drives through
``fe.cycle.driver.drive`` when the configurations have face points), with the two touching
configurations of ``fe.general.cycle.configurations`` (the clevis at ``±2Δr`` from the tang,
the pin at ``±Δr``):

* **start**: the pin centred in its holes, the clevis centred (``δ = −2Δr`` in the
  tension configuration's coordinates), nothing touching; the clamp is applied with the
  first load increment, as at Δr = 0.
* **force control** (as ``fe.general.increments.advance_force``) in the current
  configuration while the target is within what the faces hold, or on the side where the
  pin is engaged; the pin may open and float (``p = 0`` on all its points), the faces then
  carry the load alone.
  Until the first slide the faces alone are solved (``_held``) and the pin stays centred.
* **approach**: when a target lies beyond ``F_slide`` on the side where the pin is not
  engaged, force control goes to ``(1 − APPROACH_MARGIN) F_slide``, then the grip is
  moved (displacement control, pin included) in doubling steps until every face point
  slips and the pin is open: the faces' limit load, reached without a limit point.
* **slide**: the face points are tang nodes against the arm's plane, so crossing the free
  play is a pure tangential shift of their reference: the state is carried into the
  other configuration unchanged (forces, relative displacement; the grip coordinate
  shifted by ``(s_old − s_new)·2Δr``, so the machine displacement ``δ + s·2Δr`` is
  continuous). Where the pin first touches in the new configuration is a linear program
  (the grip's extreme position, over the pin's rigid positions, with every pin gap ≥ 0
  under the faces' sliding forces, ``fe.general.crossing.engagement``). The slide is then one
  displacement-controlled increment of the faces alone (the pin carries nothing) to that
  position: the friction work of that increment is the rectangle.
* **force control** in the new configuration from there.

Every recorded step is one increment of the linear contact problem, so the trapezoidal
energy identity of ``fe.contact`` holds step by step and the loop area (with the free
play, ``CycleResult.machine_path``) equals the friction work of pin and face points. The
approximation: the face points keep their master facets over the slide (the arm's
compliance is taken at the tang node's centred position; the travel is 4Δr, small against
the footprint).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator

import numpy as np
import numpy.typing as npt

from cad.errors import ConvergenceError
from fe.contact.law import ContactStatus
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState, IncrementResult
from fe.cycle.driver import Recorded, Target
from fe.cycle.protocol import CycleSettings, stage_targets, with_cutbacks
from fe.cycle.result import CycleResult, Increment
from fe.general.crossing import (
    consistent_w,
    engagement,
    face_mask,
    face_rows,
    status_counts,
    switched_state,
)
from fe.general.increments import Branch, branch_start, record_increment, solve_at_force
from fe.general.system import GRIP, N_PIN_MODES, N_RIGID
from fe.structure.condensed import Condensed

FloatArray = npt.NDArray[np.float64]

APPROACH_MARGIN = 0.05
"""Force control stops this fraction below ``F_slide`` before the grip is moved instead."""

FIRST_APPROACH_STEP_MM = 2e-5
"""First grip step of the approach [mm] (the faces' elastic travel to full slip is ~0.1–1 µm)."""

FREE_PIN_TOL = 1e-9
"""The pin is free (carries nothing) when its contact forces sum to at most this × Fg."""

MAX_APPROACH_STEPS = 40
"""Doublings of the grip step before the faces must be in full slip."""


@dataclasses.dataclass(frozen=True)
class _Step:
    """A converged step: the full state of its configuration and the works of the step."""

    state: ContactState
    friction_work: float
    normal_work: float
    iterations: int
    n_counts: tuple[int, int, int]


def _scattered(
    cond: Condensed, sel: npt.NDArray[np.bool_], res: IncrementResult, alpha: FloatArray
) -> _Step:
    """The full step of a sub-problem solved on the ``sel`` points at rigid amplitudes ``alpha``.

    Points outside ``sel`` keep ``p = 0`` and get the consistent ``w``; the solved points keep
    the solver's own (exact) ``w``.
    """
    m = len(cond.geo.slave)
    p = np.zeros((m, 3))
    p[sel] = res.state.p
    w = consistent_w(cond, p, alpha)
    w[sel] = res.state.w
    status = np.zeros(m, dtype=np.int8)
    status[sel] = res.state.status
    return _Step(
        ContactState(p, w, status, alpha),
        float(np.sum(res.friction_work)),
        float(np.sum(res.normal_work)),
        res.iterations,
        status_counts(status),
    )


def _displaced(
    cond: Condensed,
    state: ContactState,
    delta_mm: float,
    contact: ContactSettings,
    mask: npt.NDArray[np.bool_] | None,
    index: int,
) -> _Step:
    """One displacement-controlled increment: the grip moved to ``delta_mm``.

    ``mask`` None: every point, the pin's six modes free (``Gᵀp = 0`` on them); else only
    the masked points (faces), which the pin modes do not move. Returns the full state
    (points outside the mask keep ``p = 0`` and get consistent ``w``).
    """
    m = len(cond.geo.slave)
    sel = np.ones(m, dtype=bool) if mask is None else mask
    rows = face_rows(sel)
    W = np.asarray(cond.W)[np.ix_(rows, rows)]
    G = np.asarray(cond.G)[rows]
    k = N_PIN_MODES if mask is None else 0
    w_free = (np.asarray(cond.w0)[sel].ravel() + G[:, GRIP] * delta_mm).reshape(-1, 3)
    prev = ContactState(
        np.asarray(state.p)[sel],
        np.asarray(state.w)[sel],
        np.asarray(state.status)[sel],
        np.asarray(state.alpha)[:k],
    )
    res = solve_increment(W, w_free, prev, contact, G=G[:, :k], e=np.zeros(k), increment=index)
    alpha = np.array(state.alpha, dtype=np.float64, copy=True)
    alpha[:k] = res.state.alpha
    alpha[GRIP] = delta_mm
    return _scattered(cond, sel, res, alpha)


def _held(
    cond: Condensed, state: ContactState, force_n: float, contact: ContactSettings, index: int
) -> _Step:
    """One force-controlled increment of the faces alone, the pin kept where it is (centred).

    While the faces hold the clevis in the middle of the free play the pin touches nothing;
    leaving it out keeps it centred (in the whole problem it would float to the
    minimum-norm position, against the far side of the clevis' holes).
    """
    sel = face_mask(cond)
    rows = face_rows(sel)
    W = np.asarray(cond.W)[np.ix_(rows, rows)]
    G = np.asarray(cond.G)[rows][:, [GRIP]]
    prev = ContactState(
        np.asarray(state.p)[sel],
        np.asarray(state.w)[sel],
        np.asarray(state.status)[sel],
        np.asarray(state.alpha)[[GRIP]],
    )
    w_free = np.asarray(cond.w0)[sel]
    res = solve_increment(W, w_free, prev, contact, G=G, e=np.array([-force_n]), increment=index)
    alpha = np.array(state.alpha, dtype=np.float64, copy=True)
    alpha[GRIP] = res.state.alpha[0]
    return _scattered(cond, sel, res, alpha)


def _held_steps(
    cond: Condensed,
    state: ContactState,
    f_from: float,
    f_to: float,
    contact: ContactSettings,
    settings: CycleSettings,
    index: int,
    partial: Callable[[], CycleResult],
) -> list[_Step]:
    """``_held`` from ``f_from`` to ``f_to``, with cut-backs; every sub-step returned."""

    def attempt(n_sub: int) -> list[_Step]:
        out: list[_Step] = []
        st = state
        for k in range(1, n_sub + 1):
            out.append(_held(cond, st, f_from + (f_to - f_from) * k / n_sub, contact, index))
            st = out[-1].state
        return out

    what = f"increment {index} (F {f_from:.4g} → {f_to:.4g} N, faces holding)"
    return with_cutbacks(
        attempt, settings.max_cutbacks, increment=index, what=what, partial=partial
    )


def slide_force(cond: Condensed, contact: ContactSettings, direction: int) -> float:
    """Force the faces hold before they slide, ``F_slide`` [N] (> 0), for a grip moving ``direction``.

    The faces alone (the pin open), clamped from the open state and slid by a travel far
    larger than their elastic displacements, so every point slips along x: the grip force
    of that state is ``μ Σ p_n`` of the faces at full slip.
    """
    faces = face_mask(cond)
    travel = 1.0  # [mm]: thousands of times the faces' elastic displacement
    start = ContactState.initial(
        len(cond.geo.slave),
        N_RIGID,
        w=consistent_w(cond, np.zeros((len(cond.geo.slave), 3)), np.zeros(N_RIGID)),
    )
    step = _displaced(cond, start, direction * travel, contact, faces, 0)
    return abs(float(-np.asarray(cond.G)[:, GRIP] @ np.ravel(step.state.p)))


def _forced(
    cond: Condensed,
    state: ContactState,
    f_from: float,
    f_to: float,
    contact: ContactSettings,
    settings: CycleSettings,
    index: int,
    partial: Callable[[], CycleResult],
    previous: Branch | None,
) -> list[tuple[float, ContactState, IncrementResult]]:
    """Force control from ``f_from`` to ``f_to`` (as ``advance_force``), every sub-step kept.

    A cut-back's sub-steps are returned (and recorded) one by one, so the loop has their
    points and its trapezoidal area matches their works exactly.
    """

    def attempt(n_sub: int) -> list[tuple[float, ContactState, IncrementResult]]:
        out: list[tuple[float, ContactState, IncrementResult]] = []
        st, f0, prev = state, f_from, previous
        for k in range(1, n_sub + 1):
            f = f_from + (f_to - f_from) * k / n_sub
            start = branch_start(st, f0, f, prev)  # every sub-step on the branch
            res = solve_at_force(cond, st, f, contact, index + len(out), start)
            out.append((f, res.state, res))
            st, f0, prev = res.state, f, (f0, st)
        return out

    what = f"increment {index} (F {f_from:.4g} → {f_to:.4g} N)"
    return with_cutbacks(
        attempt, settings.max_cutbacks, increment=index, what=what, partial=partial
    )


def _approach(
    cond: Condensed,
    state: ContactState,
    direction: int,
    contact: ContactSettings,
    settings: CycleSettings,
    index: int,
    partial: Callable[[], CycleResult],
    centred: bool,
) -> list[_Step]:
    """Move the grip in doubling steps until no face point sticks and the pin is free.

    Displacement control has no limit point, so the faces' limit load (where they let go)
    is reached without the force-controlled solve failing at it. Returns every step.
    ``centred``: the pin is in the middle of its holes and stays out of the solve.
    """
    faces = face_mask(cond)
    mask = faces if centred else None
    steps: list[_Step] = []
    step_mm = FIRST_APPROACH_STEP_MM
    for _ in range(MAX_APPROACH_STEPS):
        start = state
        to = float(start.alpha[GRIP]) + direction * step_mm
        idx = index + len(steps)

        def attempt(
            n_sub: int, st: ContactState = start, to: float = to, idx: int = idx
        ) -> list[_Step]:
            a0 = float(st.alpha[GRIP])
            out: list[_Step] = []
            for k in range(1, n_sub + 1):
                out.append(
                    _displaced(cond, st, a0 + (to - a0) * k / n_sub, contact, mask, idx + k - 1)
                )
                st = out[-1].state
            return out

        what = f"approach {idx} (δ → {to:.6g} mm)"
        # a cut-back's sub-steps are recorded one by one (as in ``_forced``): the loop then
        # has their points, and its trapezoidal area matches their works exactly
        steps += with_cutbacks(
            attempt, settings.max_cutbacks, increment=idx, what=what, partial=partial
        )
        state = steps[-1].state
        status = np.asarray(state.status)
        pin_load = float(np.abs(np.asarray(state.p)[~faces]).sum())
        if (
            np.all(status[faces] != ContactStatus.STICK)
            and np.any(status[faces] == ContactStatus.SLIP)
            and pin_load <= FREE_PIN_TOL * settings.amplitude_n
        ):
            return steps
        step_mm *= 2.0
    raise ConvergenceError(
        f"the faces did not reach full slip after {MAX_APPROACH_STEPS} grip steps",
        increment=index + len(steps),
        iteration=0,
        residual=float("nan"),
        partial=partial(),
    )


def _slide(
    old: Condensed,
    new: Condensed,
    state: ContactState,
    shift_mm: float,
    direction: int,
    contact: ContactSettings,
    index: int,
) -> _Step:
    """Carry the free state into ``new`` and slide the faces to where the pin first touches.

    One displacement-controlled increment of the faces alone (the pin carries nothing);
    the pin is placed where the linear program of ``engagement`` puts it.
    """
    carried = switched_state(old, new, state, shift_mm)
    fn = face_mask(new)
    trial = _displaced(new, carried, 0.0, contact, fn, index)  # the faces' sliding forces
    delta_e, pin_modes = engagement(new, np.asarray(trial.state.p), direction)
    slid = _displaced(new, carried, delta_e, contact, fn, index)
    alpha = np.array(slid.state.alpha, dtype=np.float64, copy=True)
    alpha[:N_PIN_MODES] = pin_modes
    p = np.asarray(slid.state.p)
    w = consistent_w(new, p, alpha)
    w[fn] = np.asarray(slid.state.w)[fn]
    return dataclasses.replace(slid, state=ContactState(p, w, slid.state.status, alpha))


class SlidingStep:
    """The increment of a hinge with clearance and clamped faces, for ``fe.cycle.driver.drive``.

    The module docstring's steps: force control while the faces hold the clevis or the pin
    is engaged on the side pulled to; where a target lies beyond the faces' slip force on
    the other side, force control to just below it, the approach and the slide, then
    force control on to the target. Every step is recorded; the slides' indices and the
    centred start are kept in the result (``CycleResult.slides``, ``start_disp_mm``).
    """

    def __init__(
        self, clearance_mm: float, settings: CycleSettings, configs: dict[int, Condensed]
    ) -> None:
        """Start with the pin and the clevis centred in the tension configuration's coordinates."""
        self.clearance_mm = clearance_mm
        self.settings = settings
        self.configs = configs
        self.contact = settings.contact()
        self.half = 2.0 * clearance_mm  # the clevis' offset of each touching configuration
        self.f_slide = {d: slide_force(configs[d], self.contact, d) for d in (1, -1)}
        self.side, self.engaged = 1, 0  # coordinates of the tension configuration; pin centred
        cond = configs[self.side]
        m = len(cond.geo.slave)
        alpha0 = np.zeros(N_RIGID)
        alpha0[0], alpha0[GRIP] = -0.5 * self.half, -self.half  # pin and clevis centred
        p0 = np.zeros((m, 3))
        status0 = np.zeros(m, dtype=np.int8)
        self.state = ContactState(p0, consistent_w(cond, p0, alpha0), status0, alpha0)
        self.previous: Branch | None = None
        self.slides: list[int] = []

    def targets(self, f_from: float, f_to: float, n: int) -> FloatArray:
        """The graded targets of the stage (``stage_targets``), shape (n,) [N]."""
        return stage_targets(f_from, f_to, n, self.settings.grading)

    def advance(self, target: Target, partial: Callable[[], CycleResult]) -> Iterator[Recorded]:
        """Reach ``target.f_to``, sliding across the free play first where the faces let go."""
        if target.first:
            self.previous = None  # no extrapolation across a reversal
        f_prev, index, stage = target.f_from, target.index, target.stage
        d = 1 if target.f_to > 0 else -1
        if d != self.engaged and abs(target.f_to) > self.f_slide[d]:  # the faces let go
            f_a = d * (1.0 - APPROACH_MARGIN) * self.f_slide[d]
            if d * f_prev < abs(f_a):
                held = self._force(stage, f_prev, f_a, index, partial)
                yield from held
                index += len(held)
            steps = _approach(self.configs[self.side], self.state, d, self.contact,
                              self.settings, index, partial, self.engaged == 0)  # fmt: skip
            for step in steps:
                yield self._keep(stage, step)
            index += len(steps)
            shift = (self.side - d) * self.half
            slid = _slide(self.configs[self.side], self.configs[d], steps[-1].state, shift, d,
                          self.contact, index)  # fmt: skip
            self.side, self.engaged = d, d
            self.slides.append(index)
            slide = self._keep(stage, slid)
            self.state, self.previous = slid.state, None
            yield slide
            f_prev, index = slide[0].force_n, index + 1
        before = (f_prev, self.state)
        records = self._force(stage, f_prev, target.f_to, index, partial)
        self.previous = before
        yield from records

    def _force(
        self,
        stage: int,
        f_from: float,
        f_to: float,
        index: int,
        partial: Callable[[], CycleResult],
    ) -> list[Recorded]:
        """Force control from ``f_from`` to ``f_to``, every (sub-)step recorded; the state moves on."""
        cond = self.configs[self.side]
        if self.engaged == 0:  # the faces hold the clevis centred: the pin stays out
            held = _held_steps(cond, self.state, f_from, f_to, self.contact, self.settings,
                               index, partial)  # fmt: skip
            records = [self._keep(stage, step) for step in held]
        else:
            forced = _forced(cond, self.state, f_from, f_to, self.contact, self.settings, index,
                             partial, self.previous)  # fmt: skip
            records = [(record_increment(stage, f, self.side, res, cond), new)
                       for f, new, res in forced]  # fmt: skip
        self.state = records[-1][1]
        return records

    def _keep(self, stage: int, step: _Step) -> Recorded:
        """The record of a step of this module on the current side."""
        cond = self.configs[self.side]
        p = np.ravel(step.state.p)
        inc = Increment(
            stage=stage,
            force_n=float(-np.asarray(cond.G)[:, GRIP] @ p),
            disp_mm=float(step.state.alpha[GRIP]),
            side=self.side,
            iterations=step.iterations,
            n_open=step.n_counts[0],
            n_stick=step.n_counts[1],
            n_slip=step.n_counts[2],
            friction_work=step.friction_work,
            normal_work=step.normal_work,
            elastic_energy=0.5 * float(p @ (cond.W @ p)),
        )
        return inc, step.state

    def result(
        self,
        increments: tuple[Increment, ...],
        states: tuple[ContactState, ...],
        timings_s: dict[str, float],
    ) -> CycleResult:
        """The cycle of these increments, with its slides and the centred start."""
        return CycleResult(
            self.settings,
            self.clearance_mm,
            increments,
            4 * self.clearance_mm,
            states,
            self.configs,
            timings_s,
            slides=tuple(self.slides),
            start_disp_mm=-self.half,
        )
