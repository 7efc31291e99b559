"""Property-based tests: loop metrics and the comparison never fail with anything but a
named data error, whatever the loop (degenerate, random, zero area, tiny, flat)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cad.errors import DataError, ParameterError
from validation.compare import ModelResult, compare
from validation.hysteresis import hysteresis, judge
from validation.loop_files import Loop
from validation.loops import process_loop
from validation.measurements import Case, MeasurementSet

EXPECTED = (DataError, ParameterError)


def _cycle(
    amp: float, stiff: float, width: float, n: int, skew: float
) -> tuple[np.ndarray, np.ndarray]:
    """0 → +Fg → −Fg → +Fg, n samples a branch: δ = F/k ± width (a parallelogram, skewed)."""
    up = np.linspace(0.0, amp, n)
    down = np.linspace(amp, -amp, 2 * n)[1:]
    back = np.linspace(-amp, amp, 2 * n)[1:]
    force = np.concatenate([up, down, back])
    disp = force / stiff
    bulge = width * (1 - np.abs(force) / amp) ** skew
    down = slice(n, 3 * n - 1)
    disp[down] += bulge[down]  # unloading runs right of loading: the loop turns the passive way
    disp[3 * n - 1 :] -= bulge[3 * n - 1 :]
    return force, disp


loops = st.builds(
    _cycle,
    amp=st.floats(1e-6, 1e5),
    stiff=st.floats(1e-3, 1e9),
    width=st.one_of(st.just(0.0), st.floats(0.0, 1.0)),
    n=st.integers(1, 40),
    skew=st.floats(0.1, 4.0),
)


def _case(force: np.ndarray, disp: np.ndarray, amp: float, clearance: float = 0.0) -> Case:
    values = {"clearance_mm": clearance}
    return Case("c", "general", values, amp, loop=Loop(force, disp, None, "test"))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(loops)
def test_process_loop_returns_metrics_or_a_data_error(loop) -> None:  # type: ignore[no-untyped-def]
    force, disp = loop
    try:
        p = process_loop(force, disp, "test")
    except EXPECTED:
        return
    m = p.metrics
    assert math.isfinite(m.delta_max_mm) or math.isnan(m.delta_max_mm)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(measured=loops, model=loops, clearance=st.sampled_from([0.0, 0.1]))
def test_compare_of_any_two_loops_gives_a_verdict_or_a_data_error(
    measured, model, clearance
) -> None:  # type: ignore[no-untyped-def]
    amp = float(np.max(measured[0]))
    case = _case(*measured, amp, clearance)
    result = ModelResult(Loop(model[0], model[1], None, "model"))
    try:
        cmp = compare({"c": result}, MeasurementSet((case,), Path(".")))
    except EXPECTED:
        return
    (c,) = cmp.cases
    assert isinstance(c.passed, bool)
    for m, e in c.errors.items():  # an error that cannot be formed is a failure, not a pass
        if not math.isfinite(e):
            assert m in c.failed
    for m, j in c.judgements.items():  # W and η: judged, failed or not measurable, never absurd
        assert (m in c.errors) == j.relative
        assert (m in c.not_measurable) != (j.relative or m in c.failed)
        if j.relative:
            assert j.sigma is not None
            assert j.sigma <= c.uncertainty[m] <= 1.0


def test_a_zero_area_loop_is_a_finding_not_a_crash() -> None:
    """The issue's probe: a 4-row loop 0, +Fg, −Fg, +Fg of zero area."""
    force = np.array([0.0, 400.0, -400.0, 400.0])
    disp = force / 1e5
    case = _case(force, disp, 400.0)
    model_force, model_disp = _cycle(400.0, 1e5, 1e-4, 10, 1.0)
    cmp = compare(
        {"c": ModelResult(Loop(model_force, model_disp, None, "m"))},
        MeasurementSet((case,), Path(".")),
    )
    (c,) = cmp.cases
    # four samples cannot tell their noise from their ramps (the noise estimate is of the
    # order of Fg): the loop area is reported as not measurable, never judged as a pass
    assert "W_cycle_Nmm" not in c.errors
    assert "noise" in c.not_measurable["W_cycle_Nmm"]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(loop=loops, play=st.floats(0.0, 1.0), band=st.floats(1e-3, 0.5))
def test_hysteresis_without_free_play_of_any_loop(loop, play, band) -> None:  # type: ignore[no-untyped-def]
    """Cutting the zero band out of any loop gives finite W', σ ≥ 0 and η' finite or NaN."""
    force, disp = loop
    disp = disp + play * np.sign(force)  # a free play crossed where the force changes sign
    try:
        p = process_loop(force, disp, "test")
    except EXPECTED:
        return
    h = hysteresis(p, band * p.metrics.f_max_n, remove_free_play=True)
    assert math.isfinite(h.W_Nmm)
    assert h.sigma_W_noise >= 0.0
    assert h.sigma_delta_noise >= 0.0
    assert math.isfinite(h.eta) or math.isnan(h.eta)


@settings(max_examples=150, deadline=None)
@given(
    v=st.one_of(st.just(0.0), st.floats(-1e6, 1e6)),
    u=st.one_of(st.just(0.0), st.floats(-1e6, 1e6), st.just(math.nan)),
    sigma=st.one_of(st.just(0.0), st.floats(0.0, 1e6), st.just(math.inf)),
    noise=st.floats(0.0, 1e6),
)
def test_judge_never_forms_a_relative_sigma_above_one(v, u, sigma, noise) -> None:  # type: ignore[no-untyped-def]
    """Whatever the numbers: a verdict, a relative σ ≤ 1 where judged relatively, else a reason."""
    j = judge(v, u, sigma, noise, k=2.0, max_rel_sigma=1.0, min_rel_sigma=0.005)
    if j.relative:
        assert j.sigma is not None
        assert j.sigma <= 1.0
        assert abs(v) > 0.0
    else:
        assert j.reason
        assert j.error is None
