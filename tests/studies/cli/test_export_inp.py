"""``hingelab export-inp`` end to end: a deck from a model file, overrides, clear errors."""

from __future__ import annotations

import json

import pytest

from cad.general_params import GeneralHingeParams
from fe.cycle.protocol import CycleSettings
from mesh.settings import MeshSettings
from model.file import write_model
from model.spec import ModelSpec
from studies.cli.main import main


@pytest.fixture
def model_file(tmp_path):
    spec = ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(amplitude_n=250.0, mu=0.15),
    )
    return write_model(spec, tmp_path / "MODEL.toml")


def test_deck_from_model_file_with_overrides(tmp_path, capsys, model_file):
    out = tmp_path / "deck" / "model.inp"
    argv = ["export-inp", str(model_file), "--out", str(out), "--json", "--contact", "node"]
    assert main([*argv, "--amplitude", "300", "--clearance", "0.1", "--mu", "0.3"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["amplitude_N"] == 300.0
    assert summary["mu"] == 0.3
    assert summary["clearance_mm"] == 0.1
    assert summary["pairs"] == ["pin-tang", "pin-clevis_1", "pin-clevis_2"]
    text = out.read_text()
    assert text.count("*STEP") == 3
    assert text.count("*CONTACT PAIR") == 3
    assert "*FRICTION\n0.3, " in text
    # With clearance the grip spring's force at the touching configuration (50 N/mm · 2Δr)
    # is added to the *CLOAD, so the hinge carries 300 N.
    assert "grip_ref, 1, 310.\n" in text
    assert "grip_ref, 1, -310.\n" in text


def test_model_file_values_are_the_defaults(tmp_path, capsys, model_file):
    out = tmp_path / "m.inp"
    assert main(["export-inp", str(model_file), "--out", str(out)]) == 0
    assert "ccx -i m" in capsys.readouterr().out
    text = out.read_text()
    assert "grip_ref, 1, 250.\n" in text
    assert "*FRICTION\n0.15, " in text


def test_default_deck_is_mortar_on_the_conforming_mesh(tmp_path, capsys, model_file):
    """The default is the deck ccx completes (issue 33, item 9): DeckSettings.exact_mortar —
    mortar pairs, hard contact (no *SURFACE BEHAVIOR), no ADJUST — on the model's mesh sizes
    with pin and hole nodes at the same angles; no caution is printed."""
    out = tmp_path / "mortar.inp"
    assert main(["export-inp", str(model_file), "--out", str(out), "--json"]) == 0
    cap = capsys.readouterr()
    summary = json.loads(cap.out)
    assert (summary["contact"], summary["mesh"]) == ("MORTAR", "conforming")
    assert "caution" not in summary
    assert cap.err == ""
    text = out.read_text()
    assert text.count("TYPE=MORTAR") == 3
    assert "\n*SURFACE BEHAVIOR" not in text
    assert "ADJUST=" not in text
    # the model's own (graded) mesh is another mesh: more elements around the load line
    model = tmp_path / "model.inp"
    assert (
        main(["export-inp", str(model_file), "--out", str(model), "--json", "--mesh", "model"]) == 0
    )
    own = json.loads(capsys.readouterr().out)
    assert own["n_nodes"] != summary["n_nodes"]
    assert "--mesh conforming" in own["caution"]


def test_penalty_contact_is_written_with_a_caution(tmp_path, capsys, model_file):
    """Node-to-surface keeps its penalty cards, and says on stderr that ccx may not finish it
    and which options make a deck that completes."""
    node = tmp_path / "node.inp"
    assert main(["export-inp", str(model_file), "--out", str(node), "--contact", "node"]) == 0
    err = capsys.readouterr().err
    assert "\n*SURFACE BEHAVIOR" in node.read_text()
    assert err.startswith("caution: --contact node is penalty contact")
    assert "--contact mortar --mesh conforming" in err
    assert err.count("\n") == 1


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--mu", "-1"], "--mu must be in [0, 2], got -1.0"),
        (["--amplitude", "0"], "--amplitude must be in (0, 1e+06], got 0.0"),
        (["--clearance", "-0.1"], "--clearance must be in [0, 5], got -0.1"),
        (["--penalty", "0"], "--penalty must be in (0, 1e+12], got 0.0"),
    ],
    ids=["mu", "amplitude", "clearance", "penalty"],
)
def test_bad_parameter_exits_1_with_one_line(tmp_path, capsys, model_file, extra, needle):
    assert main(["export-inp", str(model_file), "--out", str(tmp_path / "m.inp"), *extra]) == 1
    err = capsys.readouterr().err
    assert needle in err
    assert err.startswith("hingelab export-inp: error:")
    assert err.count("\n") == 1


def test_wrong_suffix_and_missing_model(tmp_path, capsys, model_file):
    assert main(["export-inp", str(model_file), "--out", str(tmp_path / "m.txt")]) == 1
    assert "out must end in .inp" in capsys.readouterr().err
    assert main(["export-inp", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "m.inp")]) == 1
    assert "model file not found" in capsys.readouterr().err
