"""Sparse linear algebra: the SPD direct solver (MKL PARDISO or SciPy SuperLU).

:mod:`fe.linalg.sparse` holds ``Factorization``, ``inverse_block`` (a Schur-complement
compliance) and ``LinearSolverBackend``; they are re-exported here.
"""

from fe.linalg.sparse import Factorization, LinearSolverBackend, inverse_block

__all__ = ["Factorization", "LinearSolverBackend", "inverse_block"]
