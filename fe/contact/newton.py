"""One generalised-Newton step of the condensed Alart–Curnier system (see fe.contact).

Internal to :mod:`fe.contact`: the reduced active-set linear algebra of an iterate
evaluated by :mod:`fe.contact.residual`. Notation and conventions are those of
:mod:`fe.contact`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from fe.contact.dense import Factor, factor_jacobian, lu_threads, solve_bordered
from fe.contact.law import ContactStatus, per_point, slip_frame
from fe.contact.residual import Iterate, Problem, sparse_product

FloatArray = npt.NDArray[np.float64]


def __getattr__(name: str) -> int:
    """Keep ``LU_THREADS`` importable: the effective value of :func:`lu_threads` now."""
    if name == "LU_THREADS":
        return lu_threads()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class Step(NamedTuple):
    """A Newton direction.

    Attributes:
        dp: Force increment, shape (m, 3), float64 [N].
        alpha_new: Full-step rigid amplitudes (minimum norm), shape (k,), float64.
        factor: Factorisation used (new, or the reused one of a chord step).
        reused: Whether ``factor`` was reused (chord step) rather than computed.
    """

    dp: FloatArray
    alpha_new: FloatArray
    factor: Factor | None
    reused: bool


@dataclass(frozen=True)
class Linear:
    """The reduced generalised-Newton system of one iterate (see :func:`newton_step`).

    The step is ``dp = T dq + s`` with ``dq`` (n_q,) and rigid amplitudes ``a`` (k,)
    solving ``J dq + Jα a = b, H dq = h`` where ``J = R W T + diag(d)``. ``T`` and ``R``
    are block diagonal over the closed points (``t_loc``, ``r_loc`` restricted to the
    kept slots); the sparse matrices are built only when asked for (the Krylov
    operators): the direct path works on the blocks.

    Attributes:
        closed: Closed (or force-closed) points, shape (c,), int64.
        keep: Kept slots of the closed points, shape (c, 3), bool.
        kind: Per closed point 0 stick, 1 slip, 2 frictionless, shape (c,), int8.
        u: Slip direction per closed point (zero unless slipping), shape (c, 2).
        t_loc: Per closed point the columns of T (slot → force components), (c, 3, 3).
        r_loc: Per closed point the rows of R (slot ← components), (c, 3, 3).
        d: Extra diagonal ``(1-κ)/r`` on slip slots, shape (n_q,), float64 [mm/N].
        s: Shift of the step, shape (m, 3), float64 [N].
        b: Right-hand side, shape (n_q,), float64 [mm].
        Jalpha: ``R G``, shape (n_q, k), float64.
        H: ``(T.T G).T``, shape (k, n_q), float64.
        h: Equilibrium right-hand side, shape (k,), float64 [N].
        keys: Global slot ``3 i + slot`` of every reduced unknown, shape (n_q,), int64.
        kappa: Slip ratio ``κ`` per closed point (zero unless slipping), shape (c,).
    """

    closed: npt.NDArray[np.int64]
    keep: npt.NDArray[np.bool_]
    kind: npt.NDArray[np.int8]
    u: FloatArray
    t_loc: FloatArray
    r_loc: FloatArray
    d: FloatArray
    s: FloatArray
    b: FloatArray
    Jalpha: FloatArray
    H: FloatArray
    h: FloatArray
    keys: npt.NDArray[np.int64]
    kappa: FloatArray

    @cached_property
    def _operators(self) -> tuple[sp.csr_array, sp.csr_array]:
        return _slot_operators(self.closed, self.keep, self.t_loc, self.r_loc, 3 * len(self.s))

    @property
    def T(self) -> sp.csr_array:
        """Slot-to-force map, shape (3m, n_q), sparse (built on first use)."""
        return self._operators[0]

    @property
    def R(self) -> sp.csr_array:
        """Row map, shape (n_q, 3m), sparse (built on first use)."""
        return self._operators[1]

    def expand(self, dq: FloatArray) -> FloatArray:
        """The force step ``T dq + s`` of reduced unknowns ``dq`` (n_q,), shape (m, 3) [N]."""
        full = np.zeros(self.keep.shape)
        full[self.keep] = dq
        step = self.s.copy()
        step[self.closed] += np.einsum("cab,cb->ca", self.t_loc, full)
        return step


def newton_step(
    prob: Problem,
    it: Iterate,
    r: FloatArray,
    cut: float,
    *,
    force_closed: npt.NDArray[np.bool_] | None = None,
    reuse: Factor | None = None,
    threads: int | None = None,
    single_min: int | None = None,
) -> Step | None:
    """Solve the reduced generalised-Newton system by dense LU; None if it is singular.

    If ``reuse`` has the same unknown layout as this iterate, its stale factors replace
    the Jacobian (a chord step: exact residual, approximate matrix, no factorisation);
    the caller decides when that is good enough. The system is that of :func:`linearise`.

    Args:
        prob: Increment data.
        it: Current iterate (its trial status defines the active sets).
        r: Augmentation per point, shape (m,), float64 [N/mm].
        cut: Absolute singular-value cut of the rigid-body Schur complement.
        force_closed: Points to close if open, shape (m,), bool (default none).
        reuse: Factors of an earlier step to reuse when the layout matches.
        threads: BLAS threads of a large LU (see :func:`fe.contact.dense.lu_threads`).
        single_min: Factorise in float32 from this many unknowns (None: never); the step
            is then accurate to single precision only, for a predictor whose result is
            evaluated on the exact residual (the rescue's).

    Returns:
        The full Newton step, or None if the reduced matrix is numerically singular.
    """
    lin = linearise(prob, it, r, force_closed)
    reused = reuse is not None and np.array_equal(reuse.keys, lin.keys)
    if reuse is not None and reused:
        factor: Factor | None = reuse
    else:
        all_points = np.arange(len(it.p), dtype=np.int64)
        J = form_jacobian(prob.W, all_points, lin, symmetric=prob.symmetric)
        single = single_min is not None and len(lin.keys) >= single_min
        factor = factor_jacobian(J, lin.keys, threads, single=single)
    if factor is None:
        return None
    dq, alpha_new = solve_bordered(factor, lin.Jalpha, lin.H, lin.b, lin.h, cut)
    return Step(lin.expand(dq), alpha_new, factor, reused)


def linearise(
    prob: Problem,
    it: Iterate,
    r: FloatArray,
    force_closed: npt.NDArray[np.bool_] | None = None,
    *,
    w_times: Callable[[FloatArray], FloatArray] | None = None,
) -> Linear:
    """Build the reduced generalised-Newton system of an iterate (the matrix not formed).

    Open points flagged in ``force_closed`` are treated as closed and frictionless (a
    bilateral predictor that lets a floating body that touches nothing find contact).

    Unknowns per closed point (slots n, t1, t2): stick (dp_n, dp_t1, dp_t2); slip
    (dp_n, b) with ``dp_t = (μ(p_n + dp_n) - p_t·u) u + b v``; frictionless (dp_n) with
    ``dp_t = -p_t``. Rows (divided by r): ``dw_n = -w_n``; stick ``dw_t = -Δw_t``; slip
    ``(1-κ)/r b + κ v·dw_t = -C_t·v/r``. Open points get ``dp = -p``. Here
    ``u = ξ_t/|ξ_t|``, ``v`` is ``u`` turned by +90° and ``κ = μ ξ_n/|ξ_t|``.

    Args:
        prob: Increment data.
        it: Current iterate (its trial status defines the active sets).
        r: Augmentation per point, shape (m,), float64 [N/mm].
        force_closed: Points to close if open, shape (m,), bool (default none).
        w_times: ``x ↦ W x`` for x of shape (m, 3), returning shape (3m,), exact at least
            on the closed points' DOFs (only those enter ``b``); default
            :func:`sparse_product`.

    Returns:
        The reduced system.
    """
    status = it.law.status
    forced = status == ContactStatus.OPEN
    forced &= np.zeros(len(status), dtype=bool) if force_closed is None else force_closed
    closed = np.flatnonzero((status != ContactStatus.OPEN) | forced)
    mu = per_point(prob.mu, len(status))
    u, kappa = slip_frame(it.g, it.p, mu, r)
    is_slip = (status[closed] == ContactStatus.SLIP) & (mu[closed] > 0.0)
    is_free = ((status[closed] == ContactStatus.SLIP) & (mu[closed] == 0.0)) | forced[closed]
    u_c, kap_c = u[closed], kappa[closed]
    v_c = np.stack([-u_c[:, 1], u_c[:, 0]], axis=1)  # (c, 2), u rotated by +90°

    s = -it.p.copy()  # shift: dp = T dq + s
    s[closed] = 0.0
    sl = closed[is_slip]
    u_s, v_s, k_s = u_c[is_slip], v_c[is_slip], kap_c[is_slip]
    a0 = mu[sl] * it.p[sl, 0] - np.sum(it.p[sl, 1:] * u_s, axis=1)
    s[sl, 1:] = a0[:, None] * u_s
    s[closed[is_free], 1:] = -it.p[closed[is_free], 1:]

    # Per closed point: columns of T (slot → 3 components) and rows of R, (c, 3, 3).
    t_loc = np.broadcast_to(np.eye(3), (len(closed), 3, 3)).copy()
    t_loc[is_slip, 1:, 0] = mu[sl, None] * u_s
    t_loc[is_slip, 1:, 1] = v_s
    r_loc = t_loc.transpose(0, 2, 1).copy()
    r_loc[is_slip, 0, 1:] = 0.0
    r_loc[is_slip, 1, 1:] = k_s[:, None] * v_s
    keep = np.ones((len(closed), 3), dtype=bool)
    keep[is_slip, 2] = False
    keep[is_free, 1:] = False

    # Own targets of the rows: -w_n, -Δw_t (stick), -C_t·v/r (slip, second slot).
    own = -it.g[closed]
    own[is_slip, 1] = -np.sum(it.C[sl, 1:] * v_s, axis=1) / r[sl]
    Ws = sparse_product(prob.W, s, prob.symmetric) if w_times is None else w_times(s)  # (3m,)
    k = prob.G.shape[1]
    G_c = prob.G.reshape(len(it.p), 3, k)[closed]  # (c, 3, k)
    Jalpha = (r_loc @ G_c)[keep]  # R G, (n_q, k)
    b = own[keep] - np.einsum("cab,cb->ca", r_loc, Ws.reshape(-1, 3)[closed])[keep]
    b += Jalpha @ it.alpha
    H = np.ascontiguousarray((t_loc.transpose(0, 2, 1) @ G_c)[keep].T)  # (Tᵀ G)ᵀ, (k, n_q)
    h = prob.e - prob.G.T @ (it.p + s).ravel()
    point, slot = np.nonzero(keep)
    q_slip = (np.cumsum(keep.ravel()) - 1).reshape(-1, 3)[is_slip, 1]
    d = np.zeros(len(point))
    d[q_slip] = (1.0 - k_s) / r[sl]
    kind = np.where(is_slip, 1, np.where(is_free, 2, 0)).astype(np.int8)
    u_kind = np.where(is_slip[:, None], u_c, 0.0)
    keys = 3 * closed[point] + slot
    kap_kind = np.where(is_slip, kap_c, 0.0)
    return Linear(closed, keep, kind, u_kind, t_loc, r_loc, d, s, b, Jalpha, H, h, keys, kap_kind)


def form_jacobian(
    W_block: npt.NDArray[np.floating[Any]],
    block: npt.NDArray[np.int64],
    lin: Linear,
    *,
    symmetric: bool = True,
) -> npt.NDArray[np.floating[Any]]:
    """Form ``J = R W T + diag(d)`` densely, shape (n_q, n_q), C-ordered.

    Up to ``LOCAL_MAX`` unknowns ``R`` and ``T`` are applied as their 3×3 blocks (batched
    products on the closed points' block of ``W``; no sparse matrices: at 300 unknowns
    the sparse path's set-up cost more than its arithmetic). Above, for symmetric ``W``,
    ``W T = (Tᵀ W)ᵀ``: the columns of ``T`` become combinations of
    contiguous rows of ``W``, transposed in cache-sized chunks onto the closed DOFs, and
    ``R`` then combines rows again (column gathers and column assignment on a wide
    C-ordered array were several times slower). Otherwise ``W T`` is formed directly.

    Args:
        W_block: ``W`` restricted to the DOFs of the points ``block`` (rows and columns
            node-major in ``block`` order), shape (3 len(block), 3 len(block)) [mm/N];
            ``W`` itself when ``block`` is every point. float64, or float32 for a J that
            is only factorised in float32 (J then has that dtype).
        block: Sorted point indices, shape (n_b,), int64; a superset of ``lin.closed``.
        lin: The reduced system.
        symmetric: Whether ``W`` is symmetric.

    Returns:
        The reduced Jacobian.
    """
    n_q = len(lin.keys)
    cols = (3 * np.searchsorted(block, lin.closed)[:, None] + np.arange(3)).ravel()
    dtype = W_block.dtype  # float32 for a preconditioner's base, else float64
    if n_q == 0:
        return np.zeros((0, 0), dtype=dtype)
    if n_q <= LOCAL_MAX:
        # R W by (3, 3) row blocks, kept rows only; then (R W T)ᵀ = Tᵀ (R W)ᵀ the same way.
        c = len(lin.closed)
        kept = np.flatnonzero(lin.keep.ravel())
        W_cc = W_block if len(cols) == W_block.shape[0] else W_block[cols][:, cols]
        RW = np.matmul(lin.r_loc.astype(dtype), W_cc.reshape(c, 3, 3 * c))
        RW_k = RW.reshape(3 * c, 3 * c)[kept]  # (n_q, 3c)
        J_t = np.matmul(lin.t_loc.transpose(0, 2, 1).astype(dtype), RW_k.T.reshape(c, 3, -1))
        J_local: npt.NDArray[np.floating[Any]] = np.ascontiguousarray(
            J_t.reshape(3 * c, n_q)[kept].T
        )
        J_local[np.diag_indices_from(J_local)] += lin.d
        return J_local
    full = len(block) * 3 == 3 * len(lin.s)
    T_b = lin.T if full else lin.T[(3 * block[:, None] + np.arange(3)).ravel(), :]
    if symmetric:
        t_rows = sp.csr_array(T_b.T, dtype=dtype)  # (n_q, 3 n_b)
        WT = np.empty((len(cols), n_q), dtype=dtype)  # W T on the closed DOFs, (3c, n_q)
        for i in range(0, n_q, _CHUNK):
            rows = t_rows[i : i + _CHUNK] @ W_block  # (chunk, 3 n_b): rows of (W T)ᵀ
            WT[:, i : i + _CHUNK] = (rows if len(cols) == rows.shape[1] else rows[:, cols]).T
    else:
        WT = np.ascontiguousarray((T_b.T @ W_block[cols].T).T)  # (3c, n_q)
    dofs = (3 * lin.closed[:, None] + np.arange(3)).ravel()
    J: npt.NDArray[np.floating[Any]] = lin.R[:, dofs].astype(dtype) @ WT  # (n_q, n_q)
    J[np.diag_indices_from(J)] += lin.d
    return J


LOCAL_MAX = 300
"""Up to this many unknowns :func:`form_jacobian` applies ``R`` and ``T`` blockwise: on the
hinge's reduced Jacobians the blocks are faster than the sparse path below it and slower
above. Chosen by measurement (benchmarks/bench_contact.txt, 'LOCAL_MAX')."""


_CHUNK = 256
"""Rows of ``Tᵀ W`` formed and transposed at a time (a few MB: stays in cache)."""


def _slot_operators(
    closed: npt.NDArray[np.int64],
    keep: npt.NDArray[np.bool_],
    t_loc: FloatArray,
    r_loc: FloatArray,
    n_dof: int,
) -> tuple[sp.csr_array, sp.csr_array]:
    """Assemble T (n_dof, n_q) and R (n_q, n_dof) from per-point blocks of kept slots."""
    point, slot = np.nonzero(keep)  # point-major, so q = position in this list
    q = np.arange(len(point))
    comp = 3 * closed[point][:, None] + np.arange(3)  # (n_q, 3) global DOFs
    t_val = t_loc[point, :, slot]  # (n_q, 3): component a of column q
    r_val = r_loc[point, slot, :]  # (n_q, 3): component a of row q
    rows_q = np.repeat(q, 3)
    T = sp.csr_array((t_val.ravel(), (comp.ravel(), rows_q)), shape=(n_dof, len(q)))
    R = sp.csr_array((r_val.ravel(), (rows_q, comp.ravel())), shape=(len(q), n_dof))
    T.eliminate_zeros()
    R.eliminate_zeros()
    return T, R
