"""The hinge's hysteresis cycle: 0 → +Fg → −Fg → +Fg under force control, and its loss factor.

Force control is exact here (see ``fe.general.system``): each increment prescribes F and
the grip displacement δ comes out of the contact solve. Increments are graded so the
steps are small just after each reversal, where the stick zones start to slip.

This module sets the cycle up (the touching configurations, the contact settings) and runs
it through ``fe.cycle.driver.drive`` with the hinge's step: ``HingeStep`` here, or
``fe.general.freeplay.SlidingStep`` where clamped faces hold the clevis in the free play. The
protocol is ``fe.cycle.protocol`` and what is measured on the result (η, W_cycle, U_max,
the energy balance) is ``fe.cycle.result``; the stage loop is ``fe.cycle.driver``.
"""

from __future__ import annotations

__all__ = [
    "HingeStep",
    "configurations",
    "grip_force",
    "hinge_contact",
    "run_cycle",
    "seed_state",
]

import dataclasses
import logging
import time
from collections.abc import Callable, Iterator

import numpy as np
import numpy.typing as npt
from threadpoolctl import threadpool_limits

from cad.errors import ParameterError, check_range
from cad.general_params import MAX_CLEARANCE_MM
from fe.contact.memo import start_afresh
from fe.contact.state import ContactSettings, ContactState
from fe.cycle.driver import CycleStep, Recorded, Target, drive
from fe.cycle.protocol import CycleSettings, stage_targets
from fe.cycle.result import CycleResult, Increment
from fe.general.condensation import condense
from fe.general.crossing import has_faces
from fe.general.freeplay import SlidingStep
from fe.general.increments import (
    Branch,
    advance_force,
    check_window,
    record_increment,
)
from fe.general.system import GRIP, N_RIGID, HingeSystem, is_tang_side
from fe.structure.condensed import Condensed
from fe.surfaces.geometry import contact_geometry, split_window

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
        system: The factorised hinge (``fe.general.system.build_system``).
        clearance_mm: Its radial clearance Δr [mm] (sets the touching configurations).
        settings: Load protocol and solver options.
        configs: Condensed configurations to reuse (they depend on the mesh and Δr only).
        progress: Called as ``progress(done, total)`` after each load target, ``total``
            being the targets of the whole cycle.

    Returns:
        The cycle.

    Raises:
        ConvergenceError: If an increment fails after ``max_cutbacks`` halvings; its
            ``partial`` is the CycleResult of the increments that converged.
    """
    check_range("clearance_mm", clearance_mm, 0.0, MAX_CLEARANCE_MM)
    start_afresh()  # nothing learnt by earlier cycles on these configurations' W
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
        step: CycleStep
        if clearance_mm > 0 and has_faces(configs[1]):  # clamped faces: the free play is slid
            step = SlidingStep(clearance_mm, settings, configs)
        else:
            step = HingeStep(clearance_mm, settings, configs, hinge_contact(settings))
        timings = {"condensation": t_cond}
        result = drive(step, settings, progress, timings_s=timings, phase="contact")
        check_window(system, result)
    return result


class HingeStep:
    """The general hinge's increment for ``fe.cycle.driver.drive``: force control, F = 0 crossed.

    Each target is one force-controlled increment in the current touching configuration
    (``fe.general.increments.advance_force``), started on the branch's extrapolation. With
    clearance the unloaded start is the tension configuration seeded toward the first
    force (``seed_state``); where the force changes sign the pin changes sides: the
    increment to F = 0 is recorded, and the other configuration is seeded toward the
    target.
    """

    def __init__(
        self,
        clearance_mm: float,
        settings: CycleSettings,
        configs: dict[int, Condensed],
        contact: ContactSettings,
    ) -> None:
        """Start unloaded in the tension configuration (+1) of ``configs``."""
        self.clearance_mm = clearance_mm
        self.settings = settings
        self.configs = configs
        self.contact = contact
        self.side = 1
        self.state: ContactState | None = None  # seeded at the first target
        self.previous: Branch | None = None

    def targets(self, f_from: float, f_to: float, n: int) -> FloatArray:
        """The graded targets of the stage (``stage_targets``), shape (n,) [N]."""
        return stage_targets(f_from, f_to, n, self.settings.grading)

    def advance(self, target: Target, partial: Callable[[], CycleResult]) -> Iterator[Recorded]:
        """Reach ``target.f_to``; yield the increment to F = 0 first where the pin changes sides."""
        cond = self.configs[self.side]
        if self.state is None:
            self.state = (
                seed_state(cond, target.f_to)
                if self.clearance_mm > 0
                else ContactState.initial(len(cond.geo.slave), N_RIGID, w=cond.w0)
            )
        if target.first:
            self.previous = None  # no extrapolation across a reversal
        f_from, index = target.f_from, target.index
        if self.clearance_mm > 0 and f_from * target.f_to < 0:  # the pin changes sides
            new, res = advance_force(cond, self.state, f_from, 0.0, self.contact, self.settings,
                               index, partial, self.previous)  # fmt: skip
            yield record_increment(target.stage, 0.0, self.side, res, cond), new
            self.side = -self.side
            cond = self.configs[self.side]
            self.state = seed_state(cond, target.f_to)
            f_from, index, self.previous = 0.0, index + 1, None
        new, res = advance_force(cond, self.state, f_from, target.f_to, self.contact, self.settings,
                           index, partial, self.previous)  # fmt: skip
        self.previous, self.state = (f_from, self.state), new
        yield record_increment(target.stage, target.f_to, self.side, res, cond), new

    def result(
        self,
        increments: tuple[Increment, ...],
        states: tuple[ContactState, ...],
        timings_s: dict[str, float],
    ) -> CycleResult:
        """The cycle of these increments: free play 4Δr, both configurations kept."""
        return CycleResult(
            self.settings,
            self.clearance_mm,
            increments,
            4 * self.clearance_mm,
            states,
            self.configs,
            timings_s,
        )


HINGE_SINGLE_MIN = 256
"""The hinge's Krylov bases are float32 from this many unknowns (``KrylovOptions.single_min``).

Its reduced Jacobians are well conditioned (W is a compliance; measured: GMRES on the exact
system converges on a fresh float32 base in 2-3 iterations), so the halved LU time pays
from a few hundred unknowns. Chosen by measurement (benchmarks/bench_cycle.txt,
'HINGE_SINGLE_MIN')."""


HINGE_KRYLOV_MIN = 500
"""Reduced systems of fewer unknowns are factorised at every Newton step, not updated from a
kept base (``KrylovOptions.min_size``): there the update and GMRES cost more Python and
numpy calls than an LU of a few milliseconds. Chosen by measurement
(benchmarks/bench_cycle.txt, 'HINGE_KRYLOV_MIN')."""


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


def grip_force(cond: Condensed, p: FloatArray) -> float:
    """Force the grip applies to the clevis, from the contact forces [N] (= F at equilibrium)."""
    return float(-cond.G[:, 6] @ np.ravel(p))
