"""``hingelab paper``: both hinges through the sweeps, surfaces and the report beside the paper."""

from __future__ import annotations

import json

import pytest

from studies.cli import main


def test_paper_smoke_one_point_per_hinge(tmp_path, capsys):
    """One point per hinge (coarse meshes, tied bearing interfaces): the pipeline end to end."""
    argv = ["paper", "--out", str(tmp_path), "--quick", "--points", "1", "--interfaces", "bonded"]
    assert main([*argv, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["sweeps"]["general"]["ok"] == 1
    assert report["sweeps"]["modified"]["ok"] == 1
    g, m = report["general"], report["modified"]
    # our η beside the paper's at the same point (Table 1: Δr 0, 100 N; Table 4: Fp 0, 100 N)
    assert g["points"][0]["eta_paper"] == pytest.approx(0.0656)
    assert m["points"][0]["eta_paper"] == pytest.approx(0.0161)
    assert g["points"][0]["eta_ours"] > 0.005  # the general hinge dissipates
    assert abs(m["points"][0]["eta_ours"]) < 1e-4  # tied bearing hinge: nothing dissipates
    text = (tmp_path / "report.md").read_text()
    for needle in ("General hinge (Table 1)", "Modified hinge (Table 4)", "Why ours differs"):
        assert needle in text
    # a rerun reads every point back
    assert main([*argv, "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["sweeps"]["general"]["skipped"] == 1
    # and the folder has its HTML report (structure checked as for every report kind)
    from tests.studies.test_cmd_report import check_structure

    assert main(["report", str(tmp_path), "--out", str(tmp_path / "report.html")]) == 0
    page = check_structure(tmp_path / "report.html")
    text = " ".join(page.text)
    for needle in ("paper study", "General hinge beside Table 1", "Modified hinge beside Table 4"):
        assert needle in text
    assert "0.0656" in text  # Table 1 at Δr 0, 100 N, beside ours


@pytest.mark.slow
def test_paper_quick_fits_both_surfaces_and_draws_them(tmp_path, capsys):
    """``--quick`` (3 × 3 per hinge, coarse, frictional fits): surfaces, figures, reductions."""
    assert main(["paper", "--out", str(tmp_path), "--quick", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    for hinge in ("general", "modified"):
        h = report[hinge]
        assert h["n_points"] == 9
        assert h["surface"]["degree"] == 2
        for fig in h["surface"]["figures"].values():
            assert (tmp_path / fig).read_bytes()[:4] == b"\x89PNG"
        assert h["eta_max"] > h["eta_min"]
        assert h["eta_max_points"] > h["eta_min_points"] > 0  # every point dissipates
    assert set(report["reduction_percent"]) == {"min", "max"}
    assert report["reduction_basis"] in ("surface extremes", "sampled points")
    assert report["loops"]["general"]
    assert report["loops"]["modified"]
    assert report["wall_s"] < 600
