import sqlite3

import numpy as np
import pytest

from cad.errors import DataError, ParameterError
from rsm import trace, trace_store
from rsm.metrics import fit_metrics
from rsm.polynomial import fit_response_surface
from rsm.tables import read_xy


def _run(tmp_path, k, clearance, force, eta):
    d = tmp_path / "runs" / f"p{k:03d}"
    d.mkdir(parents=True)
    files = {}
    for kind, name in [
        ("step", "hinge.step"),
        ("mesh_msh", "mesh.msh"),
        ("mesh_png", "mesh.png"),
        ("loop_csv", "loop.csv"),
        ("loop_png", "loop.png"),
    ]:
        (d / name).write_text(f"{kind} of point {k}\n", encoding="utf-8")
        files[kind] = d / name
    return trace_store.record_point(
        tmp_path / "trace.sqlite",
        study="general-5x5",
        params={"clearance_mm": clearance, "amplitude_N": force},
        artifacts=files,
        mesh_stats={"n_nodes": 1200, "n_elem": 800, "min_scaled_jacobian": 0.62},
        solver={"n_increments": 40, "friction": 0.2},
        convergence={"iterations": [3, 4, 3], "max_residual": 1e-9},
        results={"eta": eta, "w_cycle_mj": 0.12},
    )


def test_round_trip(tmp_path):
    pid = _run(tmp_path, 1, 0.1, 200.0, 0.0989)
    t = trace.walk(tmp_path / "trace.sqlite", pid)
    assert t.params == {"clearance_mm": 0.1, "amplitude_N": 200.0}
    assert [a.kind for a in t.artifacts] == ["step", "mesh_msh", "mesh_png", "loop_csv", "loop_png"]
    assert t.intact
    assert t.mesh_stats["n_elem"] == 800
    assert t.convergence["iterations"] == [3, 4, 3]
    assert t.results["eta"] == 0.0989
    assert t.artifacts[0].recorded_path == "runs/p001/hinge.step"  # relative to the DB folder
    text = trace.format_trace(t)
    assert (
        text.index("step") < text.index("mesh_msh") < text.index("solver") < text.index("loop_csv")
    )


def test_moved_and_changed_files_are_reported(tmp_path):
    pid = _run(tmp_path, 1, 0.1, 200.0, 0.0989)
    (tmp_path / "runs" / "p001" / "mesh.png").rename(tmp_path / "elsewhere.png")
    (tmp_path / "runs" / "p001" / "loop.csv").write_text("edited\n", encoding="utf-8")
    t = trace.walk(tmp_path / "trace.sqlite", pid)
    states = {a.kind: a.state for a in t.artifacts}
    assert states["mesh_png"] is trace.ArtifactState.MISSING
    assert states["loop_csv"] is trace.ArtifactState.CHANGED
    assert states["step"] is trace.ArtifactState.OK
    assert not t.intact
    text = trace.format_trace(t)
    assert "MISSING" in text
    assert "moved or deleted" in text
    assert "CHANGED" in text


def test_whole_study_folder_can_move(tmp_path):
    pid = _run(tmp_path / "a", 1, 0.1, 200.0, 0.0989)
    (tmp_path / "a").rename(tmp_path / "b")
    assert trace.walk(tmp_path / "b" / "trace.sqlite", pid).intact


def test_failed_point_and_validation(tmp_path):
    db = tmp_path / "trace.sqlite"
    pid = trace_store.record_point(
        db,
        study="s",
        params={"clearance_mm": 0.4},
        status="failed",
        error="Newton did not converge at increment 12",
    )
    t = trace.walk(db, pid)
    assert t.status == "failed"
    assert "increment 12" in (t.error or "")
    with pytest.raises(ParameterError, match="error must be given"):
        trace_store.record_point(db, study="s", params={"a": 1.0}, status="failed")
    with pytest.raises(FileNotFoundError, match="artifact 'step'"):
        trace_store.record_point(
            db, study="s", params={"a": 1.0}, artifacts={"step": tmp_path / "no.step"}
        )


def test_walk_unknown_point_and_missing_db(tmp_path):
    _run(tmp_path, 1, 0.1, 200.0, 0.0989)
    with pytest.raises(DataError, match="no point 99"):
        trace.walk(tmp_path / "trace.sqlite", 99)
    with pytest.raises(FileNotFoundError):
        trace.walk(tmp_path / "absent.sqlite", 1)
    assert not (tmp_path / "absent.sqlite").exists()  # walking never creates a database


def test_export_fit_and_record_fit(tmp_path):
    levels = [(c, f) for c in (0.0, 0.2, 0.4) for f in (100.0, 300.0, 500.0)]
    ids = [
        _run(tmp_path, k, c, f, 0.05 + 0.1 * c - 1e-4 * f + 2e-7 * f * f)
        for k, (c, f) in enumerate(levels)
    ]
    db = tmp_path / "trace.sqlite"
    table = trace.export_table(db, tmp_path / "table.csv", study="general-5x5")
    xy = read_xy(table, ["clearance_mm", "amplitude_N"], "eta")
    assert xy.labels == tuple(f"point {i}" for i in ids)
    s = fit_response_surface(xy.x, xy.y, 2, x_names=xy.x_names, labels=xy.labels)
    fid = trace_store.record_fit(db, surface=s, metrics=fit_metrics(s, warn=False), point_ids=ids)
    assert trace.walk(db, ids[3]).fit_ids == (fid,)
    with sqlite3.connect(db) as con:
        n = con.execute("SELECT count(*) FROM fit_points WHERE fit_id = ?", (fid,)).fetchone()[0]
    assert n == len(ids)
    with pytest.raises(DataError, match="not in the trace"):
        trace_store.record_fit(
            db, surface=s, metrics=fit_metrics(s, warn=False), point_ids=[*ids[:-1], 999]
        )
    assert np.isfinite(s.condition_number)


def _backdate_step(path, stamp=b"2001-01-01T00:00:00"):
    """Give a STEP file the header of an export made long ago (as by an earlier run)."""
    import re

    data = re.sub(rb"(FILE_NAME\('[^']*',')[^']*", rb"\g<1>" + stamp, path.read_bytes(), count=1)
    path.write_bytes(data)
    return data


def test_a_rerun_rewriting_an_unchanged_step_is_not_changed_a_new_geometry_is(tmp_path):
    """The geometry of a rerun is exported again: the trace flags only a real change.

    OpenCASCADE writes the time of export into the STEP header, so before the fix every
    rerun replaced hinge.step with new bytes and the trace called it CHANGED.
    """
    import os

    from cad.general import make_general_hinge
    from cad.general_params import GeneralHingeParams
    from cad.step import write_step

    step = tmp_path / "geometry" / "c0.000" / "hinge.step"
    step.parent.mkdir(parents=True)
    model = make_general_hinge(GeneralHingeParams(clearance_mm=0.0))
    first = _backdate_step(write_step(model, step))
    db = tmp_path / "trace.sqlite"
    pid = trace_store.record_point(
        db, study="s", params={"clearance_mm": 0.0}, artifacts={"step": step}
    )
    write_step(model, step)  # the rerun: same geometry, exported now
    os.utime(step, (1e9, 2e9))  # and a modification time of its own: not looked at
    assert step.read_bytes() == first
    (a,) = trace.walk(db, pid).artifacts
    assert a.state is trace.ArtifactState.OK, a.message
    write_step(make_general_hinge(GeneralHingeParams(clearance_mm=0.2)), step)  # another geometry
    (a,) = trace.walk(db, pid).artifacts
    assert a.state is trace.ArtifactState.CHANGED
    assert "has changed since it was recorded" in a.message
    assert not list(step.parent.glob(".*tmp*"))  # no temporary file left behind
