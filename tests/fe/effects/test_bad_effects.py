"""Bad plug-ins: each is refused with one line naming the file (or entry point), the class and
what is wrong; a diagnosis records the candidate as failed and runs the others; nothing
half-written is stored. The hinge is the plug-in kind ``jenkins_pin`` (no FE)."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

from cad.errors import EffectError, HingelabError, ParameterError
from fe.effects import plugins
from model.file import read_model
from model.service import ModelService
from model.spec import DesignPoint
from model.store import ResultStore

HEAD = """from dataclasses import dataclass
import math, time
import numpy as np
from fe.effects.base import Effect, ParamSpec

"""

EFFECT = """@dataclass(frozen=True)
class Bad(Effect):
    name: str = "bad"
    params: tuple = (ParamSpec("c_mm_per_n", 0.0, {hi}, 1e-5, "mm/N", "a compliance"),)

    def post(self, history, values):
        {body}
"""

GOOD_BODY = "return history.disp_mm + values['c_mm_per_n'] * history.force_n"

MODEL = """[hinge]
kind = "jenkins_pin"

[effects.bad]
from = "bad.py:Bad"
{params}"""

POINT = DesignPoint(400.0, {"slip_force_n": 60.0})


def write(tmp_path: Path, code: str, params: str = "c_mm_per_n = 1e-5\n") -> Path:
    (tmp_path / "bad.py").write_text(HEAD + code)
    path = tmp_path / "MODEL.toml"
    path.write_text(MODEL.format(params=params))
    return path


def refused(tmp_path: Path, code: str) -> str:
    with pytest.raises(ParameterError) as err:
        read_model(write(tmp_path, code))
    text = str(err.value)
    assert "\n" not in text
    assert str(tmp_path / "bad.py") in text
    assert "[effects.bad]" in text
    return text


def failed_run(tmp_path: Path, body: str) -> str:
    spec = read_model(write(tmp_path, EFFECT.format(hi=1e-3, body=body)))
    with pytest.raises(EffectError) as err:
        ModelService().run_point(spec, POINT)
    text = str(err.value)
    assert "\n" not in text
    assert f"{tmp_path / 'bad.py'}:Bad" in text
    assert "Bad.post" in text
    return text


def test_a_missing_file_is_named(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = write(tmp_path, "")
    (tmp_path / "bad.py").unlink()
    with pytest.raises(
        ParameterError,
        match=r"\[effects.bad\]: from = 'bad.py:Bad': effect file .*bad.py not found",
    ):
        read_model(path)


def test_a_class_that_is_not_an_effect(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    text = refused(tmp_path, "class Bad:\n    pass\n")
    assert text.endswith("class Bad is not a subclass of fe.effects.base.Effect")


def test_a_name_that_the_file_does_not_have(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    assert refused(tmp_path, "class Other:\n    pass\n").endswith("the file has no 'Bad'")


@pytest.mark.parametrize("hi", ["math.inf", "math.nan"], ids=["infinite", "nan"])
def test_a_parameter_without_finite_bounds(jenkins, tmp_path, hi) -> None:  # type: ignore[no-untyped-def]
    text = refused(tmp_path, EFFECT.format(hi=hi, body=GOOD_BODY))
    assert "c_mm_per_n: range must be finite" in text


def test_a_parameter_made_around_its_checks(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A ParamSpec built without its ``__post_init__`` is checked again on loading."""
    code = textwrap.dedent("""
        _p = object.__new__(ParamSpec)
        for k, v in dict(name="c_mm_per_n", lo=0.0, hi=math.inf, default=0.0, unit="", doc="").items():
            object.__setattr__(_p, k, v)

        @dataclass(frozen=True)
        class Bad(Effect):
            name: str = "bad"
            params: tuple = (_p,)
    """)
    text = refused(tmp_path, code)
    assert "Bad parameter c_mm_per_n: range must be finite" in text


def test_an_effect_that_raises(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    text = failed_run(tmp_path, "return 1 // 0")
    assert "Bad.post raised ZeroDivisionError" in text


def test_an_effect_that_returns_nan(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    text = failed_run(tmp_path, "return history.disp_mm * np.nan")
    assert "Bad.post displacement is not finite at" in text


def test_an_effect_that_returns_the_wrong_shape(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    text = failed_run(tmp_path, "return history.disp_mm[:3]")
    assert "Bad.post displacement has shape (3,), expected (" in text


def test_a_slow_effect_is_refused_after_its_call(jenkins, tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setattr(plugins, "CALL_LIMIT_S", 0.02)
    text = failed_run(tmp_path, "time.sleep(0.05)\n        return history.disp_mm")
    assert "Bad.post took" in text
    assert "more than the 0.02 s a call may take" in text


def test_a_failing_effect_stores_nothing(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    spec = read_model(write(tmp_path, EFFECT.format(hi=1e-3, body="raise RuntimeError('no')")))
    store = ResultStore(tmp_path / "store")
    (run,) = ModelService(store=store).run(spec, [POINT])
    assert not run.ok
    assert "Bad.post raised RuntimeError: no" in (run.error or "")
    assert not (tmp_path / "store").exists() or not any((tmp_path / "store").iterdir())


def test_a_broken_entry_point_is_named_and_the_others_still_load(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    from fe.effects.registry import REGISTRY, effect_entry, unregister_effect, validate_effects

    dist = tmp_path / "hingelab_broken-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: hingelab-broken\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[hingelab.effects]\nbroken = no_such_module:Thing\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        assert "broken" in REGISTRY
        with pytest.raises(ParameterError, match=r"entry point broken = 'no_such_module:Thing' "
                           r"\(hingelab.effects\): ModuleNotFoundError"):  # fmt: skip
            effect_entry("broken")
        assert validate_effects({"frame_compliance": {}})  # the others are not held up
    finally:
        unregister_effect("broken")


def test_diagnose_records_a_failing_candidate_and_runs_the_others(
    jenkins, tmp_path, capsys
) -> None:  # type: ignore[no-untyped-def]
    """A declared user effect whose hook raises is 'failed: …'; the hidden compliance is found."""
    from studies.cli.main import main

    data = tmp_path / "data"
    model = write(tmp_path, EFFECT.format(hi=1e-3, body="raise ValueError('broken')"), params="")
    cases = "30:200,400;60:200,400;90:200,400"
    argv = ["synth", str(model), "--effect", "frame_compliance:compliance_mm_per_n=2e-5"]
    assert main([*argv, "--cases", cases, "--seed", "4", "--out", str(data)]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(model), str(data), "--json"]) == 0
    verdict = json.loads(capsys.readouterr().out)
    assert verdict["effects"] == ["frame_compliance"]
    why = verdict["skipped"]["bad"]
    assert why.startswith("failed: ")
    assert f"{tmp_path / 'bad.py'}:Bad: Bad.post raised" in why
    assert "bad" not in [c["name"] for c in verdict["candidates"]]
    assert isinstance(EffectError("x"), HingelabError)
