"""The architecture as tests: the layer and no-cycle contracts, and module size."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from importlinter.cli import lint_imports

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("cad", "mesh", "fe", "model", "rsm", "studies", "validation")

MAX_LINES = 500
"""A module longer than this is split by concept (shared/STYLE.md, section 1)."""

OVER_LIMIT: dict[str, int] = {}
"""Modules allowed over the limit, with their length: each may only shrink; a new module
over the limit fails. Empty since issue 31 split the last five."""


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


KIND_BRANCH = re.compile(
    r"""\bkind\s*[!=]=\s*["']"""  # spec.kind == "bearing"
    r"""|[!=]=\s*["'](general|bearing)["']"""  # hinge != "general"
    r"""|["'](general|bearing)["']\s*[!=]="""
    r"""|\(\s*["']general["']\s*,\s*["']bearing["']\s*\)"""  # kind in ("general", "bearing")
    r"""|isinstance\([^)]*(System|HingeParams)\b"""  # isinstance(system, BearingSystem)
)
"""A branch on the hinge kind: a kind name compared, or a kind's system or parameters tested."""

KIND_PACKAGES = ("fe/general/", "fe/bearing/", "fe/kinds/")
"""Where a kind may look at itself: its own mechanics and its registered object."""


def test_no_branch_on_the_hinge_kind_outside_the_kinds() -> None:
    """The rest of the code asks the registry (fe.kinds) and the kind, never compares kinds."""
    found = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel.startswith(KIND_PACKAGES):
                continue
            for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                if KIND_BRANCH.search(line):
                    found.append(f"{rel}:{n}: {line.strip()}")
    assert not found, "branches on the hinge kind:\n" + "\n".join(found)


def test_the_kind_branch_pattern_catches_what_it_is_for() -> None:
    caught = [
        'if spec.kind == "bearing":',
        'bearing = args.hinge == "bearing"',
        'if kind not in ("general", "bearing"):',
        "if isinstance(system, BearingSystem | FitSystem):",
        "elif isinstance(spec.hinge, GeneralHingeParams):",
    ]
    allowed = [
        'kind = hinge_kind("bearing")',
        'if design_type == "full_factorial":',
        'for name in ("general", "modified"):  # the paper\'s two cases',
    ]
    assert all(KIND_BRANCH.search(line) for line in caught)
    assert not any(KIND_BRANCH.search(line) for line in allowed)


def test_readme_command_table_names_every_command_and_only_those() -> None:
    from studies.cli.main import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    commands = set(sub.choices)
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = text.split("## Command line", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    named = set(re.findall(r"^hingelab ([a-z][a-z-]*)", block, re.M))
    assert named == commands, f"README lists {sorted(named)}, the CLI has {sorted(commands)}"


def test_architecture_md_names_files_and_modules_that_exist() -> None:
    text = (ROOT / "ARCHITECTURE.md").read_text(encoding="utf-8")
    paths = set(
        re.findall(r"`((?:cad|mesh|fe|model|rsm|studies|validation|tests)/[\w/]+\.py)`", text)
    )
    assert paths, "ARCHITECTURE.md names no file"
    missing = sorted(p for p in paths if not (ROOT / p).is_file())
    assert not missing, f"ARCHITECTURE.md names files that do not exist: {missing}"
    names = set(re.findall(r"`((?:fe|model|studies|mesh)\.[\w.]+)`", text))
    absent = sorted(n for n in names if not _resolves(n))
    assert not absent, f"ARCHITECTURE.md names modules or objects that do not exist: {absent}"


def _resolves(dotted: str) -> bool:
    """True if ``dotted`` is a module, or an attribute path inside one."""
    import importlib

    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


INSTALL_COMMAND = re.compile(
    r"""["'](?:apt-get|apt|pip|dpkg)["']\s*,\s*["'](?:install|update|-i)["']"""
)
"""A subprocess argument list that installs packages, e.g. ``["apt-get", "install", ...]``."""


def test_no_test_installs_packages() -> None:
    """Installs belong in `make peers`, not in tests: a test skips with the command instead."""
    offenders = [
        str(p.relative_to(ROOT))
        for p in (ROOT / "tests").rglob("*.py")
        if p.name != "test_architecture.py"
        and INSTALL_COMMAND.search(p.read_text(encoding="utf-8"))
    ]
    assert not offenders, f"tests that install packages: {offenders}"


def test_install_pattern_catches_an_install() -> None:
    assert INSTALL_COMMAND.search('subprocess.run(["apt-get", "install", "-y", "chromium"])')
    assert INSTALL_COMMAND.search("cmd = ['pip', 'install', 'x']")
    assert not INSTALL_COMMAND.search('pytest.skip("run `make peers` to install it")')
