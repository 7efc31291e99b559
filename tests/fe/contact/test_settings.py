"""ContactSettings.lu_threads: the LU thread count as a setting, the environment read at call time."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info

from cad.errors import ParameterError
from fe.contact import dense as contact_dense
from fe.contact.dense import LU_THREADED_MIN, factor_jacobian, lu_threads
from fe.contact.state import ContactSettings, ContactState


def test_setting_wins_over_the_environment(monkeypatch):
    monkeypatch.setenv("HINGELAB_LU_THREADS", "3")
    assert lu_threads(1) == 1
    assert lu_threads(None) == 3


def test_environment_is_read_at_call_time_not_at_import(monkeypatch):
    from fe.contact.newton import LU_THREADS as before  # the name studies/sweep.py imports

    monkeypatch.setenv("HINGELAB_LU_THREADS", str(before + 4))
    from fe.contact.newton import LU_THREADS as after

    assert after == before + 4 == lu_threads()


@pytest.mark.parametrize("value", [0, -2])
def test_bad_lu_threads_setting_names_the_parameter(value):
    with pytest.raises(ParameterError, match=f"lu_threads.*{value}"):
        ContactSettings(lu_threads=value)


def test_factor_uses_the_given_thread_count(monkeypatch):
    seen = []
    real = contact_dense.threadpool_limits

    def spy(limits, user_api):
        seen.append(limits)
        return real(limits=limits, user_api=user_api)

    monkeypatch.setattr(contact_dense, "threadpool_limits", spy)
    n = LU_THREADED_MIN
    J = np.eye(n) + 0.01 * np.random.default_rng(0).standard_normal((n, n))
    assert factor_jacobian(J.copy(), np.arange(n, dtype=np.int64), threads=2) is not None
    assert factor_jacobian(J[:10, :10].copy(), np.arange(10, dtype=np.int64), threads=2) is not None
    assert seen == [2]  # only the large LU is threaded
    assert threadpool_info()  # the BLAS is visible to threadpoolctl


def _blas_threads():
    return {i["filepath"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def test_large_products_run_on_the_lu_threads_small_ones_on_the_callers():
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        outside = _blas_threads()
        with contact_dense.wide(contact_dense.PRODUCT_THREADED_MIN, threads=2):
            assert set(_blas_threads().values()) == {2}
        with contact_dense.wide(contact_dense.PRODUCT_THREADED_MIN - 1, threads=2):
            assert _blas_threads() == outside
        with contact_dense.wide(contact_dense.PRODUCT_THREADED_MIN, threads=1):
            assert _blas_threads() == outside
        assert _blas_threads() == outside  # restored on leaving
    assert set(outside.values()) == {1}


def test_products_give_the_same_numbers_on_two_threads():
    """A threaded product may sum in another order: equal to round-off, not bitwise."""
    from fe.contact.residual import sparse_product

    rng = np.random.default_rng(3)
    n = 1200  # (3 n)² entries > PRODUCT_THREADED_MIN
    W = rng.standard_normal((3 * n, 3 * n))
    W = 0.5 * (W + W.T)
    x = np.zeros((n, 3))
    x[rng.choice(n, n // 2, replace=False)] = rng.standard_normal((n // 2, 3))
    np.testing.assert_allclose(sparse_product(W, x, threads=2), W @ x.ravel(), atol=1e-10)
    np.testing.assert_allclose(sparse_product(W, x, threads=1), W @ x.ravel(), atol=1e-10)


def _counted_sums(monkeypatch, W):
    """Count the passes of ``np.sum`` over ``W`` (the fingerprint's)."""
    calls = []
    total = np.sum

    def counted(a, *args, **kwargs):
        if a is W:
            calls.append(1)
        return total(a, *args, **kwargs)

    monkeypatch.setattr(np, "sum", counted)
    return calls


def test_a_frozen_W_is_summed_once_a_writeable_one_every_time(monkeypatch):
    from fe.contact.state import fingerprint

    W = np.arange(36.0).reshape(6, 6).copy()  # owns its data
    calls = _counted_sums(monkeypatch, W)
    first = fingerprint(W)
    W[0, 0] += 1.0  # writeable: a change in place must show
    assert fingerprint(W) == first + 1.0
    assert len(calls) == 2
    W.setflags(write=False)
    frozen = fingerprint(W)
    assert fingerprint(W) == frozen == first + 1.0
    assert len(calls) == 3  # the second call of the frozen W reused the sum


def test_a_read_only_view_of_a_writeable_array_is_not_frozen(monkeypatch):
    from fe.contact.state import fingerprint

    base = np.ones((6, 6))
    view = base[:, :]
    view.setflags(write=False)
    calls = _counted_sums(monkeypatch, view)
    assert fingerprint(view) == 36.0
    base[1, 1] = 2.0  # reaches the view's data
    assert fingerprint(view) == 37.0
    assert len(calls) == 2


def test_a_frozen_W_is_still_refused_when_not_finite_at_every_call():
    from fe.contact.state import validate_problem

    W = np.eye(3)
    W[1, 1] = np.nan
    W.setflags(write=False)
    with pytest.raises(ParameterError, match="W and w_free must be finite"):
        validate_problem(W, np.zeros((1, 3)), ContactState.initial(1), None, None)
    with pytest.raises(ParameterError, match="W and w_free must be finite"):
        validate_problem(W, np.zeros((1, 3)), ContactState.initial(1), None, None)
