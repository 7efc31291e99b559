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
