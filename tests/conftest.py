"""Fixtures shared across the test packages."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from fe.kinds import hinge_kind, unregister_hinge_kind

PLUGINS = Path(__file__).parent / "plugins"
"""A package outside hingelab that registers a hinge kind by entry point (README there)."""

EFFECT_PLUGINS = PLUGINS / "effects"
"""A package outside hingelab that registers an effect by entry point (README there)."""


@pytest.fixture(scope="session", autouse=True)
def _one_blas_thread():  # type: ignore[no-untyped-def]
    """The tests run their BLAS (OpenBLAS, MKL) on one thread, as the cycles' contact phase does.

    Outside the cycles' own ``threadpool_limits`` (the nodal compliances, the condensation,
    the field recovery) the BLAS otherwise starts a thread per core. With the 2 cores shared
    by other processes, those threads wait on each other: a coarse general cycle took 12 s
    with 2 threads and 2 s with 1 (compliance 10.1 s vs 0.21 s; load average 3.6 on
    2 cores). Tests that check the threaded paths ask for their thread count explicitly
    (``fe.contact.dense.wide``, ``factor_jacobian(..., threads=2)``), which still applies
    inside this limit.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield


@pytest.fixture(autouse=True)
def _effects_registered_by_a_test_are_forgotten():  # type: ignore[no-untyped-def]
    """A user's effect registered in one test (a MODEL.toml ``from``) is not seen by the next."""
    from fe.effects.registry import effect_names, unregister_effect

    before = set(effect_names())
    yield
    for name in set(effect_names()) - before:
        unregister_effect(name)


@pytest.fixture
def grips(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """The plug-in effect ``grip_compliance``, visible through its entry point for one test."""
    from fe.effects.registry import unregister_effect

    monkeypatch.syspath_prepend(str(EFFECT_PLUGINS))
    yield "grip_compliance"
    unregister_effect("grip_compliance")
    sys.modules.pop("hingelab_grips", None)


@pytest.fixture
def jenkins(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """The plug-in kind ``jenkins_pin``, visible through its entry point for one test."""
    monkeypatch.syspath_prepend(str(PLUGINS))
    yield hinge_kind("jenkins_pin")
    unregister_hinge_kind("jenkins_pin")
    sys.modules.pop("hingelab_jenkins", None)
