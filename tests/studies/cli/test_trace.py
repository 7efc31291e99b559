import json

from rsm import trace_store
from studies.cli.main import main


def _point(tmp_path):
    run = tmp_path / "study" / "runs" / "p1"
    run.mkdir(parents=True)
    arts = {}
    for kind in ("step", "mesh_msh", "mesh_png", "loop_csv", "loop_png"):
        f = run / f"{kind}.dat"
        f.write_text(kind, encoding="utf-8")
        arts[kind] = f
    db = tmp_path / "study" / "trace.sqlite"
    pid = trace_store.record_point(
        db,
        study="demo",
        params={"clearance_mm": 0.2, "amplitude_N": 300.0},
        artifacts=arts,
        mesh_stats={"n_elem": 512},
        solver={"mu": 0.2},
        convergence={"iterations": 4},
        results={"eta": 0.0841},
    )
    return db, pid, run


def test_trace_json_round_trip(tmp_path, capsys):
    db, pid, _ = _point(tmp_path)
    assert main(["trace", str(db), str(pid), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["results"]["eta"] == 0.0841
    assert data["intact"] is True
    assert [a["kind"] for a in data["artifacts"]][:3] == ["step", "mesh_msh", "mesh_png"]


def test_trace_moved_file_exit_1_with_clear_message(tmp_path, capsys):
    db, pid, run = _point(tmp_path)
    (run / "loop_png.dat").rename(tmp_path / "moved.dat")
    assert main(["trace", str(db), str(pid)]) == 1
    out = capsys.readouterr()
    assert "loop_png" in out.out
    assert "MISSING" in out.out
    assert "moved or deleted" in out.err


def test_trace_unknown_point_and_missing_db(tmp_path, capsys):
    db, _, _ = _point(tmp_path)
    assert main(["trace", str(db), "42"]) == 1
    assert "no point 42" in capsys.readouterr().err
    assert main(["trace", str(tmp_path / "nope.sqlite"), "1"]) == 1
    assert "does not exist" in capsys.readouterr().err
