"""The worked example of docs/worked_example_user_effect.md, on data from an independent generator.

The records come from ``worked_example_data`` (a Jenkins element with a Kelvin–Voigt element
in series, integrated by ``solve_ivp`` at the records' own clocks, three loading rates,
noise and a displacement zero of 0.37 mm) — not from ``synth`` and not from the example's
``Damper`` class. The chain is the one the doc shows, through the CLI: ``diagnose`` with
the built-ins → the user's damper declared → ``calibrate --effects damper`` → ``compare``.
A null set (the same generator without the dashpot) must stay quiet.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from studies.cli.main import main

from .worked_example_data import PHI, write_set

ROOT = Path(__file__).parents[2]
EXAMPLE = ROOT / "studies" / "examples" / "effects" / "damper.py"
DOC = ROOT / "docs" / "worked_example_user_effect.md"
PLAIN = """[hinge]
kind = "jenkins_pin"

[cycle]
increments_per_stage = 12
"""
DECLARED = (
    PLAIN
    + """
[effects.damper]
from = "effects/damper.py:Damper"
"""
)
SEED = 3


def _folder(tmp_path: Path, phi: float) -> tuple[Path, Path]:
    """(MODEL.toml without the damper, the data folder)."""
    model = tmp_path / "MODEL.toml"
    model.write_text(PLAIN)
    return model, write_set(tmp_path / "data", phi, SEED)


def _json(capsys, argv: list[str]) -> dict:  # type: ignore[no-untyped-def]
    capsys.readouterr()
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_a_rate_dependent_user_effect_is_found_written_calibrated_and_compared(
    jenkins, tmp_path, capsys
) -> None:  # type: ignore[no-untyped-def]
    """The issue's done-when: φ within 20 %, error ≥ 5× down, compare passes what it fits."""
    from model.file import read_model

    model, data = _folder(tmp_path, PHI)
    diag = _json(capsys, ["diagnose", str(model), str(data), "--json"])
    assert diag["verdict"] == "unexplained", diag["message"]
    rows = {r["kind"]: r for r in diag["signatures"]["rows"]}
    assert rows["rate"]["significant"], rows["rate"]
    assert rows["rate"]["fits"], rows["rate"]  # a creep in series: the residual within the noise
    assert rows["rate"]["unit"] == "mm/(N·s)", rows["rate"]  # the series form, a fluidity
    assert rows["rate"]["size"] == pytest.approx(PHI, rel=0.3)  # a lead, near the truth
    loop_rows = [r for r in rows.values() if r["significant"] and r["kind"] != "loss"]
    assert max(loop_rows, key=lambda r: r["explained"])["kind"] == "rate"
    assert not rows["step"]["significant"]
    assert not rows["offset"]["significant"]
    # the user writes the damper next to MODEL.toml and declares it
    (tmp_path / "effects").mkdir()
    shutil.copy(EXAMPLE, tmp_path / "effects" / "damper.py")
    model.write_text(DECLARED)
    out = tmp_path / "calibrated"
    argv = ["calibrate", str(model), str(data), "--effects", "damper", "--out", str(out)]
    ledger = _json(capsys, [*argv, "--json", "--no-compare"])["ledger"]
    base, step = ledger
    written = out / "MODEL.toml"
    phi = read_model(written).effects["damper"]["fluidity_mm_per_ns"]
    assert phi == pytest.approx(PHI, rel=0.2)
    assert abs(phi - PHI) < 3 * step["sigma"]["damper.fluidity_mm_per_ns"]
    assert base["error"] >= 5 * step["file_error"], (base["error"], step["file_error"])
    assert step["file_error"] < 1.0  # within the noise
    cmp_dir = tmp_path / "cmp"
    argv = ["compare", str(written), str(data), "--out", str(cmp_dir), "--no-plots"]
    assert main([*argv, "--fail-on-mismatch"]) == 0
    report = json.loads((cmp_dir / "comparison.json").read_text())
    passed = sorted(c["case_id"] for c in report["cases"] if c["passed"])
    assert set(step["fitted_cases"]) <= set(passed)
    assert report["summary"]["features"]["error"] == pytest.approx(step["file_error"], rel=1e-9)
    base_argv = ["compare", str(model), str(data), "--out", str(tmp_path / "base"), "--no-plots"]
    assert main([*base_argv, "--fail-on-mismatch"]) == 2  # without the damper it fails


def test_the_null_set_stays_quiet(jenkins, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """The same generator without the dashpot: no missing effect, no signature significant."""
    from model.file import read_model
    from validation.candidate_fit import DiagnoseSettings, measured_features
    from validation.evaluate import ModelEvaluator
    from validation.measurements import read_measurement_set
    from validation.signature_data import signature_table

    model, data = _folder(tmp_path, 0.0)
    diag = _json(capsys, ["diagnose", str(model), str(data), "--json"])
    assert diag["verdict"] == "no_missing_effect", diag["message"]
    (tmp_path / "effects").mkdir()
    shutil.copy(EXAMPLE, tmp_path / "effects" / "damper.py")
    declared = tmp_path / "DECLARED.toml"
    declared.write_text(DECLARED)
    diag = _json(capsys, ["diagnose", str(declared), str(data), "--json"])
    assert diag["verdict"] == "no_missing_effect", diag["message"]
    damper = next(c for c in diag["candidates"] if c["name"] == "damper")
    assert not damper["significant"], damper
    assert damper["value"] < 0.05 * PHI, damper
    s = DiagnoseSettings()
    measured = read_measurement_set(data)
    meas = measured_features(measured, s.features)
    ev = ModelEvaluator(read_model(model), meas.points, clocks=meas.clocks)
    table = signature_table(ev, measured, meas, {}, s.features.rel_floor, s.alpha)
    rows = {r.kind: r for r in table.rows}
    assert np.isfinite(rows["rate"].p_value)  # testable: time_s and three rates
    assert not any(r.significant for r in table.rows), table.text()


def _evaluators(jenkins, tmp_path: Path, effects: dict) -> tuple:  # type: ignore[no-untyped-def,type-arg]
    """(features at the records' clocks, features at the protocol's, the data, the spec)."""
    from model.file import read_model
    from validation.candidate_fit import measured_features
    from validation.evaluate import ModelEvaluator
    from validation.features import FeatureSettings
    from validation.measurements import read_measurement_set

    (tmp_path / "effects").mkdir(exist_ok=True)
    shutil.copy(EXAMPLE, tmp_path / "effects" / "damper.py")
    model = tmp_path / "MODEL.toml"
    model.write_text(DECLARED)
    if not (tmp_path / "data").exists():
        write_set(tmp_path / "data", PHI, SEED)
    data = read_measurement_set(tmp_path / "data")
    spec = read_model(model)
    meas = measured_features(data, FeatureSettings())
    timed = ModelEvaluator(spec, meas.points, clocks=meas.clocks).features(effects)
    protocol = ModelEvaluator(spec, meas.points).features(effects)
    return timed, protocol, data, spec


def test_rate_independent_effects_and_untimed_records_keep_the_previous_numbers(
    jenkins, tmp_path
) -> None:  # type: ignore[no-untyped-def]
    """A rate-independent effect (or the damper switched off) on timed records, and the
    damper on records without ``time_s``: exactly the protocol clock's features, bit for bit.
    """
    from validation.candidate_fit import measured_features
    from validation.evaluate import ModelEvaluator
    from validation.features import FeatureSettings
    from validation.loop_files import Loop
    from validation.measurements import MeasurementSet

    compliance = {"frame_compliance": {"compliance_mm_per_n": 3e-5}}
    for effects in ({}, compliance, {"damper": {"fluidity_mm_per_ns": 0.0}}):
        timed, protocol, data, spec = _evaluators(jenkins, tmp_path, effects)
        assert np.array_equal(timed, protocol), effects
    untimed = MeasurementSet(
        tuple(
            dataclasses.replace(c, loop=Loop(c.loop.force_n, c.loop.displacement_mm, None, "x"))
            for c in data.cases
        ),
        data.root,
    )
    meas = measured_features(untimed, FeatureSettings())
    assert meas.clocks == tuple(() for _ in meas.points)
    damper = {"damper": {"fluidity_mm_per_ns": PHI}}
    a = ModelEvaluator(spec, meas.points, clocks=meas.clocks).features(damper)
    b = ModelEvaluator(spec, meas.points).features(damper)
    assert np.array_equal(a, b)


def test_a_time_dependent_effect_is_evaluated_at_each_records_clock(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The damper on timed records: the evaluator's features are those of compare's loop at
    each record's clock (``loop_at_record_times``), and differ from the protocol clock's.
    """
    import dataclasses as dc

    from validation.evaluate import loop_at_record_times
    from validation.features import loop_features
    from validation.loops import process_loop
    from validation.workflow import point_of

    damper = {"damper": {"fluidity_mm_per_ns": PHI}}
    timed, protocol, data, spec = _evaluators(jenkins, tmp_path, damper)
    with_damper = dc.replace(spec, effects=damper)
    expected = []
    for case in data.cases:  # one record per design point, in the rows' order
        run = dc.replace(with_damper, cycle=dc.replace(spec.cycle, amplitude_n=case.amplitude_n))
        F, d = loop_at_record_times(run, point_of(run, case), case.loop.force_n, case.loop.time_s)
        expected.append(loop_features(process_loop(F, d, case.case_id)))
    np.testing.assert_allclose(timed, np.array(expected), rtol=1e-12)
    assert np.max(np.abs(timed[:, 1] / protocol[:, 1] - 1.0)) > 0.05  # the clock matters


def test_the_doc_shows_the_shipped_files_and_is_linked() -> None:
    """The worked example shows the damper and its test verbatim; README links it."""
    doc = DOC.read_text()
    assert EXAMPLE.read_text() in doc
    assert (EXAMPLE.parent / "test_damper.py").read_text() in doc
    assert "docs/worked_example_user_effect.md" in (ROOT / "README.md").read_text()
