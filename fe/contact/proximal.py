"""Proximal-point fallback for singular reduced Jacobians (rank-deficient ``W``).

Internal to :mod:`fe.contact`. When the Delassus operator is rank deficient (more contact
constraints than body freedoms, as in stacks of rigid bodies) the reduced Jacobian of
the active set is singular and no Newton step exists. The proximal-point iteration

    p_{j+1} solves the contact problem with  W_ε = W + ε I,  w_free,ε = w_free - ε p_j

has the same solutions as the original problem at its fixed points
(``W_ε p + w_free,ε = W p + w_free`` when ``p_{j+1} = p_j``), and ``W_ε`` is positive
definite, so the inner problems are solved by the same globalised Newton. ``ε`` starts
at ``eps_start · mean(diag W)``, is divided by ``1/shrink`` after each inner solve that
converged quickly (the outer contraction factor on an eigenvalue λ of ``W`` is
``ε/(λ + ε)``), and grown after an inner failure. Each inner solve stops at a tolerance
tied to the current outer residual (inexact proximal point); convergence is always
judged on the original problem's ``ρ``.
"""

from __future__ import annotations

import logging

import numpy as np
import numpy.typing as npt

from fe.contact.globalise import Run, newton_loop
from fe.contact.newton import Iterate, Problem, evaluate
from fe.contact.state import ContactSettings, ProximalOptions

FloatArray = npt.NDArray[np.float64]

logger = logging.getLogger(__name__)


def proximal_loop(
    prob: Problem,
    it: Iterate,
    r_base: FloatArray,
    cut: float,
    settings: ContactSettings,
    opts: ProximalOptions,
    max_iter: int,
) -> Run:
    """Proximal-point iteration from ``it`` until the original ``ρ <= settings.tol``.

    Args:
        prob: The original problem.
        it: Starting iterate on ``prob``, evaluated with ``r_base``.
        r_base: Augmentation of the original problem, shape (m,), float64 [N/mm].
        cut: Absolute singular-value cut of the rigid-body Schur complement.
        settings: Tolerance and Newton options.
        opts: Tuning.
        max_iter: Budget of inner Newton iterations (all inner solves together).

    Returns:
        Where it stopped (``singular`` is False); converged iff ``run.it.rho <= tol``.
    """
    m = len(it.p)
    scale = np.diagonal(prob.W).reshape(m, 3).mean(axis=1)  # (m,) [mm/N]
    eps_rel = opts.eps_start
    history: list[float] = []
    n_iter = rescues = n_factor = 0
    diag = np.diag_indices(3 * m)
    while it.rho > settings.tol and n_iter < max_iter:
        eps = eps_rel * scale  # (m,)
        W_eps = prob.W.copy()
        W_eps[diag] += np.repeat(eps, 3)
        w_free = prob.w_free - eps[:, None] * it.p
        sub = prob._replace(W=W_eps, w_free=w_free, w_sum=float("nan"))
        r_sub = settings.r_scale / np.diagonal(W_eps).reshape(m, 3).mean(axis=1)
        tol = max(settings.tol, opts.inner_rate * it.rho)
        start = evaluate(sub, it.p, it.alpha, r_sub)
        budget = min(opts.inner_iter, max_iter - n_iter)
        run = newton_loop(
            sub,
            start,
            r_sub,
            cut,
            settings,
            ws=None,
            max_iter=budget,
            tol=tol,
            stop_on_singular=True,
        )
        n_iter += run.iterations
        logger.debug(
            "proximal: eps %.1e, inner %d its (singular %s), inner rho %.2e -> tol %.1e",
            eps_rel,
            run.iterations,
            run.singular,
            run.it.rho,
            tol,
        )
        rescues += run.rescues
        n_factor += run.factorizations
        if run.singular or run.it.rho > tol:
            eps_rel = min(eps_rel / opts.shrink, opts.eps_max)
            if run.it.merit >= start.merit:
                history.append(it.rho)
                continue
        it = evaluate(prob, run.it.p, run.it.alpha, r_base)
        history.append(it.rho)
        logger.debug("proximal: outer rho %.3e", it.rho)
        if run.iterations <= opts.fast_inner and not run.singular:
            eps_rel = max(eps_rel * opts.shrink, opts.eps_min)
    return Run(it, r_base, n_iter, tuple(history), rescues, n_factor, False)
