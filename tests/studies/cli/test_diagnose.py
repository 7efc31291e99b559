"""``hingelab diagnose`` and ``hingelab calibrate``: argument wiring and output (the FE is stubbed)."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest

from studies.cli.main import main


@pytest.fixture
def model_path(tmp_path):
    from cad.general_params import GeneralHingeParams
    from model.file import write_model
    from model.spec import ModelSpec

    return write_model(ModelSpec("general", GeneralHingeParams()), tmp_path / "MODEL.toml")


@pytest.fixture
def stubs(monkeypatch):
    import validation.calibrate
    import validation.diagnose
    import validation.measurements
    from validation.calibrate import LedgerRow
    from validation.diagnose import Diagnosis

    def fake_diagnose(spec, data, settings=None, evaluator=None, **kwargs):
        return Diagnosis(
            "no_missing_effect",
            (),
            "consistent",
            ("no systematic pattern beyond the noise",),
            12,
            10.0,
            26.2,
            (),
            {},
            None,
            {"n_cycles": 0, "wall_s": 0.0},
        )

    def fake_calibrate(spec, data, names, settings=None, fit_mu=False, **kwargs):
        rows = [
            LedgerRow("baseline", {}, 0, 900.0, 8.7, 8.7, 900.0, 900.0),
            LedgerRow(
                "+frame_compliance",
                {"frame_compliance.compliance_mm_per_n": 2e-5},
                1,
                12.0,
                1.0,
                1.1,
                14.0,
                14.5,
            ),
        ]
        import dataclasses

        return dataclasses.replace(
            spec, effects={"frame_compliance": {"compliance_mm_per_n": 2e-5}}
        ), rows

    monkeypatch.setattr(validation.diagnose, "diagnose", fake_diagnose)
    monkeypatch.setattr(validation.calibrate, "calibrate", fake_calibrate)
    no_cases = types.SimpleNamespace(cases=())  # a force-controlled set as far as the CLI asks
    monkeypatch.setattr(validation.measurements, "read_measurement_set", lambda path: no_cases)

    import validation.workflow

    compared = []

    def fake_compare_and_write(spec, data, out, settings, **kw):
        compared.append((spec, out))
        case = types.SimpleNamespace(case=types.SimpleNamespace(case_id="c1"), passed=True)
        return types.SimpleNamespace(summary={"n_pass": 1, "n_cases": 1}, cases=[case]), {}

    monkeypatch.setattr(validation.workflow, "compare_and_write", fake_compare_and_write)
    return compared


def test_diagnose_prints_json(model_path, tmp_path, stubs, capsys):
    assert main(["diagnose", str(model_path), str(tmp_path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["verdict"] == "no_missing_effect"
    assert out["features"] == ["delta_max_mm", "W_cycle_Nmm", "opening_mm"]


def test_calibrate_writes_model_ledger_and_plot(model_path, tmp_path, stubs, capsys):
    from fe.effects.registry import REGISTRY
    from model.file import read_model

    out = tmp_path / "cal"
    argv = [
        "calibrate",
        str(model_path),
        str(tmp_path),
        "--effects",
        "frame_compliance",
        "--out",
        str(out),
    ]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "+frame_compliance" in printed
    assert "compare with the new model: 1/1 cases pass" in printed
    ((compared_spec, folder),) = stubs  # the comparison re-ran with the calibrated model
    assert compared_spec.effects["frame_compliance"]["compliance_mm_per_n"] == 2e-5
    assert folder == out / "compare"
    spec = read_model(out / "MODEL.toml", REGISTRY)
    assert np.isclose(spec.effects["frame_compliance"]["compliance_mm_per_n"], 2e-5)
    assert (out / "ledger.png").is_file()
    assert (out / "ledger.csv").is_file()
    assert [r["step"] for r in json.loads((out / "ledger.json").read_text())] == [
        "baseline",
        "+frame_compliance",
    ]
