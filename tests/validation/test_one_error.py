"""One error on every screen (issue 32, item 4): compare, diagnose and calibrate agree.

The hinge is the plug-in kind ``jenkins_pin`` (no FE: a calibration in seconds). The data
come from an independent generator written here — a Jenkins element solved sample by
sample, a series compliance, a series slider (a spring of compliance c_b behind a play of
half-width r: a friction in the load path), a free play the pin may rest anywhere in,
noise — not from ``synth`` with the effects' own classes.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from model.file import read_model

K0, K1 = 2000.0, 6000.0  # the model's own element [N/mm]
SLIPS = (30.0, 60.0)  # design variable: the element's slip force [N]
AMPLITUDES = (200.0, 400.0)  # [N]
SIGMA_F, SIGMA_D = 0.2, 2e-4  # noise [N], [mm]
C_FRAME = 8e-5  # series compliance [mm/N]
C_SLIDER, R_SLIDER = 1e-4, 40.0  # the series slider's compliance [mm/N] and play [N]

SLIDER_FILE = '''"""A spring of compliance c_b behind a play of half-width r, in series with the hinge."""

from dataclasses import dataclass

import numpy as np

from fe.effects.base import Effect, FloatArray, History, ParamSpec, Values


def play(force_n: FloatArray, r: float) -> FloatArray:
    """The play operator y(F) of half-width r, from y = 0 [N]."""
    y = np.zeros_like(force_n)
    for i in range(1, force_n.size):
        y[i] = min(max(y[i - 1], force_n[i] - r), force_n[i] + r)
    return y


@dataclass(frozen=True)
class SeriesSlider(Effect):
    """δ ← δ + c_b · play_r(F); off at c_b = 0."""

    name: str = "series_slider"
    params: tuple[ParamSpec, ...] = (
        ParamSpec("compliance_mm_per_n", 0.0, 1e-3, 1e-4, "mm/N", "spring behind the play"),
        ParamSpec("slip_force_n", 0.0, 1000.0, 40.0, "N", "half-width of the play"),
    )

    def post(self, history: History, values: Values) -> FloatArray:
        y = play(history.force_n, values["slip_force_n"])
        return history.disp_mm + values["compliance_mm_per_n"] * y
'''

MODEL = """[hinge]
kind = "jenkins_pin"

[cycle]
increments_per_stage = 40

[effects.series_slider]
from = "slider.py:SeriesSlider"
"""


@dataclasses.dataclass(frozen=True)
class Truth:
    """What the generator hides in the data."""

    c_frame: float = 0.0
    c_slider: float = 0.0
    free_play_mm: float = 0.0
    rest_mm: float = 0.0  # where the pin rests in its free play (−g/2 … g/2), or the pre-slip
    shift_mm: float = 0.0  # a constant on the whole record (the transducer's zero)


def _force_path(amp: float, n: int = 120, rest: int = 15) -> np.ndarray:
    ramps = [np.zeros(rest), np.linspace(0, amp, n), np.linspace(amp, -amp, 2 * n)]
    ramps += [np.linspace(-amp, amp, 2 * n)]
    return np.concatenate([ramps[0], *[r[1:] for r in ramps[1:]]])


def generate(slip: float, amp: float, truth: Truth, rng: np.random.Generator):
    """(force [N], displacement [mm]) of one record 0 → +Fg → −Fg → +Fg."""
    F = _force_path(amp)
    s = truth.rest_mm if truth.free_play_mm == 0.0 else 0.0  # a pre-slipped slider …
    pin = truth.rest_mm if truth.free_play_mm > 0.0 else 0.0  # … or a pin off centre
    half = 0.5 * truth.free_play_mm
    y = 0.0
    d_out, f_out = [], []
    for f in F:
        target = pin if f == 0.0 else (half if f > 0 else -half)
        if target != pin:  # the free play is crossed at zero force (the slider sticks there)
            d_zero = K1 * s / (K0 + K1) + truth.c_slider * y
            for p in np.linspace(pin, target, 6)[1:-1]:
                f_out.append(0.0)
                d_out.append(d_zero + p)
            pin = target
        dj = (f + K1 * s) / (K0 + K1)  # Jenkins: stick …
        q = K1 * (dj - s)
        if abs(q) > slip:  # … or slip
            q = np.sign(q) * slip
            dj = (f - q) / K0
            s = dj - q / K1
        y = min(max(y, f - R_SLIDER), f + R_SLIDER)
        f_out.append(f)
        d_out.append(dj + truth.c_frame * f + truth.c_slider * y + pin)
    Fo, do = np.array(f_out), np.array(d_out)
    return Fo + rng.normal(0, SIGMA_F, Fo.size), do + truth.shift_mm + rng.normal(
        0, SIGMA_D, do.size
    )


def write_set(folder: Path, truth: Truth, seed: int = 7) -> Path:
    """A measurement set of every (slip force, amplitude), one record each."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True)
    rows = ["case_id,hinge,slip_force_N,amplitude_N,loop_file"]
    for slip in SLIPS:
        for amp in AMPLITUDES:
            cid = f"s{slip:g}_a{amp:g}"
            F, d = generate(slip, amp, truth, rng)
            lines = [
                "force_N,displacement_mm",
                *(f"{a:.6f},{b:.8f}" for a, b in zip(F, d, strict=True)),
            ]
            (folder / f"{cid}.csv").write_text("\n".join(lines) + "\n")
            rows.append(f"{cid},jenkins_pin,{slip:g},{amp:g},{cid}.csv")
    (folder / "cases.csv").write_text("\n".join(rows) + "\n")
    return folder


def _model(tmp: Path) -> Path:
    (tmp / "slider.py").write_text(SLIDER_FILE)
    path = tmp / "MODEL.toml"
    path.write_text(MODEL)
    return path


def _compare(spec, data):
    from validation.compare import compare
    from validation.workflow import run_model_for_cases

    results, _ = run_model_for_cases(spec, data.cases)
    return compare(results, data)


def _verdicts(spec, data):
    """Per case: (passed, failed metrics, errors rounded to noise) and the feature summary."""
    cmp = _compare(spec, data)
    cases = {c.case.case_id: (c.passed, c.failed, c.errors, c.uncertainty) for c in cmp.cases}
    return cases, cmp.summary["features"]


@pytest.mark.parametrize("free_play", [0.0, 0.02])
def test_the_displacement_zero_changes_no_verdict(jenkins, tmp_path, free_play) -> None:  # type: ignore[no-untyped-def]
    """Where the pin rests (in its free play, or a pre-slipped slider) and a constant on the
    record change no verdict of compare or diagnose and no fitted value of calibrate.

    Before the fix compare judged δ(+Fg) from the record's first samples: with the pin
    resting against one side (rest = ±g/2) or pre-slipped, that error moved by rest/δ_max.
    """
    from validation.calibrate import calibrate
    from validation.candidate_fit import DiagnoseSettings
    from validation.diagnose import diagnose
    from validation.measurements import read_measurement_set

    spec = read_model(_model(tmp_path))
    rest = 0.5 * free_play if free_play else 0.015  # in the stick range of the softer slider
    shifts = [(0.0, 0.0), (-rest, 0.0), (rest, 3.7), (rest, -0.25), (0.0, 12.0)]
    settings = DiagnoseSettings(candidates=("frame_compliance", "series_slider"))
    seen = []
    for k, (r, shift) in enumerate(shifts):
        truth = Truth(C_FRAME, 0.0, free_play, r, shift)
        data = read_measurement_set(write_set(tmp_path / f"d{k}", truth, seed=3))
        cases, feats = _verdicts(spec, data)
        diag = diagnose(spec, data, settings)
        _, rows = calibrate(spec, data, ["frame_compliance"], settings)
        seen.append((cases, feats, diag.verdict, rows[-1].params, rows[-1].n_fitted))
    ref_cases, ref_feats, ref_verdict, ref_params, ref_fitted = seen[0]
    for cases, feats, verdict, params, fitted in seen[1:]:
        assert verdict == ref_verdict
        assert fitted == ref_fitted
        assert feats["n_fitted"] == ref_feats["n_fitted"]
        assert feats["error"] == pytest.approx(ref_feats["error"], rel=0.05, abs=0.3)
        for cid, (passed, failed, errors, _) in cases.items():
            assert (passed, failed) == ref_cases[cid][:2], cid
            for m, e in errors.items():  # other noise draws where the samples differ: ≤ σ/2
                sigma = ref_cases[cid][3][m]
                assert e == pytest.approx(ref_cases[cid][2][m], abs=0.5 * sigma), (cid, m)
        for name, v in params.items():
            assert v == pytest.approx(ref_params[name], rel=0.02), name
    assert ref_verdict == "effect_missing"  # the compliance is found, whatever the zero


def test_two_correlated_effects_are_recovered_jointly(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A series compliance and a series slider, both hidden: calibrate with both named
    recovers both within 20 %; the greedy first step (the slider alone) is off by more,
    having absorbed the compliance; the joint re-fit says the slider moved, with σ and a
    negative correlation; and compare with the written model agrees with the ledger.
    """
    from model.file import write_model
    from validation.calibrate import calibrate
    from validation.measurements import read_measurement_set

    spec = read_model(_model(tmp_path))
    data = read_measurement_set(write_set(tmp_path / "d", Truth(C_FRAME, C_SLIDER)))
    new, rows = calibrate(spec, data, ["series_slider", "frame_compliance"])
    slider, frame = "series_slider.compliance_mm_per_n", "frame_compliance.compliance_mm_per_n"
    greedy = rows[1].greedy[slider]
    assert abs(greedy / C_SLIDER - 1.0) > 0.2  # one at a time: the slider took the compliance
    final = rows[-1].model
    assert final[slider] == pytest.approx(C_SLIDER, rel=0.2)
    assert final[frame] == pytest.approx(C_FRAME, rel=0.2)
    assert slider in rows[-1].moved
    assert rows[-1].sigma[slider] < 0.2 * C_SLIDER
    assert rows[-1].sigma[frame] < 0.2 * C_FRAME
    assert rows[-1].correlation[slider][frame] < -0.2  # both soften: they trade off
    assert rows[0].error > 5.0
    assert rows[-1].error < 1.0
    # the written file, read back, compared: the ledger's error and fitted cases
    written = read_model(write_model(new, tmp_path / "cal" / "MODEL.toml"))
    cmp = _compare(written, data)
    feats = cmp.summary["features"]
    assert feats["chi2"] == pytest.approx(rows[-1].file_chi2, rel=1e-6)
    assert feats["n_fitted"] == rows[-1].file_n_fitted == len(data.cases)
    passed = {c.case.case_id for c in cmp.cases if c.passed}
    assert set(rows[-1].fitted_cases) <= passed
    assert cmp.summary["n_pass"] == len(data.cases)
