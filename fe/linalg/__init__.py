"""Sparse linear algebra: the SPD direct solver (MKL PARDISO or SciPy SuperLU).

:mod:`fe.linalg.sparse` holds ``Factorization``, ``inverse_block`` (a Schur-complement
compliance) and ``LinearSolverBackend``.
"""
