"""Sparse direct solves of symmetric positive definite systems: MKL PARDISO or SuperLU.

``Factorization`` factorises once and solves many right-hand sides; ``inverse_block``
returns the compliance of a few DOFs from a PARDISO Schur complement (one partial
factorisation with those DOFs ordered last).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import ctypes
import os
import sys
import weakref
from collections.abc import Callable, Iterator, Sequence
from enum import Enum
from pathlib import Path
from typing import TypeVar

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from cad.errors import ParameterError, SolverError

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
T = TypeVar("T")

__all__ = ["Factorization", "LinearSolverBackend", "inverse_block"]


class LinearSolverBackend(Enum):
    """Sparse direct solver behind ``Factorization``."""

    AUTO = "auto"
    """MKL PARDISO if pypardiso is importable, else SciPy SuperLU."""
    PARDISO = "pardiso"
    """MKL PARDISO, real symmetric positive definite (mtype = 2), upper triangle only."""
    SCIPY = "scipy"
    """SciPy SuperLU in symmetric mode (fallback; slower, more memory)."""


_PARDISO_SPD = 2


def _iparm(*, schur: bool = False) -> npt.NDArray[np.int32]:
    """PARDISO's integer parameters as this module uses them (one place for both calls)."""
    iparm = np.zeros(64, dtype=np.int32)
    iparm[0] = 1  # we set iparm ourselves
    iparm[1] = 2  # nested-dissection (METIS) ordering
    iparm[34] = 1  # zero-based ia/ja
    if schur:
        iparm[35] = 1  # return the Schur complement of the DOFs marked in perm, dense, in x
    return iparm


def _point_pypardiso_at_mkl() -> None:
    """Tell pypardiso where the venv's ``libmkl_rt`` is, if it is where pip puts it.

    Without ``PYPARDISO_MKL_RT`` pypardiso's import and every ``PyPardisoSolver()`` glob
    ``sys.prefix/lib*/**`` recursively, a cost every process that factorises pays
    (benchmarks/bench_cycle.txt, '_point_pypardiso_at_mkl'). ``sys.prefix/lib`` is where
    the ``mkl`` wheel installs it; elsewhere pypardiso's own search still runs.
    """
    if os.environ.get("PYPARDISO_MKL_RT"):
        return
    for lib in sorted(Path(sys.prefix, "lib").glob("libmkl_rt.so*"), key=lambda f: len(f.name)):
        try:
            ctypes.CDLL(str(lib))
        except OSError:
            continue
        os.environ["PYPARDISO_MKL_RT"] = str(lib)
        return


def _load_mkl() -> ctypes.CDLL | None:
    _point_pypardiso_at_mkl()
    try:
        import pypardiso  # optional dependency, hence imported lazily
    except ImportError:
        return None
    # Reuse pypardiso's search for mkl_rt; call PARDISO ourselves so a solve does not
    # re-convert the index arrays or compare the matrix on every call.
    lib: ctypes.CDLL = pypardiso.PyPardisoSolver().libmkl
    fn = lib.pardiso
    i32p = ctypes.POINTER(ctypes.c_int32)
    fn.argtypes = [ctypes.POINTER(ctypes.c_int64), i32p, i32p, i32p, i32p, i32p,
                   ctypes.c_void_p, i32p, i32p, i32p, i32p, i32p, i32p,
                   ctypes.c_void_p, ctypes.c_void_p, i32p]  # fmt: skip
    fn.restype = None
    return lib


_MKL: list[ctypes.CDLL | None] = []


@contextlib.contextmanager
def _one_mkl_thread(lib: ctypes.CDLL) -> Iterator[None]:
    """Run PARDISO's factorisation on one MKL thread (this thread only; restored after).

    The factor MKL builds depends on its thread count, and so, in the last bits, does every
    solve with it: measured on a 3D Laplacian (1 728-216 000 unknowns), a factor built on two
    threads gives solutions 4e-16 to 2e-15 away from one built on one, and two 2-thread
    factors of the same matrix differ from each other. Solves with a factor built on one
    thread are bitwise the same on 1 and 2 threads for 1-128 right-hand sides. So the
    numbers of a job are the same wherever it runs (in process on the machine's cores, on
    a one-thread Dask worker: issue 35) and from run to run. MKL's CNR mode
    (``iparm[33]``, ``MKL_CBWR``) does not give this (measured: the same differences).
    Cost, in process only (a Dask worker has one thread anyway): the factorisation's
    second thread, and the solves of a one-thread factor gain little from one (a 125 000-
    unknown Laplacian, 128 right-hand sides: 2.02 s on one thread, 1.80 s on two, 1.49 s
    with a two-thread factor). The default general cycle is unchanged within noise (13 s);
    the bearing hinge's fit condensation took 38 s instead of 24 s until it shared its
    blocks between one-thread handles (``Factorization.in_parallel``: 23 s again;
    benchmarks/bench_bearing_cli.txt, session 22).
    """
    fn = getattr(lib, "MKL_Set_Num_Threads_Local", None)
    if fn is None:  # not an MKL runtime with thread-local settings: leave it
        yield
        return
    before = fn(1)
    try:
        yield
    finally:
        fn(before)


def _mkl_threads() -> int:
    """MKL's thread count here (1 without MKL)."""
    lib = _mkl()
    return 1 if lib is None else max(1, int(lib.MKL_Get_Max_Threads()))


def _mkl() -> ctypes.CDLL | None:
    if not _MKL:
        _MKL.append(_load_mkl())
    return _MKL[0]


class _Pardiso:
    """One MKL PARDISO handle holding the factor of an SPD matrix (upper triangle)."""

    def __init__(self, lib: ctypes.CDLL, upper: sp.csr_matrix) -> None:
        self._lib, self._upper = lib, upper  # for ``twin``
        self._fn = lib.pardiso
        self.n = upper.shape[0]
        self._a = np.ascontiguousarray(upper.data, dtype=np.float64)
        self._ia = np.ascontiguousarray(upper.indptr, dtype=np.int32)
        self._ja = np.ascontiguousarray(upper.indices, dtype=np.int32)
        self._pt = np.zeros(64, dtype=np.int64)
        self._iparm = _iparm()
        with _one_mkl_thread(lib):
            self._call(12, np.zeros((self.n, 1), order="F"))
        weakref.finalize(self, _Pardiso._release, self._fn, self._pt, self._iparm, self.n)

    def twin(self) -> _Pardiso:
        """Another handle with the same factor, bitwise (factorised again, on one thread)."""
        return _Pardiso(self._lib, self._upper)

    def _call(self, phase: int, b: FloatArray) -> FloatArray:
        x = np.zeros_like(b, order="F")
        err = ctypes.c_int32(0)
        i32 = ctypes.c_int32
        i32p = ctypes.POINTER(i32)
        self._fn(
            self._pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
            ctypes.byref(i32(1)), ctypes.byref(i32(1)), ctypes.byref(i32(_PARDISO_SPD)),
            ctypes.byref(i32(phase)), ctypes.byref(i32(self.n)), self._a.ctypes.data,
            self._ia.ctypes.data_as(i32p), self._ja.ctypes.data_as(i32p), None,
            ctypes.byref(i32(b.shape[1])), self._iparm.ctypes.data_as(i32p),
            ctypes.byref(i32(0)), b.ctypes.data, x.ctypes.data, ctypes.byref(err),
        )  # fmt: skip
        if err.value != 0:
            raise SolverError(
                f"PARDISO phase {phase} failed with error {err.value} (-4: matrix not positive "
                "definite, e.g. too few fixed DOFs)"
            )
        return x

    @staticmethod
    def _release(
        fn: Callable[..., None], pt: IntArray, iparm: npt.NDArray[np.int32], n: int
    ) -> None:
        i32 = ctypes.c_int32
        dummy = np.zeros(1, dtype=np.float64)
        err = i32(0)
        fn(pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(i32(1)),
           ctypes.byref(i32(1)), ctypes.byref(i32(_PARDISO_SPD)), ctypes.byref(i32(-1)),
           ctypes.byref(i32(n)), dummy.ctypes.data, None, None, None, ctypes.byref(i32(1)),
           iparm.ctypes.data_as(ctypes.POINTER(i32)), ctypes.byref(i32(0)), dummy.ctypes.data,
           dummy.ctypes.data, ctypes.byref(err))  # fmt: skip

    def solve(self, B: FloatArray) -> FloatArray:
        return self._call(33, np.asfortranarray(B))


class Factorization:
    """A sparse Cholesky-type factorisation of a symmetric positive definite matrix.

    The matrix is factorised once, in the constructor; ``solve`` then costs only the two
    triangular sweeps, so factorise once and call ``solve`` many times, preferably with
    blocks of right-hand sides (see benchmarks/bench_assembly.py for timings). A PARDISO
    handle is not thread-safe: use one ``Factorization`` per thread.

    Attributes:
        n: Size of the system.
        backend: The backend actually used (never AUTO).
    """

    def __init__(
        self,
        K_ff: sp.spmatrix | sp.sparray,
        *,
        backend: LinearSolverBackend = LinearSolverBackend.AUTO,
        symmetry_rtol: float = 1e-10,
    ) -> None:
        """Factorise ``K_ff``.

        Args:
            K_ff: Symmetric positive definite matrix, shape (n, n), float64 (the full
                matrix, not a triangle). It is copied, never modified.
            backend: Which solver to use.
            symmetry_rtol: Allowed max|K - Kᵀ| relative to max|K|.

        Raises:
            ParameterError: If K_ff is not square or not symmetric, or if PARDISO was
                requested but pypardiso is not installed.
            SolverError: If PARDISO finds K_ff not positive definite.
        """
        if not isinstance(backend, LinearSolverBackend):
            raise ParameterError(f"backend must be a LinearSolverBackend, got {backend!r}")
        A = sp.csr_matrix(K_ff, dtype=np.float64)
        if A.shape[0] != A.shape[1] or A.shape[0] == 0:
            raise ParameterError(f"K_ff must be square and non-empty, got shape {A.shape}")
        scale = abs(A).max()
        asym = abs(A - A.T).max() if A.nnz else 0.0
        if asym > symmetry_rtol * scale:
            raise ParameterError(
                f"K_ff is not symmetric: max|K - Kᵀ| = {asym:.3e}, max|K| = {scale:.3e}"
            )
        self.n: int = A.shape[0]
        lib = _mkl() if backend is not LinearSolverBackend.SCIPY else None
        if backend is LinearSolverBackend.PARDISO and lib is None:
            raise ParameterError("backend PARDISO requested but pypardiso is not installed")
        self._impl: _Pardiso | spla.SuperLU
        if lib is not None:
            upper = sp.triu(A, format="csr")
            upper.sort_indices()
            self._impl = _Pardiso(lib, upper)
            self.backend = LinearSolverBackend.PARDISO
        else:
            self._impl = spla.splu(
                A.tocsc(),
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
            self.backend = LinearSolverBackend.SCIPY

    def in_parallel(self, items: Sequence[T], work: Callable[[Factorization, T], None]) -> None:
        """Call ``work(solver, item)`` for every item, on MKL's threads as one-thread solvers.

        The solves of a factor built on one thread (``_one_mkl_thread``) gain little from
        more MKL threads; here each thread has its own PARDISO handle of the same factor
        (factorised again, on one thread, so bitwise the same: every item's numbers are
        those of a sequential run) and solves on one MKL thread. Items are dealt out in
        turn; ``work`` must write only its own item's part of any shared output. On one
        MKL thread (a Dask worker), with SuperLU, or for one item, it is a plain loop.
        Memory: one more factor per extra thread, alive during the call.

        Raises:
            Whatever ``work`` raises (the other threads finish their items first).
        """
        threads = _mkl_threads() if isinstance(self._impl, _Pardiso) else 1
        n = min(threads, len(items))
        if n <= 1:
            for item in items:
                work(self, item)
            return
        impl = self._impl
        assert isinstance(impl, _Pardiso)

        def run(k: int) -> None:
            with _one_mkl_thread(impl._lib):
                solver = self if k == 0 else self._with(impl.twin())
                for item in items[k::n]:
                    work(solver, item)

        with concurrent.futures.ThreadPoolExecutor(n) as pool:
            for f in [pool.submit(run, k) for k in range(n)]:
                f.result()

    def _with(self, impl: _Pardiso) -> Factorization:
        twin = object.__new__(Factorization)
        twin.n, twin.backend, twin._impl = self.n, self.backend, impl
        return twin

    def solve(self, B: npt.ArrayLike, *, rows: npt.ArrayLike | None = None) -> FloatArray:
        """Solve K_ff X = B.

        A block of right-hand sides is solved column by column (PARDISO's layout): pass it
        column-major (``C.toarray().T``, not ``C.T.toarray()``) and ask for the ``rows`` a
        product needs, and no copy of the whole block is made either way (a 185k × 128
        block is 190 MB; its two transposes cost 0.6 s per block on the bearing hinge's
        default mesh, benchmarks/bench_bearing_cli.txt).

        Args:
            B: One right-hand side, shape (n,), or a block of k, shape (n, k), float64.
            rows: Only these rows of X are returned, shape (r,), in this order.

        Returns:
            X with the shape of B, float64; ``X[rows]`` if ``rows`` is given.

        Raises:
            ParameterError: If B has the wrong shape.
        """
        rhs = np.asarray(B, dtype=np.float64)
        if rhs.ndim not in (1, 2) or rhs.shape[0] != self.n:
            raise ParameterError(f"B must have shape ({self.n},) or ({self.n}, k), got {rhs.shape}")
        block = rhs.reshape(self.n, -1)
        if block.shape[1] == 0:
            X = np.zeros(rhs.shape, dtype=np.float64)
            return X if rows is None else X[np.asarray(rows, dtype=np.int64)]
        X = self._impl.solve(block)
        if rows is None:
            return np.ascontiguousarray(X, dtype=np.float64).reshape(rhs.shape)
        r = np.asarray(rows, dtype=np.int64)
        return np.ascontiguousarray(X[r], dtype=np.float64).reshape((len(r), *rhs.shape[1:]))


def inverse_block(
    K_ff: sp.spmatrix | sp.sparray,
    idx: npt.ArrayLike,
    *,
    factor: Factorization | Callable[[], Factorization] | None = None,
    block_rhs: int = 128,
    backend: LinearSolverBackend = LinearSolverBackend.AUTO,
) -> FloatArray:
    """Return ``(K_ff⁻¹)[idx, idx]``, the compliance of a few DOFs of a sparse SPD matrix.

    With MKL PARDISO the block comes from the Schur complement
    ``S = K_bb − K_bi K_ii⁻¹ K_ib`` (b = idx), which PARDISO forms during a partial
    factorisation with the b DOFs ordered last, and ``(K⁻¹)_bb = S⁻¹`` (a dense Cholesky
    inverse). That costs about one factorisation plus O(b³), instead of b sparse
    triangular solves (benchmarks/bench_assembly.txt, 'inverse_block'). Without PARDISO,
    unit right-hand sides are solved in blocks of ``block_rhs`` with ``factor`` (built
    here if None).

    Args:
        K_ff: Symmetric positive definite matrix, shape (n, n), float64.
        idx: Distinct DOF indices, shape (b,), in any order; the result follows it.
        factor: A factorisation of K_ff to reuse on the fallback path, or a callable
            returning one (called only on that path, so it can be made lazily).
        block_rhs: Right-hand sides per block solve on the fallback path.
        backend: AUTO or PARDISO: the Schur complement (PARDISO required); SCIPY: block
            solves (with ``factor``, whatever its backend).

    Returns:
        The symmetric block, shape (b, b) [inverse units of K_ff].

    Raises:
        ParameterError: Repeated or out-of-range indices.
        SolverError: K_ff (or its Schur complement) is not positive definite.
    """
    A = sp.csr_matrix(K_ff, dtype=np.float64)
    n = A.shape[0]
    b = np.asarray(idx, dtype=np.int64).ravel()
    if b.size and (b.min() < 0 or b.max() >= n):
        raise ParameterError(f"idx must lie in [0, {n}), got {b.min()}..{b.max()}")
    if np.unique(b).size != b.size:
        raise ParameterError(f"idx contains {b.size - np.unique(b).size} repeated DOFs")
    if b.size == 0:
        return np.zeros((0, 0))
    lib = None if backend is LinearSolverBackend.SCIPY else _mkl()
    if backend is LinearSolverBackend.PARDISO and lib is None:
        raise ParameterError("backend PARDISO requested but pypardiso is not installed")
    if lib is None or b.size == n:
        f = factor() if callable(factor) else factor
        f = Factorization(A) if f is None else f
        out = np.empty((b.size, b.size))
        for j in range(0, b.size, block_rhs):
            cols = b[j : j + block_rhs]
            E = np.zeros((n, cols.size))
            E[cols, np.arange(cols.size)] = 1.0
            out[:, j : j + cols.size] = f.solve(E)[b]
        return 0.5 * (out + out.T)
    order = np.argsort(b)
    S = _pardiso_schur(lib, A, b[order])
    c, info = sla.lapack.dpotrf(S, lower=0, overwrite_a=1)
    if info != 0:
        raise SolverError(f"Schur complement not positive definite (dpotrf info {info})")
    inv, info = sla.lapack.dpotri(c, lower=0, overwrite_c=1)
    if info != 0:
        raise SolverError(f"Schur complement inversion failed (dpotri info {info})")
    inv = _symmetrise_upper(inv)
    if np.array_equal(order, np.arange(order.size)):  # idx sorted: no reordering
        return inv.T if inv.flags.f_contiguous else np.ascontiguousarray(inv)  # C-ordered
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    return np.ascontiguousarray(inv[np.ix_(back, back)])


SYMMETRISE_BLOCK = 512
"""Rows copied at a time by :func:`_symmetrise_upper` (a few MB: stays in cache)."""


def _symmetrise_upper(A: FloatArray) -> FloatArray:
    """Fill the lower triangle of ``A`` from its upper one, in place, block by block.

    ``np.triu(A) + np.triu(A, 1).T`` makes three full temporaries; copying blocks of the
    upper triangle down makes none (benchmarks/bench_cycle.txt, '_symmetrise_upper').
    """
    n = A.shape[0]
    for i0 in range(0, n, SYMMETRISE_BLOCK):
        i1 = min(i0 + SYMMETRISE_BLOCK, n)
        A[i0:i1, :i0] = A[:i0, i0:i1].T
        diag = A[i0:i1, i0:i1]
        diag[...] = np.triu(diag) + np.triu(diag, 1).T
    return A


def _pardiso_schur(lib: ctypes.CDLL, A: sp.csr_matrix, b: IntArray) -> FloatArray:
    """Schur complement of A onto the sorted DOFs b by a PARDISO partial factorisation, (nb, nb)."""
    upper = sp.triu(A, format="csr")
    upper.sort_indices()
    n = A.shape[0]
    a = np.ascontiguousarray(upper.data, dtype=np.float64)
    ia = np.ascontiguousarray(upper.indptr, dtype=np.int32)
    ja = np.ascontiguousarray(upper.indices, dtype=np.int32)
    pt = np.zeros(64, dtype=np.int64)
    iparm = _iparm(schur=True)
    perm = np.zeros(n, dtype=np.int32)
    perm[b] = 1
    S = np.zeros((b.size, b.size), order="F")
    rhs = np.zeros(n)
    err = ctypes.c_int32(0)
    i32 = ctypes.c_int32
    i32p = ctypes.POINTER(i32)
    fn = lib.pardiso
    try:
        with _one_mkl_thread(lib):  # the Schur complement is formed in the factorisation
            fn(pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(i32(1)),
               ctypes.byref(i32(1)), ctypes.byref(i32(_PARDISO_SPD)), ctypes.byref(i32(12)),
               ctypes.byref(i32(n)), a.ctypes.data, ia.ctypes.data_as(i32p),
               ja.ctypes.data_as(i32p), perm.ctypes.data_as(i32p), ctypes.byref(i32(1)),
               iparm.ctypes.data_as(i32p), ctypes.byref(i32(0)), rhs.ctypes.data, S.ctypes.data,
               ctypes.byref(err))  # fmt: skip
    finally:
        _Pardiso._release(fn, pt, iparm, n)
    if err.value != 0:
        raise SolverError(
            f"PARDISO Schur complement failed with error {err.value} (-4: matrix not positive "
            "definite, e.g. too few fixed DOFs)"
        )
    return S  # upper triangle used by the Cholesky that follows
