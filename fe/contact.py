"""Incremental frictional contact on the condensed (Delassus) system.

The stiffness is linear and constant; the caller condenses it once onto ``m`` contact
points (slave nodes) and passes, per load increment,

* ``W`` — the Delassus operator ``C K⁻¹ Cᵀ``, shape (3m, 3m), float64 [mm/N], symmetric
  positive (semi)definite, rows and columns node-major ``[n, t1, t2]`` per point;
* ``w_free`` — the relative displacement with zero contact force, shape (m, 3) [mm];
* optionally ``G`` (3m, k) [mm per rigid amplitude] and ``e`` (k,) for floating bodies.

Conventions:
    * ``p_i = (p_n, p_t1, p_t2)`` [N] is the contact force on the slave at point ``i``
      (``-p_i`` acts on the master); ``p_n >= 0`` is compressive.
    * ``w = W p + G α + w_free`` (flattened node-major) is the relative displacement of
      slave w.r.t. master [mm]; ``w_n`` is the gap (``>= 0`` open, ``W_nn > 0``).
    * ``α`` (k,) are rigid-body amplitudes of floating bodies with equilibrium
      ``Gᵀ p = e``. Rigid directions the contact forces cannot see are undetermined:
      ``p`` stays unique and the minimum-norm ``α`` is returned.
    * Signorini ``w_n >= 0, p_n >= 0, w_n p_n = 0`` and Coulomb ``|p_t| <= μ p_n`` with
      ``Δw_t = w_t - w_t_prev = 0`` where ``|p_t| < μ p_n``, else ``Δw_t = -γ p_t/|p_t|``,
      ``γ >= 0``, written as the Alart–Curnier equations ``C(p) = p - λ(p - r g) = 0`` of
      :mod:`fe.contact_law` with ``g = (w_n, Δw_t)``.

Algorithm: semismooth (generalised) Newton on ``C(p, α) = 0, Gᵀp = e`` with the active
set read off the trial force. Open points are eliminated (``p = 0``), the component of a
slipping point's tangential force along the slip direction is eliminated
(``p_t·u = μ p_n``), so each step factorises a dense system of size
``3 n_stick + 2 n_slip + n_frictionless`` (``+ k`` rigid amplitudes via a k×k Schur
complement solved by least squares with ``rcond``, which gives the minimum-norm ``α``).
While the unknown layout is unchanged and the iteration converges fast, the last LU
factors are reused (chord steps: exact residual, stale matrix; see ``chord_rate``).
Globalisation: Armijo backtracking on the merit ``φ = ½|C/r|² + ½|(Gᵀp - e)/r̄|²``.
If no step ``>= min_step`` decreases ``φ`` (or the step matrix is singular) a rescue is
taken, alternately (a) if some points are open, a full predictor step: floating bodies
with unbalanced load are first moved rigidly to first contact and the touching points
closed (without floating bodies all open points are closed), frictionless; this is how a
floating pin in a clearance finds contact, and (b) rescaling ``r`` by the next factor of
``RESCUE_FACTORS``, which changes the merit and the active-set path but not the solution. The line search keeps ``φ``
monotone between rescues, so the plain Newton cycle between active sets cannot occur;
the loop stops at ``max_iter`` with a ConvergenceError.

Convergence: the scaled residual ``ρ = max(|C/r|_∞ / d_ref, |Gᵀp - e|_∞ / f_ref)`` must
drop to ``tol``, where ``d_ref = max(|W p|_∞, |G α|_∞, |w_free - (0, w_t_prev)|_∞)`` [mm]
and ``f_ref = max(|e|_∞, ||G|ᵀ |p||_∞, r̄ d_ref max|G|)`` [N] (the last term is the load
one point takes at the displacement scale, so ``ρ`` stays meaningful when ``e = 0``).
``C/r`` is the violation in displacement units (penetration, stick drift, or force/r),
so ``ρ`` is a relative error that is invariant under scaling the load and independent
of units.

Energy: for increment ``p_prev → p`` the consistent (trapezoidal) works are
``friction_work_i = -½ (p_t,prev + p_t)·Δw_t`` and
``normal_work_i = -½ (p_n,prev + p_n) Δw_n``. With ``K u = f + Cᵀ p`` and the
trapezoidal external work ``½ (f_prev + f)·Δu`` they satisfy exactly
``W_ext = ΔE_elastic + Σ (friction_work + normal_work)``, so over a cycle that closes
(``ΔE = 0``) the summed works equal the loop area. ``normal_work`` is zero for points that
stay closed or stay open and is a first-order discretisation term at increments where a
point opens or closes. ``dissipation_i = -p_t·Δw_t >= 0`` is the backward-Euler value
(it tends to ``friction_work`` as the increments shrink).

Example:
    >>> import numpy as np
    >>> W = np.diag([1.0, 2.0, 2.0])            # one point, mm/N
    >>> w_free = np.array([[-1.0, 0.5, 0.0]])   # 1 mm interference, 0.5 mm drag
    >>> res = solve_increment(W, w_free, ContactState.initial(1), ContactSettings(mu=0.2))
    >>> res.state.p.round(12).tolist(), res.n_slip
    ([[1.0, -0.2, 0.0]], 1)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cad.errors import ConvergenceError, ParameterError, check_range
from fe.contact_krylov import KrylovOptions, Workspace, krylov_step, workspace_for
from fe.contact_law import ContactStatus
from fe.contact_newton import Factor, Iterate, Problem, Step, evaluate, newton_step

FloatArray = npt.NDArray[np.float64]

RESCUE_FACTORS = (0.1, 10.0, 0.01, 100.0, 1e-3, 1e3)
"""Factors applied in turn to ``r`` when Newton stalls (see module docstring)."""

__all__ = [
    "ContactSettings",
    "ContactState",
    "ContactStatus",
    "IncrementResult",
    "KrylovOptions",
    "LinearSolver",
    "complementarity",
    "solve_increment",
]


class LinearSolver(Enum):
    """How each Newton direction is computed (the converged solution is the same).

    Attributes:
        LU: Form and LU-factorise the reduced Jacobian, with chord steps (``chord_rate``).
        KRYLOV: GMRES on the exact reduced system, preconditioned by an earlier LU
            updated to the new active set (:mod:`fe.contact_krylov`); the LU is kept
            between increments on the same ``W`` and refactorised only when needed.
    """

    LU = "lu"
    KRYLOV = "krylov"


@dataclass(frozen=True)
class ContactSettings:
    """Options of :func:`solve_increment`.

    Attributes:
        mu: Coulomb friction coefficient, ``>= 0``.
        r_scale: Augmentation factor; point ``i`` uses ``r_i = r_scale / mean(diag W_ii)``
            [N/mm]. Algorithmic only: the converged solution does not depend on it.
        tol: Tolerance on the scaled residual ``ρ`` (module docstring).
        max_iter: Newton iteration cap per increment.
        warm_start: Start from the previous increment's ``p`` and ``α`` (else from zero).
        armijo: Sufficient-decrease constant of the line search.
        min_step: Smallest line-search step before a rescue is taken.
        chord_rate: Keep reusing the last factorisation (chord steps with the exact
            residual) while each such step divides ``ρ`` by at least ``1/chord_rate``
            and the unknown layout is unchanged; 0 refactorises at every iteration.
        rigid_rcond: Rigid directions whose singular value in the k×k Schur complement
            ``Gᵀ J⁻¹ G`` is below ``rigid_rcond · max_j |G_j|² / mean(diag W)`` are
            treated as undetermined (they get no component of ``α``).
        linear_solver: How the Newton directions are computed (``chord_rate`` applies
            to ``LinearSolver.LU`` only).
        krylov: Tuning of ``LinearSolver.KRYLOV``.
    """

    mu: float = 0.0
    r_scale: float = 1.0
    tol: float = 1e-10
    max_iter: int = 60
    warm_start: bool = True
    armijo: float = 1e-4
    min_step: float = 1e-4
    chord_rate: float = 0.1
    rigid_rcond: float = 1e-10
    linear_solver: LinearSolver = LinearSolver.KRYLOV
    krylov: KrylovOptions = field(default_factory=KrylovOptions)

    def __post_init__(self) -> None:
        check_range("mu", self.mu, 0.0, float("inf"))
        check_range("r_scale", self.r_scale, 0.0, float("inf"), lo_open=True, hi_open=True)
        check_range("tol", self.tol, 0.0, 1.0, lo_open=True, hi_open=True)
        check_range("max_iter", self.max_iter, 1, float("inf"))
        check_range("armijo", self.armijo, 0.0, 0.5, lo_open=True, hi_open=True)
        check_range("min_step", self.min_step, 0.0, 1.0, lo_open=True, hi_open=True)
        check_range("chord_rate", self.chord_rate, 0.0, 1.0, hi_open=True)
        check_range("rigid_rcond", self.rigid_rcond, 0.0, 1.0, lo_open=True, hi_open=True)


def _frozen(
    a: npt.ArrayLike, dtype: type, shape: tuple[int, ...], name: str
) -> npt.NDArray[np.generic]:
    arr: npt.NDArray[np.generic] = np.array(a, dtype=dtype, copy=True)
    if arr.shape != shape:
        raise ParameterError(f"{name} must have shape {shape}, got {arr.shape}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class ContactState:
    """Converged contact state after an increment (arrays are read-only copies).

    Attributes:
        p: Contact forces on the slave, shape (m, 3), float64 [N], frame [n, t1, t2].
        w: Relative displacements, shape (m, 3), float64 [mm]; ``w[:, 1:]`` is the
            tangential reference ``w_t_prev`` of the next increment.
        status: ContactStatus codes, shape (m,), int8.
        alpha: Rigid-body amplitudes, shape (k,), float64 (units set by ``G``).
    """

    p: FloatArray
    w: FloatArray
    status: npt.NDArray[np.int8]
    alpha: FloatArray

    def __post_init__(self) -> None:
        m = np.shape(self.p)[0] if np.ndim(self.p) == 2 else -1
        object.__setattr__(self, "p", _frozen(self.p, np.float64, (m, 3), "p"))
        object.__setattr__(self, "w", _frozen(self.w, np.float64, (m, 3), "w"))
        object.__setattr__(self, "status", _frozen(self.status, np.int8, (m,), "status"))
        k = np.size(self.alpha)
        object.__setattr__(self, "alpha", _frozen(np.ravel(self.alpha), np.float64, (k,), "alpha"))

    @classmethod
    def initial(cls, n_points: int, n_rigid: int = 0, w: FloatArray | None = None) -> ContactState:
        """Return the unloaded state: no force, all open, ``α = 0``.

        Args:
            n_points: Number of contact points ``m``.
            n_rigid: Number of rigid amplitudes ``k``.
            w: Relative displacement at zero load, shape (m, 3) [mm] (default zero); its
                tangential part is the slip reference, its normal part only enters
                ``normal_work`` of the first increment.

        Returns:
            The initial state.
        """
        w0 = np.zeros((n_points, 3)) if w is None else w
        status = np.zeros(n_points, dtype=np.int8)
        return cls(np.zeros((n_points, 3)), w0, status, np.zeros(n_rigid))


@dataclass(frozen=True)
class IncrementResult:
    """Outcome of one increment.

    Attributes:
        state: The converged state.
        iterations: Newton iterations used.
        residuals: Scaled residual ``ρ`` at every iterate (the last is below ``tol``).
        n_open: Number of open points.
        n_stick: Number of sticking points.
        n_slip: Number of slipping points.
        friction_work: ``-½ (p_t,prev + p_t)·Δw_t``, shape (m,), float64 [N·mm].
        normal_work: ``-½ (p_n,prev + p_n) Δw_n``, shape (m,), float64 [N·mm].
        dissipation: ``-p_t·Δw_t >= 0`` (backward Euler), shape (m,), float64 [N·mm].
        rescues: How many rescues (predictor or ``r`` change) were needed.
        factorizations: LU factorisations done (iterations minus chord and Krylov steps).
        linear_iterations: GMRES iterations done (``LinearSolver.KRYLOV``).
    """

    state: ContactState
    iterations: int
    residuals: tuple[float, ...]
    n_open: int
    n_stick: int
    n_slip: int
    friction_work: FloatArray
    normal_work: FloatArray
    dissipation: FloatArray
    rescues: int
    factorizations: int
    linear_iterations: int = 0


def _validate(
    W: FloatArray,
    w_free: FloatArray,
    state_prev: ContactState,
    G: FloatArray | None,
    e: FloatArray | None,
) -> Problem:
    m = state_prev.p.shape[0]
    W = np.asarray(W, dtype=np.float64)
    if W.shape != (3 * m, 3 * m):
        raise ParameterError(f"W must have shape {(3 * m, 3 * m)} for {m} points, got {W.shape}")
    w_free = np.asarray(w_free, dtype=np.float64)
    if w_free.shape != (m, 3):
        raise ParameterError(f"w_free must have shape {(m, 3)}, got {w_free.shape}")
    # One pass without a temporary: NaN and inf propagate into the sum (an overflowing
    # sum of finite entries falls back to the entrywise check).
    w_sum = float(np.sum(W))
    finite_w = np.isfinite(w_sum) or bool(np.all(np.isfinite(W)))
    if not (finite_w and np.all(np.isfinite(w_free))):
        raise ParameterError("W and w_free must be finite, got NaN or inf")
    d_n = np.diag(W)[0::3]
    if np.any(d_n <= 0.0):
        i = int(np.argmin(d_n))
        raise ParameterError(f"W_nn must be > 0 at every point, got {d_n[i]:g} at point {i}")
    k = state_prev.alpha.shape[0]
    if (G is None) != (e is None):
        raise ParameterError("G and e must be given together, got only one of them")
    G_arr = np.zeros((3 * m, k)) if G is None else np.asarray(G, dtype=np.float64)
    e_arr = np.zeros(k) if e is None else np.asarray(e, dtype=np.float64)
    if G_arr.shape != (3 * m, k) or e_arr.shape != (k,):
        raise ParameterError(
            f"G and e must have shapes {(3 * m, k)} and {(k,)} (k from state_prev.alpha), "
            f"got {G_arr.shape} and {e_arr.shape}"
        )
    return Problem(W, w_free, G_arr, e_arr, np.array(state_prev.w[:, 1:]), 0.0, w_sum)


def _line_search(
    prob: Problem, it: Iterate, step: Step, r: FloatArray, settings: ContactSettings
) -> Iterate | None:
    """Armijo backtracking on the merit; None if no step >= min_step decreases it.

    One product ``W dp`` serves every trial: ``W (p + τ dp) = W p + τ W dp``.
    """
    W_dp = (prob.W @ step.dp.ravel()).reshape(-1, 3)
    tau = 1.0
    while tau >= settings.min_step:
        alpha = it.alpha + tau * (step.alpha_new - it.alpha)
        trial = evaluate(prob, it.p + tau * step.dp, alpha, r, it.Wp + tau * W_dp)
        if trial.merit <= (1.0 - 2.0 * settings.armijo * tau) * it.merit:
            return trial
        tau *= 0.5
    return None


def solve_increment(
    W: FloatArray,
    w_free: FloatArray,
    state_prev: ContactState,
    settings: ContactSettings,
    *,
    G: FloatArray | None = None,
    e: FloatArray | None = None,
    increment: int = 0,
    start: tuple[FloatArray, FloatArray] | None = None,
) -> IncrementResult:
    """Solve one quasi-static increment of the frictional contact problem.

    Args:
        W: Delassus operator, shape (3m, 3m), float64 [mm/N], node-major [n, t1, t2].
        w_free: Relative displacement at zero contact force, shape (m, 3), float64 [mm].
        state_prev: Converged state of the previous increment (``ContactState.initial``
            for the first); supplies ``w_t_prev`` and the warm start. ``k`` is
            ``state_prev.alpha.size``.
        settings: Friction coefficient and solver options.
        G: Rigid-body map of floating bodies, shape (3m, k), float64 [mm per unit α].
        e: Load on the rigid amplitudes, ``Gᵀ p = e``, shape (k,), float64 [N].
        increment: Index reported in a ConvergenceError.
        start: Starting iterate ``(p (m, 3), α (k,))`` for Newton, e.g. extrapolated from
            the last increments; it changes where Newton starts, never the solution, and
            never the works (those use ``state_prev``). Default: the warm start.

    Returns:
        The new state, iteration count, residual history, status counts and works.

    Raises:
        ParameterError: On inconsistent shapes or non-finite input.
        ConvergenceError: If ``ρ > tol`` after ``max_iter`` iterations; ``partial``
            holds the last iterate as a ContactState.
    """
    prob = _validate(W, w_free, state_prev, G, e)._replace(mu=settings.mu)
    m, k = state_prev.p.shape[0], state_prev.alpha.shape[0]
    blocks = np.diagonal(prob.W).reshape(m, 3)
    r_base = settings.r_scale / blocks.mean(axis=1)
    r = r_base
    col_sq = float(np.max(np.sum(prob.G**2, axis=0))) if k else 0.0
    cut = settings.rigid_rcond * col_sq / float(np.mean(blocks))
    if start is not None:
        p0, a0 = np.array(start[0], dtype=np.float64), np.array(start[1], dtype=np.float64)
        if p0.shape != (m, 3) or a0.shape != (k,):
            raise ParameterError(
                f"start must have shapes {(m, 3)} and {(k,)}, got {p0.shape} and {a0.shape}"
            )
    elif settings.warm_start:
        p0, a0 = np.array(state_prev.p), np.array(state_prev.alpha)
    else:
        p0, a0 = np.zeros((m, 3)), np.zeros(k)
    it = evaluate(prob, p0, a0, r)
    history, rescues, n_factor = [it.rho], 0, 0
    n_iter, factor = 0, None
    krylov = settings.linear_solver is LinearSolver.KRYLOV
    ws = workspace_for(prob.W, prob.w_sum) if krylov else None
    gmres_before = 0 if ws is None else ws.gmres_iterations
    while it.rho > settings.tol:
        if n_iter == settings.max_iter:
            partial = ContactState(it.p, it.w, it.law.status, it.alpha)
            raise ConvergenceError(
                "contact Newton did not converge",
                increment=increment,
                iteration=n_iter,
                residual=it.rho,
                partial=partial,
            )
        n_iter += 1
        step, new = _direction(prob, it, r, cut, settings, factor, ws)
        n_factor += 0 if step is None else step.factorizations
        if new is None:
            rescued = _rescue(prob, it, r, r_base, cut, rescues)
            rescues += 1
            r, new, factor = rescued.law_r, rescued.iterate, None
        elif step is not None:
            fast = new.rho <= settings.chord_rate * it.rho
            factor = step.step.factor if fast and settings.chord_rate > 0.0 else None
        it = new
        history.append(it.rho)
    n_gmres = 0 if ws is None else ws.gmres_iterations - gmres_before
    if n_iter:  # W p was updated along the steps: report w with an exact product
        Wp = (prob.W @ it.p.ravel()).reshape(-1, 3)
        it = it._replace(w=Wp + (prob.G @ it.alpha).reshape(-1, 3) + prob.w_free, Wp=Wp)
    return _result(prob, state_prev, it, n_iter, history, rescues, n_factor, n_gmres)


class _Direction(NamedTuple):
    step: Step
    factorizations: int


def _direction(
    prob: Problem,
    it: Iterate,
    r: FloatArray,
    cut: float,
    settings: ContactSettings,
    factor: Factor | None,
    ws: Workspace | None,
) -> tuple[_Direction | None, Iterate | None]:
    """Newton direction and line search; a reused matrix that fails is replaced once.

    Returns the direction (None if the matrix was singular) with the number of LU
    factorisations it took, and the accepted iterate (None: the line search failed).
    """
    if ws is None:
        step = newton_step(prob, it, r, cut, reuse=factor)
    else:
        step = krylov_step(prob, it, r, cut, ws, settings.krylov)
    new = None if step is None else _line_search(prob, it, step, r, settings)
    if step is None or not step.reused or new is not None:
        return (None if step is None else _Direction(step, int(not step.reused))), new
    # The stale matrix (chord step or preconditioner) was not good enough: refactorise.
    if ws is None:
        retry = newton_step(prob, it, r, cut)
    else:
        ws.refresh = True
        retry = krylov_step(prob, it, r, cut, ws, settings.krylov)
    if retry is None:
        return None, None
    return _Direction(retry, 1), _line_search(prob, it, retry, r, settings)


class _Rescued(NamedTuple):
    iterate: Iterate
    law_r: FloatArray


def _rescue(
    prob: Problem, it: Iterate, r: FloatArray, r_base: FloatArray, cut: float, count: int
) -> _Rescued:
    """Leave a stall: alternately a contact predictor (if points are open) and a new r.

    The predictor first moves unbalanced floating bodies rigidly to first contact (see
    :func:`_approach`) and closes the touching points; without floating bodies it closes
    every open point. It then takes the full Newton step with those points closed and
    frictionless. The r change (``r_base`` times the next of ``RESCUE_FACTORS``) keeps the
    iterate but changes the merit and the active-set path. Neither changes the solution,
    and the alternation keeps Newton from repeating a cycle.
    """
    is_open = it.law.status == ContactStatus.OPEN
    if count % 2 == 0 and np.any(is_open):
        approach = _approach(prob, it, is_open)
        if approach is not None:
            it, is_open = evaluate(prob, it.p, approach[0], r), approach[1]
        step = newton_step(prob, it, r, cut, force_closed=is_open)
        if step is not None:
            return _Rescued(evaluate(prob, it.p + step.dp, step.alpha_new, r), r)
    new_r = r_base * RESCUE_FACTORS[(count // 2) % len(RESCUE_FACTORS)]
    return _Rescued(evaluate(prob, it.p, it.alpha, new_r), new_r)


def _approach(
    prob: Problem, it: Iterate, is_open: npt.NDArray[np.bool_]
) -> tuple[FloatArray, npt.NDArray[np.bool_]] | None:
    """Move floating bodies along the unbalanced load until the first open point touches.

    The direction ``d = Gᵀp - e`` is the rigid motion on which the unbalanced external
    load does positive work; the step is the smallest ``s >= 0`` that closes an open gap,
    ``w_n + s G_n d = 0``. Returns the moved ``α`` and the touching points, or None if
    there is no floating body, no unbalance, or no gap closes along ``d``.
    """
    if it.eq.size == 0 or not np.any(it.eq):
        return None
    rate = (prob.G[0::3] @ it.eq)[is_open]  # d w_n / d s of the open points
    closing = rate < 0.0
    if not np.any(closing):
        return None
    s = np.full(len(rate), np.inf)
    s[closing] = np.maximum(it.w[is_open, 0][closing], 0.0) / -rate[closing]
    s_min = float(s.min())
    touching = np.zeros(len(is_open), dtype=bool)
    touching[np.flatnonzero(is_open)[s <= s_min * (1.0 + 1e-9)]] = True
    return it.alpha + s_min * it.eq, touching


def _result(
    prob: Problem,
    prev: ContactState,
    it: Iterate,
    n_iter: int,
    history: list[float],
    rescues: int,
    n_factor: int,
    n_gmres: int,
) -> IncrementResult:
    status = it.law.status
    dw = it.w - prev.w
    p_mid = 0.5 * (prev.p + it.p)
    friction_work = -np.sum(p_mid[:, 1:] * dw[:, 1:], axis=1)
    normal_work = -p_mid[:, 0] * dw[:, 0]
    dissipation = -np.sum(it.p[:, 1:] * dw[:, 1:], axis=1)
    return IncrementResult(
        state=ContactState(it.p, it.w, status, it.alpha),
        iterations=n_iter,
        residuals=tuple(history),
        n_open=int(np.sum(status == ContactStatus.OPEN)),
        n_stick=int(np.sum(status == ContactStatus.STICK)),
        n_slip=int(np.sum(status == ContactStatus.SLIP)),
        friction_work=friction_work,
        normal_work=normal_work,
        dissipation=dissipation,
        rescues=rescues,
        factorizations=n_factor,
        linear_iterations=n_gmres,
    )


class Complementarity(NamedTuple):
    """Alart–Curnier residual and its generalised Jacobian (see :func:`complementarity`).

    Attributes:
        residual: ``C``, shape (m, 3), float64 [N].
        jacobian: ``∂C/∂p`` with α fixed, shape (3m, 3m), float64 [-], node-major.
        status: ContactStatus codes of the trial, shape (m,), int8.
    """

    residual: FloatArray
    jacobian: FloatArray
    status: npt.NDArray[np.int8]


def complementarity(
    W: FloatArray,
    w_free: FloatArray,
    state_prev: ContactState,
    p: FloatArray,
    settings: ContactSettings,
    *,
    alpha: FloatArray | None = None,
    G: FloatArray | None = None,
) -> Complementarity:
    """Evaluate ``C(p) = p - λ(p - r g(p))`` and ``∂C/∂p = (I - D) + r D W`` densely.

    Meant for checks and small problems (it forms a (3m, 3m) matrix).

    Args:
        W: Delassus operator, shape (3m, 3m), float64 [mm/N].
        w_free: Free relative displacement, shape (m, 3), float64 [mm].
        state_prev: Previous converged state (``w_t_prev``).
        p: Contact forces at which to evaluate, shape (m, 3), float64 [N].
        settings: Supplies ``mu`` and ``r_scale``.
        alpha: Rigid amplitudes, shape (k,) (default zero).
        G: Rigid-body map, shape (3m, k) (default none).

    Returns:
        Residual, Jacobian and trial status.
    """
    k = state_prev.alpha.shape[0]
    e = None if G is None else np.zeros(k)
    prob = _validate(W, w_free, state_prev, G, e)._replace(mu=settings.mu)
    m = p.shape[0]
    r = settings.r_scale / np.diagonal(prob.W).reshape(m, 3).mean(axis=1)
    a = np.zeros(k) if alpha is None else np.asarray(alpha, dtype=np.float64)
    it = evaluate(prob, np.asarray(p, dtype=np.float64), a, r)
    D = it.law.tangent  # (m, 3, 3)
    jac = np.zeros((3 * m, 3 * m))
    rows = np.arange(3 * m).reshape(m, 3)
    jac[rows[:, :, None], rows[:, None, :]] = np.eye(3) - D
    rD = r[:, None, None] * D
    jac += np.einsum("mab,mbj->maj", rD, prob.W.reshape(m, 3, 3 * m)).reshape(3 * m, 3 * m)
    return Complementarity(it.C, jac, it.law.status)
