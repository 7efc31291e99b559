"""A command line that never loses work: outputs checked before the work, one-line errors, strict JSON."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from model.jsonio import dumps
from studies.cli.main import main


def _no_nan(text: str) -> object:
    def refuse(name: str) -> None:
        raise AssertionError(f"non-strict JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


def _table(tmp_path: Path, n: int = 6) -> Path:
    x = np.linspace(0.0, 1.0, n)
    rows = "\n".join(f"{i + 1},{v:.6g},{1.0 + 2.0 * v + 0.5 * v * v:.9g}" for i, v in enumerate(x))
    path = tmp_path / "table.csv"
    path.write_text("point_id,x,y\n" + rows + "\n")
    return path


def _one_error_line(err: str, *needles: str) -> None:
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    for n in needles:
        assert n in err, (n, err)


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.startswith("hingelab ")


def test_help_does_not_import_the_geometry_stack():
    code = "import sys, studies.cli.main; studies.cli.main.build_parser(); print('build123d' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_dumps_is_strict():
    text = dumps(
        {"eta": float("nan"), "w": [1.0, float("inf")], "p": Path("a/b"), "n": np.float64(2.5)}
    )
    assert _no_nan(text) == {"eta": None, "w": [1.0, None], "p": "a/b", "n": 2.5}


def test_rsm_fit_json_has_no_nan(tmp_path, capsys):
    table = _table(tmp_path, n=2)  # 2 points, 2 coefficients: R²_adj and RMSE are undefined
    assert (
        main(
            [
                "rsm",
                "fit",
                str(table),
                "--x",
                "x",
                "--y",
                "y",
                "--degree",
                "1",
                "--json",
                "--no-plots",
            ]
        )
        == 0
    )
    rep = _no_nan(capsys.readouterr().out)
    assert isinstance(rep, dict)
    assert rep["metrics"]["RMSE"] is None


@pytest.mark.parametrize("alpha", ["0", "0.7", "nan"], ids=["zero", "above-half", "nan"])
def test_diagnose_alpha_range(tmp_path, capsys, alpha):
    assert main(["diagnose", str(tmp_path / "MODEL.toml"), str(tmp_path), "--alpha", alpha]) == 1
    _one_error_line(capsys.readouterr().err, "--alpha must be in (0, 0.5]", alpha)


def test_rsm_fit_checks_outputs_before_fitting(tmp_path, capsys):
    table = _table(tmp_path)
    blocker = tmp_path / "plots"
    blocker.write_text("a file where the plot folder should go")
    assert (
        main(
            [
                "rsm",
                "fit",
                str(table),
                "--x",
                "x",
                "--y",
                "y",
                "--degree",
                "2",
                "--out",
                str(blocker),
            ]
        )
        == 1
    )
    _one_error_line(capsys.readouterr().err, "--out", str(blocker))
    not_a_db = tmp_path / "notes.sqlite"
    not_a_db.write_text("my notes")
    args = ["rsm", "fit", str(table), "--x", "x", "--y", "y", "--degree", "2", "--no-plots"]
    assert main([*args, "--trace", str(not_a_db)]) == 1
    _one_error_line(capsys.readouterr().err, "--trace", "not an SQLite database")
    assert not_a_db.read_text() == "my notes"
    import sqlite3

    foreign = tmp_path / "other.sqlite"
    with sqlite3.connect(foreign) as con:
        con.execute("CREATE TABLE customers(id INTEGER)")
    assert main([*args, "--trace", str(foreign)]) == 1
    _one_error_line(capsys.readouterr().err, "not a hingelab trace")


def test_sweep_refuses_a_foreign_trace_before_meshing(tmp_path, capsys):
    out = tmp_path / "s"
    out.mkdir()
    (out / "trace.sqlite").write_text("not a database")
    args = ["sweep", "--clearance", "0", "--amplitude", "300", "--size", "4", "--contact-size", "2"]
    assert main([*args, "--increments", "6", "--out", str(out)]) == 1
    _one_error_line(capsys.readouterr().err, "trace.sqlite", "not an SQLite database")
    assert not (out / "geometry").exists()


def test_trace_schema_and_changed_file(tmp_path, capsys):
    from rsm import trace_store

    assert main(["trace", "--schema"]) == 0
    assert "points(id INTEGER PRIMARY KEY" in capsys.readouterr().out
    loop = tmp_path / "loop.csv"
    loop.write_text("force_N,displacement_mm\n0,0\n")
    db = tmp_path / "trace.sqlite"
    pid = trace_store.record_point(
        db, study="t", params={"clearance_mm": 0.0}, artifacts={"loop_csv": loop}
    )
    assert main(["trace", str(db), str(pid)]) == 0
    loop.write_text("force_N,displacement_mm\n0,1\n")  # edited after it was recorded
    capsys.readouterr()
    assert main(["trace", str(db), str(pid)]) == 1
    assert "loop.csv" in capsys.readouterr().err


def test_missing_trace_is_one_line(tmp_path, capsys):
    assert main(["trace", str(tmp_path / "nowhere.sqlite"), "1"]) == 1
    _one_error_line(capsys.readouterr().err, "nowhere.sqlite")


def _model_and_data(tmp_path: Path) -> tuple[Path, Path]:
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.file import write_model
    from model.spec import ModelSpec

    spec = ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(increments_per_stage=6, clearance_increments=6),
    )
    model = write_model(spec, tmp_path / "MODEL.toml")
    data = tmp_path / "data"
    data.mkdir()
    t = np.linspace(0.0, 2.5 * math.pi, 51)  # 0 → +Fg → −Fg → +Fg
    force, disp = (
        300.0 * np.sin(t),
        0.05 * np.sin(t - 0.3),
    )  # far softer and lossier than the model (δ lags F)
    np.savetxt(
        data / "c1.csv",
        np.column_stack([force, disp]),
        delimiter=",",
        header="force_N,displacement_mm",
        comments="",
    )
    (data / "cases.csv").write_text(
        "case_id,hinge,clearance_mm,preload_N,amplitude_N,loop_file,temperature_C\nc1,general,0,0,300,c1.csv,21\n"
    )
    return model, data


def test_compare_checks_out_before_running_the_model(tmp_path, capsys, monkeypatch):
    import validation.workflow

    def no_model(*args, **kwargs):
        raise AssertionError("the model ran before the output folder was checked")

    monkeypatch.setattr(validation.workflow, "run_model_for_cases", no_model)
    model, data = _model_and_data(tmp_path)
    blocker = tmp_path / "cmp_file"
    blocker.write_text("in the way")
    assert main(["compare", str(model), str(data), "--out", str(blocker), "--no-plots"]) == 1
    _one_error_line(capsys.readouterr().err, "--out", "cmp_file")


@pytest.mark.slow  # one coarse cycle: ~10 s alone, over 30 s on the shared machine
def test_compare_fails_on_mismatch(tmp_path, capsys):
    model, data = _model_and_data(tmp_path)
    out = tmp_path / "cmp"
    assert (
        main(
            [
                "compare",
                str(model),
                str(data),
                "--out",
                str(out),
                "--no-plots",
                "--fail-on-mismatch",
            ]
        )
        == 2
    )
    assert "1 of 1 cases fail" in capsys.readouterr().err
    report = _no_nan((out / "comparison.json").read_text())
    assert isinstance(report, dict)
    assert report["cases"][0]["passed"] is False


def test_every_option_help_states_its_default():
    """Each optional value of every command says what it is when not given (issue 33)."""
    import argparse

    from studies.cli.main import build_parser

    parser = build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    flags = (argparse._HelpAction, argparse._StoreTrueAction, argparse._StoreFalseAction)
    silent = [
        f"{name} {'/'.join(a.option_strings)}"
        for name, sub in commands.items()
        for a in sub._actions
        if a.option_strings
        and not a.required
        and not isinstance(a, flags)
        and "default" not in (a.help or "")
    ]
    assert not silent, f"options whose help gives no default: {silent}"


def test_verbose_logs_hingelab_not_third_party_chatter(tmp_path):
    """-v shows hingelab's progress; build123d's INFO lines (one per face) stay out (issue 33)."""
    import subprocess
    import sys

    argv = [
        "-v",
        "mesh",
        "--size",
        "4",
        "--contact-size",
        "2",
        "--no-picture",
        "--out",
        str(tmp_path),
    ]
    run = subprocess.run(
        [sys.executable, "-m", "studies.cli.main", *argv],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "INFO" in run.stderr  # -v does log
    assert "build123d" not in run.stderr
