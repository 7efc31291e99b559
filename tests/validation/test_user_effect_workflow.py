"""A user's rate-dependent effect, in a file next to MODEL.toml, through diagnose → calibrate → compare.

The hinge is the plug-in kind ``jenkins_pin`` (no FE, a diagnosis in seconds); the data are
made by ``synth`` with the effect hidden (the synthetic machine's noise and offsets, its
own clock at 20 N/s). The effect is the documented example ``studies/examples/effects/damper.py``.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from model.file import read_model
from studies.cli.main import main

EXAMPLE = Path(__file__).parents[2] / "studies" / "examples" / "effects" / "damper.py"
MODEL = """[hinge]
kind = "jenkins_pin"

[cycle]
increments_per_stage = 12

[effects.damper]
from = "effects/damper.py:Damper"
"""


def test_a_users_damper_is_diagnosed_calibrated_and_compared(jenkins, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    (tmp_path / "effects").mkdir()
    shutil.copy(EXAMPLE, tmp_path / "effects" / "damper.py")
    model = tmp_path / "MODEL.toml"
    model.write_text(MODEL)
    data = tmp_path / "data"
    cases = "30:200,400;90:200,400"
    hidden = "damper:fluidity_mm_per_ns=5e-6"
    argv = ["synth", str(model), "--effect", hidden, "--cases", cases, "--seed", "2"]
    assert main([*argv, "--out", str(data)]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(model), str(data), "--json"]) == 0
    verdict = json.loads(capsys.readouterr().out)
    assert verdict["verdict"] == "effect_missing", verdict["message"]
    assert verdict["effects"] == ["damper"]
    out = tmp_path / "cal"
    argv = ["calibrate", str(model), str(data), "--effects", "damper", "--out", str(out), "--json"]
    argv += ["--no-compare"]  # compare runs below, without its pictures
    assert main(argv) == 0
    capsys.readouterr()
    written = next(out.glob("*.toml"))
    assert 'from = "../effects/damper.py:Damper"' in written.read_text()
    fitted = read_model(written).effects["damper"]["fluidity_mm_per_ns"]
    assert fitted == pytest.approx(5e-6, rel=0.2)
    strict = ["--no-plots", "--fail-on-mismatch"]
    assert main(["compare", str(written), str(data), "--out", str(tmp_path / "cmp"), *strict]) == 0
    assert main(["compare", str(model), str(data), "--out", str(tmp_path / "base"), *strict]) == 2
