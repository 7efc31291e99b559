"""The model service seen from the command line: files in, files out, no work lost or repeated."""

from __future__ import annotations

import csv
import json

import numpy as np

from studies.cli.main import main

FAST = ["--size", "4", "--contact-size", "2", "--increments", "6"]


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _sweep(out, *extra):
    return main(
        [
            "sweep",
            "--clearance",
            "0",
            "--amplitude",
            "300",
            *FAST,
            "--out",
            str(out),
            "--json",
            *extra,
        ]
    )


def test_compare_reads_a_model_file_with_effects(tmp_path, capsys):
    """A MODEL.toml with [effects.*] (as calibrate writes it) runs through compare from files."""
    import dataclasses

    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.file import write_model
    from model.spec import ModelSpec
    from validation.measurements import Case
    from validation.workflow import run_model_for_cases

    base = ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(increments_per_stage=6, clearance_increments=6),
    )
    spec = dataclasses.replace(base, effects={"frame_compliance": {"compliance_mm_per_n": 2e-5}})
    model = write_model(spec, tmp_path / "MODEL.toml")
    assert "[effects." in model.read_text()
    results, _ = run_model_for_cases(spec, [Case("c1", "general", {"clearance_mm": 0.0}, 300.0)])
    loop = results["c1"].loop
    data = tmp_path / "data"
    data.mkdir()
    np.savetxt(
        data / "c1.csv",
        np.column_stack([loop.force_n, loop.displacement_mm]),
        delimiter=",",
        header="force_N,displacement_mm",
        comments="",
    )
    (data / "cases.csv").write_text(
        "case_id,hinge,clearance_mm,preload_N,amplitude_N,loop_file,temperature_C\n"
        "c1,general,0,0,300,c1.csv,21\n"
    )
    out = tmp_path / "cmp"
    assert main(["compare", str(model), str(data), "--out", str(out), "--json", "--no-plots"]) == 0
    report = json.loads(capsys.readouterr().out)
    (case,) = report["cases"]
    assert case["passed"]
    # the effect is on: without it the model would be far stiffer than these data
    assert abs(case["errors"]["disp_at_peak_mm"]) < 0.01
    bare = write_model(base, tmp_path / "BARE.toml")
    assert (
        main(
            ["compare", str(bare), str(data), "--out", str(tmp_path / "b"), "--json", "--no-plots"]
        )
        == 0
    )
    (bare_case,) = json.loads(capsys.readouterr().out)["cases"]
    assert not bare_case["passed"]


def test_sweep_resumed_with_another_mu_recomputes(tmp_path, capsys):
    out = tmp_path / "s"
    assert _sweep(out) == 0
    first = json.loads(capsys.readouterr().out)
    assert (first["ok"], first["skipped"]) == (1, 0)
    eta_02 = float(_rows(out / "table.csv")[0]["eta"])
    assert _sweep(out) == 0  # identical inputs: nothing to do
    again = json.loads(capsys.readouterr().out)
    assert (again["ok"], again["skipped"]) == (0, 1)
    assert _sweep(out, "--mu", "0.1") == 0
    other = json.loads(capsys.readouterr().out)
    assert (other["ok"], other["skipped"]) == (1, 0)
    (row,) = _rows(out / "table.csv")  # this run's point only
    assert float(row["eta"]) < 0.8 * eta_02  # less friction, less loss


def test_interrupted_sweep_keeps_finished_points_and_resumes(tmp_path, monkeypatch, capsys):
    from model.service import ModelService

    real = ModelService._compute
    calls = []

    def interrupt_second(self, spec, point, prepared, progress):
        calls.append(point)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(self, spec, point, prepared, progress)

    monkeypatch.setattr(ModelService, "_compute", interrupt_second)
    out = tmp_path / "s"
    args = ["sweep", "--clearance", "0", "--amplitude", "200,400", *FAST, "--out", str(out)]
    assert main(args) == 130
    err = capsys.readouterr().err
    assert "interrupted" in err
    assert "rerun" in err
    assert "Traceback" not in err
    monkeypatch.setattr(ModelService, "_compute", real)
    assert main([*args, "--json"]) == 0
    resumed = json.loads(capsys.readouterr().out)
    assert (resumed["ok"], resumed["skipped"]) == (1, 1)  # the first point was kept
    assert sorted(float(r["amplitude_N"]) for r in _rows(out / "table.csv")) == [200.0, 400.0]


def test_duplicate_levels_run_once(tmp_path, capsys):
    out = tmp_path / "s"
    args = [
        "sweep",
        "--clearance",
        "0,0.0",
        "--amplitude",
        "300,300",
        *FAST,
        "--out",
        str(out),
        "--json",
    ]
    assert main(args) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["ok"], summary["failed"], summary["skipped"]) == (1, 0, 0)
    assert len(_rows(out / "table.csv")) == 1
    assert len(list((out / "results").glob("*.npz"))) == 1
