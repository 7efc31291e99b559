"""Regularised (proximal) Newton fallback for singular reduced Jacobians (rank-deficient ``W``).

Internal to :mod:`fe.contact`. When the Delassus operator is rank deficient (more contact
constraints than body freedoms, as in stacks of rigid bodies) the reduced Jacobian of
the active set is singular and no Newton step exists. Each iteration here takes instead
the Newton step of the proximal-point problem at the current force ``p_j``,

    W_ε = W + ε I,   w_free,ε = w_free - ε p_j,

whose residual at ``p_j`` is the original one (``W_ε p_j + w_free,ε = W p_j + w_free``)
and whose reduced Jacobian is nonsingular: a Levenberg–Marquardt step on the original
Alart–Curnier equations. ``ε = clip(rate·ρ, eps_min, eps_start) · boost · mean(diag W_ii)``
per point follows the residual ``ρ`` down, so the steps tend to the (minimum-norm)
Newton steps and the iteration converges fast once the active set settles; the
components of a step in the null space of ``W`` stay bounded by ``1/ε``.

The step is accepted by a nonmonotone Armijo search on the original merit (the decrease
is measured from the largest of the last ``memory`` merits): with many contacts changing
status at once a monotone search on the nonsmooth merit creeps with steps of 1e-2 and
less, which a nonmonotone one lets through. A step the search rejects, or a singular
regularised matrix, multiplies ``boost`` by ``grow`` (a larger ``ε``: a shorter,
better-conditioned step), and so does an accepted step that raised the merit more than
``bounce``-fold (without that, two steps can bounce between two active sets for ever,
each accepted against the other's merit: KaplasTower-i1061-4 bounced between ρ 1e-6 and
1e-9 for 40 steps); any other accepted step multiplies ``boost`` by ``relax`` (down to
1). Growing faster than it relaxes is the Levenberg–Marquardt trust rule. Every step
counts as one iteration of the shared ``max_iter`` budget, rejected ones included.
"""

from __future__ import annotations

import logging

import numpy as np
import numpy.typing as npt

from fe.contact.globalise import Run, line_search
from fe.contact.newton import newton_step
from fe.contact.residual import Iterate, Problem, evaluate
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
    """Regularised Newton iteration from ``it`` until the original ``ρ <= settings.tol``.

    Args:
        prob: The original problem.
        it: Starting iterate on ``prob``, evaluated with ``r_base``.
        r_base: Augmentation of the original problem, shape (m,), float64 [N/mm].
        cut: Absolute singular-value cut of the rigid-body Schur complement.
        settings: Tolerance, line-search and LU options.
        opts: Tuning.
        max_iter: Budget of iterations (each one regularised Newton step).

    Returns:
        Where it stopped (``singular`` is False, ``rescues`` counts the rejected steps);
        converged iff ``run.it.rho <= tol``.
    """
    m = len(it.p)
    scale = np.diagonal(prob.W).reshape(m, 3).mean(axis=1)  # (m,) [mm/N]
    diag = np.diag_indices(3 * m)
    boost_max = opts.eps_max / opts.eps_min
    boost, merits, history = 1.0, [it.merit], []
    n_iter = n_factor = rejected = 0
    while it.rho > settings.tol and n_iter < max_iter:
        n_iter += 1
        eps_rel = min(
            float(np.clip(opts.rate * it.rho, opts.eps_min, opts.eps_start)) * boost, opts.eps_max
        )
        eps = eps_rel * scale  # (m,) [mm/N]
        shift = eps[:, None] * it.p  # (m, 3) [mm]
        W_eps = prob.W.copy()
        W_eps[diag] += np.repeat(eps, 3)
        sub = prob._replace(W=W_eps, w_free=prob.w_free - shift, w_sum=float("nan"))
        # the residual of the regularised problem at p is the original one: W_ε p = W p + ε p
        start = evaluate(sub, it.p, it.alpha, r_base, it.Wp + shift)
        step = newton_step(sub, start, r_base, cut, threads=settings.lu_threads)
        new = None
        if step is not None:
            n_factor += 1
            ref = max(merits[-opts.memory :])
            new = line_search(prob, it, step, r_base, settings, ref)
        if new is None:  # singular or no acceptable step: regularise more
            rejected += 1
            boost = min(boost * opts.grow, boost_max)
            history.append(it.rho)
            logger.debug("proximal: eps %.1e rejected (singular %s)", eps_rel, step is None)
            continue
        # an accepted step that raised the merit a lot (nonmonotone) damps the next one:
        # else two steps can bounce between active sets for ever, each accepted against
        # the other's merit; small rises are let through (growing ε on them stalls a slow
        # final approach at an ε far above rate·ρ)
        up = new.merit > opts.bounce * it.merit
        boost = min(boost * opts.grow, boost_max) if up else max(boost * opts.relax, 1.0)
        it = new
        merits.append(it.merit)
        history.append(it.rho)
        logger.debug("proximal: eps %.1e, rho %.3e", eps_rel, it.rho)
    if it.rho > settings.tol:
        logger.debug(
            "proximal: stopped at rho %.3e, %d of %d steps rejected", it.rho, rejected, n_iter
        )
    return Run(it, r_base, n_iter, tuple(history), rejected, n_factor, False)
