"""``hingelab cycle`` end to end on a coarse mesh: files, JSON keys, clear errors."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from studies.cli.main import main

COARSE = ["--size", "4", "--contact-size", "2", "--increments", "6"]


def test_cycle_json_files_and_loop_csv(tmp_path, capsys):
    argv = [
        "cycle",
        "--clearance",
        "0.05",
        "--amplitude",
        "300",
        "--mu",
        "0.15",
        *COARSE,
        "--frames",
        "6",
        "--out",
        str(tmp_path),
        "--json",
        "--no-progress",
    ]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    for key in (
        "eta",
        "W_cycle_Nmm",
        "U_max_Nmm",
        "disp_at_peak_mm",
        "free_play_mm",
        "energy_balance_rel_err",
        "n_dof",
        "n_contact_pairs",
        "wall_s",
        "timings_s",
    ):
        assert key in out, key
    assert out["free_play_mm"] == pytest.approx(0.2)
    assert out["energy_balance_rel_err"] < 0.02
    assert {"factorisation", "condensation", "contact", "fields"} <= set(out["timings_s"])
    assert 0.0 < out["timings_s"]["fields"] < out["wall_s"]
    with open(tmp_path / "loop.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {"force_N", "displacement_mm"} <= set(rows[0])
    assert max(float(r["force_N"]) for r in rows) == pytest.approx(300.0)
    assert json.loads((tmp_path / "result.json").read_text())["eta"] == out["eta"]
    pvd = (tmp_path / "fields" / "cycle.pvd").read_text()
    assert pvd.count("<DataSet") >= 3
    # ParaView's time is the load path: increasing, the last frame at +Fg after one loop (τ = 5)
    import itertools
    import re

    import meshio

    times = [float(t) for t in re.findall(r'timestep="([^"]+)"', pvd)]
    assert all(b > a for a, b in itertools.pairwise(times))
    assert times[-1] == pytest.approx(5.0)
    last = re.findall(r'file="([^"]+)"', pvd)[-1]
    frame = meshio.read(tmp_path / "fields" / last)
    assert float(np.ravel(frame.field_data["force_N"])[0]) == pytest.approx(out["amplitude_N"])
    assert "part:pin" in frame.field_data
    assert (tmp_path / "loop.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--amplitude", "-1"], "--amplitude must be in (0, 1e+06], got -1.0"),
        (["--mu", "-0.3"], "--mu must be in [0, 2], got -0.3"),
        (
            ["--preload", "50"],
            "--preload does not apply to the general hinge (got --preload 50.0); it is a parameter of the bearing",
        ),
        (
            ["--hinge", "bearing", "--clearance", "0.1"],
            "--clearance does not apply to the bearing hinge (got --clearance 0.1); it is a parameter of the gen",
        ),
        (["--hinge", "bearing", "--preload", "600"], "--preload must be in [0, 500], got 600.0"),
        (
            ["--hinge", "bearing", "--ball-model", "full", "--interfaces", "contact"],
            "ball_model = 'full' runs with interfaces = 'bonded' only",
        ),
        (["--ball-model", "hertz"], "--ball-model does not apply to the general hinge"),
    ],
    ids=[
        "negative-amplitude",
        "negative-mu",
        "preload-on-general",
        "clearance-on-bearing",
        "preload-too-large",
        "full-balls-with-fits",
        "ball-model-on-general",
    ],
)
def test_cycle_bad_input(tmp_path, capsys, argv, needle):
    assert main(["cycle", *argv, "--out", str(tmp_path), "--no-progress"]) == 1
    assert needle in capsys.readouterr().err


def test_bearing_cycle_writes_the_common_result_and_the_balls(tmp_path, capsys):
    argv = ["cycle", "--hinge", "bearing", "--preload", "100", "--amplitude", "300"]
    argv += ["--size", "4", "--contact-size", "0.8", "--frames", "20", "--out", str(tmp_path)]
    assert main([*argv, "--json", "--no-progress"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("eta", "W_cycle_Nmm", "U_max_Nmm", "disp_at_peak_mm", "timings_s", "increments"):
        assert key in out
    assert out["hinge"] == "bearing"
    assert out["ball_model"] == "hertz"
    assert abs(out["W_cycle_Nmm"]) < 1e-4 * out["U_max_Nmm"]  # nothing dissipates
    pre = out["preload_step"]
    assert pre["dissipation_Nmm"] == 0.0
    assert 15.0 < pre["contact_angle_mean_deg"] < 20.0  # Jones: 17.9° at 100 N, rigid rings
    plus = out["balls"]["plus_Fg"]
    assert len(plus) == 20
    # the ball at azimuth 0 (toward the load) carries the most; inner = outer load
    loads = [b["inner_load_N"] for b in plus if b["bearing"] == 0]
    assert loads[0] == max(loads)
    assert all(b["inner_load_N"] == b["outer_load_N"] for b in plus)
    assert (tmp_path / "fields" / "cycle.pvd").is_file()
    import meshio

    frame = meshio.read(next((tmp_path / "fields").glob("step_*.vtu")))
    assert "ball_load" in frame.point_data


@pytest.mark.slow
def test_bearing_cycle_with_frictional_fits_dissipates(tmp_path, capsys):
    argv = ["cycle", "--hinge", "bearing", "--interfaces", "contact", "--preload", "100"]
    argv += ["--size", "4", "--contact-size", "0.8", "--increments", "10", "--out", str(tmp_path)]
    assert main([*argv, "--json", "--no-progress"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["interfaces"] == "contact"
    assert out["n_contact_points"] > 100
    assert out["eta"] > 1e-3  # the bonded hinge: |η| < 3e-5
    assert out["energy_balance_rel_err"] < 0.05
    assert (tmp_path / "loop.csv").is_file()


@pytest.mark.slow
def test_bearing_cycle_with_full_balls_writes_the_same_result(tmp_path, capsys, monkeypatch):
    """--ball-model full through the same command: the same JSON keys and files as hertz.

    The rig at MESH_LEVELS[0] (built in ~4 s, cached under tmp_path) keeps this a minute.
    """
    from fe.bearing import ball_rig

    monkeypatch.setattr(ball_rig, "DEFAULT_RIG_LEVEL", 0)
    monkeypatch.setattr(ball_rig, "_MEMO", {})  # not a rig another test kept in memory
    monkeypatch.setenv("HINGELAB_CACHE_DIR", str(tmp_path / "cache"))
    argv = ["cycle", "--hinge", "bearing", "--ball-model", "full", "--preload", "100"]
    argv += ["--size", "4", "--contact-size", "0.8", "--increments", "10", "--frames", "20"]
    assert main([*argv, "--out", str(tmp_path), "--json", "--no-progress"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["ball_model"] == "full"
    for key in ("eta", "W_cycle_Nmm", "U_max_Nmm", "disp_at_peak_mm", "balls", "preload_step"):
        assert key in out
    assert out["preload_step"]["dissipation_Nmm"] == 0.0
    assert out["energy_balance_rel_err"] < 1e-4
    assert out["ball_friction_work_loop_Nmm"] >= 0.0
    plus = out["balls"]["plus_Fg"]
    loads = [b["inner_load_N"] for b in plus if b["bearing"] == 0]
    assert loads[0] == max(loads)
    assert (tmp_path / "fields" / "cycle.pvd").is_file()
    assert (tmp_path / "loop.csv").is_file()
    assert list((tmp_path / "cache").glob("ball_rig_*.npz"))


MODEL = """[hinge]
kind = "general"
clearance_mm = 0.05

[mesh]
size_mm = 4.0
contact_size_mm = 2.0

[friction]
mu = 0.15

[cycle]
amplitude_n = 250.0
increments_per_stage = 6
"""


def test_cycle_runs_a_model_file_and_takes_overrides(tmp_path, capsys):
    model = tmp_path / "MODEL.toml"
    model.write_text(MODEL)
    argv = [
        "cycle",
        "--model",
        str(model),
        "--out",
        str(tmp_path / "o"),
        "--frames",
        "0",
        "--json",
        "--no-progress",
    ]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["amplitude_N"], out["mu"], out["clearance_mm"]) == (250.0, 0.15, 0.05)
    assert main([*argv, "--amplitude", "120"]) == 0
    assert json.loads(capsys.readouterr().out)["amplitude_N"] == 120.0


@pytest.mark.parametrize(
    ("text", "needle"),
    [(MODEL.replace("mu = 0.15", "mu = -1"), "mu"), (MODEL + "\n[hinge2]\nx = 1\n", "hinge2")],
    ids=["out-of-range", "unknown-section"],
)
def test_cycle_refuses_bad_model_files(tmp_path, capsys, text, needle):
    model = tmp_path / "MODEL.toml"
    model.write_text(text)
    assert (
        main(["cycle", "--model", str(model), "--out", str(tmp_path / "o"), "--no-progress"]) == 1
    )
    assert needle in capsys.readouterr().err


def test_model_file_excludes_geometry_options(tmp_path, capsys):
    model = tmp_path / "MODEL.toml"
    model.write_text(MODEL)
    assert main(["cycle", "--model", str(model), "--clearance", "0.1", "--out", str(tmp_path)]) == 1
    assert "--clearance" in capsys.readouterr().err


def test_cycle_model_file_with_an_effect(tmp_path, capsys):
    # series compliance of the frame: same loop area, δ(+Fg) larger by exactly C_f·Fg
    base = tmp_path / "BASE.toml"
    base.write_text(MODEL.replace("clearance_mm = 0.05", "clearance_mm = 0.0"))
    framed = tmp_path / "FRAMED.toml"
    framed.write_text(
        base.read_text() + "\n[effects.frame_compliance]\ncompliance_mm_per_n = 1e-5\n"
    )
    out = []
    for model in (base, framed):
        argv = [
            "cycle",
            "--model",
            str(model),
            "--out",
            str(tmp_path / model.stem),
            "--frames",
            "0",
            "--json",
        ]
        assert main([*argv, "--no-progress"]) == 0
        out.append(json.loads(capsys.readouterr().out))
    assert out[1]["disp_at_peak_mm"] == pytest.approx(
        out[0]["disp_at_peak_mm"] + 1e-5 * 250.0, rel=1e-9
    )
    assert out[1]["W_cycle_Nmm"] == pytest.approx(out[0]["W_cycle_Nmm"], rel=1e-6)
    assert out[1]["eta"] < out[0]["eta"]


@pytest.mark.slow  # 24 s: a frictional-fit cycle of the coarse bearing hinge
def test_cycle_summary_of_the_structure_interface_friction_makes(tmp_path):
    """interface_friction turns the bonded fits into contacts: the summary is the fits' one."""
    import json
    from pathlib import Path

    example = Path(__file__).parents[3] / "studies" / "examples" / "MODEL_bearing.toml"
    text = example.read_text().replace(
        "[cycle]", "[effects.interface_friction]\nmu_interface = 0.2\n\n[cycle]"
    )
    model = tmp_path / "MODEL.toml"
    model.write_text(text)
    out = tmp_path / "out"
    assert (
        main(
            [
                "cycle",
                "--model",
                str(model),
                "--increments",
                "8",
                "--frames",
                "0",
                "--out",
                str(out),
                "--json",
            ]
        )
        == 0
    )
    summary = json.loads((out / "result.json").read_text())
    assert summary["interfaces"] == "contact"
    assert summary["W_cycle_Nmm"] > 0  # the fits dissipate
