"""compare and diagnose on Dask equal the in-process run; a rerun computes nothing.

The model is the plug-in kind ``jenkins_pin`` (``tests/plugins``: a rigid pin on a Jenkins
element, a cycle in milliseconds), so these check the dispatch, not the physics. The
workers find the plug-in through ``PYTHONPATH``, as a user's workers would find an
installed package.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

from studies.cli.main import main
from tests.conftest import PLUGINS
from tests.dask_cluster import external_cluster

CASES = "30:200,400;60:200,400;90:200,400"
HIDDEN = "frame_compliance:compliance_mm_per_n=2e-5"


def _model(tmp_path: Path) -> Path:
    path = tmp_path / "MODEL.toml"
    path.write_text(
        '[hinge]\nkind = "jenkins_pin"\nk0_n_per_mm = 2000.0\nk1_n_per_mm = 6000.0\n'
        "slip_force_n = 60.0\n[cycle]\nincrements_per_stage = 12\n"
    )
    return path


def _data(tmp_path: Path, model: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    data = tmp_path / "data"
    argv = ["synth", str(model), "--effect", HIDDEN, "--cases", CASES, "--seed", "4"]
    assert main([*argv, "--out", str(data)]) == 0
    capsys.readouterr()
    return data


def _diagnose(model: Path, data: Path, out: Path, capsys, *extra: str) -> dict:  # type: ignore[no-untyped-def]
    assert main(["diagnose", str(model), str(data), "--json", "--out", str(out), *extra]) == 0
    return json.loads(capsys.readouterr().out)


def _same_diagnosis(a: dict, b: dict) -> None:  # type: ignore[type-arg]
    """Verdict, effects, χ² and fitted values equal to 1e-12 relative (timings aside)."""
    assert (a["verdict"], a["effects"], a["skipped"]) == (b["verdict"], b["effects"], b["skipped"])
    assert b["chi2_base"] == pytest.approx(a["chi2_base"], rel=1e-12)
    assert [c["name"] for c in a["candidates"]] == [c["name"] for c in b["candidates"]]
    for ca, cb in zip(a["candidates"], b["candidates"], strict=True):
        for k in ("value", "chi2", "delta_chi2", "heldout_chi2", "heldout_chi2_base"):
            assert cb[k] == pytest.approx(ca[k], rel=1e-12, abs=1e-300), (ca["name"], k)
        assert (ca["significant"], ca["heldout_ok"]) == (cb["significant"], cb["heldout_ok"])


def test_a_diagnosis_rerun_reads_its_cycles_back(jenkins, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    model = _model(tmp_path)
    data = _data(tmp_path, model, capsys)
    first = _diagnose(model, data, tmp_path / "d", capsys)
    assert first["verdict"] == "effect_missing"
    assert first["stats"]["n_computed"] > 0
    again = _diagnose(model, data, tmp_path / "d", capsys)
    assert again["stats"]["n_computed"] == 0  # every cycle read from d/results
    _same_diagnosis(first, again)
    assert (
        json.loads((tmp_path / "d" / "diagnosis.json").read_text())["verdict"] == "effect_missing"
    )


@pytest.mark.slow  # a LocalCluster of two processes takes ~8 s to start
def test_compare_on_a_local_cluster_equals_the_in_process_run(
    jenkins, tmp_path, capsys, monkeypatch
) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(PLUGINS), *sys.path]))
    model = _model(tmp_path)
    data = _data(tmp_path, model, capsys)
    reports = {}
    for name, extra in (("here", []), ("dask", ["--workers", "2"])):
        out = tmp_path / name
        assert (
            main(["compare", str(model), str(data), "--out", str(out), "--no-plots", *extra]) == 0
        )
        reports[name] = json.loads((out / "comparison.json").read_text())
    assert reports["dask"]["n_computed"] == reports["here"]["n_computed"] == 6
    for a, b in zip(reports["here"]["cases"], reports["dask"]["cases"], strict=True):
        assert a["passed"] == b["passed"]
        for k, v in a["errors"].items():
            assert b["errors"][k] == pytest.approx(v, rel=1e-12, abs=1e-15)
    # a rerun on the cluster's folder computes nothing
    out = tmp_path / "dask"
    assert (
        main(["compare", str(model), str(data), "--out", str(out), "--no-plots", "--workers", "2"])
        == 0
    )
    assert json.loads((out / "comparison.json").read_text())["n_computed"] == 0


@pytest.mark.slow
def test_diagnose_on_an_existing_cluster_equals_the_in_process_run(
    jenkins, tmp_path, capsys
) -> None:  # type: ignore[no-untyped-def]
    model = _model(tmp_path)
    data = _data(tmp_path, model, capsys)
    here = _diagnose(model, data, tmp_path / "here", capsys)
    env = {**os.environ, "PYTHONPATH": str(PLUGINS)}  # the plug-in kind, as an installed package
    with external_cluster(tmp_path, env=env) as address:
        there = _diagnose(model, data, tmp_path / "there", capsys, "--scheduler", address)
    assert here["verdict"] == "effect_missing"
    _same_diagnosis(here, there)
    assert there["stats"]["n_computed"] == here["stats"]["n_computed"] > 0


@pytest.mark.slow
def test_diagnose_refuses_a_cluster_whose_workers_run_other_code(jenkins, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """Workers that import an edited copy of hingelab are refused before any cycle runs."""
    import shutil

    from model.code import ALL_PACKAGES

    model = _model(tmp_path)
    data = _data(tmp_path, model, capsys)
    root, edited = Path(__file__).resolve().parents[2], tmp_path / "edited"
    for package in ALL_PACKAGES:
        shutil.copytree(
            root / package, edited / package, ignore=shutil.ignore_patterns("__pycache__")
        )
    with (edited / "fe" / "__init__.py").open("a") as fh:
        fh.write("# an edit this process does not have\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(edited), str(PLUGINS)])}
    out = tmp_path / "there"
    with external_cluster(tmp_path, env=env) as address:
        argv = ["diagnose", str(model), str(data), "--json", "--out", str(out)]
        assert main([*argv, "--scheduler", address]) == 1
    err = capsys.readouterr().err
    assert "runs other code than this process (source " in err, err
    assert "(and 1 other worker(s))" in err
    assert not list(out.glob("results/*.npz"))  # no cycle ran, none was stored
