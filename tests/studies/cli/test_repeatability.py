"""``hingelab repeatability`` end to end: files, one key number, the η–θ note, one-line errors."""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import studies.cli.main
from studies.cli.main import main

EXAMPLE = Path(__file__).parents[3] / "validation" / "data" / "repeatability_example.csv"
NAN_FILE = "reading_um\n" + "1\n" * 5 + "NaN\n1\n2\n"  # the bad value on line 7
TEXT_FILE = "reading_um\n" + "1\n" * 5 + "one\n1\n2\n"


@pytest.fixture(autouse=True)
def _only_this_subcommand(monkeypatch):
    """Build the parser with this subcommand only: the test does not depend on the others
    importing (gmsh, the FE stack) and stays fast."""
    monkeypatch.setattr(studies.cli.main, "SUBCOMMAND_MODULES", ("studies.cli.repeatability",))


def test_registered_in_the_cli():
    source = Path(studies.cli.main.__file__).read_text(
        encoding="utf-8"
    )  # the fixture hides the tuple
    assert '"studies.cli.repeatability",' in source


def _strict_json(path):
    def refuse(constant):
        raise AssertionError(f"{constant} in {path}")

    return json.loads(path.read_text(encoding="utf-8"), parse_constant=refuse)


def _example_sigma_mm(hinge):
    with open(EXAMPLE, encoding="utf-8") as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    x = np.array([float(r["reading_um"]) for r in rows if r["hinge"] == hinge]) * 1e-3
    return stats.norm.fit(x)[1]


def test_example_two_hinges_with_eta(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["repeatability", str(EXAMPLE), "--length-mm", "25", "--out", str(out)]
    assert main([*argv, "--eta", "general=0.0659,modified=0.0160", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    doc = _strict_json(out / "repeatability.json")
    assert printed == doc
    names = {p.name for p in out.iterdir()}
    assert names == {
        "repeatability.json",
        "repeatability.csv",
        "histogram_general.png",
        "histogram_modified.png",
        "eta_theta.png",
        "commands.jsonl",  # the command line, for hingelab report
    }
    general = doc["hinges"][0]
    theta = math.asin(6 * _example_sigma_mm("general") / 25.0)
    assert general["theta_rad"] == pytest.approx(theta, rel=1e-12)
    assert general["theta_ci_rad"]["lo"] < 2.6260e-4 < general["theta_ci_rad"]["hi"]  # Table 7
    assert general["eta"] == 0.0659
    corr = doc["correlation"]
    assert corr["n_points"] == 2
    assert corr["pearson_r"] is None
    assert corr["p_value"] is None
    assert "always fits exactly" in corr["note"]
    with open(out / "repeatability.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["hinge"] for r in rows] == ["general", "modified"]
    assert float(rows[0]["theta_rad"]) == pytest.approx(theta, rel=1e-12)


def test_text_output_without_eta_says_why_no_correlation(tmp_path, capsys):
    argv = ["repeatability", str(EXAMPLE), "--length-mm", "25", "--out", str(tmp_path)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "hinge modified" in text
    assert "Shapiro–Wilk" in text
    assert "needs η for at least 2 hinges, got 0" in text
    assert not (tmp_path / "eta_theta.png").exists()
    doc = _strict_json(tmp_path / "repeatability.json")
    assert doc["correlation"] is None
    assert doc["hinges"][1]["resolution"]["coarse"]  # σ = 0.24 µm read to 0.1 µm


def test_three_hinges_from_a_hinge_table_report_pearson(tmp_path):
    rng = np.random.default_rng(6)
    sigmas_um, etas = (0.3, 0.7, 1.0), (0.02, 0.05, 0.08)
    lines = ["hinge,reading_um"]
    for i, s in enumerate(sigmas_um):
        lines += [f"h{i},{v:.5f}" for v in rng.normal(0.0, s, 60)]
    readings = tmp_path / "r.csv"
    readings.write_text("\n".join(lines) + "\n")
    table = tmp_path / "hinges.csv"
    table.write_text("hinge,eta,comment\n" + "".join(f"h{i},{e},x\n" for i, e in enumerate(etas)))
    out = tmp_path / "out"
    argv = ["repeatability", str(readings), "--length-mm", "25", "--out", str(out)]
    assert main([*argv, "--hinges", str(table), "--confidence", "0.9"]) == 0
    doc = _strict_json(out / "repeatability.json")
    thetas = [h["theta_rad"] for h in doc["hinges"]]
    r, p = stats.pearsonr(etas, thetas)
    assert doc["correlation"]["pearson_r"] == pytest.approx(r, rel=1e-12)
    assert doc["correlation"]["p_value"] == pytest.approx(p, rel=1e-12)
    assert doc["confidence"] == 0.9
    assert (out / "eta_theta.png").is_file()


def test_single_column_with_unit_and_label(tmp_path):
    x_mm = np.random.default_rng(1).normal(0.0, 2e-3, 30)
    readings = tmp_path / "l.csv"
    readings.write_text("l\n" + "".join(f"{v:.6f}\n" for v in x_mm))
    out = tmp_path / "out"
    argv = ["repeatability", str(readings), "--length-mm", "40", "--out", str(out), "--unit", "mm"]
    assert main([*argv, "--label", "pin A", "--eta", "0.07"]) == 0
    doc = _strict_json(out / "repeatability.json")
    assert doc["hinges"][0]["hinge"] == "pin A"
    assert doc["hinges"][0]["eta"] == 0.07
    assert (out / "histogram_pin_A.png").is_file()


@pytest.mark.parametrize(
    ("extra", "text", "message"),
    [
        (["--length-mm", "0"], None, r"--length-mm must be in \(0, inf\), got 0.0"),
        (["--length-mm", "-3"], None, r"--length-mm must be in \(0, inf\), got -3.0"),
        (["--length-mm", "0.001"], None, r"hinge 'general': length_mm must be > 6σ = 0.0064\d* mm .*got 0.001"),
        (["--length-mm", "25", "--confidence", "95"], None, r"--confidence must be in \(0, 1\), got 95.0"),
        (["--length-mm", "25", "--eta", "0.05"], None, r"--eta '0.05': one number needs a file with one hinge"),
        (["--length-mm", "25", "--eta", "general=x"], None, r"--eta: 'general=x' is not NAME=NUMBER"),
        (["--length-mm", "25", "--eta", "other=0.1"], None, r"--eta names hinge\(s\) \['other'\] not in"),
        (["--length-mm", "25", "--eta", "general=-1"], None, r"--eta general must be in \[0, inf\), got -1.0"),
        (["--length-mm", "25"], "reading_um\n1\n2\n", r"hinge 'r' has 2 readings, need at least 8"),
        (["--length-mm", "25"], NAN_FILE, r"line 7, column reading_um: not a finite number: 'NaN'"),
        (["--length-mm", "25"], "reading_um\n" + "1\n" * 5 + "1,5\n", r"line 7 has 2 fields"),
        (["--length-mm", "25"], TEXT_FILE, r"line 7, column reading_um: not a number: 'one'"),
        (["--length-mm", "25"], "l\n" + "1\n" * 8, r"unit of column 'l' .* must be one of um, mm"),
    ],
    ids=["length-zero", "length-negative", "six-sigma", "confidence", "eta-number", "eta-text", "eta-unknown",
         "eta-negative", "few", "nan", "fields", "text", "no-unit"],
)  # fmt: skip
def test_bad_input_exits_1_with_one_line(tmp_path, capsys, extra, text, message):
    readings = EXAMPLE
    if text is not None:
        readings = tmp_path / "r.csv"
        readings.write_text(text)
    assert main(["repeatability", str(readings), "--out", str(tmp_path / "o"), *extra]) == 1
    err = capsys.readouterr().err
    assert err.startswith("hingelab repeatability: error: ")
    assert err.count("\n") == 1
    assert re.search(message, err), err
    assert not (tmp_path / "o" / "repeatability.json").exists()


def test_bad_hinge_table(tmp_path, capsys):
    table = tmp_path / "t.csv"
    table.write_text("hinge,eta\ngeneral,0.06\nmodified,abc\n")
    argv = ["repeatability", str(EXAMPLE), "--length-mm", "25", "--out", str(tmp_path)]
    assert main([*argv, "--hinges", str(table)]) == 1
    assert "line 3, column eta: not a number: 'abc'" in capsys.readouterr().err
