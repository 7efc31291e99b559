"""validation.signatures: the generic shapes an unexplained residual is tested against.

The residual sets are made here from each signature's own formula plus white noise (three
records of ±200, ±300, ±400 N, loaded sinusoidally so that dF/dt varies along the loop), a
null set of noise only must stay quiet at α, and a diagnosis of the plug-in kind
``jenkins_pin`` (no FE) on data from an independent generator — a Jenkins element with a
cubic stiffening spring in series, solved here, not by ``synth`` — must be ``unexplained``
and name stiffening.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from validation.signatures import LoopResidual, LossResidual, loop_signatures

SIGMA = 0.002  # residual noise [mm]
OMEGA = 0.05  # sinusoidal loading [rad/s]
AMPS = (200.0, 300.0, 400.0)
F_REF = 400.0


def residual_set(
    rng: np.random.Generator, shape: dict[str, float], time: bool = True
) -> tuple[list[LoopResidual], LossResidual]:
    """Loop residuals (and η log-ratios at 4 amplitudes × 2 designs) of the given shapes."""
    loops = []
    for a in AMPS:
        half = np.linspace(0.02 * a, 0.98 * a, 20)
        grid = np.concatenate([-half[::-1], half])
        F = np.concatenate([grid[::-1], grid])  # descending, then ascending
        branch = np.repeat([1.0, -1.0], grid.size)
        phase = np.arccos(F / a)
        phase = np.where(branch > 0, phase, 2 * math.pi - phase)  # F = a cos(ωt)
        progress = phase / (2 * math.pi)
        rate = -a * OMEGA * np.sin(phase)
        r = {
            "compliance": F,
            "stiffening": (F / F_REF) ** 3,
            "step": np.sign(F),
            "drift": progress - 0.75,  # as centred on the midpoint of the peaks
            "rate": -rate,
        }
        y = sum((v * r[k] for k, v in shape.items() if k in r), np.zeros_like(F))
        y = y + rng.normal(0.0, SIGMA, F.size)
        sig = np.full(F.size, SIGMA)
        loops.append(LoopResidual(f"c{a:g}", F, branch, y, sig, progress, rate if time else None))
    amps = np.tile([100.0, 200.0, 300.0, 400.0], 2)
    group = np.repeat([0.0, 1.0], 4)
    y = shape.get("loss", 0.0) * np.log(amps) + 0.1 * group + rng.normal(0.0, 0.05, 8)
    return loops, LossResidual(amps, group, y, np.full(8, 0.05))


PLAUSIBLE = {  # kinds that may also fit a shape: odd shapes mimic each other at low signal
    "compliance": {"compliance"},
    "stiffening": {"stiffening", "step", "compliance"},
    "step": {"step", "stiffening", "compliance"},
    "drift": {"drift", "offset"},
    "rate": {"rate", "drift"},
    "loss": {"loss"},
}
SIZES = {"compliance": 2e-5, "stiffening": -0.03, "step": 0.01, "drift": 0.01, "rate": 2e-3}


@pytest.mark.parametrize("kind", sorted(PLAUSIBLE))
def test_each_signature_is_found_and_only_plausible_ones_fit(kind: str) -> None:
    size = SIZES.get(kind, 0.3)
    for seed in (11, 12, 13):
        loops, loss = residual_set(np.random.default_rng(seed), {kind: size})
        table = loop_signatures(loops, loss, 0.01)
        rows = {r.kind: r for r in table.rows}
        assert rows[kind].fits, table.text()
        assert set(table.fitting) <= PLAUSIBLE[kind], table.text()
        sig = [r for r in table.rows if r.significant and r.kind != "loss"]
        if kind != "loss":  # the best significant shape (full models nest the compliance)
            best = max(sig, key=lambda r: r.explained)
            assert best.kind == kind or best.explained == pytest.approx(1.0, abs=0.02)
        want = 0.3 if kind == "loss" else size
        if kind == "stiffening" and rows[kind].note != "k = 2":  # a neighbouring power won
            assert rows[kind].size == pytest.approx(want, rel=0.25)
        elif kind != "drift":  # drift is fitted with its offset: v itself is the size
            assert rows[kind].size == pytest.approx(want, abs=4 * rows[kind].size_sigma)


def test_stiffening_and_softening_have_their_sign() -> None:
    for size in (-0.03, 0.03):
        loops, loss = residual_set(np.random.default_rng(5), {"stiffening": size})
        rows = {r.kind: r for r in loop_signatures(loops, loss, 0.01).rows}
        assert math.copysign(1.0, rows["stiffening"].size) == math.copysign(1.0, size)
        assert rows["stiffening"].note == "k = 2"  # F|F|² = F³, the shape made


def test_a_null_set_stays_quiet_at_alpha() -> None:
    """Noise only, 50 seeds: the family-wise false alarms are binomial with p ≤ α.

    The bound is the count that 50 tests at a rate of α itself exceed with probability
    ≤ 1 % (Bonferroni over the 7 signatures makes the true rate lower still).
    """
    alpha, n = 0.05, 50
    alarms = 0
    for seed in range(1000, 1000 + n):
        loops, loss = residual_set(np.random.default_rng(seed), {})
        table = loop_signatures(loops, loss, alpha)
        alarms += any(r.significant for r in table.rows)
    bound = int(stats.binom.ppf(0.99, n, alpha))
    assert alarms <= bound


def test_a_mixed_residual_fits_only_together() -> None:
    loops, loss = residual_set(np.random.default_rng(7), {"stiffening": -0.03, "drift": 0.02})
    table = loop_signatures(loops, loss, 0.01)
    rows = {r.kind: r for r in table.rows}
    assert rows["stiffening"].significant, table.text()
    assert rows["drift"].significant, table.text()
    assert not table.fitting, table.text()  # neither alone explains it
    assert table.together is not None
    kinds, explained, ok = table.together
    assert {"stiffening", "drift"} <= set(kinds)
    assert ok
    assert explained > 0.95
    assert "together" in table.summary()


def test_rate_needs_time_and_more_than_one_rate() -> None:
    loops, loss = residual_set(np.random.default_rng(3), {"rate": 2e-3}, time=False)
    rows = {r.kind: r for r in loop_signatures(loops, loss, 0.01).rows}
    assert rows["rate"].word == "not testable: no time_s in the records"
    const = [
        LoopResidual(lr.case_id, lr.force_n, lr.branch, lr.residual_mm, lr.sigma_mm,
                     lr.progress, -20.0 * lr.branch)
        for lr in loops
    ]  # fmt: skip
    rows = {r.kind: r for r in loop_signatures(const, loss, 0.01).rows}
    assert rows["rate"].word.startswith("not testable: one loading rate")


def test_the_table_is_honest_and_points_to_the_guide() -> None:
    loops, loss = residual_set(np.random.default_rng(2), {"step": 0.01})
    table = loop_signatures(loops, loss, 0.01)
    text = table.text()
    assert "a lead, not a diagnosis" in text
    assert "docs/user_effects.md" in text
    assert (Path(__file__).parents[2] / "docs" / "user_effects.md").is_file()
    d = table.to_dict()
    assert d["fitting"] == ["step"]
    assert {r["kind"] for r in d["rows"]} == {
        "compliance", "stiffening", "step", "offset", "drift", "rate", "loss"
    }  # fmt: skip


# --- through diagnose, on the plug-in kind (no FE) -------------------------------------

K0, K1, FS = 2000.0, 6000.0, 60.0  # the kind's defaults: N/mm, N/mm, N
CUBIC = -0.03  # stiffening: δ −0.03 mm at 400 N [mm]
RATE = 20.0  # force rate [N/s]


def jenkins_record(amp: float, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """(F, δ, t) of 0 → +Fg → −Fg → +Fg on a Jenkins element plus a cubic stiffening.

    Solved sample by sample here (spring k0 parallel to k1 in series with a slider Fs),
    with noise on both channels and a dwell at zero before loading.
    """
    legs = [np.linspace(0, amp, 150), np.linspace(amp, -amp, 300), np.linspace(-amp, amp, 300)]
    F = np.concatenate([np.zeros(30), legs[0], legs[1][1:], legs[2][1:]])
    d = np.empty_like(F)
    s = 0.0  # slider position
    for i, f in enumerate(F):
        x = (f + K1 * s) / (K0 + K1)  # stick
        q = K1 * (x - s)
        if abs(q) > FS:
            q = math.copysign(FS, q)
            x = (f - q) / K0
            s = x - q / K1
        d[i] = x + CUBIC * (f / F_REF) ** 3
    t = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(F)) / RATE + 0.01)])
    return F + rng.normal(0, 0.05, F.size), d + rng.normal(0, 2e-4, F.size), t


def test_diagnose_names_stiffening_on_independent_data(jenkins) -> None:  # type: ignore[no-untyped-def]
    from fe.cycle.protocol import CycleSettings
    from model.spec import ModelSpec
    from validation.candidate_fit import DiagnoseSettings
    from validation.diagnose import diagnose
    from validation.loop_files import Loop
    from validation.measurements import Case, MeasurementSet

    rng = np.random.default_rng(4)
    cases = []
    for amp in AMPS:
        F, d, t = jenkins_record(amp, rng)
        loop = Loop(F, d, t, f"jenkins+cubic {amp:g} N")
        cases.append(Case(f"a{amp:g}", "jenkins_pin", {"slip_force_n": FS}, amp, loop=loop))
    data = MeasurementSet(tuple(cases), Path("."))
    spec = ModelSpec("jenkins_pin", jenkins.params_type(), cycle=CycleSettings())
    result = diagnose(spec, data, DiagnoseSettings(increments_per_stage=24))
    assert result.verdict == "unexplained", result.text()
    table = result.signatures
    assert table is not None
    rows = {r.kind: r for r in table.rows}
    assert rows["stiffening"].significant, table.text()
    assert rows["stiffening"].size < 0
    sig = [r for r in table.rows if r.significant and r.kind != "loss"]
    best = max(sig, key=lambda r: r.explained)
    assert best.kind == "stiffening", table.text()
    assert rows["rate"].word.startswith("not testable: one loading rate")
    assert not rows["drift"].fits
    assert not rows["offset"].fits
    assert "signatures of the residual" in result.text()
    assert result.to_dict()["signatures"]["rows"][1]["kind"] == "stiffening"


def test_the_report_shows_the_table_of_a_diagnosis(tmp_path: Path) -> None:
    import json

    from studies.report.validation import paper_validation_report

    loops, loss = residual_set(np.random.default_rng(2), {"step": 0.01})
    sig = loop_signatures(loops, loss, 0.01).to_dict()
    diag = {"verdict": "unexplained", "message": "m", "candidates": [], "signatures": sig}
    (tmp_path / "report.json").write_text(json.dumps({"diagnose_3x3": diag}))
    body = paper_validation_report(tmp_path, tmp_path)
    html = next(str(s.body) for s in body.sections if s.anchor == "diagnose_3x3")
    assert "What kind of effect is missing" in html
    assert html.count("<tr>") >= 8  # header + 7 signatures
    assert "a lead, not a diagnosis" in html
    del diag["signatures"]  # a diagnosis without the table (older, or explained) still shows
    (tmp_path / "report.json").write_text(json.dumps({"diagnose_3x3": diag}))
    body = paper_validation_report(tmp_path, tmp_path)
    assert "What kind" not in next(str(s.body) for s in body.sections if s.anchor == "diagnose_3x3")


def _viscous_set(seed: int, tau: float = 0.0, phi: float = 0.0) -> list[LoopResidual]:
    """Loops under F = a cos ωt at two frequencies per amplitude, with a dashpot in parallel
    (width ∝ dF/dt: r = −τ dF/dt) or in series (a creep h = φ∫F dt = φ a sin(ωt)/ω), each
    from its own closed form. At one frequency the two are proportional (both ∝ a), so only
    rates that differ at one amplitude tell them apart."""
    rng = np.random.default_rng(seed)
    loops = []
    for a in AMPS:
        for omega in (0.05, 0.2):
            half = np.linspace(0.02 * a, 0.98 * a, 20)
            grid = np.concatenate([-half[::-1], half])
            F = np.concatenate([grid[::-1], grid])
            branch = np.repeat([1.0, -1.0], grid.size)
            phase = np.arccos(F / a)
            phase = np.where(branch > 0, phase, 2 * math.pi - phase)
            rate = -a * omega * np.sin(phase)
            y = -tau * rate + phi * a * np.sin(phase) / omega + rng.normal(0.0, SIGMA, F.size)
            sig = np.full(F.size, SIGMA)
            loops.append(
                LoopResidual(f"c{a:g}w{omega:g}", F, branch, y, sig, phase / (2 * math.pi), rate)
            )
    return loops


def test_a_creep_in_series_fits_the_rate_row_in_its_series_form() -> None:
    """The rate row's series column, β(F_max² − F²)/(2|dF/dt|), is ∫F dt on a constant-rate
    ramp; on a sine it is half of it, so the size reads 2φ."""
    phi = 2e-6  # mm/(N·s)
    for seed in (21, 22, 23):
        table = loop_signatures(_viscous_set(seed, phi=phi), None, 0.01)
        rate = {r.kind: r for r in table.rows}["rate"]
        assert rate.fits, table.text()
        assert rate.unit == "mm/(N·s)", table.text()
        assert rate.size == pytest.approx(2 * phi, abs=4 * rate.size_sigma), table.text()


def test_a_width_growing_with_the_rate_keeps_the_parallel_form() -> None:
    for seed in (31, 32):
        table = loop_signatures(_viscous_set(seed, tau=2e-3), None, 0.01)
        rate = {r.kind: r for r in table.rows}["rate"]
        assert rate.fits, table.text()
        assert rate.unit == "mm·s/N", table.text()
        assert rate.size == pytest.approx(2e-3, abs=4 * rate.size_sigma), table.text()
