"""A factor's solves do not depend on how many threads MKL has (issue 35).

In process PARDISO has the machine's cores, on a Dask worker one: a diagnosis must give
the same numbers on both, so its solves must be bitwise independent of the thread count,
not only close. The factorisation runs on one thread (``sparse._one_mkl_thread``); the
solves, most of the time of a condensation, keep MKL's threads.
"""

from __future__ import annotations

import contextlib

import numpy as np
import pytest
import scipy.sparse as sp
from threadpoolctl import ThreadpoolController

from fe.linalg import sparse
from fe.linalg.sparse import Factorization, LinearSolverBackend, inverse_block


def _laplacian(m: int) -> sp.csr_matrix:
    """A 3D 7-point Laplacian with a small shift (SPD), m³ unknowns."""
    eye = sp.identity(m)
    d = sp.diags([-1.0, 2.0001, -1.0], [-1, 0, 1], shape=(m, m))
    k = sp.kron(sp.kron(d, eye), eye) + sp.kron(sp.kron(eye, d), eye)
    return (k + sp.kron(sp.kron(eye, eye), d)).tocsr()


@pytest.fixture
def mkl():  # type: ignore[no-untyped-def]
    if sparse._mkl() is None:
        pytest.skip("MKL PARDISO is not installed (no pypardiso): SuperLU is single-threaded")
    pools = ThreadpoolController().select(internal_api="mkl")
    if not pools.lib_controllers:
        pytest.skip("threadpoolctl does not see MKL's thread pool")
    return pools


def _solutions(mkl, K: sp.csr_matrix, b: np.ndarray) -> list[np.ndarray]:  # type: ignore[no-untyped-def]
    """Factorise and solve on 1, 2, 1 and 2 MKL threads (a factor and its solve each)."""
    out = []
    for threads in (1, 2, 1, 2):
        with mkl.limit(limits=threads):
            out.append(Factorization(K, backend=LinearSolverBackend.PARDISO).solve(b))
    return out


@pytest.mark.parametrize("k", [1, 2, 5])
def test_solves_are_bitwise_the_same_on_one_and_two_mkl_threads(mkl, k):
    K = _laplacian(16)  # 4 096 unknowns
    b = np.random.default_rng(3).standard_normal((K.shape[0], k))

    x = _solutions(mkl, K, b)

    assert all(np.array_equal(x[0], xi) for xi in x[1:])
    assert np.allclose(K @ x[0], b, rtol=0, atol=1e-10)  # and it is the solution


def test_a_factor_built_on_two_threads_shows_them_in_the_last_bits(mkl, monkeypatch):
    """Why the factorisation runs on one thread: the test above fails without it."""
    monkeypatch.setattr(sparse, "_one_mkl_thread", lambda lib: contextlib.nullcontext())
    K = _laplacian(16)
    b = np.random.default_rng(3).standard_normal((K.shape[0], 5))

    x = _solutions(mkl, K, b)

    assert not np.array_equal(x[0], x[1])
    assert np.abs(x[0] - x[1]).max() < 1e-13  # only rounding


def test_schur_compliance_is_bitwise_the_same_on_one_and_two_mkl_threads(mkl):
    """The nodal compliances (``inverse_block``): held here with and without the
    one-thread factorisation (measured up to 27 000 unknowns); this guards it."""
    K = _laplacian(16)
    idx = np.sort(np.random.default_rng(4).choice(K.shape[0], 120, replace=False))
    blocks = []
    for threads in (1, 2, 2):
        with mkl.limit(limits=threads):
            blocks.append(inverse_block(K, idx, backend=LinearSolverBackend.PARDISO))

    assert np.array_equal(blocks[0], blocks[1])
    assert np.array_equal(blocks[1], blocks[2])


def test_blocks_solved_in_parallel_are_bitwise_those_of_a_plain_loop(mkl):
    """``in_parallel`` gives the second core back to a condensation (one one-thread handle
    per thread): the same numbers as one handle solving every block in turn."""
    K = _laplacian(16)
    B = np.random.default_rng(5).standard_normal((K.shape[0], 40))
    F = Factorization(K, backend=LinearSolverBackend.PARDISO)
    starts = range(0, 40, 8)
    plain = np.column_stack([F.solve(B[:, s : s + 8]) for s in starts])
    out = np.zeros_like(plain)
    solvers = set()

    def work(solver, start):  # type: ignore[no-untyped-def]
        solvers.add(id(solver))
        out[:, start : start + 8] = solver.solve(B[:, start : start + 8])

    with mkl.limit(limits=2):
        F.in_parallel(starts, work)

    assert len(solvers) == 2  # two handles, one per thread
    assert np.array_equal(out, plain)
