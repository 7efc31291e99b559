"""The globalised semismooth Newton loop (line search, rescues) shared by the solvers.

Internal to :mod:`fe.contact` (see its docstring for the algorithm): :func:`newton_loop`
iterates one problem until ``ρ <= tol``, the iteration budget is spent, or (if asked) a
step matrix is singular, which :func:`fe.contact.solve.solve_increment` then hands to the
regularised fallback of :mod:`fe.contact.proximal`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from fe.contact.dense import Factor
from fe.contact.krylov import Workspace
from fe.contact.krylov_step import krylov_step
from fe.contact.law import ContactStatus
from fe.contact.newton import Step, newton_step
from fe.contact.residual import Iterate, Problem, evaluate, sparse_product
from fe.contact.state import ContactSettings

FloatArray = npt.NDArray[np.float64]

RESCUE_FACTORS = (0.1, 10.0, 0.01, 100.0, 1e-3, 1e3)
"""Factors applied in turn to ``r`` when Newton stalls (see module docstring)."""


def line_search(
    prob: Problem,
    it: Iterate,
    step: Step,
    r: FloatArray,
    settings: ContactSettings,
    ref: float | None = None,
) -> Iterate | None:
    """Armijo backtracking on the merit; None if no step >= min_step decreases it.

    One product ``W dp`` serves every trial: ``W (p + τ dp) = W p + τ W dp``. With
    ``ref`` (>= ``it.merit``, e.g. the largest of the last few merits) the decrease is
    measured from ``ref`` instead (a nonmonotone search); None keeps it monotone.
    """
    W_dp = sparse_product(prob.W, step.dp, prob.symmetric).reshape(-1, 3)  # rows of dp ≠ 0
    tau = 1.0
    while tau >= settings.min_step:
        alpha = it.alpha + tau * (step.alpha_new - it.alpha)
        trial = evaluate(prob, it.p + tau * step.dp, alpha, r, it.Wp + tau * W_dp)
        decrease = 2.0 * settings.armijo * tau
        bound = (1.0 - decrease) * it.merit if ref is None else ref - decrease * it.merit
        if trial.merit <= bound:
            return trial
        tau *= 0.5
    return None


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
    tol: float = 0.0,
) -> tuple[_Direction | None, Iterate | None]:
    """Newton direction and line search; a reused matrix that fails is replaced once.

    Returns the direction (None if the matrix was singular) with the number of LU
    factorisations it took, and the accepted iterate (None: the line search failed).
    """
    threads = settings.lu_threads
    if ws is None:
        step = newton_step(prob, it, r, cut, reuse=factor, threads=threads)
    else:
        step = krylov_step(prob, it, r, cut, ws, settings.krylov, threads, tol)
    new = None if step is None else line_search(prob, it, step, r, settings)
    if step is None or not step.reused or new is not None:
        return (None if step is None else _Direction(step, int(not step.reused))), new
    # The stale matrix (chord step or preconditioner) was not good enough: refactorise.
    if ws is None:
        retry = newton_step(prob, it, r, cut, threads=threads)
    else:
        ws.refresh = True
        retry = krylov_step(prob, it, r, cut, ws, settings.krylov, threads, tol)
    if retry is None:
        return None, None
    return _Direction(retry, 1), line_search(prob, it, retry, r, settings)


class _Rescued(NamedTuple):
    iterate: Iterate
    law_r: FloatArray


def _rescue(
    prob: Problem,
    it: Iterate,
    r: FloatArray,
    r_base: FloatArray,
    cut: float,
    count: int,
    threads: int | None,
    single_min: int | None = None,
) -> _Rescued:
    """Leave a stall: alternately a contact predictor (if points are open) and a new r.

    The predictor first moves unbalanced floating bodies rigidly to first contact (see
    :func:`_approach`) and closes the touching points; without floating bodies it closes
    every open point. It then takes the full Newton step with those points closed and
    frictionless. The r change (``r_base`` times the next of ``RESCUE_FACTORS``) keeps the
    iterate but changes the merit and the active-set path. Neither changes the solution,
    and the alternation keeps Newton from repeating a cycle. The predictor is taken
    unchecked, so from ``single_min`` unknowns its LU is float32 (at level 1 of the hinge
    it closes every point: a 9 400-unknown LU).
    """
    is_open = it.law.status == ContactStatus.OPEN
    if count % 2 == 0 and np.any(is_open):
        approach = _approach(prob, it, is_open)
        if approach is not None:
            it, is_open = evaluate(prob, it.p, approach[0], r), approach[1]
        step = newton_step(
            prob, it, r, cut, force_closed=is_open, threads=threads, single_min=single_min
        )
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


class Run(NamedTuple):
    """Where :func:`newton_loop` stopped.

    Attributes:
        it: The last iterate (on the loop's problem, with its last ``r``).
        r: The augmentation in use at the end, shape (m,), float64 [N/mm].
        iterations: Newton iterations done.
        history: Scaled residual ``ρ`` after every iteration (not the starting one).
        rescues: Rescues taken.
        factorizations: LU factorisations done.
        singular: The loop stopped at a singular step matrix (``stop_on_singular``).
    """

    it: Iterate
    r: FloatArray
    iterations: int
    history: tuple[float, ...]
    rescues: int
    factorizations: int
    singular: bool


def newton_loop(
    prob: Problem,
    it: Iterate,
    r_base: FloatArray,
    cut: float,
    settings: ContactSettings,
    *,
    ws: Workspace | None,
    max_iter: int,
    tol: float,
    stop_on_singular: bool,
) -> Run:
    """Iterate globalised Newton from ``it`` until ``ρ <= tol`` or ``max_iter`` iterations.

    Args:
        prob: The problem.
        it: Starting iterate, evaluated with ``r_base``.
        r_base: Augmentation per point, shape (m,), float64 [N/mm] (rescues scale it).
        cut: Absolute singular-value cut of the rigid-body Schur complement.
        settings: Line search, chord and rescue options.
        ws: Krylov workspace of ``prob.W`` (None: dense LU steps).
        max_iter: Iteration budget.
        tol: Tolerance on ``ρ``.
        stop_on_singular: Stop at the first singular step matrix instead of a rescue.

    Returns:
        Where it stopped; converged iff ``run.it.rho <= tol``.
    """
    r, history, rescues, n_factor, n_iter, factor = r_base, [], 0, 0, 0, None
    while it.rho > tol and n_iter < max_iter:
        step, new = _direction(prob, it, r, cut, settings, factor, ws, tol)
        n_iter += 1
        if step is None and stop_on_singular:
            history.append(it.rho)
            return Run(it, r, n_iter, tuple(history), rescues, n_factor, True)
        n_factor += 0 if step is None else step.factorizations
        if new is None:
            rescued = _rescue(
                prob, it, r, r_base, cut, rescues, settings.lu_threads, settings.krylov.single_min
            )
            rescues += 1
            r, new, factor = rescued.law_r, rescued.iterate, None
        elif step is not None:
            fast = new.rho <= settings.chord_rate * it.rho
            factor = step.step.factor if fast and settings.chord_rate > 0.0 else None
        it = new
        history.append(it.rho)
    return Run(it, r, n_iter, tuple(history), rescues, n_factor, False)
