"""Refusals name what the user typed: the command-line option or the file key, not the field.

The dataclasses check their own fields (``increments_per_stage``); each command lists the
fields its options set (``FIELD_OPTIONS``), and ``main`` words a refusal in the option. The
walk below covers every entry of every command's mapping: the option exists in that
command's parser, the dataclass that checks the field says which field it refused, and the
refusal reaches the user under the option's name.
"""

from __future__ import annotations

import argparse
import importlib
import re
from pathlib import Path
from typing import Any

import pytest

from cad.bearing_geometry import BearingHingeParams
from cad.errors import ParameterError, check_range
from cad.general_params import GeneralHingeParams
from fe.cycle.protocol import CycleSettings
from fe.interop.deck_settings import DeckSettings
from mesh.settings import MeshSettings
from model.cluster import Cluster
from rsm.polynomial import monomial_exponents
from studies.cli.args import in_user_terms
from studies.cli.main import SUBCOMMAND_MODULES, build_parser, main
from studies.paper.study import PaperStudy
from validation.candidate_fit import DiagnoseSettings
from validation.compare import CompareSettings
from validation.features import FeatureSettings
from validation.synth import SynthSettings

EXAMPLES = Path(__file__).parents[3] / "studies" / "examples"

REFUSALS: dict[str, Any] = {
    "amplitude_n": lambda: CycleSettings(amplitude_n=-1.0),
    "mu": lambda: CycleSettings(mu=-1.0),
    "increments_per_stage": lambda: CycleSettings(increments_per_stage=1),
    "clearance_increments": lambda: CycleSettings(clearance_increments=1),
    "n_cycles": lambda: CycleSettings(n_cycles=0),
    "clearance_mm": lambda: GeneralHingeParams(clearance_mm=-1.0),
    "preload_n": lambda: BearingHingeParams(preload_n=-1.0),
    "refinement": lambda: MeshSettings(refinement=9),
    "size_mm": lambda: MeshSettings(size_mm=0.0),
    "contact_size_mm": lambda: MeshSettings(contact_size_mm=2.0, size_mm=1.0),
    "penalty_mpa_per_mm": lambda: DeckSettings(penalty_mpa_per_mm=-1.0),
    "stick_slope_mpa_per_mm": lambda: DeckSettings(stick_slope_mpa_per_mm=0.0),
    "noise_force_n": lambda: SynthSettings(noise_force_n=-1.0),
    "noise_disp_mm": lambda: SynthSettings(noise_disp_mm=-1.0),
    "seed": lambda: SynthSettings(seed=-1),
    "k": lambda: CompareSettings(k=-1.0),
    "default_rel_uncertainty": lambda: CompareSettings(default_rel_uncertainty=-1.0),
    "eta_rel_sigma": lambda: FeatureSettings(eta_rel_sigma=-1.0),
    "rel_floor": lambda: FeatureSettings(rel_floor=-1.0),
    "candidates": lambda: DiagnoseSettings(candidates=("no_such_effect",)),
    "points": lambda: PaperStudy(points=-1),
    "degree": lambda: monomial_exponents(2, 9),
    "workers": lambda: Cluster(workers=0),
}
"""Field → a call that makes the dataclass (or function) that checks it refuse it."""


def _command_modules() -> dict[str, Any]:
    return {
        m.rsplit(".", 1)[1].replace("_", "-"): importlib.import_module(m)
        for m in SUBCOMMAND_MODULES
    }


def _options(parser: argparse.ArgumentParser) -> set[str]:
    """Every option string of a parser and of its nested subcommands (``rsm fit --degree``)."""
    out = set(parser._option_string_actions)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                out |= _options(sub)
    return out


def _mapping() -> list[tuple[str, str, str]]:
    return [
        (command, field, option)
        for command, module in _command_modules().items()
        for field, options in getattr(module, "FIELD_OPTIONS", {}).items()
        for option in options
    ]


def test_the_mapping_covers_the_commands_whose_options_set_fields():
    commands = {c for c, _, _ in _mapping()}
    assert commands >= {"cycle", "sweep", "mesh", "export-inp", "synth", "compare", "diagnose"}
    assert commands >= {"calibrate", "paper", "rsm"}


MAPPING = _mapping()


@pytest.mark.parametrize(
    ("command", "field", "option"), MAPPING, ids=[f"{c}{o}-{f}" for c, f, o in MAPPING]
)
def test_every_mapped_field_reaches_the_user_as_the_option(command, field, option):
    sub = next(
        a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)
    ).choices[command]
    assert option in _options(sub), f"{command} has no option {option}"
    with pytest.raises(ParameterError) as caught:
        REFUSALS[field]()
    err = caught.value
    assert err.parameter == field  # the dataclass says which field it refused
    typed = argparse.Namespace(**{option.lstrip("-").replace("-", "_"): 1.0})
    text = str(in_user_terms(err, typed, {field: (option,)}))
    assert text.startswith(option + " ") or text.startswith(option + ": "), text
    assert not re.search(rf"\b{field}\b", text.replace(option, "")), text
    # an option the user did not give renames nothing: the value came from a file or default
    assert str(in_user_terms(err, argparse.Namespace(), {field: (option,)})) == str(err)


def test_check_range_records_the_parameter_and_renaming_keeps_the_range():
    with pytest.raises(ParameterError) as caught:
        check_range("increments_per_stage", 1, 2, 10_000)
    assert caught.value.parameter == "increments_per_stage"
    renamed = caught.value.renamed("--increments")
    assert str(renamed) == "--increments must be in [2, 10000], got 1"
    assert renamed.parameter == "--increments"
    plain = ParameterError("give the levels once")  # no parameter: left as it is
    assert plain.renamed("--levels") is plain


def _run(capsys, argv: list[str]) -> str:
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["cycle", "--increments", "1"], "--increments must be in [2, 10000], got 1"),
        (["cycle", "--cycles", "0"], "--cycles must be in [1, 100], got 0"),
        (["cycle", "--refinement", "7"], "--refinement must be an integer in [0, 4], got 7"),
        (
            ["cycle", "--model", str(EXAMPLES / "MODEL.toml"), "--increments", "1"],
            "--increments must be in [2, 10000], got 1",
        ),
        (["sweep", "--levels", "0,-1"], "--levels must be in [0, 5], got -1.0"),
        (["sweep", "--increments", "1"], "--increments must be in [2, 10000], got 1"),
        (
            ["export-inp", str(EXAMPLES / "MODEL.toml"), "--penalty", "-1"],
            "--penalty must be in (0, 1e+12], got -1.0",
        ),
        (
            ["export-inp", str(EXAMPLES / "MODEL.toml"), "--stick-slope", "0"],
            "--stick-slope must be in (0, 1e+12], got 0.0",
        ),
        (
            ["synth", str(EXAMPLES / "MODEL.toml"), "--noise-force", "-1"],
            "--noise-force must be in [0, 100], got -1.0",
        ),
        (
            ["diagnose", str(EXAMPLES / "MODEL.toml"), "DATA", "--model-error", "-1"],
            "--model-error must be in [0, 1], got -1.0",
        ),
        (
            ["diagnose", str(EXAMPLES / "MODEL.toml"), "DATA", "--candidates", "frame"],
            "--candidates: unknown effect(s) ['frame']; known: frame_compliance,",
        ),
    ],
    ids=[
        "cycle-increments",
        "cycle-cycles",
        "cycle-refinement",
        "cycle-model-increments",
        "sweep-levels",
        "sweep-increments",
        "export-penalty",
        "export-stick-slope",
        "synth-noise",
        "diagnose-model-error",
        "diagnose-candidates",
    ],
)
def test_a_refusal_names_the_option_typed(tmp_path, capsys, argv, expected):
    argv = [str(EXAMPLES / "measurements") if a == "DATA" else a for a in argv]
    out = ["--out", str(tmp_path / ("x.inp" if argv[0] == "export-inp" else "out"))]
    err = _run(capsys, argv + ([] if argv[0] == "diagnose" else out))
    assert err.startswith(f"hingelab {argv[0]}: error: {expected}")


@pytest.mark.parametrize(
    ("section", "text", "expected"),
    [
        (
            "cycle",
            "increments_per_stage = 1",
            "[cycle]: increments_per_stage must be in [2, 10000]",
        ),
        ("friction", "mu = -1", "[friction]: mu must be in [0, 2], got -1.0"),
    ],
    ids=["cycle-key", "friction-key"],
)
def test_a_model_file_refusal_names_its_section_and_key(tmp_path, capsys, section, text, expected):
    model = tmp_path / "MODEL.toml"
    model.write_text(f'[hinge]\nkind = "general"\n[{section}]\n{text}\n')
    err = _run(capsys, ["cycle", "--model", str(model), "--out", str(tmp_path / "out")])
    assert f"{model}: {expected}" in err
    assert "--" not in err.replace(str(tmp_path), "")  # no option was typed for it


def test_a_study_file_refusal_names_the_key_written(tmp_path, capsys):
    study = tmp_path / "study.toml"
    study.write_text("[solver]\nincrements = 1\n[design.amplitude_N]\nlevels = [100.0, 200.0]\n")
    err = _run(capsys, ["study", str(study), "--out", str(tmp_path / "out"), "--dry-run"])
    assert "[solver] increments must be in [2, 10000], got 1" in err
    study.write_text("[design.amplitude_N]\nlevels = [100.0, -5.0]\n")
    err = _run(capsys, ["study", str(study), "--out", str(tmp_path / "out"), "--dry-run"])
    assert "point 2 (clearance_mm = 0, amplitude_N = -5): amplitude_N must be in (0, 1e+06]" in err
