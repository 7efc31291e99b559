"""``hingelab study`` on a bearing model: the shipped 2 × 2 preload × amplitude example, end to end."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from model.code import code_version
from studies.cli.main import main

EXAMPLE = Path(__file__).parents[3] / "studies" / "examples" / "bearing_coarse_2x2.toml"
POINTS = [(0.0, 200.0), (0.0, 400.0), (200.0, 200.0), (200.0, 400.0)]


@pytest.mark.slow
def test_bearing_study_runs_traces_fits_and_reads_every_point_back(tmp_path, capsys):
    """One setup of the tied coarse bearing model shared by both preloads (~10-14 s on two
    loaded cores), four cycles of hundredths of a second; the reruns compute nothing.
    21 s in all on the first run: slow."""
    out = tmp_path / "out"
    argv = ["study", str(EXAMPLE), "--out", str(out)]
    assert main([*argv, "--json", "--no-plots"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert (first["hinge"], first["variables"]) == ("bearing", ["preload_N", "amplitude_N"])
    assert (first["n_points"], first["computed"], first["failed"]) == (4, 4, 0)
    assert first["surface"]["x"] == ["preload_N", "amplitude_N"]

    with (out / "table.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert "clearance_mm" not in rows[0]
    assert sorted((float(r["preload_N"]), float(r["amplitude_N"])) for r in rows) == POINTS
    eta = {(float(r["preload_N"]), float(r["amplitude_N"])): float(r["eta"]) for r in rows}
    assert all(abs(v) < 1e-3 for v in eta.values())  # the tied model dissipates next to nothing

    pid = int(rows[-1]["point_id"])
    assert main(["trace", str(out / "trace.sqlite"), str(pid), "--json"]) == 0
    t = json.loads(capsys.readouterr().out)
    assert t["study"] == "bearing_coarse_2x2"
    assert t["params"] == {"preload_N": float(rows[-1]["preload_N"]), "amplitude_N": 400.0}
    assert t["status"] == "ok"
    assert t["solver"]["result_key"]
    assert t["solver"]["code"] == code_version().short()
    assert t["intact"]

    # a rerun finds every point in the trace; without the trace, every point in results/
    assert main([*argv, "--json", "--no-plots"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert (again["computed"], again["already_done"], again["failed"]) == (0, 4, 0)
    (out / "trace.sqlite").unlink()
    assert main([*argv, "--no-plots"]) == 0
    captured = capsys.readouterr()
    assert "0 computed, 4 read back" in captured.out
    assert "[4/4] F_p = " in captured.err
    assert "Δr" not in captured.err + captured.out
    with (out / "table.csv").open() as f:
        back = {
            (float(r["preload_N"]), float(r["amplitude_N"])): float(r["eta"])
            for r in csv.DictReader(f)
        }
    assert back == eta  # read back bit for bit


def test_bearing_study_next_command_fits_preload_and_amplitude(tmp_path, capsys):
    """Without a [surface] the summary names ``rsm fit`` with the bearing's x (no FE run:
    the points are already in the trace of a stubbed sweep)."""
    from studies.cli import study as cmd_study
    from studies.study_file import read_study

    study = read_study(EXAMPLE)

    class Outcome:
        failed, ok, cached, skipped, wall_s = 0, 4, 0, 0, 1.0
        db, table = tmp_path / "trace.sqlite", tmp_path / "table.csv"

    class Args:
        out = tmp_path

    s = cmd_study._summary(study, Outcome(), None, Args())  # type: ignore[arg-type]
    assert "--x preload_N,amplitude_N" in s["next"]
