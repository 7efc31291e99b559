"""Dense linear algebra of the Newton steps: LU of a reduced Jacobian and bordered solves.

Internal to :mod:`fe.contact` (notation of :mod:`fe.contact.newton`). Also holds the rule
for the BLAS threads of a large LU (:func:`lu_threads`), read at every call so that a
setting or the ``HINGELAB_LU_THREADS`` environment variable takes effect without a
re-import.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
from threadpoolctl import ThreadpoolController, threadpool_limits

from cad.errors import ParameterError

FloatArray = npt.NDArray[np.float64]

LU_THREADS_ENV = "HINGELAB_LU_THREADS"
"""Environment variable that sets the LU threads when the setting is None."""

LU_THREADED_MIN = 2000
"""Smallest reduced Jacobian factorised with :func:`lu_threads` threads.

The rest of the contact phase runs on ``CycleSettings.blas_threads`` (1) but for the
large products (:func:`wide`): its many small operations and its triangular solves are
slower with two threads (threaded triangular solves run on scipy's OpenBLAS as numpy's
spins from a product). A large LU is compute-bound and gains. Chosen by measurement
(benchmarks/bench_cycle.txt, 'LU_THREADED_MIN')."""


PRODUCT_THREADED_MIN = 1_000_000
"""Products with a dense matrix of at least this many entries run on :func:`lu_threads`
threads (:func:`wide`). They are memory-bound and a second core doubles the bandwidth.
Chosen by measurement (benchmarks/bench_cycle.txt, 'PRODUCT_THREADED_MIN')."""

_CONTROLLER: list[ThreadpoolController] = []


def wide(entries: int, threads: int | None = None) -> contextlib.AbstractContextManager[object]:
    """BLAS threads for one product with a dense matrix of ``entries`` entries.

    ``lu_threads(threads)`` threads from ``PRODUCT_THREADED_MIN`` entries, else the
    caller's setting unchanged: one by default, since a matrix-vector product's bits
    depend on OpenBLAS's thread count too (n = 1 500 and 5 100: 1e-13 apart on 1 and 2
    threads; n = 2 000 and 3 000 the same). The controller is made on first use (by then
    numpy's and scipy's BLAS are loaded) and switching costs ~10 µs, against
    milliseconds a product.
    """
    n = lu_threads(threads) if entries >= PRODUCT_THREADED_MIN else 1
    if n <= 1:
        return contextlib.nullcontext()
    if not _CONTROLLER:
        _CONTROLLER.append(ThreadpoolController())
    limit: contextlib.AbstractContextManager[object] = _CONTROLLER[0].limit(
        limits=n, user_api="blas"
    )
    return limit


def lu_threads_from_env() -> int:
    """``HINGELAB_LU_THREADS`` if set (an integer ≥ 1), else 1 (see :func:`lu_threads`)."""
    raw = os.environ.get(LU_THREADS_ENV)
    if raw is None:
        return 1
    try:
        value = int(raw)
    except ValueError:
        value = 0
    if value < 1:
        raise ParameterError(f"{LU_THREADS_ENV} must be an integer ≥ 1, got {raw!r}")
    return value


def lu_threads(setting: int | None = None) -> int:
    """Return the BLAS threads of a dense LU of at least ``LU_THREADED_MIN`` unknowns.

    One by default, on every machine, in process and on a Dask worker alike: OpenBLAS's
    LU depends on its thread count in the last bits (n = 3 000: factors 9e-13 apart on 1
    and 2 threads; one default-mesh cycle's contact pressures 1.7e-12 apart), and a
    difference in the last bits can change a Newton path, so a job's numbers would
    depend on where it ran (issue 35). The large products (:func:`wide`) take the same count. Measured cost of one
    thread against two: none at the default mesh (the 6-case general diagnosis 118 s
    against 127 s; the default cycle 13.4 s against 12.7-14.6 s); at level 1 the contact
    phase gains from a second thread (zero clearance: 76.8 → 69.9 s from the products,
    and a large LU n = 3 000: 0.82 → 0.50 s), so a user who runs one process on a finer
    mesh may ask for two, knowing the numbers then differ in the last bits from a
    one-thread run (so the count is part of a result's key, ``model.spec.result_key``:
    a store filled with two threads is not read back as a one-thread run's).

    Args:
        setting: ``ContactSettings.lu_threads``; None means the environment variable
            ``HINGELAB_LU_THREADS`` read now, else 1.

    Returns:
        The effective thread count (≥ 1).

    Raises:
        ParameterError: If the environment variable is not an integer ≥ 1.
    """
    return lu_threads_from_env() if setting is None else setting


class Factor(NamedTuple):
    """LU factors of a reduced matrix and the unknown layout they belong to.

    Attributes:
        keys: Global slot ``3 i + slot`` of every reduced unknown, shape (n_q,), int64.
        lu: ``scipy.linalg.lu_factor`` output for ``Jᵀ`` (solve with ``trans=1``).
    """

    keys: npt.NDArray[np.int64]
    lu: tuple[FloatArray, npt.NDArray[np.int32]]


def factor_jacobian(
    J: npt.NDArray[np.floating[Any]],
    keys: npt.NDArray[np.int64],
    threads: int | None = None,
    *,
    single: bool = False,
) -> Factor | None:
    """LU-factor ``J`` (destroyed); None if it is numerically singular.

    Args:
        J: Square matrix, shape (n, n), float64, C-ordered; overwritten.
        keys: Unknown layout stored with the factors, shape (n,), int64.
        threads: BLAS threads if ``n >= LU_THREADED_MIN`` (None: :func:`lu_threads`).
        single: Factorise in float32 (half the time and memory traffic of float64): for
            a preconditioner only, whose solves go through :func:`lu_solve`.

    Returns:
        The factors, or None if a pivot is below ``1e3 ε`` times the largest (ε of the
        precision used).
    """
    if J.shape[0] == 0:
        return Factor(keys, (np.zeros((0, 0)), np.zeros(0, dtype=np.int32)))
    if single:
        J = np.asarray(J, dtype=np.float32)
    n_threads = lu_threads(threads) if J.shape[0] >= LU_THREADED_MIN else 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", sla.LinAlgWarning)
        try:
            # J is C-ordered, so J.T is Fortran-ordered: LAPACK factors Jᵀ in place.
            limit = (
                threadpool_limits(limits=n_threads, user_api="blas")
                if n_threads > 1
                else contextlib.nullcontext()
            )
            with limit:
                lu = sla.lu_factor(J.T, overwrite_a=True, check_finite=False)
        except sla.LinAlgWarning:
            return None
    diag = np.abs(np.diag(lu[0]))
    eps = float(np.finfo(lu[0].dtype).eps)
    if not np.all(np.isfinite(diag)) or diag.min() <= 1e3 * eps * diag.max():
        return None
    return Factor(keys, lu)


def lu_solve(
    lu: tuple[npt.NDArray[np.floating], npt.NDArray[np.int32]], B: FloatArray
) -> FloatArray:
    """Solve ``J X = B`` with the factors of ``Jᵀ`` (as stored in :class:`Factor`), float64 out.

    Args:
        lu: Factors from :func:`factor_jacobian`, float64 or float32.
        B: Right-hand sides, shape (n,) or (n, p), float64.

    Returns:
        X, shape of B, float64 (from a float32 solve if the factors are float32).
    """
    rhs = B if lu[0].dtype == B.dtype else B.astype(lu[0].dtype)
    X = sla.lu_solve(lu, rhs, trans=1, check_finite=False)
    return np.asarray(X, dtype=np.float64)


GATHER_ROWS = 256
"""Rows gathered at a time by :func:`gather_block` (a few MB: stays in cache)."""


def gather_block(W: FloatArray, idx: npt.NDArray[np.int64]) -> FloatArray:
    """Return ``W[np.ix_(idx, idx)]``, C-ordered.

    ``np.ix_`` indexing of a large ``W`` goes through numpy's generic two-axis path, which
    is slow there. Contact points come in runs of consecutive indices (a contact zone is
    numbered zone by zone: about 50 runs at level 0 of the hinge), so the block is copied
    as rectangles ``W[run_i, run_j]`` (strided copies); with many runs, by chunks of rows
    whose columns are taken straight into the result. Timings:
    benchmarks/bench_contact_profile.txt, 'gather_block'.

    Args:
        W: Square matrix, shape (n, n), float64.
        idx: Row and column indices, shape (b,), int64.

    Returns:
        The block, shape (b, b), float64.
    """
    out = np.empty((len(idx), len(idx)))
    starts, ends = runs(idx)
    if len(starts) <= GATHER_RUNS:
        first = idx[starts]
        for a, b, i in zip(starts, ends, first, strict=True):
            rows = W[i : i + (b - a)]
            for c, d, j in zip(starts, ends, first, strict=True):
                out[a:b, c:d] = rows[:, j : j + (d - c)]
        return out
    for i in range(0, len(idx), GATHER_ROWS):
        np.take(W[idx[i : i + GATHER_ROWS]], idx, axis=1, out=out[i : i + GATHER_ROWS])
    return out


def runs(idx: npt.NDArray[np.int64]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Runs of consecutive values in ``idx``: positions ``[starts[k], ends[k])``, (r,) each.

    ``idx[starts[k]:ends[k]]`` is ``idx[starts[k]] + 0, 1, …``; none for an empty ``idx``.
    """
    if len(idx) == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    breaks = np.flatnonzero(np.diff(idx) != 1) + 1
    starts = np.concatenate([[0], breaks]).astype(np.int64)
    ends = np.concatenate([breaks, [len(idx)]]).astype(np.int64)
    return starts, ends


def is_subset(a: npt.NDArray[np.int64], b: npt.NDArray[np.int64]) -> bool:
    """Whether every value of ``a`` is in ``b``, both sorted ascending, shapes (n_a,), (n_b,).

    A binary search per value of ``a`` (``np.isin`` sorts both, a cost paid per Newton step
    and per increment: benchmarks/bench_contact.txt, 'is_subset').
    """
    if len(a) == 0:
        return True
    at = np.searchsorted(b, a)
    return bool(at[-1] < len(b)) and bool(np.array_equal(b[np.minimum(at, len(b) - 1)], a))


GATHER_RUNS = 200
"""Index sets of at most this many runs are gathered as rectangles (``runs²`` copies)."""


def solve_bordered(
    factor: Factor,
    Jalpha: FloatArray,
    H: FloatArray,
    b: FloatArray,
    h: FloatArray,
    cut: float,
) -> tuple[FloatArray, FloatArray]:
    """Solve ``J x + Jα a = b, H x = h`` with min-norm ``a``, J given by its factors.

    Singular values of the k×k Schur complement ``S = H J⁻¹ Jα`` below ``cut`` are
    treated as zero (undetermined rigid directions get no component of ``a``).
    """
    k = Jalpha.shape[1]
    if len(factor.keys) == 0:
        return np.zeros(0), np.zeros(k)
    if k == 0:
        return lu_solve(factor.lu, b), np.zeros(0)
    Y = lu_solve(factor.lu, np.column_stack([b, Jalpha]))
    U, sv, Vt = np.linalg.svd(H @ Y[:, 1:])  # Schur complement S, (k, k)
    good = sv > max(cut, float(sv[0]) * np.finfo(float).eps * k)
    coef = (U[:, good].T @ (H @ Y[:, 0] - h)) / sv[good]
    a = Vt[good].T @ coef
    return Y[:, 0] - Y[:, 1:] @ a, a
