"""``hingelab mesh`` end to end: files written, JSON summary, clear errors."""

from __future__ import annotations

import json

import pytest

from studies.cli.main import main


def test_mesh_json_and_files(tmp_path, capsys):
    assert (
        main(["mesh", "--hinge", "general", "--clearance", "0.1", "--out", str(tmp_path), "--json"])
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert set(out["parts"]) == {"tang", "clevis", "pin"}
    for key in ("n_nodes", "hex_fraction", "min_scaled_jacobian", "sets", "wall_s"):
        assert key in out
    assert out["hex_fraction"] == 1.0
    assert all(n > 0 for n in out["sets"].values())
    for name in ("hinge.step", "mesh.msh", "mesh.vtu", "mesh.png"):
        assert (tmp_path / name).stat().st_size > 1000, name
    png = (tmp_path / "mesh.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--clearance", "-0.2"], "--clearance must be in [0, 5], got -0.2"),
        (["--refinement", "9"], "--refinement must be an integer in [0, 4], got 9"),
        (["--hinge", "general", "--preload", "50"], "preload"),
    ],
    ids=["negative-clearance", "refinement", "preload-on-general"],
)
def test_bad_parameter_exits_1_with_message(tmp_path, capsys, argv, needle):
    assert main(["mesh", *argv, "--out", str(tmp_path), "--no-picture"]) == 1
    err = capsys.readouterr().err
    assert needle in err
    assert "error" in err


@pytest.mark.slow
def test_bearing_hinge_mesh_on_defaults(tmp_path, capsys):
    assert (
        main(["mesh", "--hinge", "bearing", "--preload", "150", "--out", str(tmp_path), "--json"])
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert out["hex_fraction"] == 1.0
    assert out["min_scaled_jacobian"] > 0
    balls = [p for p in out["parts"] if p.startswith("ball_")]
    assert len(balls) == 2 * 10
    assert all(n > 0 for n in out["sets"].values())
    assert out["wall_s"] < 300
