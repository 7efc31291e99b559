"""ContactSettings.lu_threads: the LU thread count as a setting, the environment read at call time."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info

from cad.errors import ParameterError
from fe.contact import ContactSettings
from fe.contact import dense as contact_dense
from fe.contact.dense import LU_THREADED_MIN, factor_jacobian, lu_threads


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
