"""The Krylov path's operators and preconditioner: ``J`` on a kept ``W`` block, ``M⁻¹``.

Internal to :mod:`fe.contact` (the method is described in :mod:`fe.contact.krylov`):

* the operators of the reduced Jacobian ``J = R W T + diag(d)`` restricted to the closed
  points' DOFs, on the ``W`` block a :class:`fe.contact.krylov.Workspace` keeps
  (:func:`ensure_block`, :func:`block_product`, :func:`operators`);
* ``M⁻¹``, the base LU updated to the new layout by Schur complements, and its bordering
  with the rigid amplitudes (:func:`precondition`, :func:`bordered`, :func:`apply_p`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
import scipy.sparse as sp

from fe.contact.dense import factor_jacobian, gather_block, is_subset, lu_solve, wide
from fe.contact.krylov import Base, KrylovOptions, Workspace
from fe.contact.newton import Linear
from fe.contact.residual import Problem, sparse_product

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


BLOCK_SLACK = 1.25
"""A kept ``W`` block may hold at most this many times the closed points (each GMRES
iteration costs ``(3 n_b)²``; regathering costs a pass over the rows of the block)."""


class Operators(NamedTuple):
    """``J`` restricted to the closed points' DOFs: ``J x = R_b (W_b (T_b x)) + d x``."""

    block: IntArray
    W_b: npt.NDArray[np.floating[Any]]
    R_b: sp.csr_array
    T_b: sp.csr_array
    d: FloatArray
    threads: int | None = None


def ensure_block(prob: Problem, closed: IntArray, ws: Workspace) -> IntArray:
    """Keep or regather ``ws.W_block`` so that it holds the points ``closed``."""
    m = len(prob.w_free)
    block = ws.block
    if block is None or not _block_fits(block, closed, m):
        # The old block and its float32 copy go first: never two blocks at once.
        ws.block, ws.W_block, ws.W_single = None, None, None
        if len(closed) > 0.8 * m:  # gathering would copy nearly all of W
            block = np.arange(m, dtype=np.int64)  # W_block None: W itself
        else:
            dofs = (3 * closed[:, None] + np.arange(3)).ravel()
            block, ws.W_block = closed, gather_block(prob.W, dofs)
        ws.block = block
    return block


def block_product(
    prob: Problem, ws: Workspace, x: FloatArray, threads: int | None = None
) -> FloatArray:
    """``W x`` on the DOFs of ``ws.block`` (zero elsewhere), x of shape (m, 3).

    The block part is a product with ``W_block``; the few points outside the block where
    ``x ≠ 0`` (points that just opened) add their rows of the symmetric ``W``.
    """
    if ws.W_block is None or ws.block is None:
        return sparse_product(prob.W, x, threads=threads)
    m = len(x)
    dofs = (3 * ws.block[:, None] + np.arange(3)).ravel()
    out = np.zeros(3 * m)
    with wide(ws.W_block.size, threads):
        out[dofs] = ws.W_block @ x[ws.block].ravel()
    outside = np.ones(m, dtype=bool)
    outside[ws.block] = False
    outside = np.flatnonzero(outside & np.any(x != 0.0, axis=1))
    if len(outside):
        # Their rows of the symmetric W, read in place: where the contact zone changes
        # sides thousands of points open at once, and copying their rows raised the
        # contact phase's memory peak (benchmarks/bench_cycle.txt, 'block_product').
        x_out = np.zeros_like(x)
        x_out[outside] = x[outside]
        out[dofs] += sparse_product(prob.W, x_out, threads=threads)[dofs]
    return out


def operators(
    prob: Problem,
    lin: Linear,
    ws: Workspace,
    threads: int | None = None,
    block: IntArray | None = None,
) -> Operators:
    """The Krylov operators of ``lin`` on ``ws``'s ``W`` block.

    ``block``: what :func:`ensure_block` returned for ``lin.closed`` on this ``ws`` (None:
    ensured here).
    """
    if block is None:
        block = ensure_block(prob, lin.closed, ws)
    W_b = prob.W if ws.W_block is None else ws.W_block
    dofs = (3 * block[:, None] + np.arange(3)).ravel()
    if len(dofs) == prob.W.shape[0]:
        return Operators(block, W_b, lin.R, lin.T, lin.d, threads)
    return Operators(block, W_b, lin.R[:, dofs], lin.T[dofs, :], lin.d, threads)


def _block_fits(block: IntArray, closed: IntArray, m: int) -> bool:
    """Whether a kept block holds the closed points with at most ``BLOCK_SLACK`` slack."""
    if len(block) > max(BLOCK_SLACK * len(closed), 0.8 * m):
        return False
    return is_subset(closed, block)


def _apply(ops: Operators, X: FloatArray) -> FloatArray:
    """``J X`` for X of shape (n_q,) or (n_q, p) (float32 products if ``W_b`` is float32)."""
    y = ops.T_b @ X
    with wide(ops.W_b.size, ops.threads):
        Wy = np.asarray(ops.W_b @ y.astype(ops.W_b.dtype, copy=False), dtype=np.float64)
    out: FloatArray = ops.R_b @ Wy
    return out + (ops.d * X.T).T


def _rows(ops: Operators, q: IntArray) -> FloatArray:
    """Rows ``q`` of ``J``, shape (len(q), n_q).

    ``R_q W_b`` combines the few rows of ``W_b`` each row of ``R_q`` touches (a sparse
    times dense product reads only those; a dense product with ``R_q`` as a matrix cost
    ``2 (3 n_b)² len(q)`` flops).
    """
    A = np.asarray(ops.R_b[q] @ ops.W_b)  # (len(q), 3 n_b)
    out: FloatArray = (ops.T_b.T @ A.T).T
    out[np.arange(len(q)), q] += ops.d[q]
    return out


def _cols(ops: Operators, q: IntArray) -> FloatArray:
    """Columns ``q`` of ``J``, shape (n_q, len(q)), from rows of the symmetric ``W_b``.

    ``W_b T_q = (T_qᵀ W_b)ᵀ``: combinations of the few rows of ``W_b`` each column of
    ``T_q`` touches, as in :func:`_rows`.
    """
    A = np.asarray(sp.csr_array(ops.T_b[:, q].T) @ ops.W_b)  # (len(q), 3 n_b)
    out: FloatArray = ops.R_b @ np.ascontiguousarray(A.T)
    out[q, np.arange(len(q))] += ops.d[q]
    return out


class _Precond(NamedTuple):
    """Data of ``M⁻¹`` (see the module docstring)."""

    lu: tuple[npt.NDArray[np.floating], npt.NDArray[np.int32]]
    n0: int
    qS_new: IntArray
    qS_old: IntArray
    qN: IntArray
    qO: IntArray
    Z_S: FloatArray
    Zoo: tuple[FloatArray, npt.NDArray[np.int32]] | None
    J_NS: FloatArray
    V: FloatArray
    sigma: tuple[FloatArray, npt.NDArray[np.int32]] | None


def _solve_ss(pc: _Precond, Y_S: FloatArray) -> FloatArray:
    """``J₀,SS⁻¹ Y_S`` for Y_S of shape (n_S, p)."""
    Y = np.zeros((pc.n0, Y_S.shape[1]))
    Y[pc.qS_old] = Y_S
    X = lu_solve(pc.lu, Y)
    if pc.Zoo is None:
        return X[pc.qS_old]
    out: FloatArray = X[pc.qS_old] - pc.Z_S @ sla.lu_solve(
        pc.Zoo, X[pc.qO], trans=1, check_finite=False
    )
    return out


def _solve_m(pc: _Precond, Y: FloatArray) -> FloatArray:
    """``M⁻¹ Y`` for Y of shape (n_q, p)."""
    t = _solve_ss(pc, Y[pc.qS_new])
    X = np.empty_like(Y)
    if pc.sigma is None:
        X[pc.qS_new] = t
        return X
    x_N = sla.lu_solve(pc.sigma, Y[pc.qN] - pc.J_NS @ t, trans=1, check_finite=False)
    X[pc.qN] = x_N
    X[pc.qS_new] = t - pc.V @ x_N
    return X


def _lu_or_none(A: FloatArray) -> tuple[FloatArray, npt.NDArray[np.int32]] | None:
    """LU of ``Aᵀ`` (solve with ``trans=1``), None if A is empty; raises if singular."""
    if A.size == 0:
        return None
    f = factor_jacobian(np.ascontiguousarray(A), np.zeros(0, dtype=np.int64))
    if f is None:
        raise np.linalg.LinAlgError("singular update")
    return (f.lu[0], f.lu[1])


def precondition(base: Base, lin: Linear, ops: Operators, opts: KrylovOptions) -> _Precond | None:
    """Set up ``M⁻¹`` from the base; None if the layout changed too much or it is singular."""
    common, ia, ib = np.intersect1d(base.closed, lin.closed, return_indices=True)
    same = base.kind[ia] == lin.kind[ib]
    turn = np.sum(base.u[ia] * lin.u[ib], axis=1)
    # κ lies in [0, 1): kappa_change = 1 keeps every direction-steady point (off).
    steady = (turn >= opts.turn_cos) & (np.abs(base.kappa[ia] - lin.kappa[ib]) <= opts.kappa_change)
    same &= (lin.kind[ib] != 1) | steady
    keep_pts = common[same]
    in_new = np.isin(lin.keys // 3, keep_pts)
    in_old = np.isin(base.factor.keys // 3, keep_pts)
    qS_new, qN = np.flatnonzero(in_new), np.flatnonzero(~in_new)
    qS_old, qO = np.flatnonzero(in_old), np.flatnonzero(~in_old)
    n = len(lin.keys)
    if len(qN) + len(qO) > opts.max_update * n or len(qS_new) != len(qS_old):
        return None
    lu = base.factor.lu
    n0 = len(base.factor.keys)
    try:
        if len(qO):
            E = np.zeros((n0, len(qO)))
            E[qO, np.arange(len(qO))] = 1.0
            Z = lu_solve(lu, E)
            pc = _Precond(lu, n0, qS_new, qS_old, qN, qO, Z[qS_old], _lu_or_none(Z[qO]), *_EMPTY)
        else:
            pc = _Precond(lu, n0, qS_new, qS_old, qN, qO, np.zeros((0, 0)), None, *_EMPTY)
        if len(qN):
            J_N = _rows(ops, qN)  # (|N|, n)
            J_colN = _cols(ops, qN)  # (n, |N|)
            V = _solve_ss(pc, J_colN[qS_new])
            J_NS = J_N[:, qS_new]
            sigma = _lu_or_none(J_colN[qN] - J_NS @ V)
            pc = pc._replace(J_NS=J_NS, V=V, sigma=sigma)
    except (np.linalg.LinAlgError, ValueError):
        return None
    return pc


_EMPTY = (np.zeros((0, 0)), np.zeros((0, 0)), None)


class _Bordered(NamedTuple):
    """Right preconditioner of ``[[J, Jα], [H/r̄, 0]]`` built on ``M⁻¹``."""

    pc: _Precond
    M_alpha: FloatArray
    H: FloatArray
    U: FloatArray
    inv_sv: FloatArray
    Vt: FloatArray
    r_bar: float


def bordered(pc: _Precond, lin: Linear, cut: float, r_bar: float) -> _Bordered | None:
    """Border ``M⁻¹`` with the rigid amplitudes; None if the Schur complement is deficient."""
    k = lin.Jalpha.shape[1]
    if k == 0:
        z = np.zeros((0, 0))
        return _Bordered(pc, np.zeros((len(lin.keys), 0)), lin.H, z, np.zeros(0), z, r_bar)
    M_alpha = _solve_m(pc, lin.Jalpha)
    U, sv, Vt = np.linalg.svd(lin.H @ M_alpha)  # (k, k)
    if not np.all(sv > max(cut, float(sv[0]) * np.finfo(float).eps * k)):
        return None  # undetermined rigid directions: the exact path gives the min-norm α
    return _Bordered(pc, M_alpha, lin.H, U, 1.0 / sv, Vt, r_bar)


def apply_p(bp: _Bordered, z: FloatArray) -> FloatArray:
    """Approximate solution of ``[[J, Jα], [H/r̄, 0]] (x, a) = z``, z of shape (n_q + k,)."""
    n = bp.M_alpha.shape[0]
    t = _solve_m(bp.pc, z[:n, None])[:, 0]
    if bp.M_alpha.shape[1] == 0:
        return t
    a = bp.Vt.T @ (bp.inv_sv * (bp.U.T @ (bp.H @ t - bp.r_bar * z[n:])))
    return np.concatenate([t - bp.M_alpha @ a, a])


def apply_k(ops: Operators, lin: Linear, r_bar: float, z: FloatArray) -> FloatArray:
    """``[[J, Jα], [H/r̄, 0]] z``, z of shape (n_q + k,)."""
    n = len(lin.keys)
    x, a = z[:n], z[n:]
    top = _apply(ops, x) + lin.Jalpha @ a
    return np.concatenate([top, (lin.H @ x) / r_bar])
