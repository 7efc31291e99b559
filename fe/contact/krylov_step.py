"""The Newton direction by GMRES on the exact reduced system (see :mod:`fe.contact.krylov`).

Internal to :mod:`fe.contact`: :func:`krylov_step` gathers the ``W`` block, linearises,
and solves by GMRES (:mod:`fe.contact.gmres`) preconditioned with the workspace's base LU
(:mod:`fe.contact.preconditioner`), or forms and factorises ``J``, which becomes the new
base.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from fe.contact.dense import factor_jacobian, solve_bordered
from fe.contact.gmres import gmres
from fe.contact.krylov import Base, KrylovOptions, Workspace
from fe.contact.law import ContactStatus
from fe.contact.newton import Linear, Step, form_jacobian, linearise
from fe.contact.preconditioner import (
    Operators,
    apply_k,
    apply_p,
    block_product,
    bordered,
    ensure_block,
    operators,
    precondition,
)
from fe.contact.residual import Iterate, Problem

FloatArray = npt.NDArray[np.float64]

SINGLE_OPERATOR_RTOL = 1e-4
"""GMRES solves with a relative tolerance of at least this use the float32 ``W`` block."""


def krylov_step(
    prob: Problem,
    it: Iterate,
    r: FloatArray,
    cut: float,
    ws: Workspace,
    opts: KrylovOptions,
    threads: int | None = None,
    tol: float = 0.0,
) -> Step | None:
    """Newton direction by GMRES on the exact reduced system, base LU as preconditioner.

    Falls back to forming and factorising ``J`` (which becomes the new base) when there
    is no usable base or GMRES does not reach ``min(opts.forcing, ρ²)``. The returned
    ``Step.reused`` is True when no factorisation was done.

    Args:
        prob: Increment data.
        it: Current iterate.
        r: Augmentation per point, shape (m,), float64 [N/mm].
        cut: Absolute singular-value cut of the rigid-body Schur complement.
        ws: The workspace of ``prob.W`` (base LU, cached ``W`` block); updated.
        opts: Tuning.
        threads: BLAS threads of a large LU (see :func:`fe.contact.dense.lu_threads`).
        tol: The Newton loop's tolerance on ``ρ`` (0: no oversolving safeguard).

    Returns:
        The Newton step, or None if the reduced matrix is numerically singular.
    """
    # The closed set is the trial's (no forced points here): gather the block first, so
    # that the right-hand side's W s comes from it.
    block = ensure_block(prob, np.flatnonzero(it.law.status != ContactStatus.OPEN), ws)
    lin = linearise(prob, it, r, w_times=lambda x: block_product(prob, ws, x, threads))
    n = len(lin.keys)
    r_bar = float(np.mean(r))
    krylov = ws.base is not None and not ws.refresh and n >= opts.min_size and n > 0
    if krylov or n >= opts.single_min:
        ops = operators(prob, lin, ws, threads, block)
        if krylov:
            step = _gmres_step(it, lin, ops, ws, opts, cut, r_bar, tol, refresh_after=True)
            if step is not None:
                return step
        if n >= opts.single_min:
            if ws.W_single is None:
                ws.W_single = ops.W_b.astype(np.float32)
            single = factor_jacobian(
                form_jacobian(ws.W_single, ops.block, lin), lin.keys, threads, single=True
            )
            if single is not None:
                # A float32 base is a preconditioner only: the step comes from GMRES on
                # the exact system, where it is exact but for round-off (a few iterations).
                ws.base, ws.refresh = Base(single, lin.closed, lin.kind, lin.u, lin.kappa), False
                step = _gmres_step(it, lin, ops, ws, opts, cut, r_bar, tol, refresh_after=False)
                if step is not None:
                    return step._replace(reused=False)
    # Direct: J from the W block (the Krylov operators' slices of R and T are not needed).
    W_b = prob.W if ws.W_block is None else ws.W_block
    factor = factor_jacobian(form_jacobian(W_b, block, lin), lin.keys, threads)
    if factor is None:
        return None
    ws.base, ws.refresh = Base(factor, lin.closed, lin.kind, lin.u, lin.kappa), False
    dq, alpha_new = solve_bordered(factor, lin.Jalpha, lin.H, lin.b, lin.h, cut)
    return Step(lin.expand(dq), alpha_new, factor, False)


def _gmres_step(
    it: Iterate,
    lin: Linear,
    ops: Operators,
    ws: Workspace,
    opts: KrylovOptions,
    cut: float,
    r_bar: float,
    tol: float,
    *,
    refresh_after: bool,
) -> Step | None:
    """The Newton step by GMRES preconditioned with ``ws.base``; None if that fails.

    ``refresh_after``: ask for a refactorisation at the next step if GMRES needed more
    than ``opts.refresh_iter`` iterations.
    """
    if ws.base is None:
        return None
    n = len(lin.keys)
    pc = precondition(ws.base, lin, ops, opts)
    bp = None if pc is None else bordered(pc, lin, cut, r_bar)
    if bp is None:
        return None
    # Unknowns (dq, α_new - α): the right-hand side is then of the size of the
    # Newton residual, so the relative tolerance is a forcing term.
    rhs = np.concatenate([lin.b - lin.Jalpha @ it.alpha, lin.h / r_bar])
    rtol = max(min(opts.forcing, it.rho**2), 1e-14)  # last steps near round-off
    if it.rho > 0.0:  # ... but not far below what the step needs to end under tol
        rtol = min(max(rtol, opts.oversolve * tol / it.rho), opts.forcing)
    # Loose solves (far from the solution) take W's products in float32: half the memory
    # traffic, an operator error ~1e-7 far below the forcing term.
    op = ops
    if rtol >= SINGLE_OPERATOR_RTOL and ws.W_single is not None:
        op = ops._replace(W_b=ws.W_single)
    sol = gmres(
        lambda z: apply_k(op, lin, r_bar, z),
        lambda z: apply_p(bp, z),
        rhs,
        rtol,
        opts.max_iter,
    )
    ws.gmres_iterations += sol.iterations
    if not sol.converged:
        return None
    if refresh_after:
        ws.refresh = sol.iterations > opts.refresh_iter
    dq, alpha_new = sol.z[:n], it.alpha + sol.z[n:]
    step = lin.expand(dq)
    return Step(step, alpha_new, ws.base.factor, True)
