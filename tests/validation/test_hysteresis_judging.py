"""Clearance loops judged on their hysteresis, not on the noise of the free play (issue 33, item 4).

The loops are made here, independently of ``validation.synth``: a Jenkins element (a
spring k_1 in series with a Coulomb slider of slip force F_s) in parallel with a spring
k_2, driven in displacement through 0 → +u_a → −u_a → +u_a, with a dead zone: wherever
the force changes sign the grips cross the free play 4Δr at zero force (first 2Δr from
the centred start). Its loss factor without the free play is known in closed form.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from validation.compare import CaseComparison, CompareSettings, Comparison, ModelResult, compare
from validation.hysteresis import Judgement, Status, hysteresis, judge
from validation.loop_files import Loop
from validation.loops import process_loop, zero_band_n
from validation.measurements import Case, MeasurementSet

K1, K2, FS = 4e4, 6e4, 5.0  # N/mm, N/mm, N
UA = 0.004  # displacement amplitude of the hinge [mm]
CLEARANCE = 0.1  # Δr [mm]


def jenkins_loop(
    fs: float = FS,
    *,
    n: int = 400,
    n_play: int = 400,
    clearance: float = CLEARANCE,
    noise_f: float = 0.0,
    noise_d: float = 0.0,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """(force [N], grip displacement [mm]): n samples per quarter branch, n_play per crossing."""
    legs = [np.linspace(0, UA, n), np.linspace(UA, -UA, 2 * n), np.linspace(-UA, UA, 2 * n)]
    u = np.concatenate([legs[0], legs[1][1:], legs[2][1:]])
    F = np.empty_like(u)
    up = 0.0  # slider position
    for i, ui in enumerate(u):
        f_slider = K1 * (ui - up)
        if abs(f_slider) > fs:
            up = ui - math.copysign(fs, f_slider) / K1
            f_slider = math.copysign(fs, f_slider)
        F[i] = K2 * ui + f_slider
    force, disp = [0.0], [0.0]
    side = 0.0  # pin centred: the first load crosses 2Δr
    for i in range(1, u.size):
        s = math.copysign(1.0, F[i])
        if s != side:  # the force changed sign: the hinge stops at F = 0, the grips cross
            t = -F[i - 1] / (F[i] - F[i - 1])  # where F = 0 between samples i−1 and i
            u0 = u[i - 1] + t * (u[i] - u[i - 1])
            force += [0.0] * (n_play + 1)
            disp += list(np.linspace(u0 + side * 2 * clearance, u0 + s * 2 * clearance, n_play + 1))
            side = s
        force.append(F[i])
        disp.append(u[i] + side * 2 * clearance)
    rng = np.random.default_rng(seed)
    fa, da = np.array(force), np.array(disp)
    zeros = 50  # the machine dwells at zero before loading
    fa = np.concatenate([np.zeros(zeros), fa]) + rng.normal(0, noise_f, fa.size + zeros)
    da = np.concatenate([np.zeros(zeros), da]) + rng.normal(0, noise_d, da.size + zeros)
    return fa, da


def eta_jenkins(fs: float) -> float:
    """η without the free play: W = 4 F_s (u_a − F_s/k_1), F_max = k_2 u_a + F_s."""
    W = 4 * fs * (UA - fs / K1)
    f_max = K2 * UA + fs
    return W / (math.pi * f_max * UA)


def _comparison(measured, model_loop, clearance=CLEARANCE):
    amp = K2 * UA + FS
    case = Case("c", "general", {"clearance_mm": clearance}, amp, loop=Loop(*measured, None, "m"))
    result = ModelResult(Loop(*model_loop, None, "model"))
    return compare({"c": result}, MeasurementSet((case,), Path(".")))


def _compare(measured, model_loop, clearance=CLEARANCE):
    return _comparison(measured, model_loop, clearance).cases[0]


def test_the_generator_is_a_jenkins_loop_with_free_play():
    F, d = jenkins_loop(clearance=0.0, n=4000)
    p = process_loop(F, d, "jenkins")
    assert p.metrics.eta == pytest.approx(eta_jenkins(FS), rel=2e-3)  # the closed form
    F, d = jenkins_loop()
    p = process_loop(F, d, "jenkins")
    assert p.metrics.delta_max_mm == pytest.approx(UA + 2 * CLEARANCE, rel=1e-9)


def test_free_play_removed_loop_has_the_hinge_eta():
    """The crossings cut out, W' is the Jenkins element's loop area and η' its η.

    The band cut around F = 0 (±2 % of F_max) takes its elastic travel, 2b/k_2 per branch,
    with it: δ'_max is short by b/k_2 (2 %), on the model's loop alike.
    """
    F, d = jenkins_loop()
    p = process_loop(F, d, "jenkins")
    band = zero_band_n(p, p)
    h = hysteresis(p, band, remove_free_play=True)
    assert band == pytest.approx(0.02 * 0.98 * (K2 * UA + FS))
    assert h.W_Nmm == pytest.approx(4 * FS * (UA - FS / K1), rel=1e-5)  # slip onset between samples
    assert h.free_play_mm == pytest.approx(4 * CLEARANCE + 2 * band / K2, rel=1e-6)
    assert h.delta_max_mm == pytest.approx(UA - band / K2, rel=1e-6)
    assert h.eta == pytest.approx(eta_jenkins(FS) * UA / (UA - band / K2), rel=1e-5)
    assert p.metrics.eta < 0.03 * h.eta  # with the free play η is ~50× smaller


def test_a_wrong_clearance_model_fails_on_eta_instead_of_passing_silently():
    """The issue's +161 % probe: a model with 1.6× the slip force (η' +55 %) must fail on η.

    Before: η included the free play (~1e-4), its σ was thousands of % and the case passed.
    """
    measured = jenkins_loop(noise_f=0.2, noise_d=2e-5, seed=1)
    wrong = jenkins_loop(1.6 * FS, n=12, n_play=1)
    c = _compare(measured, wrong)
    assert c.free_play_removed
    true_error = eta_jenkins(1.6 * FS) / eta_jenkins(FS) - 1.0
    assert c.errors["eta"] == pytest.approx(true_error, abs=0.1)
    assert c.uncertainty["eta"] < 0.2  # a meaningful σ, not thousands of %
    assert "eta" in c.failed
    assert not c.passed


def test_a_right_clearance_model_passes_on_eta():
    measured = jenkins_loop(noise_f=0.2, noise_d=2e-5, seed=2)
    c = _compare(measured, jenkins_loop(n=12, n_play=1))
    assert abs(c.errors["eta"]) < 0.05
    assert "eta" not in c.failed
    assert c.measured["eta_without_free_play"] == pytest.approx(eta_jenkins(FS), rel=0.1)


def test_eta_is_not_measurable_at_large_noise():
    """Displacement noise ¾ of the hinge's own travel: η is neither passed nor failed."""
    measured = jenkins_loop(noise_f=0.2, noise_d=3e-3, seed=3)
    cmp = _comparison(measured, jenkins_loop(n=12, n_play=1))
    (c,) = cmp.cases
    assert set(c.not_measurable) == {"W_cycle_Nmm", "eta"}
    assert "eta" not in c.errors
    assert "eta" not in c.failed
    case_json = cmp.to_dict()["cases"][0]
    assert case_json["judged"]["eta"]["status"] == "not measurable"
    assert "noise" in case_json["not_measurable"]["eta"]


def test_no_hysteresis_gives_a_sane_message(tmp_path):
    """μ = 0 (no slider): no relative σ of a near-zero η, no absurd percentages, no warning."""
    from studies.cli.compare import format_table
    from validation.plots import write_comparison_plots

    measured = jenkins_loop(0.0, clearance=0.0, noise_f=0.2, noise_d=2e-5, seed=4)
    amp = K2 * UA
    case = Case("c", "general", {"clearance_mm": 0.0}, amp, loop=Loop(*measured, None, "m"))
    model_loop = jenkins_loop(0.0, clearance=0.0, n=12, n_play=1)
    cmp = compare(
        {"c": ModelResult(Loop(*model_loop, None, "model"))},
        MeasurementSet((case,), Path(".")),
        CompareSettings(),
    )
    (c,) = cmp.cases
    assert "eta" in c.not_measurable
    assert "eta" not in c.uncertainty  # no relative σ of a zero η
    assert c.passed  # the stiffness agrees; the hysteresis is neither passed nor failed
    table = format_table(cmp)
    sigma_cell = table.splitlines()[1].split("(record)")[0].split()[-1]
    assert sigma_cell.startswith("±")
    assert float(sigma_cell[1:]) < 0.01  # an absolute η resolution, not 4e9 %
    write_comparison_plots(cmp, tmp_path)  # pytest turns any warning into an error


def test_a_model_with_hysteresis_the_record_lacks_fails_absolutely():
    """μ = 0 record against a frictional model: the model lies far beyond kσ of zero."""
    measured = jenkins_loop(0.0, clearance=0.0, noise_f=0.2, noise_d=2e-5, seed=5)
    c = _compare(measured, jenkins_loop(FS, clearance=0.0, n=12, n_play=1), clearance=0.0)
    assert "eta" in c.failed
    assert c.judgements["eta"].status is Status.FAIL
    assert not c.judgements["eta"].relative


@pytest.mark.parametrize(
    ("measured", "model", "sigma", "noise", "status"),
    [
        (0.010, 0.0105, 0.001, 0.0005, Status.PASS),  # 5 % off, σ 10 %
        (0.010, 0.013, 0.001, 0.0005, Status.FAIL),  # 30 % off
        (0.001, 0.0015, 0.0004, 0.0006, Status.NOT_MEASURABLE),  # |v| ≤ 2σ_noise
        (0.001, 0.0015, 0.0012, 0.0001, Status.NOT_MEASURABLE),  # σ > |v|: the floor
        (0.0, 0.01, 0.001, 0.0005, Status.FAIL),  # the model shows what the record lacks
        (0.0, 1e-12, 0.001, 0.0, Status.NOT_MEASURABLE),  # both zero: a noise-free μ = 0
    ],
)
def test_judge_decides_relative_absolute_or_not_measurable(measured, model, sigma, noise, status):
    j = judge(measured, model, sigma, noise, k=2.0, max_rel_sigma=1.0, min_rel_sigma=0.005)
    assert j.status is status
    assert (j.error is not None) == j.relative
    if j.relative:
        assert j.error == pytest.approx((model - measured) / measured)
        assert j.sigma == pytest.approx(sigma / measured)
    else:
        assert j.reason


def _judged(status, difference=0.0):
    return Judgement(status, False, None, None, difference, 0.001, 0.0005, "reason")


def _case_cmp(cid, amp, errors, failed=(), judgements=None):
    case = Case(cid, "general", {"clearance_mm": 0.1 if judgements else 0.0}, amp)
    return CaseComparison(
        case,
        {},
        {},
        errors,
        dict.fromkeys(errors, 0.1),
        "stated",
        tuple(failed),
        None,
        None,
        None,
        judgements or {},  # type: ignore[arg-type]  # no loops: only the map's data
    )


def test_error_map_markers_follow_the_eta_verdict_on_a_fixed_scale():
    """○ η within kσ (even if the case fails on δ), × η outside, □ not measurable (grey)."""
    from validation.plots import GREY, error_colour, error_map_points

    cases = (
        _case_cmp("d_fails", 200.0, {"eta": -0.208, "disp_at_peak_mm": 0.078}, ["disp_at_peak_mm"]),
        _case_cmp("eta_fails", 400.0, {"eta": 0.3}, ["eta"]),
        _case_cmp("nm", 300.0, {}, judgements={"eta": _judged(Status.NOT_MEASURABLE)}),
        _case_cmp("abs", 350.0, {}, ["eta"], {"eta": _judged(Status.FAIL, 0.0146)}),
        _case_cmp("tiny", 250.0, {"eta": 3e-6}),
        _case_cmp("huge", 260.0, {"eta": 5.0}, ["eta"]),
    )
    cmp = Comparison(cases, CompareSettings(), {}, ())
    by_id = {p.case_id: p for p in error_map_points(cmp, "eta")}
    assert {k: (p.status, p.marker) for k, p in by_id.items()} == {
        "d_fails": (Status.PASS, "o"),
        "eta_fails": (Status.FAIL, "x"),
        "nm": (Status.NOT_MEASURABLE, "s"),
        "abs": (Status.FAIL, "x"),
        "tiny": (Status.PASS, "o"),
        "huge": (Status.FAIL, "x"),
    }
    assert by_id["nm"].error_pct is None
    assert by_id["nm"].colour == GREY
    assert by_id["nm"].label.startswith("n/m")
    assert by_id["abs"].label.startswith("Δ+0.0146")
    white = error_colour(0.0)
    assert np.allclose(by_id["tiny"].colour, white, atol=1e-3)  # 0.0003 % is not saturated
    assert by_id["huge"].colour == error_colour(50.0)  # clipped at the fixed scale's end
    assert error_colour(-50.0) != error_colour(50.0)
    assert by_id["d_fails"].colour != white


@pytest.mark.parametrize(
    ("eta", "text"),
    [
        (1.3841776530446985e-05, "1.38e-05"),
        (0.014323781, "0.0143"),
        (0.00157, "0.00157"),
        (-1.09e-10, "-1.09e-10"),
        (math.nan, "—"),
        (None, "—"),
    ],
)
def test_eta_is_printed_with_three_significant_digits(eta, text):
    from validation.plots import format_eta

    assert format_eta(eta) == text
