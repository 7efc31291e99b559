"""Fixtures shared across the test packages."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from fe.kinds import hinge_kind, unregister_hinge_kind

PLUGINS = Path(__file__).parent / "plugins"
"""A package outside hingelab that registers a hinge kind by entry point (README there)."""


@pytest.fixture
def jenkins(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """The plug-in kind ``jenkins_pin``, visible through its entry point for one test."""
    monkeypatch.syspath_prepend(str(PLUGINS))
    yield hinge_kind("jenkins_pin")
    unregister_hinge_kind("jenkins_pin")
    sys.modules.pop("hingelab_jenkins", None)
