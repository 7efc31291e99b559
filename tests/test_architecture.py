"""The architecture as tests: the layer and no-cycle contracts, and module size."""

from __future__ import annotations

from pathlib import Path

import pytest
from importlinter.cli import lint_imports

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("cad", "mesh", "fe", "model", "rsm", "studies", "validation")

MAX_LINES = 500
"""A module longer than this is split by concept (shared/STYLE.md, section 1)."""

OVER_LIMIT = {
    "fe/hinge/system.py": 727,
    "fe/contact/krylov.py": 564,
    "fe/bearing/cycle.py": 529,
    "fe/interop/inp.py": 526,
    "fe/contact/newton.py": 510,
    "validation/diagnose.py": 529,
}
"""Modules over the limit when the limit came in, with their length then: each may only
shrink (issue 31 splits them); a new module over the limit fails."""


def test_import_contracts_hold(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(ROOT)
    code = lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True, no_logo=True)
    assert code == 0, capsys.readouterr().out


def test_modules_stay_under_the_size_limit() -> None:
    too_long = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            n = len(path.read_text(encoding="utf-8").splitlines())
            if n > OVER_LIMIT.get(rel, MAX_LINES):
                too_long[rel] = n
    assert not too_long, (
        f"modules over {MAX_LINES} lines (or grown past their old length): {too_long}"
    )
