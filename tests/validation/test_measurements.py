"""Reading measurement sets: plain loops, Bluehill exports, η tables, and every refusal."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cad.errors import DataError
from validation.loop_files import read_bluehill, read_loop_csv, read_loop_file
from validation.loops import process_loop
from validation.measurements import read_eta_table, read_measurement_set

BLUEHILL = Path(__file__).parent / "data" / "bluehill_hinge_300N.csv"
HEADER = "case_id,hinge,clearance_mm,preload_N,amplitude_N,loop_file"


def ellipse(fg=200.0, d=0.003, n=80, dwell=5):
    theta = math.pi / 2 + np.linspace(0, 2 * math.pi, n + 1)[1:]
    s = np.linspace(0, 1, n // 4 + 1)
    F = np.concatenate([np.zeros(dwell), fg * s, fg * np.sin(theta)])
    x = np.concatenate([np.zeros(dwell), d * math.cos(0.1) * s, d * np.sin(theta - 0.1)])
    return F, x


def write_loop(path, F, x, header="force_N,displacement_mm", scale=(1.0, 1.0)):
    rows = [header] + [
        f"{f / scale[0]:.17g},{v / scale[1]:.17g}" for f, v in zip(F, x, strict=True)
    ]
    path.write_text("\n".join(rows) + "\n")
    return path


def make_set(tmp_path, rows, loops):
    for name, (F, x) in loops.items():
        write_loop(tmp_path / name, F, x)
    (tmp_path / "cases.csv").write_text("\n".join([HEADER, *rows]) + "\n")
    return tmp_path


def test_plain_loop_read_and_units_converted(tmp_path):
    F, x = ellipse()
    a = read_loop_csv(write_loop(tmp_path / "a.csv", F, x))
    b = read_loop_csv(
        write_loop(tmp_path / "b.csv", F, x, "force_kN,displacement_um", scale=(1e3, 1e-3))
    )
    np.testing.assert_allclose(b.force_n, a.force_n, rtol=1e-12)
    np.testing.assert_allclose(b.displacement_mm, a.displacement_mm, rtol=1e-12)
    assert a.time_s is None
    assert a.n_samples == F.size
    assert not a.force_n.flags.writeable


@pytest.mark.parametrize(
    ("header", "match"),
    [
        ("force_lb,displacement_mm", r"column force_lb: unknown unit 'lb'"),
        ("force_N,disp_mm", r"missing column displacement_<unit>"),
    ],
    ids=["unknown-unit", "missing-column"],
)
def test_loop_csv_header_refused(tmp_path, header, match):
    F, x = ellipse()
    with pytest.raises(DataError, match=match):
        read_loop_csv(write_loop(tmp_path / "bad.csv", F, x, header))


def test_loop_csv_extra_column_refused(tmp_path):
    path = tmp_path / "extra.csv"
    path.write_text("force_N,displacement_mm,temperature_C\n" + "1,0.1,20\n" * 5)
    with pytest.raises(DataError, match=r"unexpected column\(s\) \['temperature_C'\]"):
        read_loop_csv(path)


@pytest.mark.parametrize("bad", ["nan", "abc", ""], ids=["nan", "text", "empty"])
def test_loop_csv_bad_value_named_by_row_and_column(tmp_path, bad):
    path = write_loop(tmp_path / "v.csv", *ellipse())
    lines = path.read_text().splitlines()
    f, _ = lines[7].split(",")
    lines[7] = f"{f},{bad}"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"v\.csv: row 7 \(line 8\), column displacement_mm"):
        read_loop_csv(path)


def test_bluehill_sample_read_in_newtons_and_mm():
    loop = read_bluehill(BLUEHILL)
    assert loop.n_samples == 306
    assert loop.time_s is not None
    assert loop.time_s[1] == pytest.approx(0.1)
    assert loop.force_n.max() == pytest.approx(300.8, abs=1.0)  # 0.3 kN + 0.8 N offset
    p = process_loop(loop.force_n, loop.displacement_mm, loop.source)
    assert p.force_offset_n == pytest.approx(0.8, abs=0.2)
    # bilinear Masing loop of the sample: W = 4 Fy (Fg − Fy)(1/k2 − 1/k1) = 1.8 N·mm
    assert p.metrics.W_cycle_Nmm == pytest.approx(1.8, rel=0.02)
    assert p.metrics.disp_at_peak_mm == pytest.approx(0.0075, rel=0.01)
    assert read_loop_file(BLUEHILL).n_samples == 306


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ('"(kN)"', '"(lbs)"', r"line 11, column Load: unknown unit 'lbs'"),
        ('"Load"', '"Strain"', r"no force channel"),
        (
            '"(s)","(mm)","(kN)","(cycles)"',
            '"s","mm","kN","cycles"',
            r"no Bluehill channel-name row",
        ),
        (
            '"0.20000","0.002083","0.000759"',
            '"0.20000","0.002083","n/a"',
            r"line 14, column Load: not a number",
        ),
    ],
    ids=["unknown-unit", "no-load-channel", "no-unit-row", "bad-value"],
)
def test_bluehill_malformed_refused(tmp_path, old, new, match):
    text = BLUEHILL.read_text()
    assert old in text
    path = tmp_path / "export.csv"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(DataError, match=match):
        read_bluehill(path)


def test_bluehill_units_converted(tmp_path):
    text = BLUEHILL.read_text().replace('"(mm)"', '"(µm)"', 1).replace('"(s)"', '"(ms)"', 1)
    path = tmp_path / "um.csv"
    path.write_text(text)
    a, b = read_bluehill(BLUEHILL), read_bluehill(path)
    np.testing.assert_allclose(b.displacement_mm, a.displacement_mm * 1e-3)
    np.testing.assert_allclose(b.time_s, a.time_s * 1e-3)


def test_measurement_set_with_plain_and_bluehill_loops(tmp_path):
    (tmp_path / "bh.csv").write_text(BLUEHILL.read_text())
    folder = make_set(
        tmp_path,
        [
            "c1,general,0.0,0,200,c1.csv",
            "c2,general,0.0,0,200,c2.csv",
            "bh,general,0.05,0,300,bh.csv",
        ],
        {"c1.csv": ellipse(), "c2.csv": ellipse(d=0.0031)},
    )
    ms = read_measurement_set(folder)
    assert [c.case_id for c in ms.cases] == ["c1", "c2", "bh"]
    assert ms.cases[2].loop.force_n.max() > 290
    assert ms.replicate_groups()[("general", (("clearance_mm", 0.0),), 200.0)] == ("c1", "c2")
    assert ms.cases[0].replicate is None


def test_optional_columns_read(tmp_path):
    F, x = ellipse()
    write_loop(tmp_path / "c1.csv", F, x)
    (tmp_path / "cases.csv").write_text(
        HEADER + ",replicate,rate_mm_per_min,temperature_C\nc1,general,0,0,200,c1.csv,2,0.5,21.5\n"
    )
    c = read_measurement_set(tmp_path).cases[0]
    assert (c.replicate, c.rate_mm_per_min, c.temperature_c) == (2, 0.5, 21.5)


@pytest.mark.parametrize(
    ("rows", "match"),
    [
        (
            ["c1,general,0,0,200,c1.csv", "c1,general,0,0,200,c1.csv"],
            r"row 2 \(line 3\), column case_id: duplicate case_id 'c1'",
        ),
        (
            ["c1,general,0,0,200,missing.csv"],
            r"row 1 \(line 2\), column loop_file: loop file .*missing\.csv not found",
        ),
        (
            ["c1,general,0,0,250,c1.csv"],
            r"c1\.csv \(case 'c1', cases\.csv row 1\): the loop never reaches the stated amplitude ±250 N",
        ),
        (["c1,general,0,0,150,c1.csv"], r"overshoots the stated amplitude ±150 N"),
        (
            ["c1,general,zero,0,200,c1.csv"],
            r"row 1 \(line 2\), column clearance_mm: not a number: 'zero'",
        ),
        (["c1,general,0,0,nan,c1.csv"], r"column amplitude_N: not a finite number"),
        (["c1,hinged,0,0,200,c1.csv"], r"column hinge: hinge kind must be one of"),
        (
            ["c1,general,0,0,200,half.csv"],
            r"half\.csv .*expected the load sequence .* found −, \+, −",
        ),
    ],
    ids=[
        "duplicate",
        "missing-loop-file",
        "never-reaches",
        "overshoot",
        "text",
        "nan",
        "hinge",
        "no-stages",
    ],
)
def test_measurement_set_refusals(tmp_path, rows, match):
    F, x = ellipse()
    make_set(tmp_path, rows, {"c1.csv": (F, x), "half.csv": (-F, -x)})
    with pytest.raises(DataError, match=match):
        read_measurement_set(tmp_path)


def test_cases_csv_missing_and_unknown_columns(tmp_path):
    (tmp_path / "cases.csv").write_text("case_id,hinge,amplitude_N,loop_file\n")
    with pytest.raises(DataError, match=r"missing column\(s\) \['case_id'\]|no cases"):
        read_measurement_set(tmp_path)
    # a general-hinge row needs its design column; another kind's (preload_N) it does not
    (tmp_path / "cases.csv").write_text(
        "case_id,hinge,amplitude_N,loop_file\nc1,general,200,c1.csv\n"
    )
    with pytest.raises(
        DataError, match="missing column 'clearance_mm', a design variable of the general"
    ):
        read_measurement_set(tmp_path)
    (tmp_path / "cases.csv").write_text(HEADER + ",humidity\n")
    with pytest.raises(DataError, match=r"unknown column\(s\) \['humidity'\]"):
        read_measurement_set(tmp_path)
    with pytest.raises(DataError, match="no such measurement folder"):
        read_measurement_set(tmp_path / "empty_folder_missing")
    (tmp_path / "sub").mkdir()
    with pytest.raises(DataError, match=r"no cases\.csv \(or eta\.csv\)"):
        read_measurement_set(tmp_path / "sub")


def test_eta_table_like_the_paper(tmp_path):
    path = tmp_path / "eta.csv"
    path.write_text(
        "num,clearance_mm,amplitude_N,eta\n1,0,100,0.0656\n2,0,200,0.109\n3,0.1,100,0.08\n"
    )
    ms = read_measurement_set(tmp_path)
    assert [c.case_id for c in ms.cases] == ["row1", "row2", "row3"]
    assert ms.cases[1].eta == pytest.approx(0.109)
    assert ms.cases[2].values == {"clearance_mm": pytest.approx(0.1)}
    assert all(c.loop is None and c.hinge == "general" for c in ms.cases)
    assert read_eta_table(path).cases[0].amplitude_n == 100.0


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("clearance_mm,amplitude_N\n0,100\n", r"missing column\(s\) \['eta'\]"),
        ("amplitude_N,eta\n100,0.1\n", r"missing column\(s\) \['clearance_mm'\]"),
        (
            "clearance_mm,amplitude_N,eta\n0,100,1.5\n",
            r"row 1 \(line 2\), column eta: η must be in \(0, 1\]",
        ),
        ("clearance_mm,amplitude_N,eta\n0,100,nan\n", r"column eta: not a finite number"),
        ("clearance_mm,amplitude_N,eta\n0,100\n", r"line 2 has 2 fields, the header has 3"),
    ],
    ids=["no-eta", "no-design", "eta-range", "eta-nan", "short-row"],
)
def test_eta_table_refusals(tmp_path, text, match):
    path = tmp_path / "t.csv"
    path.write_text(text)
    with pytest.raises(DataError, match=match):
        read_eta_table(path)
