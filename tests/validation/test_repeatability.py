"""Repeatability from position readings: Table 7 from σ and L, exact intervals, normality tests, input checks."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from cad.errors import DataError, ParameterError
from validation import repeatability as rp

EXAMPLE = Path(__file__).parents[2] / "validation" / "data" / "repeatability_example.csv"
EXAMPLE_SIGMA_UM = {"general": 1.0942, "modified": 0.2388}  # Table 7's σ
EXAMPLE_SEED = 2021
SENSOR_RESOLUTION_UM = 0.1  # KEYENCE LK-G5001, as in the paper

# Table 7 of the paper: hinge, η, σ [µm], L [mm], θ [rad] (paper_table7_repeatability.csv)
TABLE7 = (
    ("general", 0.0659, 1.0942, 25.0, 2.6260e-4),
    ("modified", 0.0160, 0.2388, 25.0, 5.7312e-5),
)


def write_example(path: Path, seed: int = EXAMPLE_SEED, n: int = 200) -> Path:
    """Write the shipped example: two hinges, n readings each, σ as Table 7, rounded to 0.1 µm."""
    rng = np.random.default_rng(seed)
    lines = [
        f"# two hinges, {n} readings each, normal with Table 7's sigma (1.0942 / 0.2388 um), "
        f"rounded to the sensor's {SENSOR_RESOLUTION_UM} um; write_example() in "
        f"tests/validation/test_repeatability.py, seed {seed}",
        "hinge,reading_um",
    ]
    for hinge, sigma_um in EXAMPLE_SIGMA_UM.items():
        x = np.round(rng.normal(0.0, sigma_um, n) / SENSOR_RESOLUTION_UM) * SENSOR_RESOLUTION_UM
        lines += [f"{hinge},{v + 0.0:.1f}" for v in x]  # + 0.0 turns -0.0 into 0.0
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _readings(x_mm, hinge="h"):
    return rp.Readings(hinge, np.asarray(x_mm, dtype=np.float64), "test")


def _analyse_file(path):
    return [rp.analyse_readings(g, 25.0) for g in rp.read_readings(path, unit=rp.ReadingUnit.UM)]


def _csv(tmp_path, text, name="r.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# --- Table 7 and Eq. 14 -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("hinge", "eta", "sigma_um", "length_mm", "theta"), TABLE7, ids=["general", "modified"]
)
def test_table7_follows_arcsin_in_radians_not_eq14_as_printed(
    hinge, eta, sigma_um, length_mm, theta
):
    sigma_mm = sigma_um * 1e-3
    ours = rp.theta_from_sigma(sigma_mm, length_mm)
    # to the table's last printed digit (the general hinge's 2.62608e-4 is printed truncated)
    assert ours == pytest.approx(theta, abs=1e-8 if theta > 1e-4 else 1e-9)
    as_printed = math.asin(6 * sigma_mm / length_mm) / 180 * math.pi  # arcsin in radians
    assert as_printed / theta == pytest.approx(math.pi / 180, rel=1e-4)  # 57.3× too small
    arcsin_in_degrees = math.degrees(math.asin(6 * sigma_mm / length_mm)) / 180 * math.pi
    assert arcsin_in_degrees == pytest.approx(ours, rel=1e-14)


def test_table7_relative_changes():
    (_, eta1, s1, length, _), (_, eta2, s2, _, _) = TABLE7
    results = tuple(
        rp.analyse_readings(_readings(np.array([-1, 1] * 50) * s * 1e-3, name), length, eta=eta)
        for name, eta, s in (("general", eta1, s1), ("modified", eta2, s2))
    )  # ±s exactly: the ML σ is s
    c = rp.correlate(results)
    assert c.relative_change == pytest.approx(
        (0.7572, 0.7818), abs=1e-4
    )  # Table 7: 75.72 %, 78.18 %
    assert c.r is None
    assert c.p_value is None
    assert c.slope_stderr_rad is None
    assert "always fits exactly" in c.note
    assert c.slope_rad == pytest.approx(
        (results[0].theta_rad - results[1].theta_rad) / (eta1 - eta2)
    )


# --- intervals --------------------------------------------------------------------------------


def test_sigma_interval_matches_direct_chi2_computation():
    x = np.random.default_rng(3).normal(2.0, 0.5, 200)
    s = np.std(x, ddof=1)
    lo = math.sqrt(199 * s**2 / stats.chi2.ppf(0.975, 199))
    hi = math.sqrt(199 * s**2 / stats.chi2.ppf(0.025, 199))
    ci = rp.sigma_interval(float(np.std(x)), 200, 0.95)
    assert (ci.lo, ci.hi) == pytest.approx((lo, hi), rel=1e-12)


@pytest.mark.parametrize(
    ("n", "confidence"), [(10, 0.95), (200, 0.95), (10, 0.8)], ids=["n10-95", "n200-95", "n10-80"]
)
def test_sigma_interval_covers_truth_at_stated_rate(n, confidence):
    n_trials, sigma = 4000, 1.3
    x = np.random.default_rng(n).normal(0.0, sigma, (n_trials, n))
    hits = 0
    for s in np.std(x, axis=1):
        ci = rp.sigma_interval(float(s), n, confidence)
        hits += ci.lo <= sigma <= ci.hi
    tol = 3.5 * math.sqrt(confidence * (1 - confidence) / n_trials)
    assert hits / n_trials == pytest.approx(confidence, abs=tol)


def test_theta_interval_covers_truth_end_to_end():
    n_trials, sigma_mm, length_mm = 1000, 1.0942e-3, 25.0
    theta_true = math.asin(6 * sigma_mm / length_mm)
    rng = np.random.default_rng(11)
    hits = 0
    for _ in range(n_trials):
        r = rp.analyse_readings(_readings(rng.normal(0.0, sigma_mm, 200)), length_mm)
        hits += r.theta_ci_rad.lo <= theta_true <= r.theta_ci_rad.hi
    assert hits / n_trials == pytest.approx(0.95, abs=3.5 * math.sqrt(0.95 * 0.05 / n_trials))


def test_theta_interval_upper_end_missing_when_six_sigma_reaches_length():
    ci = rp.theta_interval(rp.Interval(1.0, 5.0, 0.95), 25.0)
    assert ci.hi is None
    assert "≥ L" in ci.reason
    assert ci.lo == pytest.approx(math.asin(6 / 25))


# --- normality --------------------------------------------------------------------------------


def test_both_tests_reject_a_uniform_sample_of_200():
    x = np.random.default_rng(5).uniform(-1.0, 1.0, 200)
    sw, ad = rp.shapiro_wilk(x), rp.anderson_darling(x)
    assert sw.rejects_normal
    assert ad.rejects_normal
    assert sw.verdict.startswith("not normal")
    assert ad.verdict.startswith("not normal")


def test_false_rejection_rate_of_normal_samples_is_alpha():
    rng = np.random.default_rng(8)
    n_trials = 600
    samples = rng.normal(0.0, 1.0, (n_trials, 200))
    sw = np.mean([rp.shapiro_wilk(x).rejects_normal for x in samples])
    ad = np.mean([rp.anderson_darling(x).rejects_normal for x in samples])
    ad_p = np.mean([rp.anderson_darling(x).p_value < 0.05 for x in samples])
    tol = 3.5 * math.sqrt(0.05 * 0.95 / n_trials)
    assert sw == pytest.approx(0.05, abs=tol)
    assert ad == pytest.approx(0.05, abs=tol)
    assert ad_p == pytest.approx(0.05, abs=tol)


def test_anderson_statistic_matches_scipy_and_p_is_five_percent_at_the_critical_value():
    x = np.random.default_rng(9).normal(3.0, 2.0, 150)
    ours = rp.anderson_darling(x)
    assert ours.statistic == pytest.approx(
        stats.anderson(x, "norm", method="interpolate").statistic, rel=1e-12
    )
    n = x.size
    assert ours.critical_value == pytest.approx(0.752 / (1 + 0.75 / n + 2.25 / n**2))
    # a sample whose A² sits on the critical value has p ≈ 0.05 (D'Agostino–Stephens)
    a_star = 0.752
    p = math.exp(1.2937 - 5.709 * a_star + 0.0186 * a_star**2)
    assert p == pytest.approx(0.05, abs=0.001)


def test_coarse_rounding_is_flagged():
    x = np.random.default_rng(2).normal(0.0, 0.2388e-3, 200)
    fine = rp.analyse_readings(_readings(x), 25.0)
    rounded = rp.analyse_readings(_readings(np.round(x, 4)), 25.0)  # 0.1 µm steps
    assert not fine.resolution.coarse
    assert rounded.resolution.coarse
    assert rounded.resolution.step_mm == pytest.approx(1e-4)


# --- reading files ----------------------------------------------------------------------------


def test_shipped_example_is_reproducible_and_has_table7_sigma(tmp_path):
    assert write_example(tmp_path / "ex.csv").read_text() == EXAMPLE.read_text()
    groups = rp.read_readings(EXAMPLE)
    assert [g.hinge for g in groups] == ["general", "modified"]
    for g in groups:
        r = rp.analyse_readings(g, 25.0)
        assert r.n == 200
        assert r.sigma_ci_mm.lo <= EXAMPLE_SIGMA_UM[g.hinge] * 1e-3 <= r.sigma_ci_mm.hi


def test_read_readings_units_groups_and_label(tmp_path):
    values = [0.5, -0.25, 1.0, 0.0, 0.75, -1.0, 0.25, -0.5]
    um = _csv(tmp_path, "hinge,reading_um\n" + "".join(f"a,{v}\nb,{2 * v}\n" for v in values))
    a, b = rp.read_readings(um)
    assert (a.hinge, b.hinge) == ("a", "b")
    np.testing.assert_allclose(a.position_mm, np.array(values) * 1e-3)
    np.testing.assert_allclose(b.position_mm, np.array(values) * 2e-3)
    mm = _csv(tmp_path, "l\n" + "\n".join(map(str, values)), "one.csv")
    (only,) = rp.read_readings(mm, unit=rp.ReadingUnit.MM, label="pendulum")
    assert only.hinge == "pendulum"
    np.testing.assert_allclose(only.position_mm, values)
    (stem,) = rp.read_readings(mm, unit=rp.ReadingUnit.UM)
    assert stem.hinge == "one"


def test_analyse_does_not_modify_its_input():
    x = np.random.default_rng(1).normal(0.0, 1e-3, 50)
    before = x.copy()
    rp.analyse_readings(_readings(x), 25.0, eta=0.05)
    np.testing.assert_array_equal(x, before)


# --- bad input: one clear message each ------------------------------------------------------------


@pytest.mark.parametrize(
    ("length_mm", "match"),
    [(0.0, r"length_mm must be in \(0, inf\), got 0.0"), (-5.0, "got -5.0"), (math.nan, "got nan")],
    ids=["zero", "negative", "nan"],
)
def test_bad_length(length_mm, match):
    with pytest.raises(ParameterError, match=match):
        rp.analyse_readings(_readings(np.arange(10.0) * 1e-3), length_mm)


def test_six_sigma_at_least_length():
    x = np.random.default_rng(0).normal(0.0, 1.0, 20)  # σ ≈ 1 mm: 6σ ≈ 6 mm
    with pytest.raises(
        ParameterError, match=r"test: hinge 'h': length_mm must be > 6σ = 5.1\d* mm .*got 5$"
    ):
        rp.analyse_readings(_readings(x), 5.0)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("reading_um\n1\n2\n3\n", r"hinge 'r' has 3 readings, need at least 8"),
        (
            "reading_um\n1\n2\nnan\n4\n5\n6\n7\n8\n",
            r"line 4, column reading_um: not a finite number: 'nan'",
        ),
        (
            "reading_um\n1\n2\nabc\n4\n5\n6\n7\n8\n",
            r"line 4, column reading_um: not a number: 'abc'",
        ),
        ("hinge,reading_um\na,1\na,\n", r"line 3, column reading_um: missing value"),
        ("hinge,reading_um\na,1\n,2\n", r"line 3, column hinge: empty hinge name"),
        ("hinge,reading_um\na,1,3\n", r"line 2 has 3 fields, the header has 2"),
        (
            "x,y,z\n1,2,3\n",
            r"missing column reading_um or reading_mm; columns are \['x', 'y', 'z'\]",
        ),
        ("reading_um,reading_mm\n1,2\n", r"both reading_um and reading_mm"),
        ("1.0\n2.0\n", r"the first line \['1.0'\] looks like data"),
        ("reading_um\n" + "5\n" * 10, r"all 10 readings equal .* σ = 0"),
        ("", r"empty file"),
    ],
    ids=[
        "few",
        "nan",
        "text",
        "missing",
        "no-hinge",
        "fields",
        "no-column",
        "two-columns",
        "no-header",
        "constant",
        "empty",
    ],
)
def test_bad_file(tmp_path, text, match):
    path = _csv(tmp_path, text)
    with pytest.raises(DataError, match=match):
        _analyse_file(path)


def test_unit_missing_or_contradicting(tmp_path):
    path = _csv(tmp_path, "l\n" + "1\n" * 8)
    with pytest.raises(ParameterError, match=r"unit of column 'l' .* must be one of um, mm"):
        rp.read_readings(path)
    named = _csv(tmp_path, "reading_mm\n" + "1\n" * 8, "n.csv")
    with pytest.raises(ParameterError, match=r"unit 'um' contradicts column reading_mm"):
        rp.read_readings(named, unit=rp.ReadingUnit.UM)


def test_missing_file(tmp_path):
    with pytest.raises(DataError, match="file not found"):
        rp.read_readings(tmp_path / "nope.csv")


@pytest.mark.parametrize("confidence", [0.0, 1.0, 95.0], ids=["zero", "one", "percent"])
def test_bad_confidence(confidence):
    with pytest.raises(ParameterError, match=rf"confidence must be in \(0, 1\), got {confidence}"):
        rp.sigma_interval(1.0, 200, confidence)


def test_bad_eta():
    with pytest.raises(ParameterError, match=r"eta of hinge 'h' must be in \[0, inf\), got -0.1"):
        rp.analyse_readings(_readings(np.arange(10.0) * 1e-3), 25.0, eta=-0.1)


# --- correlation --------------------------------------------------------------------------------


def test_pearson_with_three_hinges_matches_scipy():
    rng = np.random.default_rng(4)
    eta = [0.02, 0.05, 0.09]
    results = tuple(
        rp.analyse_readings(_readings(rng.normal(0.0, s, 200), f"h{i}"), 25.0, eta=e)
        for i, (e, s) in enumerate(zip(eta, [0.3e-3, 0.6e-3, 1.1e-3], strict=True))
    )
    c = rp.correlate(results)
    r, p = stats.pearsonr(eta, [x.theta_rad for x in results])
    assert (c.r, c.p_value) == pytest.approx((r, p), rel=1e-12)
    assert c.slope_stderr_rad is not None
    assert c.relative_change is None


def test_correlation_needs_two_hinges_with_eta_and_spread():
    x = np.random.default_rng(0).normal(0.0, 1e-3, 50)
    one = rp.analyse_readings(_readings(x, "a"), 25.0, eta=0.05)
    none = rp.analyse_readings(_readings(x, "b"), 25.0)
    assert rp.correlate((one, none)) is None
    same = rp.analyse_readings(_readings(x, "c"), 25.0, eta=0.05)
    c = rp.correlate((one, same))
    assert c.r is None
    assert c.slope_rad is None
    assert "same for every hinge" in c.note
