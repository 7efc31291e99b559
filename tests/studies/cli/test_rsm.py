import json
import shutil

import pytest

from rsm.paper_printed import GENERAL, paper_table_path
from studies.cli.main import main


@pytest.fixture
def table(tmp_path):
    with paper_table_path(GENERAL.csv_name) as p:
        dst = tmp_path / "general.csv"
        shutil.copy(p, dst)
    return dst


def test_fit_json(table, capsys):
    args = ["--x", "clearance_mm,amplitude_N", "--y", "eta_fe", "--degree", "4"]
    rc = main(["rsm", "fit", str(table), *args, "--threshold", "0.05", "--json", "--no-plots"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    terms = [c["term"] for c in out["coefficients"]]
    assert terms[:6] == ["1", "x1", "x2", "x1^2", "x1*x2", "x2^2"]
    assert "x1^2*x2" in terms
    by_term = {c["term"]: c["coefficient"] for c in out["coefficients"]}
    assert by_term["x1^4"] == pytest.approx(-0.54167, abs=5e-6)  # Eq. 6
    for key in ("R2", "R2_adj", "RMSE", "max_abs_RE_percent", "Q2", "condition_number"):
        assert key in out["metrics"]
    assert round(out["metrics"]["max_abs_RE_percent"], 3) == 0.855
    assert out["threshold_region"]["lower"][0] == pytest.approx(0.15715, abs=1e-5)


@pytest.mark.slow  # four PNGs take ~6-15 s on a loaded machine
def test_fit_writes_plots_next_to_table(table, capsys):
    rc = main(
        [
            "rsm",
            "fit",
            str(table),
            "--x",
            "clearance_mm,amplitude_N",
            "--y",
            "eta_fe",
            "--threshold",
            "0.05",
            "--json",
        ]
    )
    assert rc == 0
    assert len(json.loads(capsys.readouterr().out)["plots"]) == 4
    plot_dir = table.parent / "general_rsm"
    assert sorted(p.name for p in plot_dir.glob("*.png")) == [
        "contour.png",
        "predicted_vs_actual.png",
        "slices.png",
        "surface_3d.png",
    ]
    for png in plot_dir.glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert png.stat().st_size > 10_000


def test_fit_text_output(table, capsys):
    rc = main(
        [
            "rsm",
            "fit",
            str(table),
            "--x",
            "clearance_mm,amplitude_N",
            "--y",
            "eta_fe",
            "--degree",
            "2",
            "--no-plots",
        ]
    )
    assert rc == 0
    out = capsys.readouterr()
    assert "x1*x2" in out.out
    assert "clearance_mm*amplitude_N" in out.out
    assert "R2_adj" in out.out
    assert "condition_number" in out.out
    assert "over-fitted" in out.err  # a quadratic leaves Q2 far below R2 on this table


@pytest.mark.parametrize(
    ("content", "args", "needle"),
    [
        ("a,y\n0,1\n1,2\n2,3\n", ["--x", "a,b", "--y", "y"], "'b'"),
        ("a,y\n0,1\n1,nan\n2,3\n", ["--x", "a", "--y", "y"], "line 3, column 'y'"),
        ("a,b,y\n0,1,1\n1,1,2\n2,1,3\n", ["--x", "a,b", "--y", "y"], "column 'b' is constant"),
        (
            "a,y\n0,1\n1,2\n2,3\n",
            ["--x", "a", "--y", "y", "--degree", "4"],
            "5 coefficients but only 3",
        ),
    ],
    ids=["missing-column", "nan", "constant", "too-few-points"],
)
def test_bad_tables_exit_1_with_message(tmp_path, capsys, content, args, needle):
    p = tmp_path / "bad.csv"
    p.write_text(content, encoding="utf-8")
    assert main(["rsm", "fit", str(p), *args, "--no-plots"]) == 1
    assert needle in capsys.readouterr().err


def test_paper_report(tmp_path, capsys):
    rc = main(["rsm", "paper", "--out", str(tmp_path), "--json", "--no-plots"])
    assert rc == 0
    data = json.loads(capsys.readouterr().out)
    assert data["n_checks"] > data["n_reproduced"] > 100
    assert (tmp_path / "paper_comparison.md").is_file()
    assert data["general"]["minimum"]["eta"] == pytest.approx(0.0353, abs=5e-5)
