"""The load cycle of the bearing hinge with frictional fits (``fe.bearing.fits``).

Each increment (force F on the clevis, preload shift σ held) is a Newton iteration on the
ball coordinates ``v`` around one frictional contact solve per iteration::

    H = ∂f/∂v at v_k (regularised below a small approach, as fe.bearing.balls),
    ΔH = H − H_ref,  M = I + W_b ΔH,  N = ΔH M⁻¹,  c = f(v_k) − H_ref v_k − ΔH v_k
    W_eff = W_c − X N Xᵀ,   w_free = w0 − X (c − N W_b c)
    (p, α) = solve_increment(W_eff, w_free, state_prev, G, e = (0, …, 0, −F))
    v_{k+1} = M⁻¹ (Xᵀ p − W_b c)

until ``v`` stops changing. Every contact solve starts from the previous increment's
state, so the friction work is that of the converged iterate. The preload step finds σ
by a secant iteration on the plate force (F = 0) with the fits frictionless (the pair is
assembled before the fits' friction history starts), so it dissipates nothing by that
choice; the rigid modes that friction alone would hold are held at zero there.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from threadpoolctl import threadpool_limits

from cad.bearing_geometry import MAX_PRELOAD_N
from cad.errors import ConvergenceError, check_range
from fe.bearing.balls import REG_FRACTION, ball_law, block_diag
from fe.bearing.fits import GRIP, N_RIGID, FitSystem
from fe.bearing.loading import with_zero_crossing
from fe.bearing.pair import axial_state_from_load, bearing_from_params
from fe.contact.memo import start_afresh
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState, IncrementResult, LinearSolver
from fe.cycle.driver import Recorded, Target, drive
from fe.cycle.protocol import CycleSettings, stage_targets, with_cutbacks
from fe.cycle.result import CycleResult, Increment

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]

FIT_HALVINGS = 3
"""Halvings of the force toward zero at a crossing without preload (``with_zero_crossing``)."""

MAX_BALL_ITER = 30
"""Ball Newton iterations (each one contact solve) per increment."""


@dataclass(frozen=True)
class FitState:
    """A converged state: the contacts and the balls.

    Attributes:
        contact: Contact state of the fits (forces, relative displacements, status, α).
        v_mm: Ball coordinates (radial, axial per ball), shape (2 n_b,) [mm].
        preload_mm: Preload shift σ [mm].
        result: The last contact solve (works, counts), or None for the unloaded state.
        ball_iterations: Ball Newton iterations.
    """

    contact: ContactState
    v_mm: FloatArray
    preload_mm: float
    result: IncrementResult | None
    ball_iterations: int


def _ball(
    system: FitSystem, v: FloatArray, sigma: float, reg: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Ball forces (2 n_b,), loads, approaches and the block-diagonal tangent at ``v`` and σ."""
    n = system.n_balls
    shifted = (v + sigma * system.preload_shift).reshape(n, 2)
    f, Q, approach, H = ball_law(system.balls.d0, shifted, system.balls.k_n, reg)
    return f.ravel(), Q, approach, block_diag(H)


def solve_fit_increment(
    system: FitSystem,
    prev: FitState,
    force_n: float,
    sigma: float,
    contact: ContactSettings,
    *,
    ref_load_n: float,
    increment: int = 0,
    guess: tuple[FloatArray, FloatArray, FloatArray] | None = None,
    modes: tuple[int, ...] | None = None,
) -> FitState:
    """Solve one increment from ``prev`` to the clevis force ``force_n`` at preload shift σ.

    ``guess`` = (v, p, α) is where the iteration starts (e.g. extrapolated along the
    branch); it changes the iteration count, never the solution or the works (those are
    measured from ``prev``). ``modes``: the rigid amplitudes solved for (default all);
    the others are held at their value in ``prev``.

    Raises:
        ConvergenceError: If the contact solve or the ball iteration does not converge.
    """
    n2 = 2 * system.n_balls
    q_ref = max(ref_load_n, 1.0) / system.n_balls
    ref_mm = (q_ref / system.balls.k_n) ** (2.0 / 3.0)
    reg = REG_FRACTION * ref_mm
    m = system.n_points
    e = np.zeros(N_RIGID)
    e[GRIP] = -force_n
    w0 = np.zeros((m, 3))
    w0[:, 0] = system.geo.g0
    use = list(range(N_RIGID) if modes is None else modes)
    held = [j for j in range(N_RIGID) if j not in use]
    alpha_prev = np.asarray(prev.contact.alpha)
    w0 += (system.G[:, held] @ alpha_prev[held]).reshape(m, 3)
    G, e = system.G[:, use], e[use]
    pc = prev.contact
    state_prev = ContactState(pc.p, pc.w, pc.status, alpha_prev[use])
    if guess is None:
        v = np.array(prev.v_mm, dtype=float)
        start = (np.asarray(pc.p), alpha_prev[use])
    else:
        v, start = np.array(guess[0], dtype=float), (guess[1], np.asarray(guess[2])[use])
    step = np.inf
    for it in range(1, MAX_BALL_ITER + 1):
        f, _, _, H = _ball(system, v, sigma, reg)
        dH = H - system.H_ref
        M = np.eye(n2) + system.W_b @ dH
        N = dH @ np.linalg.inv(M)  # = (dH⁻¹ + W_b)⁻¹: symmetric (push-through identity)
        c = f - system.H_ref @ v - dH @ v
        # W_eff = W_c − X N Xᵀ with one (3m)² temporary: W_c is symmetric (built so) and
        # N is symmetrised at its size (2 n_b)², so W_eff is symmetric to round-off
        W_eff = (system.X @ (0.5 * (N + N.T))) @ system.X.T
        np.subtract(system.W_c, W_eff, out=W_eff)
        w_free = w0 - (system.X @ (c - N @ (system.W_b @ c))).reshape(m, 3)
        res = _solve_contact(W_eff, w_free, state_prev, contact, G, e, increment, start)
        p = np.ravel(res.state.p)
        v_new = np.linalg.solve(M, system.X.T @ p - system.W_b @ c)
        step = float(np.abs(v_new - v).max())
        v = v_new
        start = (np.asarray(res.state.p), np.asarray(res.state.alpha))
        if step <= contact.tol * max(float(np.abs(v).max()), ref_mm) * 10:
            alpha = alpha_prev.copy()
            alpha[use] = res.state.alpha
            st = res.state
            full = ContactState(st.p, st.w, st.status, alpha)
            return FitState(full, v, sigma, dataclasses.replace(res, state=full), it)
    raise ConvergenceError(
        "the balls did not converge around the frictional fits",
        increment=increment,
        iteration=MAX_BALL_ITER,
        residual=step,
    )


RESCUE_SETTINGS = ({"r_scale": 1.0}, {"r_scale": 10.0, "linear_solver": LinearSolver.LU})
"""Other contact-solver settings tried, in order, when one fails. ``r_scale`` and the linear
solver are algorithmic only (the converged solution does not depend on them); the first
loaded increment without preload stalled on the coarse mesh at F_g = 500 N with the
defaults of ``fit_contact_settings`` and converged with another augmentation."""


def _solve_contact(
    W: FloatArray,
    w_free: FloatArray,
    prev: ContactState,
    contact: ContactSettings,
    G: FloatArray,
    e: FloatArray,
    increment: int,
    start: tuple[FloatArray, FloatArray],
) -> IncrementResult:
    """``solve_increment``, retried with ``RESCUE_SETTINGS`` before giving up.

    ``W`` is symmetric by construction (``solve_fit_increment``), so its check is skipped.
    """

    def solve(settings: ContactSettings) -> IncrementResult:
        return solve_increment(
            W, w_free, prev, settings, G=G, e=e, increment=increment, start=start, symmetric=True
        )

    try:
        return solve(contact)
    except ConvergenceError as first:
        for change in RESCUE_SETTINGS:
            try:
                alt = dataclasses.replace(contact, **change)
                return solve(alt)
            except ConvergenceError:
                continue
        raise first


def fit_energy(system: FitSystem, s: FitState) -> float:
    """Strain energy of the structure plus the balls' Hertz energy [N·mm]."""
    p = np.ravel(s.contact.p)
    f, _, approach, _ = _ball(system, s.v_mm, s.preload_mm, 0.0)
    r_b = f - system.H_ref @ s.v_mm
    w_el = system.W_c @ p - system.X @ r_b
    structure = 0.5 * (p @ w_el - f @ s.v_mm)
    balls = 0.4 * system.balls.k_n * np.maximum(approach, 0.0) ** 2.5
    return float(structure + balls.sum())


def unloaded(system: FitSystem) -> FitState:
    """The state before anything is loaded."""
    m = system.n_points
    w0 = np.zeros((m, 3))
    w0[:, 0] = system.geo.g0
    return FitState(
        ContactState.initial(m, N_RIGID, w=w0), np.zeros(2 * system.n_balls), 0.0, None, 0
    )


FRICTIONLESS_MODES = (0, 1, 3, 4, GRIP)
"""Rigid amplitudes solved for without friction: the pin's radial translations and tilts
and the grip. The pin's axial slide and spin and the inner rings' spin are held by
friction alone; at μ = 0 they are undetermined (no force can act along them) and are held
at zero, which changes nothing else (the preload's contact Newton stalled without this on
a 0.8 mm ring mesh)."""


def fit_preload(
    system: FitSystem, preload_n: float, contact: ContactSettings
) -> tuple[FitState, float]:
    """The preload step: σ such that the plate force is F_p (F = 0); returns (state, friction work).

    The pair is assembled frictionlessly (μ = 0 on the fits whatever ``contact`` says: the
    fits' friction history starts once the hinge is assembled), so the state does not
    depend on the path and each secant step starts from the last one's state.

    Raises:
        ParameterError: If ``preload_n`` is outside [0, ``MAX_PRELOAD_N``] N.
        ConvergenceError: With increment 0 if σ or the state does not converge.
    """
    check_range("preload_n", preload_n, 0.0, MAX_PRELOAD_N)
    s0 = unloaded(system)
    if preload_n == 0.0:
        return s0, 0.0
    frictionless = dataclasses.replace(contact, mu=0.0)
    b1 = system.balls.bearing == 1
    last = [s0]

    def plate_force(sigma: float) -> float:
        st = solve_fit_increment(
            system, last[-1], 0.0, sigma, frictionless, ref_load_n=preload_n,
            modes=FRICTIONLESS_MODES,
        )  # fmt: skip
        last.append(st)
        f = _ball(system, st.v_mm, sigma, 0.0)[0].reshape(-1, 2)
        return float(f[b1, 1].sum())

    # rigid-ring guess: both bearings compress by δ_a, σ ≈ 2 δ_a
    jones = axial_state_from_load(bearing_from_params(system.params), preload_n)
    sig = [2.0 * jones.axial_deflection_mm]
    sig.append(1.2 * sig[0])
    vals = [plate_force(s) - preload_n for s in sig]
    for _ in range(30):
        if abs(vals[-1]) <= 1e-9 * preload_n:
            break
        new = sig[-1] - vals[-1] * (sig[-1] - sig[-2]) / (vals[-1] - vals[-2])
        sig.append(new)
        vals.append(plate_force(new) - preload_n)
    else:
        raise ConvergenceError(
            f"the preload step (F_p = {preload_n:g} N) did not converge",
            increment=0,
            iteration=30,
            residual=abs(vals[-1]),
        )
    return last[-1], 0.0


FIT_RIGID_RCOND = 1e-6
"""``ContactSettings.rigid_rcond`` for the fits. The pin carries no net load in the preload
step and its spin and axial slide are then held by friction alone: with the default
1e-10 the contact Newton stalled (residual 1e-5 after 200 iterations) on the coarse
mesh; with 1e-6 those nearly undetermined directions are left to the minimum norm and it
converged in 33 iterations."""

FIT_R_SCALE = 0.1
"""``ContactSettings.r_scale`` for the fits (33 iterations against 174 at 1.0, same mesh)."""


FIT_TOL = 1e-8
"""Contact tolerance of the fits: the first loaded increment stalled at ρ ≈ 3e-9 against
the general hinge's 1e-10 (coarse mesh, F_p = 100 N)."""


def fit_contact_settings(settings: CycleSettings) -> ContactSettings:
    """Contact-solver options of the fits (see ``FIT_RIGID_RCOND``)."""
    return ContactSettings(
        mu=settings.mu,
        tol=max(settings.tol, FIT_TOL),
        max_iter=max(settings.max_iter, 200),
        rigid_rcond=FIT_RIGID_RCOND,
        r_scale=FIT_R_SCALE,
    )


def run_fit_cycle(
    system: FitSystem,
    settings: CycleSettings,
    preload_n: float,
    *,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[CycleResult, FitState, float]:
    """Preload, then cycle the clevis force; returns (cycle, preload state, preload friction work).

    Raises:
        ConvergenceError: With the increment; ``partial`` holds the increments that converged.
    """
    contact = fit_contact_settings(settings)
    start_afresh()  # nothing learnt by earlier cycles on this system's W
    t0 = time.perf_counter()
    with threadpool_limits(limits=settings.blas_threads, user_api="blas"):
        pre, pre_work = fit_preload(system, preload_n, contact)  # frictionless assembly
        t_pre = time.perf_counter() - t0
        step = FitStep(system, settings, preload_n, contact, pre)
        result = drive(step, settings, progress, timings_s={"preload": t_pre})
    return result, pre, pre_work


class FitStep:
    """The bearing hinge's increment with frictional fits, for ``fe.cycle.driver.drive``.

    Each target is one increment of ``solve_fit_increment`` at the clevis force (σ held),
    started on the branch's extrapolation and halved on failure (``_advance``). The balls'
    coordinates after the preload and after every increment are kept in the result
    (``CycleResult.ball_coordinates``).
    """

    def __init__(
        self,
        system: FitSystem,
        settings: CycleSettings,
        preload_n: float,
        contact: ContactSettings,
        preload: FitState,
    ) -> None:
        """Start from the preloaded state ``preload`` (plate force ``preload_n`` [N])."""
        self.system = system
        self.settings = settings
        self.preload_n = preload_n
        self.contact = contact
        self.preload = preload
        self.state = preload
        self.before: tuple[float, FitState] | None = None
        self.balls = [np.append(preload.v_mm, preload.preload_mm)]  # (2 n_b + 1,) each

    def targets(self, f_from: float, f_to: float, n: int) -> FloatArray:
        """The graded targets of the stage, refined toward F = 0 where it is crossed [N].

        No point at F = 0 itself, and only ``FIT_HALVINGS`` toward it: near zero force the
        pin is held by friction alone and the contact Newton stalls (it did at
        F = −0.019 N of a 100 N cycle with eight halvings).
        """
        targets = stage_targets(f_from, f_to, n, self.settings.grading)
        return with_zero_crossing(
            targets, f_from, self.preload_n, at_zero=False, halvings=FIT_HALVINGS
        )

    def advance(self, target: Target, partial: Callable[[], CycleResult]) -> Iterator[Recorded]:
        """Reach ``target.f_to``: one increment."""
        if target.first:
            self.before = None  # no extrapolation across a reversal
        new = _advance(self.system, self.state, target.f_from, target.f_to, self.contact,
                       self.settings, self.preload_n, target.index, partial, self.before)  # fmt: skip
        self.before, self.state = (target.f_from, self.state), new
        self.balls.append(np.append(new.v_mm, new.preload_mm))
        res = new.result
        inc = Increment(
            stage=target.stage,
            force_n=target.f_to,
            disp_mm=float(new.contact.alpha[GRIP]),
            side=1,
            iterations=0 if res is None else res.iterations,
            n_open=0 if res is None else res.n_open,
            n_stick=0 if res is None else res.n_stick,
            n_slip=0 if res is None else res.n_slip,
            friction_work=0.0 if res is None else float(np.sum(res.friction_work)),
            normal_work=0.0 if res is None else float(np.sum(res.normal_work)),
            elastic_energy=fit_energy(self.system, new),
        )
        yield inc, new.contact

    def result(
        self,
        increments: tuple[Increment, ...],
        states: tuple[ContactState, ...],
        timings_s: dict[str, float],
    ) -> CycleResult:
        """The cycle of these increments, with the preloaded state and the balls' coordinates."""
        return CycleResult(
            self.settings,
            0.0,
            increments,
            0.0,
            states,
            {},
            timings_s,
            preload_state=self.preload.contact,
            ball_coordinates=np.array(self.balls[: len(increments) + 1]),
        )


def _advance(
    system: FitSystem,
    state: FitState,
    f_from: float,
    f_to: float,
    contact: ContactSettings,
    settings: CycleSettings,
    preload_n: float,
    index: int,
    partial: Callable[[], CycleResult],
    before: tuple[float, FitState] | None = None,
) -> FitState:
    """Reach ``f_to`` from ``state``, halving the step on failure (works summed over sub-steps).

    ``before``: the converged (force, state) preceding ``state`` on the same branch; the
    first (sub-)step then starts from the linear extrapolation of the two.
    """
    if f_to == 0.0 and preload_n == 0.0 and f_from == 0.0:
        return state
    ref = max(abs(f_to), abs(f_from), preload_n, settings.amplitude_n * 1e-3)

    def attempt(n_sub: int) -> FitState:
        s = state
        fric = normal = 0.0
        for j in range(1, n_sub + 1):
            f = f_from + (f_to - f_from) * j / n_sub
            guess = None
            if j == 1 and before is not None and before[0] != f_from:
                t = (f - f_from) / (f_from - before[0])
                b = before[1]
                guess = (
                    s.v_mm + t * (s.v_mm - b.v_mm),
                    np.asarray(s.contact.p) + t * (np.asarray(s.contact.p) - b.contact.p),
                    np.asarray(s.contact.alpha)
                    + t * (np.asarray(s.contact.alpha) - b.contact.alpha),
                )
            s = solve_fit_increment(system, s, f, state.preload_mm, contact,
                                    ref_load_n=ref, increment=index, guess=guess)  # fmt: skip
            assert s.result is not None
            fric += float(np.sum(s.result.friction_work))
            normal += float(np.sum(s.result.normal_work))
        if n_sub > 1 and s.result is not None:
            summed = dataclasses.replace(
                s.result, friction_work=np.array([fric]), normal_work=np.array([normal])
            )
            s = FitState(s.contact, s.v_mm, s.preload_mm, summed, s.ball_iterations)
        return s

    what = f"increment {index} (F {f_from:.4g} → {f_to:.4g} N)"
    return with_cutbacks(
        attempt, settings.max_cutbacks, increment=index, what=what, partial=partial
    )
