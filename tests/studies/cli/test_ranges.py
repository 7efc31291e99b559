"""One range per parameter: every command and file that refuses a clearance or a preload
states the same allowed range (issue 33: the sweep said [0, 10], the model [0, 5])."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from cad.bearing_geometry import MAX_PRELOAD_N, BearingHingeParams
from cad.errors import ParameterError
from cad.general_params import MIN_WALL_MM, GeneralHingeParams
from fe.kinds.bearing import PRELOAD
from fe.kinds.general import CLEARANCE
from studies.cli.main import main

EXAMPLES = Path(__file__).parents[3] / "studies" / "examples"
GENERAL = EXAMPLES / "MODEL.toml"


def _places(value: str, tmp: Path) -> dict[str, list[str]]:
    """Where a user gives the general hinge's clearance, as command lines."""
    (tmp / "study.toml").write_text(f"[design.clearance_mm]\nlevels = [{value}]\n")
    (tmp / "model.toml").write_text(f'[hinge]\nkind = "general"\nclearance_mm = {value}\n')
    out = str(tmp / "out")
    return {
        "cycle --clearance": ["cycle", "--clearance", value, "--out", out],
        "sweep --levels": ["sweep", "--levels", value, "--out", out],
        "sweep --clearance": ["sweep", "--clearance", value, "--out", out],
        "export-inp --clearance": [
            "export-inp",
            str(GENERAL),
            "--clearance",
            value,
            "--out",
            out + ".inp",
        ],
        "synth --cases": ["synth", str(GENERAL), f"--cases={value}:100", "--out", out],
        "study file": ["study", str(tmp / "study.toml"), "--out", out, "--dry-run"],
        "MODEL.toml": ["cycle", "--model", str(tmp / "model.toml"), "--out", out],
    }


def _range(capsys, argv: list[str], name: str) -> str:
    assert main(argv) == 1
    err = capsys.readouterr().err
    found = re.findall(rf"{name} must be in (\[[^\]]*\])", err)
    assert len(found) == 1, err
    return found[0]


@pytest.mark.parametrize(
    "value", ["7", "20", "-0.5"], ids=["above-geometry", "above-cap", "negative"]
)
def test_the_clearance_range_is_the_same_everywhere(tmp_path, capsys, value):
    # the default geometry: a hole in a 20 mm lug round a 4 mm pin keeps a 1 mm wall
    expected = f"[0, {20.0 / 2 - 4.0 - MIN_WALL_MM:g}]"
    stated = {
        where: _range(capsys, argv, r"(?:--clearance|--levels|clearance_mm)")
        for where, argv in _places(value, tmp_path).items()
    }
    assert stated == dict.fromkeys(stated, expected)


def test_the_preload_range_is_the_same_everywhere(tmp_path, capsys):
    (tmp_path / "bearing.toml").write_text('[hinge]\nkind = "bearing"\npreload_n = 900\n')
    (tmp_path / "base.toml").write_text('[hinge]\nkind = "bearing"\n')
    (tmp_path / "study.toml").write_text(
        '[study]\nmodel = "base.toml"\n[design.preload_N]\nlevels = [900]\n'
    )
    out = str(tmp_path / "out")
    places = {
        "cycle --preload": ["cycle", "--hinge", "bearing", "--preload", "900", "--out", out],
        "sweep --levels": ["sweep", "--hinge", "bearing", "--levels", "900", "--out", out],
        "study file": ["study", str(tmp_path / "study.toml"), "--out", out, "--dry-run"],
        "MODEL.toml": ["cycle", "--model", str(tmp_path / "bearing.toml"), "--out", out],
    }
    stated = {
        where: _range(capsys, argv, r"(?:--preload|--levels|preload_N|preload_n)")
        for where, argv in places.items()
    }
    assert stated == dict.fromkeys(stated, f"[0, {MAX_PRELOAD_N:g}]")


@pytest.mark.parametrize(
    ("pin", "lug", "bound"),
    [(4.0, 20.0, 5.0), (2.0, 10.0, 2.0), (4.0, 60.0, 10.0)],
    ids=["default", "small-lug", "capped"],
)
def test_the_design_variable_states_the_parameters_range(pin, lug, bound):
    size = {
        "pin_radius_mm": pin,
        "lug_width_mm": lug,
        "tang_length_mm": lug,
        "clevis_length_mm": lug,
    }
    params = GeneralHingeParams(**size)
    assert CLEARANCE.bounds(params) == (0.0, pytest.approx(bound))
    assert params.max_clearance_mm == pytest.approx(bound)
    too_big = bound + 0.5
    with pytest.raises(ParameterError) as by_variable:
        CLEARANCE.check(too_big, params)
    with pytest.raises(ParameterError) as by_params:
        GeneralHingeParams(**size, clearance_mm=too_big)
    assert str(by_variable.value) == str(by_params.value)
    CLEARANCE.check(bound, params)  # the bound itself is allowed
    GeneralHingeParams(**size, clearance_mm=bound)


def test_the_preload_variable_and_parameters_agree():
    with pytest.raises(ParameterError) as by_variable:
        PRELOAD.check(MAX_PRELOAD_N + 1, BearingHingeParams())
    with pytest.raises(ParameterError) as by_params:
        BearingHingeParams(preload_n=MAX_PRELOAD_N + 1)
    assert str(by_variable.value) == str(by_params.value)
