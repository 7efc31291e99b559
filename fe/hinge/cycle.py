"""The hinge's hysteresis cycle: 0 → +Fg → −Fg → +Fg under force control, and its loss factor.

Force control is exact here (see ``fe.hinge.system``): each increment prescribes F and
the grip displacement δ comes out of the contact solve. Increments are graded so the
steps are small just after each reversal, where the stick zones start to slip.

This module drives the cycle; the protocol is ``fe.hinge.protocol`` and what is measured on
the result (η, W_cycle, U_max, the energy balance) is ``fe.hinge.result``. Both are
re-exported here, so ``from fe.hinge.cycle import CycleSettings, run_cycle`` is the public API.
"""

from __future__ import annotations

__all__ = [
    "DEFAULT_MU",
    "CycleResult",
    "CycleSettings",
    "Increment",
    "configurations",
    "grip_force",
    "run_cycle",
    "seed_state",
    "stage_targets",
]

import dataclasses
import logging
import time
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt
from threadpoolctl import threadpool_limits

from cad.errors import ConvergenceError, ParameterError, check_range
from fe.contact import ContactSettings, ContactState, IncrementResult, solve_increment
from fe.hinge.condensed import Condensed
from fe.hinge.geometry import contact_geometry, split_window
from fe.hinge.protocol import DEFAULT_MU, CycleSettings, stage_targets, with_cutbacks
from fe.hinge.result import CycleResult, Increment
from fe.hinge.system import (
    GRIP,
    N_RIGID,
    HingeSystem,
    condense,
    displacements,
    is_tang_side,
    outside_gaps,
)

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]


def configurations(
    system: HingeSystem, clearance_mm: float, window: float = 0.0
) -> dict[int, Condensed]:
    """Condense the tension (+1) and compression (−1) touching configurations.

    They depend on the mesh and Δr only: pass them to ``run_cycle(configs=...)`` to reuse
    them for every amplitude and friction coefficient (or modify them, e.g. by an effect
    that adds interface compliance). ``window`` > 0 keeps only the points whose gap is
    ≤ window·Δr (see ``CycleSettings.contact_window``).
    """
    ex = np.array([1.0, 0.0, 0.0])
    configs: dict[int, Condensed] = {}
    for side in (1, -1):
        if side == -1 and clearance_mm == 0.0:
            configs[-1] = configs[1]  # one configuration: the pin touches all round
            break
        # Tension: the pin is pushed +Δr against the tang's hole and the clevis a further +Δr,
        # so relative to each hole the pin sits +Δr (tang) or −Δr (clevis) along x.
        shift = {
            p.name: (side if is_tang_side(p) else -side) * clearance_mm * ex
            for p in system.mesh.pairs
        }
        geo = contact_geometry(system.mesh, shift)
        if window > 0.0 and clearance_mm > 0.0:
            inside, outside = split_window(geo, window * clearance_mm)
            configs[side] = condense(system, inside, outside)
        else:
            configs[side] = condense(system, geo)
    return configs


def run_cycle(
    system: HingeSystem,
    clearance_mm: float,
    settings: CycleSettings,
    *,
    configs: dict[int, Condensed] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> CycleResult:
    """Run the load cycle on a factorised hinge.

    Args:
        system: The factorised hinge (``fe.hinge.system.build_system``).
        clearance_mm: Its radial clearance Δr [mm] (sets the touching configurations).
        settings: Load protocol and solver options.
        configs: Condensed configurations to reuse (they depend on the mesh and Δr only).
        progress: Called as ``progress(done, total)`` after each increment.

    Returns:
        The cycle.

    Raises:
        ConvergenceError: If an increment fails after ``max_cutbacks`` halvings; its
            ``partial`` is the CycleResult of the increments that converged.
    """
    check_range("clearance_mm", clearance_mm, 0.0, 10.0)
    if abs(clearance_mm - system.clearance_mm) > 1e-9:
        raise ParameterError(
            f"clearance_mm = {clearance_mm:g} does not match the mesh's exact cylinders "
            f"(hole − pin radius = {system.clearance_mm:g} mm): pass system.clearance_mm"
        )
    if clearance_mm > 0.0:
        settings = dataclasses.replace(settings, increments_per_stage=settings.clearance_increments)
    t0 = time.perf_counter()
    configs = configs or configurations(
        system, clearance_mm, settings.contact_window
    )  # all threads
    t_cond = time.perf_counter() - t0
    with threadpool_limits(limits=settings.blas_threads, user_api="blas"):  # dense contact solves
        result = _run(system, clearance_mm, settings, configs, progress)
    object.__setattr__(result, "timings_s", {"condensation": t_cond, **result.timings_s})
    return result


def _run(
    system: HingeSystem,
    clearance_mm: float,
    settings: CycleSettings,
    configs: dict[int, Condensed],
    progress: Callable[[int, int], None] | None,
) -> CycleResult:
    if clearance_mm > 0 and np.any(np.asarray(configs[1].geo.pair) < 0):
        from fe.hinge.freeplay import run_sliding  # clamped faces: the free play is slid

        return run_sliding(system, clearance_mm, settings, configs, progress)
    contact = hinge_contact(settings)
    side = 1
    cond = configs[side]
    first = settings.stages()[0]
    state = (
        seed_state(cond, stage_targets(*first, settings.grading)[0])
        if clearance_mm > 0
        else ContactState.initial(len(cond.geo.slave), N_RIGID, w=cond.w0)
    )
    incs: list[Increment] = []
    states: list[ContactState] = []
    total = sum(n for _, _, n in settings.stages())
    t1 = time.perf_counter()

    def partial() -> CycleResult:
        return CycleResult(
            settings,
            clearance_mm,
            tuple(incs),
            4 * clearance_mm,
            tuple(states),
            configs,
            {},
        )

    f_prev = 0.0
    peaks: list[int] = []  # increments at the end of a stage, where the window is checked
    for stage, (f_from, f_to, n) in enumerate(settings.stages()):
        previous: tuple[float, ContactState] | None = None  # no extrapolation across a reversal
        for target in stage_targets(f_from, f_to, n, settings.grading):
            if clearance_mm > 0 and f_prev * target < 0:  # crossing zero: the pin changes sides
                new, res = _advance(
                    cond, state, f_prev, 0.0, contact, settings, len(incs), partial, previous
                )
                incs.append(_record(stage, 0.0, side, res, cond))
                states.append(new)
                side = -side
                cond = configs[side]
                state = seed_state(cond, float(target))
                f_prev, previous = 0.0, None
            new, res = _advance(
                cond, state, f_prev, float(target), contact, settings, len(incs), partial, previous
            )
            incs.append(_record(stage, float(target), side, res, cond))
            states.append(new)
            previous, state, f_prev = (f_prev, state), new, float(target)
            if target == f_to:
                peaks.append(len(incs) - 1)
            if progress is not None:
                progress(min(len(incs), total), total)
    result = partial()
    object.__setattr__(result, "timings_s", {"contact": time.perf_counter() - t1})
    _check_window(system, result, peaks)
    return result


HINGE_SINGLE_MIN = 256
"""The hinge's Krylov bases are float32 from this many unknowns (``KrylovOptions.single_min``).

Its reduced Jacobians are well conditioned (W is a compliance; measured: GMRES on the exact
system converges on a fresh float32 base in 2-3 iterations), so the halved LU time pays
from a few hundred unknowns (level 0: LU time 2.5 → 1.5 s per cycle)."""


HINGE_KRYLOV_MIN = 500
"""Reduced systems of fewer unknowns are factorised at every Newton step, not updated from a
kept base (``KrylovOptions.min_size``): there the update and GMRES cost more Python and
numpy calls than an LU of a few milliseconds. Contact phase with 0 / 300 / 600 / 1 000,
single runs: level 0, Δr 0.1 mm (a few hundred unknowns) 1.13 / 0.99 / 0.96 / 0.94 s;
level 1, Δr 0.1 4.95 / – / 4.69 / 4.72 s; level 0, Δr 0 (about 1 100) 4.47 / – / 4.67 /
4.85 s. Best of four alternating runs, 0 against 500: level 0, Δr 0.1 1.08 / 0.95 s;
level 0, Δr 0 4.75 / 4.76 s (the single runs' spread there was noise)."""


def hinge_contact(settings: CycleSettings) -> ContactSettings:
    """The contact settings of the hinge's cycle: ``settings.contact()`` with the working set.

    Open-point elimination (``ContactSettings.working_set``: with clearance most points stay
    open, and the products of the Newton loop read only the rows of those that may close; at
    zero clearance about half may close, often more than ``fe.contact.working.MAX_FRACTION``,
    and those increments are solved whole), float32 Krylov bases from ``HINGE_SINGLE_MIN``
    unknowns, kept and updated from ``HINGE_KRYLOV_MIN`` unknowns, and the first increment
    from rest started at its frictionless solution (``ContactSettings.frictionless_start``).
    All of them change the path only.
    """
    base = settings.contact()
    return dataclasses.replace(
        base,
        working_set=True,
        frictionless_start=True,
        krylov=dataclasses.replace(
            base.krylov, single_min=HINGE_SINGLE_MIN, min_size=HINGE_KRYLOV_MIN
        ),
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


def _check_window(system: HingeSystem, result: CycleResult, peaks: list[int]) -> None:
    """Raise if a point outside the contact window has closed (the window was too small).

    Checked at the stage ends (the load peaks), all at once after the cycle: recovering
    displacements needs the sparse factors, which a large mesh holds one at a time
    (``HingeSystem.low_memory``), so one batch costs one factorisation per part.
    """
    peaks = [k for k in peaks if result.configs[result.increments[k].side].outside is not None]
    if not peaks:
        return
    fields = increment_displacements(system, result, peaks)
    for k, u in zip(peaks, fields, strict=True):
        cond = result.configs[result.increments[k].side]
        gaps = outside_gaps(cond, u)
        i = int(np.argmin(gaps))
        if gaps[i] < 0.0:
            assert cond.outside is not None
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


SEED_GAP_MM = 1e-6
"""Points whose initial gap is below this touch in the touching configuration [mm]."""


def seed_state(cond: Condensed, force_n: float) -> ContactState:
    """Initial state of a touching configuration, warm-started toward the first force.

    In a touching configuration every point starts open and the pin and clevis float,
    so Newton from p = 0 has no active set to start from. The seed solves the
    frictionless, bilateral problem on the touching points (gap ≈ 0) for the first
    force, ``W_aa p_a + G_a α = −g_a``, ``G_aᵀ p_a = e`` (least squares, minimum norm),
    keeps the compressive part, and hands it to Newton as the warm start. It changes
    where Newton starts, not what it converges to.
    """
    m = len(cond.geo.slave)
    state0 = ContactState.initial(m, N_RIGID, w=cond.w0)
    touching = np.flatnonzero(cond.geo.g0 <= SEED_GAP_MM)
    if touching.size == 0:
        return state0
    rows = 3 * touching
    k = cond.G.shape[1]
    A = np.block([[cond.W[np.ix_(rows, rows)], cond.G[rows]], [cond.G[rows].T, np.zeros((k, k))]])
    e = np.zeros(k)
    e[GRIP] = -force_n
    b = np.concatenate([-cond.geo.g0[touching], e])
    x = np.linalg.lstsq(A, b, rcond=1e-12)[0]
    p = np.zeros((m, 3))
    p[touching, 0] = np.maximum(x[: touching.size], 0.0)
    return ContactState(p, cond.w0, state0.status, x[touching.size :])


def _advance(
    cond: Condensed,
    state: ContactState,
    f_from: float,
    f_to: float,
    contact: ContactSettings,
    settings: CycleSettings,
    index: int,
    partial: Callable[[], CycleResult],
    previous: tuple[float, ContactState] | None = None,
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
            any. While the active set holds, the solution is linear in F, so Newton
            starts from the linear extrapolation of the last two states (one or two
            iterations instead of about ten); the solution does not depend on it.

    Returns the final state and the IncrementResult with works summed over sub-steps.
    """

    def attempt(n_sub: int) -> tuple[ContactState, IncrementResult]:
        s = state
        works = np.zeros(2)
        iters = 0
        for k in range(1, n_sub + 1):
            f = f_from + (f_to - f_from) * k / n_sub
            e = np.zeros(N_RIGID)
            e[GRIP] = -f  # clevis equilibrium: G_δᵀ p = −F
            start = None
            if previous is not None and k == 1 and previous[0] != f_from:
                t = (f - f_from) / (f_from - previous[0])
                start = (
                    np.asarray(s.p) + t * (np.asarray(s.p) - np.asarray(previous[1].p)),
                    np.asarray(s.alpha) + t * (np.asarray(s.alpha) - np.asarray(previous[1].alpha)),
                )
            res = solve_increment(
                cond.W, cond.w0, s, contact, G=cond.G, e=e, increment=index, start=start
            )
            works += [res.friction_work.sum(), res.normal_work.sum()]
            iters += res.iterations
            s = res.state
        return s, _summed(res, works, iters)

    what = f"increment {index} (F {f_from:.4g} → {f_to:.4g} N)"
    return with_cutbacks(
        attempt, settings.max_cutbacks, increment=index, what=what, partial=partial
    )


def _summed(res: IncrementResult, works: FloatArray, iters: int) -> IncrementResult:
    """Return ``res`` with per-point works replaced by sub-step totals (kept as length-1 arrays)."""
    return dataclasses.replace(
        res, friction_work=np.array([works[0]]), normal_work=np.array([works[1]]), iterations=iters
    )


def _record(
    stage: int, force: float, side: int, res: IncrementResult, cond: Condensed
) -> Increment:
    p = np.ravel(res.state.p)
    # W p from the converged w = W p + G α + w0 (an exact product in solve_increment),
    # rather than another pass over W
    Wp = np.ravel(res.state.w - cond.w0) - cond.G @ np.asarray(res.state.alpha)
    return Increment(
        stage=stage,
        force_n=force,
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


def grip_force(cond: Condensed, p: FloatArray) -> float:
    """Force the grip applies to the clevis, from the contact forces [N] (= F at equilibrium)."""
    return float(-cond.G[:, 6] @ np.ravel(p))
