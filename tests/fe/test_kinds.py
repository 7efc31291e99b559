"""A hinge kind from another package, found through the ``hingelab.hinges`` entry point.

The kind (``tests/plugins/hingelab_jenkins``: a rigid pin on a Jenkins element) is not
named anywhere in hingelab; putting its folder on ``sys.path`` makes its distribution, and
so its entry point, visible, as ``pip install`` would. It is then driven through the
service, ``cycle``, ``sweep``, a study file, ``synth`` and ``compare``, each checked against
the element's closed-form loop.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

from fe.cycle.protocol import CycleSettings
from fe.kinds import HingeKind, hinge_kind, kind_names
from studies.cli.main import main

MODEL = """[hinge]
kind = "jenkins_pin"
k0_n_per_mm = {k0}
k1_n_per_mm = 6000.0
slip_force_n = {slip}

[cycle]
increments_per_stage = 12
"""


def _closed_form(params, amplitude_n: float) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """(W_cycle, η) of the element: δ(±Fg) = ±(Fg − Fs)/k0 at the peaks (the slider slips)."""
    from hingelab_jenkins import loop_area

    w = loop_area(params, amplitude_n)
    delta_max = (amplitude_n - params.slip_force_n) / params.k0_n_per_mm
    return w, w / (math.pi * amplitude_n * delta_max)


def _model(tmp_path: Path, slip: float = 60.0, k0: float = 2000.0) -> Path:
    path = tmp_path / f"MODEL_{slip:g}_{k0:g}.toml"
    path.write_text(MODEL.format(slip=slip, k0=k0))
    return path


def test_the_kind_is_found_only_through_its_entry_point(jenkins) -> None:  # type: ignore[no-untyped-def]
    assert isinstance(jenkins, HingeKind)
    assert "jenkins_pin" in kind_names()
    assert jenkins.params_type.__module__ == "hingelab_jenkins"


def test_an_unknown_kind_names_the_known_ones() -> None:
    from cad.errors import ParameterError

    with pytest.raises(
        ParameterError, match=r"hinge kind must be one of \['bearing', 'general', 'joint'\]"
    ):
        hinge_kind("jenkins_pin_typo")


def test_the_service_runs_the_kind_and_its_loop_is_the_closed_form(jenkins) -> None:  # type: ignore[no-untyped-def]
    from model.service import ModelService
    from model.spec import DesignPoint, ModelSpec, point_label

    spec = ModelSpec("jenkins_pin", jenkins.params_type(), cycle=CycleSettings())
    service = ModelService()
    runs = service.run(spec, [DesignPoint(a, {"slip_force_n": 60.0}) for a in (200.0, 400.0)])
    assert [point_label(spec, r.point) for r in runs] == ["s60_F200", "s60_F400"]
    assert len(service._prepared) == 1  # the slip force is a load: one "geometry"
    for r in runs:
        m = r.result.metrics()
        w, eta = _closed_form(jenkins.params_type(), r.point.amplitude_n)
        assert m["W_cycle_Nmm"] == pytest.approx(w, rel=1e-12)
        assert m["eta"] == pytest.approx(eta, rel=1e-12)
        assert m["energy_balance_rel_err"] < 1e-12


def test_cycle_command_runs_a_model_file_of_the_kind(jenkins, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "cycle"
    assert (
        main(
            [
                "cycle",
                "--model",
                str(_model(tmp_path)),
                "--amplitude",
                "300",
                "--out",
                str(out),
                "--json",
            ]
        )
        == 0
    )
    summary = json.loads((out / "result.json").read_text())
    _, eta = _closed_form(jenkins.params_type(), 300.0)
    assert summary["hinge"] == "jenkins_pin"
    assert summary["eta"] == pytest.approx(eta, rel=1e-12)
    assert (out / "loop.png").is_file()
    assert (out / "loop.csv").is_file()
    assert "pvd" not in summary["files"]  # a kind without fields writes none


def test_sweep_varies_the_kinds_design_variable(jenkins, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "sweep"
    args = ["sweep", "--hinge", "jenkins_pin", "--levels", "30,60", "--amplitude", "200,400"]
    assert main([*args, "--out", str(out), "--json"]) == 0
    with (out / "table.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert {(float(r["slip_force_N"]), float(r["amplitude_N"])) for r in rows} == {
        (30.0, 200.0), (30.0, 400.0), (60.0, 200.0), (60.0, 400.0),
    }  # fmt: skip
    import dataclasses

    for r in rows:
        params = dataclasses.replace(jenkins.params_type(), slip_force_n=float(r["slip_force_N"]))
        _, eta = _closed_form(params, float(r["amplitude_N"]))
        assert float(r["eta"]) == pytest.approx(eta, rel=1e-12)
    assert [p.name for p in (out / "points").glob("s30_F200-*/loop.png")] == ["loop.png"]
    capsys.readouterr()
    assert main(["sweep", "--hinge", "jenkins_pin", "--clearance", "0.1", "--out", str(out)]) == 1
    assert "--clearance is not a design variable of the Jenkins pin" in capsys.readouterr().err


def test_a_study_file_of_the_kind(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    from studies.study_file import read_study

    _model(tmp_path).rename(tmp_path / "MODEL.toml")
    study = tmp_path / "STUDY.toml"
    study.write_text(
        '[study]\nname = "jenkins"\nmodel = "MODEL.toml"\n'
        '[design]\ntype = "full_factorial"\n'
        "[design.slip_force_N]\nlevels = [30.0, 60.0]\n"
        "[design.amplitude_N]\nlevels = [200.0, 400.0]\n"
    )
    parsed = read_study(study)
    assert parsed.variables == ("slip_force_N", "amplitude_N")
    assert len(parsed.points) == 4
    out = tmp_path / "study"
    assert main(["study", str(study), "--out", str(out), "--no-plots", "--json"]) == 0
    with (out / "table.csv").open() as fh:
        assert len(list(csv.DictReader(fh))) == 4


def test_synth_and_compare_with_the_kind(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    data = tmp_path / "data"
    model = _model(tmp_path)
    assert (
        main(["synth", str(model), "--cases", "60:200,400", "--seed", "3", "--out", str(data)]) == 0
    )
    with (data / "cases.csv").open() as fh:
        cases = list(csv.DictReader(fh))
    assert [c["case_id"] for c in cases] == ["fs60N_F200N", "fs60N_F400N"]
    assert {c["hinge"] for c in cases} == {"jenkins_pin"}
    # the model the data came from passes; one with a 50 % stiffer spring k0 fails (the slip
    # force is a design variable: every model runs at the case's own)
    strict = ["--no-plots", "--fail-on-mismatch"]
    assert main(["compare", str(model), str(data), "--out", str(tmp_path / "same"), *strict]) == 0
    wrong = _model(tmp_path, k0=3000.0)
    assert main(["compare", str(wrong), str(data), "--out", str(tmp_path / "wrong"), *strict]) == 2
    report = json.loads((tmp_path / "wrong" / "comparison.json").read_text())
    assert not report["passed"]
    assert {c["slip_force_N"] for c in report["cases"]} == {60.0}


def test_diagnose_and_calibrate_find_a_compliance_hidden_in_the_kinds_loops(
    jenkins, tmp_path, capsys
) -> None:  # type: ignore[no-untyped-def]
    """Loops of the element with a series compliance: diagnose names it, calibrate fits it.

    The data come from the element itself with the effect added (noise and offsets of the
    synthetic machine), so this checks the workflow's plumbing for a plug-in kind, not the
    physics: the effects that act on the general or bearing hinge's contacts are refused
    for this kind by its own checks, and the compliance is recovered near its true value.
    """
    data = tmp_path / "data"
    model = _model(tmp_path)
    hidden = "frame_compliance:compliance_mm_per_n=2e-5"
    cases = "30:200,400;60:200,400;90:200,400"
    assert (
        main(
            [
                "synth",
                str(model),
                "--effect",
                hidden,
                "--cases",
                cases,
                "--seed",
                "4",
                "--out",
                str(data),
            ]
        )
        == 0
    )
    capsys.readouterr()
    assert main(["diagnose", str(model), str(data), "--json"]) == 0
    verdict = json.loads(capsys.readouterr().out)
    assert verdict["verdict"] == "effect_missing"
    assert verdict["effects"] == ["frame_compliance"]
    assert "do not act on the Jenkins pin" in verdict["skipped"]["face_friction"]
    out = tmp_path / "cal"
    assert (
        main(
            [
                "calibrate",
                str(model),
                str(data),
                "--effects",
                "frame_compliance",
                "--out",
                str(out),
                "--json",
            ]
        )
        == 0
    )
    from model.file import read_model

    fitted = read_model(next(out.glob("*.toml"))).effects["frame_compliance"]["compliance_mm_per_n"]
    assert fitted == pytest.approx(2e-5, rel=0.1)  # seed 4: 1.86e-5 (−7 %), the fit on noisy loops


@pytest.mark.parametrize("seed", [5, 6, 7])
def test_diagnose_stays_quiet_on_loops_of_the_model_itself(jenkins, tmp_path, capsys, seed) -> None:  # type: ignore[no-untyped-def]
    """A null set: loops of the model as it is (noise and offsets only) → no missing effect.

    With the plug-in kind a diagnosis takes seconds, so the verdict logic is checked in the
    fast suite. The noise limit is the upper α quantile of χ²_N, so it lies above N (the
    median of χ²_N is about N − 2/3): a limit on the wrong tail (``chi2.ppf(α, N)``) does not.
    (These null sets' χ² is far below N, about 0.2 for N = 18: the 2 % model floor of the
    feature σ dominates the record noise here.)
    """
    data = tmp_path / "data"
    model = _model(tmp_path)
    cases = "30:200,400;60:200,400;90:200,400"
    assert (
        main(["synth", str(model), "--cases", cases, "--seed", str(seed), "--out", str(data)]) == 0
    )
    capsys.readouterr()
    assert main(["diagnose", str(model), str(data), "--json"]) == 0
    verdict = json.loads(capsys.readouterr().out)
    assert verdict["verdict"] in ("no_missing_effect", "cannot_tell"), verdict["message"]
    assert verdict["chi2_base"] <= verdict["chi2_noise_limit"]
    assert verdict["chi2_noise_limit"] > verdict["n_features"] > 0
