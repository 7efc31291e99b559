"""Dense LU of the reduced Jacobian: threading switch and its environment override."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from cad.errors import ParameterError
from fe.contact import newton as contact_newton
from fe.contact.dense import LU_THREADED_MIN, factor_jacobian, lu_threads_from_env


@pytest.mark.parametrize("raw", ["0", "-1", "two", ""])
def test_bad_lu_thread_count_names_the_variable(monkeypatch, raw):
    monkeypatch.setenv("HINGELAB_LU_THREADS", raw)
    with pytest.raises(ParameterError, match=f"HINGELAB_LU_THREADS.*{raw!r}"):
        lu_threads_from_env()


def test_lu_thread_count_from_environment(monkeypatch):
    monkeypatch.setenv("HINGELAB_LU_THREADS", "1")
    assert lu_threads_from_env() == 1
    monkeypatch.delenv("HINGELAB_LU_THREADS")
    assert lu_threads_from_env() == 1  # on every machine: the LU's bits depend on it


@pytest.mark.parametrize("threads", [1, 2])
def test_threaded_lu_solves_the_same_system(monkeypatch, threads):
    # above LU_THREADED_MIN the factorisation runs under a thread limit: the factor
    # must still solve J x = b (it factors Jᵀ; the Newton code solves with trans=1)
    monkeypatch.setattr(contact_newton, "LU_THREADS", threads)
    n = LU_THREADED_MIN
    rng = np.random.default_rng(1)
    J = rng.standard_normal((n, n)) + n**0.5 * np.eye(n)
    b = rng.standard_normal(n)
    f = factor_jacobian(J.copy(), np.arange(n, dtype=np.int64))
    assert f is not None
    x = sla.lu_solve(f.lu, b, trans=1)
    assert np.linalg.norm(J @ x - b) <= 1e-10 * np.linalg.norm(b)
