"""``synth`` of the bearing hinge: preload × amplitude cases, from a finer mesh, read back as data."""

from __future__ import annotations

import json

import pytest

from cad.errors import ParameterError
from fe.kinds import hinge_kind
from validation.synth import SynthSettings, default_design, design_cases, parse_design

COARSE = {"size_mm": 4.0, "contact_size_mm": 0.8, "part_sizes_mm": (("ring", 1.2),)}


def _bonded(increments=8):  # type: ignore[no-untyped-def]
    from cad.bearing_geometry import BearingHingeParams
    from fe.cycle.protocol import CycleSettings
    from model.spec import ModelSpec

    return ModelSpec(
        "bearing",
        BearingHingeParams(),
        hinge_kind("bearing").mesh_settings(**COARSE),
        CycleSettings(mu=0.2, increments_per_stage=increments),
    )


def test_bearing_design_is_preload_by_amplitude():
    cases = design_cases(default_design("bearing"), "bearing")
    assert len(cases) == 9
    assert {c.values for c in cases} == {(("preload_n", x),) for x in (0.0, 100.0, 200.0)}
    assert cases[3].case_id == "fp100N_F100N"
    assert cases[3].design_value == 100.0
    assert design_cases(parse_design("0.1:100"))[0].values == (("clearance_mm", 0.1),)
    with pytest.raises(ParameterError, match=r"preload_n must be in \[0, 500\], got 600"):
        design_cases(parse_design("600:100", "preload_n"), "bearing")
    with pytest.raises(ParameterError, match=r"'100-200' is not preload_n:amplitude_N"):
        parse_design("100-200", "preload_n")
    with pytest.raises(ParameterError, match="F_p = 100 N, Fg = 200 N is repeated"):
        design_cases(parse_design("100:200,200"), "bearing")
    with pytest.raises(ParameterError, match="hinge kind must be one of"):
        design_cases(default_design("bearing"), "hinge")


def test_cases_must_match_the_model_kind(tmp_path):
    from validation.synth import synthesize

    general_cases = design_cases(parse_design("0:100"))
    with pytest.raises(
        ParameterError, match=r"general-hinge case, but the model is kind 'bearing'"
    ):
        synthesize(_bonded(), {}, general_cases, SynthSettings(), tmp_path / "x")
    assert not (tmp_path / "x").exists()  # nothing half-written


@pytest.mark.slow
def test_bearing_set_from_a_finer_mesh_with_a_hidden_frame(tmp_path, capsys):
    """Through the CLI: two cases of the tied bearing hinge with a hidden frame compliance;
    the set reads back as bearing data whose peak displacement exceeds the coarse model's by
    the frame's C_f·Fg (to the mesh difference and the noise), and compare says so."""
    from model.file import write_model
    from studies.cli.main import main
    from validation.compare import compare
    from validation.measurements import read_measurement_set
    from validation.workflow import run_model_for_cases

    model = write_model(_bonded(), tmp_path / "MODEL.toml")
    out = tmp_path / "set"
    c_f = 2e-5
    argv = ["synth", str(model), "--effect", f"frame_compliance:compliance_mm_per_n={c_f}"]
    argv += ["--cases", "0:300;200:150", "--seed", "3", "--out", str(out), "--json"]
    assert main(argv) == 0
    manifest = json.loads(capsys.readouterr().out)
    assert manifest["hinge"] == "bearing"
    assert [c["preload_n"] for c in manifest["cases"]] == [0.0, 200.0]
    assert all(c["n_contact_points"] == 40 for c in manifest["cases"])  # 2 per ball
    assert manifest["synth_mesh"]["contact_size_mm"] < manifest["model_mesh"]["contact_size_mm"]
    data = read_measurement_set(out)
    assert [(c.hinge, c.values["preload_n"], c.amplitude_n) for c in data.cases] == [
        ("bearing", 0.0, 300.0),
        ("bearing", 200.0, 150.0),
    ]
    models, _ = run_model_for_cases(_bonded(), data.cases)
    for cmp in compare(models, data).cases:
        extra = cmp.measured["disp_at_peak_mm"] - cmp.model["disp_at_peak_mm"]  # [mm]
        frame = c_f * cmp.case.amplitude_n
        assert extra == pytest.approx(frame, rel=0.35), (cmp.case.case_id, extra, frame)


@pytest.mark.slow
def test_diagnose_names_interface_friction_hidden_in_bearing_data(tmp_path):
    """Loops of the bearing hinge whose fits slip (μ_interface 0.3, hidden) from synth's
    finer mesh, judged against the bonded model (which has no loop): diagnose must name
    interface_friction and fit its μ near 0.3; frame_compliance (which cannot make a loop)
    must not explain them."""
    from validation.candidate_fit import DiagnoseSettings
    from validation.diagnose import diagnose
    from validation.measurements import read_measurement_set
    from validation.synth import synthesize

    out = tmp_path / "set"
    hidden = {"interface_friction": {"mu_interface": 0.3}}
    cases = design_cases(parse_design("0:300;100:150;200:400", "preload_n"), "bearing")
    synthesize(_bonded(), hidden, cases, SynthSettings(seed=7), out)
    fast = DiagnoseSettings(grid_points=5, grid_decades=2.0, refine_iter=6, increments_per_stage=8)
    d = diagnose(_bonded(), read_measurement_set(out), fast)
    assert d.verdict in ("effect_missing", "indistinguishable"), d.text()
    assert d.effects[0] == "interface_friction", d.text()
    fit = next(c for c in d.candidates if c.name == "interface_friction")
    assert fit.value == pytest.approx(0.3, rel=0.3), d.text()
    frame = next(c for c in d.candidates if c.name == "frame_compliance")
    assert frame.chi2 > 10 * fit.chi2
