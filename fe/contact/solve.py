"""The globalised semismooth Newton iteration of one contact increment (see :mod:`fe.contact`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from cad.errors import ConvergenceError, ParameterError
from fe.contact.globalise import newton_loop
from fe.contact.krylov import workspace_for
from fe.contact.law import ContactStatus
from fe.contact.proximal import proximal_loop
from fe.contact.residual import Iterate, Problem, Solved, evaluate, sparse_product
from fe.contact.state import (
    ContactSettings,
    ContactState,
    IncrementResult,
    LinearSolver,
    validate_problem,
)
from fe.contact.working import select_points, solve_on_points, use_whole

FloatArray = npt.NDArray[np.float64]


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
    symmetric: bool | None = None,
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
        symmetric: True when ``W`` is symmetric by construction (a condensed compliance
            formed anew at every call, where checking it costs a full pass over ``W``);
            None: checked, and remembered while the same ``W`` lives.

    Returns:
        The new state, iteration count, residual history, status counts and works.

    Raises:
        ParameterError: On inconsistent shapes or non-finite input.
        ConvergenceError: If ``ρ > tol`` after ``max_iter`` iterations; ``partial``
            holds the last iterate as a ContactState.
    """
    m, k = state_prev.p.shape[0], state_prev.alpha.shape[0]
    prob = validate_problem(W, w_free, state_prev, G, e, symmetric)._replace(
        mu=settings.mu_per_point(m)
    )
    if (
        settings.frictionless_start
        and start is None
        and not np.any(state_prev.p)
        and np.any(np.asarray(prob.mu) > 0.0)
    ):
        return _from_frictionless(W, w_free, state_prev, settings, G, e, increment, prob.symmetric)
    blocks = np.diagonal(prob.W).reshape(m, 3)
    r_base = settings.r_scale / blocks.mean(axis=1)
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
    if settings.working_set and prob.symmetric:
        it = evaluate(prob, p0, a0, r_base, sparse_product(prob.W, p0).reshape(-1, 3))
        points = select_points(prob, state_prev, it, settings.working_margin)
        if points is not None:
            solved = solve_on_points(
                prob, state_prev, it, r_base, cut, settings, increment, points, newton
            )
            return _result(prob, state_prev, solved)
    else:
        it = evaluate(prob, p0, a0, r_base)
    use_whole(prob)  # a kept working set's blocks would live beside the whole W's
    return _result(prob, state_prev, newton(prob, it, r_base, cut, settings, increment))


def newton(
    prob: Problem,
    it: Iterate,
    r_base: FloatArray,
    cut: float,
    settings: ContactSettings,
    increment: int,
    max_iter: int | None = None,
) -> Solved:
    """Run the Newton loop (and the regularised fallback) from ``it`` to ``ρ <= tol``.

    Args:
        prob: The problem.
        it: Starting iterate, evaluated with ``r_base``.
        r_base: Augmentation per point, shape (m,), float64 [N/mm].
        cut: Absolute singular-value cut of the rigid-body Schur complement.
        settings: Solver options.
        increment: Index reported in a ConvergenceError.
        max_iter: Iteration budget (default ``settings.max_iter``).

    Returns:
        The converged iterate, its ``w`` from an exact product, and the counts.

    Raises:
        ConvergenceError: If ``ρ > tol`` after the budget; ``partial`` holds the last
            iterate as a ContactState.
    """
    budget = settings.max_iter if max_iter is None else max_iter
    rho0 = it.rho
    krylov = settings.linear_solver is LinearSolver.KRYLOV and prob.symmetric
    ws = workspace_for(prob.W, prob.w_sum) if krylov else None
    gmres_before = 0 if ws is None else ws.gmres_iterations
    run = newton_loop(
        prob,
        it,
        r_base,
        cut,
        settings,
        ws=ws,
        max_iter=budget,
        tol=settings.tol,
        stop_on_singular=True,
    )
    runs = [run]
    if run.singular:  # no Newton step exists (rank-deficient W): regularised fallback
        it = evaluate(prob, run.it.p, run.it.alpha, r_base)
        runs.append(
            proximal_loop(
                prob, it, r_base, cut, settings, settings.proximal, budget - run.iterations
            )
        )
    it, n_iter = runs[-1].it, sum(x.iterations for x in runs)
    history = (rho0, *(rho for x in runs for rho in x.history))
    if it.rho > settings.tol:
        reason = (
            "; singular step matrix (rank-deficient W), regularised Newton fallback"
            if run.singular
            else ""
        )
        partial = ContactState(it.p, it.w, it.law.status, it.alpha)
        raise ConvergenceError(
            f"contact Newton did not converge{reason}",
            increment=increment,
            iteration=n_iter,
            residual=it.rho,
            partial=partial,
        )
    if n_iter:  # W p was updated along the steps: report w with an exact product
        Wp = sparse_product(prob.W, it.p, prob.symmetric).reshape(-1, 3)
        it = it._replace(w=Wp + (prob.G @ it.alpha).reshape(-1, 3) + prob.w_free, Wp=Wp)
    return Solved(
        it,
        n_iter,
        history,
        sum(x.rescues for x in runs),
        sum(x.factorizations for x in runs),
        0 if ws is None else ws.gmres_iterations - gmres_before,
        n_iter - run.iterations,
    )


FRICTIONLESS_START_MAX_ITER = 20
"""Iteration budget of the frictionless pre-solve of ``ContactSettings.frictionless_start``
(the hinge's takes 3-4)."""


def _from_frictionless(
    W: FloatArray,
    w_free: FloatArray,
    state_prev: ContactState,
    settings: ContactSettings,
    G: FloatArray | None,
    e: FloatArray | None,
    increment: int,
    symmetric: bool,
) -> IncrementResult:
    """The increment from rest, started at its frictionless solution (``frictionless_start``).

    Both solves' iterations, factorisations and residual histories are summed; the works
    are the frictional solve's (from ``state_prev``, as always). A frictionless solve that
    does not converge within ``FRICTIONLESS_START_MAX_ITER`` iterations (there may be no
    frictionless equilibrium: a load only friction carries) is dropped, its iterations
    counted, and the increment solved from rest.
    """
    plain = dataclasses.replace(settings, frictionless_start=False)

    def solve(use: ContactSettings, start: tuple[FloatArray, FloatArray] | None) -> IncrementResult:
        return solve_increment(
            W, w_free, state_prev, use, G=G, e=e, increment=increment, start=start,
            symmetric=symmetric,
        )  # fmt: skip

    budget = min(settings.max_iter, FRICTIONLESS_START_MAX_ITER)
    try:
        pre = solve(dataclasses.replace(plain, mu=0.0, max_iter=budget), None)
    except ConvergenceError as err:  # e.g. a load only friction can carry: from rest
        res = solve(plain, None)
        return dataclasses.replace(res, iterations=err.iteration + res.iterations)
    res = solve(plain, (pre.state.p, pre.state.alpha))
    return dataclasses.replace(
        res,
        iterations=pre.iterations + res.iterations,
        residuals=(*pre.residuals, *res.residuals),
        rescues=pre.rescues + res.rescues,
        factorizations=pre.factorizations + res.factorizations,
        linear_iterations=pre.linear_iterations + res.linear_iterations,
        regularised_iterations=pre.regularised_iterations + res.regularised_iterations,
    )


def _result(prob: Problem, prev: ContactState, solved: Solved) -> IncrementResult:
    it = solved.it
    status = it.law.status
    dw = it.w - prev.w
    p_mid = 0.5 * (prev.p + it.p)
    friction_work = -np.sum(p_mid[:, 1:] * dw[:, 1:], axis=1)
    normal_work = -p_mid[:, 0] * dw[:, 0]
    dissipation = -np.sum(it.p[:, 1:] * dw[:, 1:], axis=1)
    return IncrementResult(
        state=ContactState(it.p, it.w, status, it.alpha),
        iterations=solved.iterations,
        residuals=solved.history,
        n_open=int(np.sum(status == ContactStatus.OPEN)),
        n_stick=int(np.sum(status == ContactStatus.STICK)),
        n_slip=int(np.sum(status == ContactStatus.SLIP)),
        friction_work=friction_work,
        normal_work=normal_work,
        dissipation=dissipation,
        rescues=solved.rescues,
        factorizations=solved.factorizations,
        linear_iterations=solved.linear_iterations,
        regularised_iterations=solved.regularised_iterations,
    )
