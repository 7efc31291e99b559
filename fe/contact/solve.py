"""The globalised semismooth Newton iteration of one contact increment (see :mod:`fe.contact`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cad.errors import ConvergenceError, ParameterError
from fe.contact.krylov import Workspace, krylov_step, workspace_for
from fe.contact.law import ContactStatus
from fe.contact.newton import Factor, Iterate, Problem, Step, evaluate, newton_step
from fe.contact.state import (
    ContactSettings,
    ContactState,
    IncrementResult,
    LinearSolver,
    validate_problem,
)

FloatArray = npt.NDArray[np.float64]

RESCUE_FACTORS = (0.1, 10.0, 0.01, 100.0, 1e-3, 1e3)
"""Factors applied in turn to ``r`` when Newton stalls (see module docstring)."""


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
    prob = validate_problem(W, w_free, state_prev, G, e)._replace(mu=settings.mu)
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
