"""Errors name the command-line option the user typed, not only the internal field."""

from __future__ import annotations

import pytest

from studies.cli import main


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["sweep", "--amplitude", "100,-5"], "--amplitude: amplitude_n must be in (0, 1e+06], got -5.0"),
        (["sweep", "--mu", "-1"], "--mu: mu must be in [0, 2], got -1.0"),
        (["sweep", "--clearance", "0,-0.1"], "--clearance: clearance_mm must be in [0, 10], got -0.1"),
        (["cycle", "--clearance", "9"], "--clearance: clearance_mm must be in [0, 5], got 9.0"),
        (["cycle", "--amplitude", "-1"], "--amplitude: amplitude_n"),
    ],
    ids=["sweep-amplitude", "sweep-mu", "sweep-clearance", "cycle-clearance", "cycle-amplitude"],
)
def test_bad_option_is_named(tmp_path, capsys, argv, needle):
    assert main([*argv, "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert needle in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()  # refused before anything was built or written
