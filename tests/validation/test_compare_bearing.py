"""``compare`` on bearing-hinge data: cases with a preload, a model file with kind = "bearing"."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from cad.errors import ParameterError
from fe.kinds import hinge_kind
from studies.cli.main import main

MODEL_MESH = {"size_mm": 4.0, "contact_size_mm": 0.8, "part_sizes_mm": (("ring", 1.2),)}
DATA_MESH = {"size_mm": 3.5, "contact_size_mm": 0.7, "part_sizes_mm": (("ring", 1.0),)}
"""The 'measurements' come from another, finer mesh than the model judged on them."""


def _spec(mesh: dict, increments: int):  # type: ignore[no-untyped-def]
    from cad.bearing_geometry import BearingHingeParams, Interfaces
    from fe.cycle.protocol import CycleSettings
    from model.spec import ModelSpec

    return ModelSpec(
        "bearing",
        BearingHingeParams(interfaces=Interfaces.CONTACT),
        hinge_kind("bearing").mesh_settings(**mesh),
        CycleSettings(mu=0.2, increments_per_stage=increments),
    )


def _cases_csv(path, rows):  # type: ignore[no-untyped-def]
    head = "case_id,hinge,clearance_mm,preload_N,amplitude_N,loop_file"
    path.write_text("\n".join([head, *rows]) + "\n")


def test_bearing_cases_are_checked_against_the_model_kind(tmp_path):
    from cad.errors import DataError
    from validation.measurements import Case
    from validation.workflow import _check_cases

    spec = _spec(MODEL_MESH, 8)
    with pytest.raises(DataError, match="hinge 'general', but the model is the bearing hinge"):
        _check_cases(spec, [Case("a", "general", {"clearance_mm": 0.0}, 300.0)])
    with pytest.raises(DataError, match=r"clearance_mm is not a design variable of the bearing"):
        _check_cases(spec, [Case("b", "bearing", {"clearance_mm": 0.1, "preload_n": 100.0}, 300.0)])
    _check_cases(spec, [Case("c", "bearing", {"preload_n": 100.0}, 300.0)])  # accepted


@pytest.mark.slow
def test_compare_passes_a_bearing_loop_from_another_mesh_and_fails_a_wrong_one(tmp_path, capsys):
    from model.file import write_model
    from model.service import ModelService
    from model.spec import DesignPoint

    data_spec = _spec(DATA_MESH, 16)
    service = ModelService()
    data = tmp_path / "data"
    data.mkdir()
    rng = np.random.default_rng(11)
    rows = []
    # the soft case is another design point (a replicate would only widen the scatter)
    for cid, amp, scale in (("fp100_F300", 300.0, 1.0), ("fp100_F200_soft", 200.0, 1.3)):
        r = service.run_point(data_spec, DesignPoint(amp, {"preload_n": 100.0}))
        F, d = r.machine_path()
        s = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(F)))])
        t = np.linspace(0.0, s[-1], 900)  # another sampling than the model's increments
        Fm = np.interp(t, s, F) + rng.normal(0.0, 0.002 * F.max(), t.size)
        dm = scale * np.interp(t, s, d) + rng.normal(0.0, 0.002 * d.max(), t.size)
        np.savetxt(data / f"{cid}.csv", np.column_stack([Fm, dm]), delimiter=",",
                   header="force_N,displacement_mm", comments="")  # fmt: skip
        rows.append(f"{cid},bearing,0,100,{amp:g},{cid}.csv")
    _cases_csv(data / "cases.csv", rows)
    model = write_model(_spec(MODEL_MESH, 8), tmp_path / "MODEL.toml")
    assert "bearing" in model.read_text()
    main(["compare", str(model), str(data), "--out", str(tmp_path / "out"), "--json"])
    report = json.loads(capsys.readouterr().out)
    cases = {c["case_id"]: c for c in report["cases"]}
    assert cases["fp100_F300"]["passed"]
    assert not cases["fp100_F200_soft"]["passed"]
    assert (tmp_path / "out" / "model_loops" / "p100_F300.csv").is_file()


@pytest.mark.slow
def test_calibrate_recovers_mu_of_the_fits_from_eta_only_bearing_data(tmp_path, capsys):
    """η-only bearing data (a Table-4-like file) made with μ = 0.3 on a finer mesh; the
    coarse model starts at μ = 0.15. Measured on the first run: μ → 0.312, error 2.16σ →
    0.28σ, compare 2/2."""
    from model.file import write_model
    from model.service import ModelService
    from model.spec import DesignPoint

    data_spec = _spec(DATA_MESH, 16)
    truth = dataclasses.replace(data_spec, cycle=dataclasses.replace(data_spec.cycle, mu=0.3))
    service = ModelService()
    rows = ["preload_N,amplitude_N,eta"]  # no clearance column: read as bearing-hinge data
    for fp, fg in ((100.0, 100.0), (100.0, 300.0)):
        eta = service.run_point(truth, DesignPoint(fg, {"preload_n": fp})).metrics()["eta"]
        rows.append(f"{fp:g},{fg:g},{eta:.6g}")
    (tmp_path / "eta.csv").write_text("\n".join(rows) + "\n")
    start = _spec(MODEL_MESH, 8)
    start = dataclasses.replace(start, cycle=dataclasses.replace(start.cycle, mu=0.15))
    model = write_model(start, tmp_path / "MODEL.toml")
    argv = ["calibrate", str(model), str(tmp_path / "eta.csv"), "--mu", "--json"]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 0
    report = json.loads(capsys.readouterr().out)
    base, fitted = report["ledger"][0], report["ledger"][-1]
    assert fitted["model"]["mu"] == pytest.approx(0.3, rel=0.15)
    assert fitted["error"] < 0.5 * base["error"]
    assert report["compare"]["n_pass"] == 2


def _bonded(mesh: dict, increments: int):  # type: ignore[no-untyped-def]
    spec = _spec(mesh, increments)
    from cad.bearing_geometry import BearingHingeParams

    return dataclasses.replace(spec, hinge=BearingHingeParams())


def test_diagnose_names_a_frame_compliance_hidden_in_bearing_loops(tmp_path):
    """Loops of the tied bearing hinge from a finer mesh, with a test-frame compliance of
    2e-5 mm/N added outside ``synth``, resampled and noised: diagnose must name it, and only
    the effects that act on a loop are candidates for the bearing hinge."""
    from model.service import ModelService
    from model.spec import DesignPoint
    from validation.candidate_fit import DiagnoseSettings
    from validation.diagnose import diagnose
    from validation.measurements import read_measurement_set

    service = ModelService()
    data_spec = _bonded(DATA_MESH, 16)
    data = tmp_path / "data"
    data.mkdir()
    rng = np.random.default_rng(4)
    rows = []
    for fp, fg in ((0.0, 200.0), (100.0, 400.0), (200.0, 300.0)):
        r = service.run_point(data_spec, DesignPoint(fg, {"preload_n": fp}))
        F, d = r.machine_path()
        d = d + 2e-5 * F  # the frame, added here: not one of synth's own effects
        s = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(F)))])
        t = np.linspace(0.0, s[-1], 700)
        Fm = np.interp(t, s, F) + rng.normal(0.0, 0.002 * fg, t.size)
        dm = np.interp(t, s, d) + rng.normal(0.0, 2e-5, t.size)
        cid = f"p{fp:g}_F{fg:g}"
        np.savetxt(data / f"{cid}.csv", np.column_stack([Fm, dm]), delimiter=",",
                   header="force_N,displacement_mm", comments="")  # fmt: skip
        rows.append(f"{cid},bearing,0,{fp:g},{fg:g},{cid}.csv")
    _cases_csv(data / "cases.csv", rows)
    # the loop effect only: interface_friction (a fits cycle per case and grid value, minutes)
    # is the other candidate for the bearing hinge; tests/validation/test_synth_bearing.py
    # diagnoses it
    fast = DiagnoseSettings(
        grid_points=5,
        grid_decades=2.5,
        refine_iter=4,
        increments_per_stage=8,
        candidates=("frame_compliance",),
    )
    d = diagnose(_bonded(MODEL_MESH, 8), read_measurement_set(data), fast)
    assert d.verdict == "effect_missing", d.text()
    assert d.effects == ("frame_compliance",)
    assert d.candidates[0].value == pytest.approx(2e-5, rel=0.2)
    assert "do not act on the bearing hinge" in d.skipped["face_friction"]
    assert d.skipped["interface_friction"] == "not among the candidates asked for"
    with pytest.raises(ParameterError, match=r"unknown effect\(s\) \['frame'\]"):
        diagnose(
            _bonded(MODEL_MESH, 8),
            read_measurement_set(data),
            DiagnoseSettings(candidates=("frame",)),
        )
    assert any("F_p = 200 N" in line for line in d.pattern)  # the bearing's design variable
