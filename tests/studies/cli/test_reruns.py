"""A rerun of ``sweep``, ``study`` and ``compare`` with nothing changed computes no cycle.

(``diagnose``: ``tests/validation/test_validation_dask.py``; the paper:
``benchmarks/bench_rerun.py``.) The model is the plug-in kind ``jenkins_pin``
(``tests/plugins``, a cycle in milliseconds); each rerun is checked by the command's own
counter and by its results, which must be those of the first run to the bit.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from studies.cli.main import main

MODEL = (
    '[hinge]\nkind = "jenkins_pin"\nk0_n_per_mm = 2000.0\nk1_n_per_mm = 6000.0\n'
    "slip_force_n = 60.0\n[cycle]\nincrements_per_stage = 12\n"
)


def _table(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def _json(capsys: pytest.CaptureFixture[str]) -> dict:  # type: ignore[type-arg]
    return json.loads(capsys.readouterr().out)


def test_a_sweep_rerun_computes_nothing(jenkins, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "sweep"
    argv = ["sweep", "--hinge", "jenkins_pin", "--levels", "30,60", "--amplitude", "200,400"]
    argv += ["--out", str(out), "--json"]
    assert main(argv) == 0
    first = _json(capsys)
    assert (first["ok"], first["skipped"]) == (4, 0)
    table = _table(out / "table.csv")
    assert main(argv) == 0
    again = _json(capsys)
    assert (again["ok"], again["skipped"], again["failed"]) == (0, 4, 0)
    assert _table(out / "table.csv") == table


def test_a_study_rerun_computes_nothing_with_or_without_its_trace(
    jenkins, tmp_path, capsys
) -> None:  # type: ignore[no-untyped-def]
    (tmp_path / "MODEL.toml").write_text(MODEL)
    study = tmp_path / "STUDY.toml"
    study.write_text(
        '[study]\nname = "jenkins"\nmodel = "MODEL.toml"\n'
        '[design]\ntype = "full_factorial"\n'
        "[design.slip_force_N]\nlevels = [30.0, 60.0]\n"
        "[design.amplitude_N]\nlevels = [200.0, 400.0]\n"
    )
    out = tmp_path / "study"
    argv = ["study", str(study), "--out", str(out), "--no-plots", "--json"]
    assert main(argv) == 0
    assert _json(capsys)["computed"] == 4
    eta = {(r["slip_force_N"], r["amplitude_N"]): r["eta"] for r in _table(out / "table.csv")}
    assert main(argv) == 0
    again = _json(capsys)
    assert (again["computed"], again["already_done"], again["failed"]) == (0, 4, 0)
    (out / "trace.sqlite").unlink()  # the stored results alone are enough
    assert main(argv) == 0
    assert _json(capsys)["computed"] == 0
    back = {(r["slip_force_N"], r["amplitude_N"]): r["eta"] for r in _table(out / "table.csv")}
    assert back == eta


def test_a_compare_rerun_computes_nothing(jenkins, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    model = tmp_path / "MODEL.toml"
    model.write_text(MODEL)
    data = tmp_path / "data"
    assert main(["synth", str(model), "--cases", "30:200;60:200,400", "--out", str(data)]) == 0
    out = tmp_path / "cmp"
    argv = ["compare", str(model), str(data), "--out", str(out), "--no-plots"]
    assert main(argv) == 0
    first = json.loads((out / "comparison.json").read_text())
    assert first["n_computed"] == 3
    assert main(argv) == 0
    again = json.loads((out / "comparison.json").read_text())
    assert again["n_computed"] == 0  # every cycle read from cmp/results
    assert [c["errors"] for c in again["cases"]] == [c["errors"] for c in first["cases"]]
    capsys.readouterr()
