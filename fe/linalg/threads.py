"""The thread counts a job computes with, so that its numbers do not depend on where it runs.

A cycle and its set-up run in process on the machine's cores or as a task on a one-thread
Dask worker (``model.cluster``), and a diagnosis must give the same numbers on both
(issue 35). Some BLAS kernels round differently on different thread counts (OpenBLAS's LU
and matrix-matrix products: n = 3 000, 9e-13 and 7e-12 apart on 1 and 2 threads), and a
difference in the last bits is enough to change a contact Newton path. So a job runs its
OpenBLAS on one thread (:func:`job_threads`), whatever the process has, but for the
contact phase's large LUs, which take ``fe.contact.dense.lu_threads`` (1 unless the user
asks for more). What is spread over the cores gives the same bits on any count: PARDISO's
solves with a factor built on one thread (``fe.linalg.sparse``), and large dense products
cut into fixed chunks, each on one BLAS thread, that the job's cores share
(:func:`chunked_product`).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import os
import threading
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import numpy.typing as npt
from threadpoolctl import ThreadpoolController


@contextlib.contextmanager
def job_threads() -> Iterator[None]:
    """OpenBLAS (numpy's and scipy's) on one thread for a job's set-up and cycle.

    MKL keeps its threads: it serves only PARDISO here, whose numbers do not depend on
    them. Made per job: the libraries loaded by then are the ones limited (~1 ms).
    Measured cost against the process's two threads: none on the default general cycle
    (13.4 s against 12.7-14.6 s with every pool at one thread).
    """
    with ThreadpoolController().select(internal_api="openblas").limit(limits=1):
        yield


CHUNK_ROWS = 1024
"""Rows of a dense matrix per task of :func:`chunked_product`: fixed, so that the bits of a
product do not depend on the cores that share its chunks. Measured on matrices of 3 072-
9 408 rows (float64 and float32): times a vector the chunks give bitwise the one-thread
product; times a block too at 3 072 and 9 408 rows, 1e-13 apart from it at 3 089. On two
cores chunks of 1 024 rows are as fast as OpenBLAS's own two threads or faster
(benchmarks/bench_contact_guard.txt, session 23)."""

_POOL: list[tuple[int, concurrent.futures.ThreadPoolExecutor]] = []
_BLAS: list[ThreadpoolController] = []
_LOCK = threading.Lock()


def job_cores() -> int:
    """Cores a job may spread deterministic work over (:func:`chunked_product`).

    The CPUs this process may run on, capped by ``OMP_NUM_THREADS`` where it is set: a
    local Dask worker is started with its share of the cores there (``model.cluster``),
    so a one-thread worker gets 1 and the in-process run the machine's cores.
    """
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count() or 1
    raw = os.environ.get("OMP_NUM_THREADS", "")
    if raw.strip().isdigit() and int(raw) >= 1:
        cores = min(cores, int(raw))
    return max(1, cores)


def chunked_product(
    M: npt.NDArray[np.floating[Any]], y: npt.NDArray[np.floating[Any]]
) -> npt.NDArray[np.floating[Any]]:
    """``M @ y`` by fixed chunks of ``CHUNK_ROWS`` rows, shared among :func:`job_cores`.

    Each chunk is one product on one BLAS thread, so every entry of the result is the same
    sum in the same order however many cores share the chunks: the bits are those of the
    one-thread product on one core or on many (OpenBLAS's own threads are not: a product
    of 5 100 rows came out 1e-13 apart on one and two threads). A large product is
    memory-bound, and a second core doubles the bandwidth.

    Args:
        M: Dense matrix, shape (n, k), C-ordered (a row chunk is then contiguous).
        y: Vector or block, shape (k,) or (k, p).

    Returns:
        ``M @ y``, shape (n,) or (n, p), of numpy's result dtype.
    """
    out = np.empty((M.shape[0], *y.shape[1:]), dtype=np.result_type(M, y))

    def work(s: int, e: int) -> None:
        np.matmul(M[s:e], y, out=out[s:e])

    in_chunks(M.shape[0], work)
    return out


def in_chunks(n: int, work: Callable[[int, int], None]) -> None:
    """Call ``work(start, stop)`` for the chunks ``CHUNK_ROWS`` long of ``range(n)``.

    The chunks are the same on any machine; :func:`job_cores` threads share them, each
    chunk's BLAS calls on one thread. ``work`` must write only its own chunk's part of
    any shared output, so the result does not depend on the order the chunks run in.
    """
    starts = range(0, n, CHUNK_ROWS)
    cores = min(job_cores(), len(starts))
    with _blas().limit(limits=1, user_api="blas"):
        if cores <= 1:
            for s in starts:
                work(s, min(s + CHUNK_ROWS, n))
            return
        futures = [_pool(cores).submit(work, s, min(s + CHUNK_ROWS, n)) for s in starts]
        for f in futures:
            f.result()


def _blas() -> ThreadpoolController:
    """One controller for the process (made on first use, when the BLAS libraries are loaded)."""
    with _LOCK:
        if not _BLAS:
            _BLAS.append(ThreadpoolController())
        return _BLAS[0]


def _pool(cores: int) -> concurrent.futures.ThreadPoolExecutor:
    """The shared pool of ``cores`` threads (made again if the count changed)."""
    with _LOCK:
        if _POOL and _POOL[0][0] != cores:
            _POOL.pop()[1].shutdown(wait=False)
        if not _POOL:
            _POOL.append((cores, concurrent.futures.ThreadPoolExecutor(cores, "hingelab-chunk")))
        return _POOL[0][1]
