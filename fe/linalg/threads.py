"""The thread counts a job computes with, so that its numbers do not depend on where it runs.

A cycle and its set-up run in process on the machine's cores or as a task on a one-thread
Dask worker (``model.cluster``), and a diagnosis must give the same numbers on both
(issue 35). Some BLAS kernels round differently on different thread counts (OpenBLAS's LU
and matrix-matrix products: n = 3 000, 9e-13 and 7e-12 apart on 1 and 2 threads), and a
difference in the last bits is enough to change a contact Newton path. So a job runs its
OpenBLAS on one thread (:func:`job_threads`), whatever the process has, but for the
contact phase's large LUs and products, which take ``fe.contact.dense.lu_threads`` (1
unless the user asks for more); what stays threaded gives the same bits on any count:
PARDISO's solves with a factor built on one thread (``fe.linalg.sparse``).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

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
