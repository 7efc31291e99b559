"""Errors name the command-line option the user typed, not only the internal field."""

from __future__ import annotations

import pytest

from studies.cli.main import main


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (
            ["sweep", "--amplitude", "100,-5"],
            "--amplitude must be in (0, 1e+06], got -5.0",
        ),
        (["sweep", "--mu", "-1"], "--mu must be in [0, 2], got -1.0"),
        (
            ["sweep", "--clearance", "0,-0.1"],
            "--clearance must be in [0, 5], got -0.1",
        ),
        (["cycle", "--clearance", "9"], "--clearance must be in [0, 5], got 9.0"),
        (["cycle", "--amplitude", "-1"], "--amplitude must be in (0, 1e+06]"),
        (
            ["sweep", "--hinge", "bearing", "--preload", "0,600"],
            "--preload must be in [0, 500], got 600.0",
        ),
        (
            ["sweep", "--hinge", "bearing", "--clearance", "0.1"],
            "--clearance is not a design variable of the bearing hinge (got --clearance 0.1); "
            "its design variables: preload_n",
        ),
        (["sweep", "--preload", "100"], "--preload is not a design variable of the general hinge"),
        (
            ["sweep", "--interfaces", "contact"],
            "--interfaces does not apply to the general hinge (got --interfaces contact); it is a param",
        ),
    ],
    ids=[
        "sweep-amplitude",
        "sweep-mu",
        "sweep-clearance",
        "cycle-clearance",
        "cycle-amplitude",
        "bearing-preload-range",
        "bearing-clearance",
        "preload-on-general",
        "interfaces-on-general",
    ],
)
def test_bad_option_is_named(tmp_path, capsys, argv, needle):
    assert main([*argv, "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert needle in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()  # refused before anything was built or written


@pytest.mark.slow  # 10 s; the resume logic is the general sweep's, tested fast there
def test_bearing_sweep_is_preload_by_amplitude_and_resumes(tmp_path, capsys):
    import csv

    argv = ["sweep", "--hinge", "bearing", "--preload", "0,100", "--amplitude", "300"]
    argv += ["--size", "4", "--contact-size", "0.8", "--out", str(tmp_path), "--json"]
    assert main(argv) == 0
    with (tmp_path / "table.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert sorted((float(r["preload_N"]), float(r["amplitude_N"])) for r in rows) == [
        (0.0, 300.0),
        (100.0, 300.0),
    ]
    assert "clearance_mm" not in rows[0]
    assert all(abs(float(r["eta"])) < 1e-4 for r in rows)  # bonded: nothing dissipates
    # the preload stiffens the hinge
    k = {float(r["preload_N"]): float(r["secant_stiffness_N_per_mm"]) for r in rows}
    assert k[100.0] > 1.3 * k[0.0]
    labels = sorted(p.name.rsplit("-", 1)[0] for p in (tmp_path / "points").iterdir())
    assert labels == ["p0_F300", "p100_F300"]  # each folder: label-<result key>
    capsys.readouterr()
    assert main(argv) == 0  # a rerun computes nothing
    import json

    assert json.loads(capsys.readouterr().out)["skipped"] == 2
