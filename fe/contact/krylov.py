"""Newton directions by GMRES, preconditioned by an earlier LU updated to the new layout.

Internal to :mod:`fe.contact` (notation of :mod:`fe.contact.newton`). The reduced
Jacobian ``J = R W T + diag(d)`` changes in every Newton iteration, but mostly a little:
stick blocks are entries of ``W``, slip rows and columns turn with the slip direction,
and a few points change status. So the LU of an earlier ``J₀`` (same ``W``) is kept as
a *base* and turned into a preconditioner ``M`` of the new system that is exact on every
row and column of a point whose status (or slip direction, beyond ``turn_cos``) changed:

* unknowns are split into ``S`` (points with the same status in both layouts), ``N``
  (the other unknowns of the new layout) and ``O`` (the other unknowns of ``J₀``);
* ``J₀,SS⁻¹`` follows from ``J₀⁻¹`` by a Schur complement on ``O``:
  ``J₀,SS⁻¹ y = x_S - Z_S (Z_O)⁻¹ x_O`` with ``x = J₀⁻¹ [y; 0]`` and ``Z = J₀⁻¹ E_O``;
* ``M = [[J₀,SS, J_SN], [J_NS, J_NN]]`` is inverted by a Schur complement on ``N``;
* the rigid amplitudes are bordered on as in :func:`fe.contact.dense.solve_bordered`.

The setup costs ``|N| + |O| + k`` triangular solves; each GMRES iteration one solve with
the base and one product with ``W`` on the closed points' DOFs. ``M`` differs from the
exact matrix only by the turn of the slip directions of ``S``, so right-preconditioned
GMRES (which minimises the true residual) converges in a few iterations. When the layout
changed too much, GMRES stalls, or the rigid Schur complement is rank deficient (where
the exact path's minimum-norm ``α`` is wanted), the exact ``J`` is formed and factorised
and becomes the new base. The preconditioner only changes how fast the direction is
found: every iterate is still accepted on the exact residual ``ρ``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
import scipy.sparse as sp

from cad.errors import check_range
from fe.contact.dense import (
    Factor,
    factor_jacobian,
    gather_block,
    is_subset,
    lu_solve,
    solve_bordered,
    wide,
)
from fe.contact.gmres import gmres
from fe.contact.law import ContactStatus
from fe.contact.memo import ArrayMemo
from fe.contact.newton import Linear, Step, form_jacobian, linearise
from fe.contact.residual import Iterate, Problem, sparse_product

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True)
class KrylovOptions:
    """Tuning of the Krylov path (algorithmic only: the solution does not depend on it).

    Attributes:
        max_update: Refactorise instead of updating the base when ``|N| + |O|`` exceeds
            this fraction of the number of unknowns.
        max_iter: GMRES iterations before giving up and refactorising.
        refresh_iter: Refactorise at the next step after a solve that needed more
            GMRES iterations than this.
        turn_cos: A slipping point whose slip direction turned so that ``u·u₀`` is
            below this counts as changed (its rows and columns become exact).
        forcing: Relative GMRES tolerance is ``min(forcing, ρ²)`` (inexact Newton that
            keeps the final equilibrium error, hence the energy balance, near round-off),
            but not below ``oversolve · tol / ρ``.
        oversolve: Safeguard against oversolving the last steps: a step from ``ρ``
            needs a relative linear residual of about ``tol / ρ`` to end below the
            Newton tolerance ``tol``, not ``ρ²``; the factor leaves room for the 2-norm
            of GMRES against the max-norm of ``ρ`` (``√n`` at most) and keeps the
            equilibrium error, hence the energy balance, near round-off. Default hinge,
            level 0, GMRES iterations per cycle with 0 / 1e-4 / 1e-2: 1 550 / 1 417 /
            1 345 at Δr 0, 2 626 / 2 093 / 1 830 at Δr 0.1 mm, energy balance 1e-14 /
            1e-14 / 6e-12 (0 solves every step to ``ρ²``).
        kappa_change: A slipping point whose slip ratio ``κ`` moved by more than this
            counts as changed too: its row ``κ v·dw_t + (1-κ)/r b`` is rescaled and its
            diagonal moved, which the base cannot know. Default hinge, level 0 / level 1,
            Δr 0 with 1 (off) and 0.1: GMRES iterations 1 457 / 1 938 → 1 089 / 1 230,
            refactorisations after slow solves (``refresh_iter``) 41 / 62 → 20 / 28,
            contact phase at level 1 64.0–65.8 → 60.8–63.0 s (three alternating pairs),
            level 0 4.11 → 3.69 s; level 1, Δr 0.1 mm 2 341 → 2 190 GMRES iterations, time
            unchanged (4.1 s). 0.03 and 0.3 at level 0: within noise of 0.1.
        min_size: Smaller systems are always factorised (dense LU is cheap there).
        single_min: Reduced systems of at least this many unknowns get a float32 LU as
            their base (half the time of float64; it is a preconditioner, the steps
            still solve the exact system), with a float64 LU where GMRES fails on it.
    """

    max_update: float = 0.15
    max_iter: int = 40
    refresh_iter: int = 12
    turn_cos: float = 0.9
    forcing: float = 1e-3
    oversolve: float = 1e-4
    min_size: int = 0
    single_min: int = 2000
    kappa_change: float = 0.1

    def __post_init__(self) -> None:
        check_range("krylov.max_update", self.max_update, 0.0, 1.0)
        check_range("krylov.max_iter", self.max_iter, 1, float("inf"))
        check_range("krylov.refresh_iter", self.refresh_iter, 1, float("inf"))
        check_range("krylov.turn_cos", self.turn_cos, -1.0, 1.0)
        check_range("krylov.forcing", self.forcing, 0.0, 1.0, lo_open=True, hi_open=True)
        check_range("krylov.oversolve", self.oversolve, 0.0, 1.0)
        check_range("krylov.min_size", self.min_size, 0, float("inf"))
        check_range("krylov.single_min", self.single_min, 1, float("inf"))
        check_range("krylov.kappa_change", self.kappa_change, 0.0, 1.0)


class Base(NamedTuple):
    """An LU of an earlier reduced Jacobian and the layout it belongs to.

    Attributes:
        factor: The LU factors (of ``J₀ᵀ``) and the unknown keys, shape (n₀,).
        closed: Closed points of that layout, shape (c₀,), int64.
        kind: 0 stick, 1 slip, 2 frictionless per closed point, shape (c₀,), int8.
        u: Slip direction per closed point, shape (c₀, 2), float64.
        kappa: Slip ratio ``κ`` per closed point, shape (c₀,), float64.
    """

    factor: Factor
    closed: IntArray
    kind: npt.NDArray[np.int8]
    u: FloatArray
    kappa: FloatArray


@dataclass
class Workspace:
    """Mutable per-``W`` cache of the Krylov path (preconditioner data only).

    Attributes:
        base: The LU kept as preconditioner (None until the first factorisation).
        refresh: Refactorise at the next step.
        block: Points whose DOFs ``W_block`` holds, shape (n_b,) (None: none yet).
        W_block: ``W`` on those DOFs; kept across increments while ``W``'s fingerprint
            ``w_sum`` is unchanged and the block holds the closed points without too
            much slack (``BLOCK_SLACK``).
        W_single: ``W_block`` (or ``W``) in float32, made on first use: float32 bases
            are formed from it (half the memory traffic of forming them in float64).
        w_sum: Fingerprint of ``W`` (``Problem.w_sum``) that ``W_block`` was taken from.
        gmres_iterations: GMRES iterations done (a counter for reports).
    """

    base: Base | None = None
    refresh: bool = False
    block: IntArray | None = None
    W_block: FloatArray | None = field(default=None, repr=False)
    W_single: npt.NDArray[np.float32] | None = field(default=None, repr=False)
    w_sum: float = float("nan")
    gmres_iterations: int = 0


SINGLE_OPERATOR_RTOL = 1e-4
"""GMRES solves with a relative tolerance of at least this use the float32 ``W`` block."""

BLOCK_SLACK = 1.25
"""A kept ``W`` block may hold at most this many times the closed points (each GMRES
iteration costs ``(3 n_b)²``; regathering costs a pass over the rows of the block)."""


_WORKSPACES: ArrayMemo[Workspace] = ArrayMemo(per_thread=True)


def workspace_for(W: FloatArray, w_sum: float = float("nan")) -> Workspace:
    """Return this thread's workspace for ``W`` (kept while ``W`` lives).

    The base LU carries over between increments on the same ``W``; being only a
    preconditioner, a stale or foreign base can cost iterations but not accuracy. The
    gathered ``W`` block enters the Krylov operator, so it is kept only while ``w_sum``
    (``Problem.w_sum``, NaN: unknown) shows that ``W`` did not change in place.
    """
    ws = _WORKSPACES.setdefault(W, Workspace)
    if ws.w_sum != w_sum:  # W changed in place since the last call (NaN: unknown)
        ws.block, ws.W_block, ws.W_single = None, None, None
    ws.w_sum = w_sum
    return ws


def release(W: FloatArray) -> Workspace | None:
    """Forget this thread's workspace for ``W`` and return it (None if there is none).

    Its ``W`` block, float32 copy and base LU are freed once the caller drops the
    returned workspace (the working set hands the base on, :mod:`fe.contact.working`).
    """
    return _WORKSPACES.pop(W)


class _Operators(NamedTuple):
    """``J`` restricted to the closed points' DOFs: ``J x = R_b (W_b (T_b x)) + d x``."""

    block: IntArray
    W_b: npt.NDArray[np.floating[Any]]
    R_b: sp.csr_array
    T_b: sp.csr_array
    d: FloatArray
    threads: int | None = None


def _ensure_block(prob: Problem, closed: IntArray, ws: Workspace) -> IntArray:
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


def _block_product(
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
        # sides thousands of points open at once, and copying their rows had put 0.37 W
        # on the contact phase's peak (level 1, Δr 0: 1.11 W -> 0.74 W without the copy).
        x_out = np.zeros_like(x)
        x_out[outside] = x[outside]
        out[dofs] += sparse_product(prob.W, x_out, threads=threads)[dofs]
    return out


def _operators(
    prob: Problem,
    lin: Linear,
    ws: Workspace,
    threads: int | None = None,
    block: IntArray | None = None,
) -> _Operators:
    """The Krylov operators of ``lin`` on ``ws``'s ``W`` block.

    ``block``: what :func:`_ensure_block` returned for ``lin.closed`` on this ``ws`` (None:
    ensured here).
    """
    if block is None:
        block = _ensure_block(prob, lin.closed, ws)
    W_b = prob.W if ws.W_block is None else ws.W_block
    dofs = (3 * block[:, None] + np.arange(3)).ravel()
    if len(dofs) == prob.W.shape[0]:
        return _Operators(block, W_b, lin.R, lin.T, lin.d, threads)
    return _Operators(block, W_b, lin.R[:, dofs], lin.T[dofs, :], lin.d, threads)


def _block_fits(block: IntArray, closed: IntArray, m: int) -> bool:
    """Whether a kept block holds the closed points with at most ``BLOCK_SLACK`` slack."""
    if len(block) > max(BLOCK_SLACK * len(closed), 0.8 * m):
        return False
    return is_subset(closed, block)


def _apply(ops: _Operators, X: FloatArray) -> FloatArray:
    """``J X`` for X of shape (n_q,) or (n_q, p) (float32 products if ``W_b`` is float32)."""
    y = ops.T_b @ X
    with wide(ops.W_b.size, ops.threads):
        Wy = np.asarray(ops.W_b @ y.astype(ops.W_b.dtype, copy=False), dtype=np.float64)
    out: FloatArray = ops.R_b @ Wy
    return out + (ops.d * X.T).T


def _rows(ops: _Operators, q: IntArray) -> FloatArray:
    """Rows ``q`` of ``J``, shape (len(q), n_q).

    ``R_q W_b`` combines the few rows of ``W_b`` each row of ``R_q`` touches (a sparse
    times dense product reads only those; a dense product with ``R_q`` as a matrix cost
    ``2 (3 n_b)² len(q)`` flops).
    """
    A = np.asarray(ops.R_b[q] @ ops.W_b)  # (len(q), 3 n_b)
    out: FloatArray = (ops.T_b.T @ A.T).T
    out[np.arange(len(q)), q] += ops.d[q]
    return out


def _cols(ops: _Operators, q: IntArray) -> FloatArray:
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


def _precondition(base: Base, lin: Linear, ops: _Operators, opts: KrylovOptions) -> _Precond | None:
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


def _bordered(pc: _Precond, lin: Linear, cut: float, r_bar: float) -> _Bordered | None:
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


def _apply_p(bp: _Bordered, z: FloatArray) -> FloatArray:
    """Approximate solution of ``[[J, Jα], [H/r̄, 0]] (x, a) = z``, z of shape (n_q + k,)."""
    n = bp.M_alpha.shape[0]
    t = _solve_m(bp.pc, z[:n, None])[:, 0]
    if bp.M_alpha.shape[1] == 0:
        return t
    a = bp.Vt.T @ (bp.inv_sv * (bp.U.T @ (bp.H @ t - bp.r_bar * z[n:])))
    return np.concatenate([t - bp.M_alpha @ a, a])


def _apply_k(ops: _Operators, lin: Linear, r_bar: float, z: FloatArray) -> FloatArray:
    """``[[J, Jα], [H/r̄, 0]] z``, z of shape (n_q + k,)."""
    n = len(lin.keys)
    x, a = z[:n], z[n:]
    top = _apply(ops, x) + lin.Jalpha @ a
    return np.concatenate([top, (lin.H @ x) / r_bar])


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
    block = _ensure_block(prob, np.flatnonzero(it.law.status != ContactStatus.OPEN), ws)
    lin = linearise(prob, it, r, w_times=lambda x: _block_product(prob, ws, x, threads))
    n = len(lin.keys)
    r_bar = float(np.mean(r))
    krylov = ws.base is not None and not ws.refresh and n >= opts.min_size and n > 0
    if krylov or n >= opts.single_min:
        ops = _operators(prob, lin, ws, threads, block)
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
    ops: _Operators,
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
    pc = _precondition(ws.base, lin, ops, opts)
    bp = None if pc is None else _bordered(pc, lin, cut, r_bar)
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
        lambda z: _apply_k(op, lin, r_bar, z),
        lambda z: _apply_p(bp, z),
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
