"""validation.calibrate: the ledger file and its plot (fast, no FE)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cad.errors import ParameterError
from validation.calibrate import LedgerRow, append_ledger, calibrate, plot_ledger


def _rows():
    return [
        LedgerRow("baseline", {}, 0, 900.0, 10.0, 10.0, 900.0, 900.0),
        LedgerRow(
            "+frame_compliance",
            {"frame_compliance.compliance_mm_per_n": 2e-5},
            1,
            9.0,
            1.0,
            1.2,
            11.0,
            11.5,
        ),
    ]


def test_ledger_appends_rounds_and_plots(tmp_path):
    every = append_ledger(tmp_path, _rows())
    assert [r["step"] for r in every] == ["baseline", "+frame_compliance"]
    second = [
        LedgerRow("baseline", {}, 1, 9.0, 1.0, 1.0, 11.0, 11.5),
        LedgerRow(
            "+roughness_softening",
            {"roughness_softening.compliance_mm3_per_n": 1e-4},
            2,
            8.0,
            0.9,
            1.0,
            12.0,
            13.0,
        ),
    ]
    every = append_ledger(tmp_path, second)  # a second round: its baseline is not repeated
    assert [r["step"] for r in every] == ["baseline", "+frame_compliance", "+roughness_softening"]
    assert json.loads((tmp_path / "ledger.json").read_text()) == every
    csv = (tmp_path / "ledger.csv").read_text().splitlines()
    assert csv[0].startswith("step,params")
    assert len(csv) == 4
    png = plot_ledger(every, tmp_path / "ledger.png")
    assert png.stat().st_size > 5000


def test_calibrate_refuses_unknown_or_present_effects():
    from cad.general_params import GeneralHingeParams
    from model.spec import ModelSpec
    from validation.measurements import MeasurementSet

    spec = ModelSpec(
        "general", GeneralHingeParams(), effects={"frame_compliance": {"compliance_mm_per_n": 1e-5}}
    )
    data = MeasurementSet((), Path("."))  # never read: the names are checked first
    with pytest.raises(ParameterError, match="unknown effect 'nope'"):
        calibrate(spec, data, ["nope"])
    with pytest.raises(ParameterError, match="already in the model"):
        calibrate(spec, data, ["frame_compliance"])


def test_evaluator_set_mu_keeps_its_increments_and_takes_the_new_mu():
    import dataclasses

    from cad.general_params import GeneralHingeParams
    from model.spec import ModelSpec
    from validation.evaluate import ModelEvaluator

    spec = ModelSpec("general", GeneralHingeParams())
    ev = ModelEvaluator(spec, [(0.0, 100.0)], increments_per_stage=6)
    ev.set_mu(dataclasses.replace(spec, cycle=dataclasses.replace(spec.cycle, mu=0.35)))
    assert ev.cycle.mu == 0.35
    assert ev.spec.cycle.mu == 0.35
    assert ev.cycle.increments_per_stage == 6  # the diagnosis protocol is kept


def test_ledger_records_every_parameter_of_the_model(tmp_path):
    """The ledger's model column is what the model file holds: re-tuned values included."""
    import dataclasses

    from cad.general_params import GeneralHingeParams
    from model.file import read_model, write_model
    from model.spec import ModelSpec
    from validation.calibrate import model_parameters

    spec = ModelSpec(
        "general",
        GeneralHingeParams(),
        effects={
            "frame_compliance": {"compliance_mm_per_n": 3.97e-5},
            "interference": {"interference_mm": 0.002},
        },
    )
    spec = dataclasses.replace(spec, cycle=dataclasses.replace(spec.cycle, mu=0.17))
    params = model_parameters(spec)
    assert params == {
        "mu": 0.17,
        "frame_compliance.compliance_mm_per_n": 3.97e-5,
        "interference.interference_mm": 0.002,
    }
    assert model_parameters(read_model(write_model(spec, tmp_path / "M.toml"))) == params
    row = LedgerRow(
        "+interference", {"interference.interference_mm": 0.002}, 2, 1.0, 1.0, 1.0, 5.0, 6.0, params
    )
    append_ledger(tmp_path, [row])
    header, line = (tmp_path / "ledger.csv").read_text().splitlines()
    assert header.endswith(",model")
    assert "frame_compliance.compliance_mm_per_n=3.97e-05" in line


@pytest.mark.slow
def test_calibrate_fits_its_grid_coarse_to_fine_and_its_ledger_is_the_models_mesh(
    tmp_path, monkeypatch
):
    import dataclasses

    import numpy as np

    import validation.calibrate as calibration
    from mesh.settings import MeshSettings
    from validation.candidate_fit import chi2, measured_features
    from validation.evaluate import ModelEvaluator

    from .screen_data import coarse_data_and_finer_model, search_settings

    model, data = coarse_data_and_finer_model(tmp_path, (100.0, 400.0), seed=41)
    settings = search_settings()
    screens = []
    original = calibration.screen_evaluator

    def spy(ev, s):
        screens.append(original(ev, s))
        return screens[-1]

    monkeypatch.setattr(calibration, "screen_evaluator", spy)
    _plain_spec, plain = calibration.calibrate(
        model, data, ["roughness_softening"], dataclasses.replace(settings, screen=False)
    )
    spec, rows = calibration.calibrate(model, data, ["roughness_softening"], settings)
    assert screens[0] is None
    assert screens[1] is not None
    assert screens[1].n_cycles > 0  # the grid ran on the coarse mesh
    assert screens[1].spec.mesh == MeshSettings.coarse()
    key = "roughness_softening.compliance_mm3_per_n"
    assert abs(np.log10(rows[-1].greedy[key] / plain[-1].greedy[key])) < 0.05
    assert rows[-1].chi2 <= 1.05 * plain[-1].chi2 + 1.0
    # the ledger's χ² is the model mesh's own, at the written values
    meas = measured_features(data, settings.features)
    again = chi2(ModelEvaluator(spec, meas.points, 6, 12).features({}), meas)
    assert again == pytest.approx(rows[-1].chi2, rel=1e-9)
