"""Repeatability of a hinge from repeated position readings (the paper's Sec. V.B, Eq. 14, Table 7).

The pendulum test records about 200 readings ``l`` of a laser sensor at the distance
``L`` from the hinge axis, each after the pendulum came to rest. Workflow:
``read_readings`` (CSV, one group per hinge) → ``analyse_readings`` (normal fit,
Shapiro–Wilk and Anderson–Darling, ``6σ`` as the position error, the repeatability
``θ = arcsin(6σ/L)`` [rad] with confidence intervals) → ``correlate`` (η against θ
across hinges). ``hingelab repeatability`` (``studies.cli.repeatability``) writes the
JSON, CSV and plots.

**Eq. 14 as printed is not what Table 7 computes.** The paper prints
``θ = arcsin(6σ/L)/180·π``. Read with ``arcsin`` in radians, that converts radians
"from degrees" a second time and gives 4.5834e-6 rad for the general hinge (σ = 1.0942
µm, L = 25 mm), 57.3 times less than Table 7's 2.6260e-4 rad. Table 7 follows
``θ = arcsin(6σ/L)`` in radians (the printed formula with ``arcsin`` returning degrees,
as on a calculator in degree mode): 2.62608e-4 and 5.73120e-5 rad, which match the
table to its last printed digit (2.6260e-4 is 2.62608e-4 truncated). At these angles
``arcsin(x) = x`` to 1e-11, so the table cannot tell the arcsine from the small-angle
form. This module uses ``θ = arcsin(6σ/L)`` [rad]:

>>> sigma_mm, length_mm = 1.0942e-3, 25.0
>>> f"{theta_from_sigma(sigma_mm, length_mm):.5e}"  # Table 7: 2.6260e-4
'2.62608e-04'
>>> import math
>>> f"{math.asin(6 * sigma_mm / length_mm) / 180 * math.pi:.5e}"  # Eq. 14 read literally
'4.58337e-06'

σ is the maximum-likelihood scale of ``scipy.stats.norm.fit`` (ddof = 0). Its
confidence interval is the exact chi-square one, ``n σ̂²/σ² ~ χ²(n − 1)`` (the same
interval as from the sample deviation with ddof = 1, since ``n σ̂² = (n − 1) s²``).
θ is increasing in σ, so its interval is the image of σ's. Both intervals assume
independent normal readings; a rounding step ``h`` comparable to σ breaks that, and
``Resolution`` flags it.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import numpy as np
import numpy.typing as npt

from cad.errors import DataError, ParameterError, check_range

FloatArray = npt.NDArray[np.float64]

MIN_READINGS = 8
"""Fewer readings cannot support a normality test or a useful interval on σ."""

NORMALITY_ALPHA = 0.05
"""Significance level of both normality tests (Anderson–Darling is tabulated at 5 %)."""

AD_CRITICAL_5PCT = 0.752
"""Critical value of the modified statistic A²(1 + 0.75/n + 2.25/n²) at 5 % for a normal
law with estimated mean and variance (Stephens 1974; the value scipy uses)."""

COARSE_STEP_RATIO = 0.15
"""A rounding step h above this fraction of σ is flagged. Measured at n = 200 (400 seeds of
rounded normal data): at h/σ = 0.1, 0.15, 0.2, 0.3 Shapiro–Wilk rejects 5, 9, 13, 57 % and
Anderson–Darling 8, 12, 32, 99.5 % of the time instead of 5 %."""

_AD_P_VALUE = (
    (0.6, 1.2937, -5.709, 0.0186),  # p = exp(c0 + c1 A* + c2 A*²)
    (0.34, 0.9177, -4.279, -1.38),
    (0.2, -8.318, 42.796, -59.938),  # p = 1 − exp(...)
    (-math.inf, -13.436, 101.14, -223.73),
)
"""D'Agostino & Stephens (1986), Table 4.9: p-value of the modified A* from its lower bound up."""

HINGE_COLUMN = "hinge"


class ReadingUnit(Enum):
    """Unit of the readings in a file (the column suffix, or ``--unit``)."""

    UM = "um"
    MM = "mm"

    @property
    def mm_per_unit(self) -> float:
        """Factor from this unit to mm."""
        return 1e-3 if self is ReadingUnit.UM else 1.0


@dataclass(frozen=True)
class Readings:
    """The readings of one hinge.

    Attributes:
        hinge: Hinge name (the ``hinge`` column, or the label).
        position_mm: Readings ``l``, shape (n,), float64 [mm].
        source: Where they came from (file path), for messages.
    """

    hinge: str
    position_mm: FloatArray
    source: str


@dataclass(frozen=True)
class Interval:
    """A two-sided confidence interval; ``hi`` is None (with ``reason``) if it does not exist."""

    lo: float
    hi: float | None
    confidence: float
    reason: str | None = None


@dataclass(frozen=True)
class NormalityTest:
    """One normality test at ``alpha``.

    Attributes:
        name: ``"Shapiro-Wilk"`` or ``"Anderson-Darling"``.
        statistic: W, or A² (unmodified, as scipy reports it).
        p_value: p-value (Anderson–Darling: D'Agostino–Stephens approximation).
        critical_value: A² critical value at ``alpha`` for this n (Anderson–Darling only).
        alpha: Significance level.
        rejects_normal: True if normality is rejected at ``alpha``.
        verdict: Plain words, with the numbers.
    """

    name: str
    statistic: float
    p_value: float
    critical_value: float | None
    alpha: float
    rejects_normal: bool
    verdict: str


@dataclass(frozen=True)
class Resolution:
    """How finely the readings are resolved.

    Attributes:
        n_distinct: Number of distinct values.
        step_mm: Smallest gap between distinct values [mm] (the rounding step if rounded).
        coarse: True if ``step_mm > COARSE_STEP_RATIO·σ``: the normality tests then
            reject normal data for the rounding alone.
    """

    n_distinct: int
    step_mm: float
    coarse: bool


@dataclass(frozen=True)
class Repeatability:
    """The repeatability of one hinge.

    Attributes:
        hinge: Hinge name.
        n: Number of readings.
        mean_mm: Fitted mean μ [mm].
        sigma_mm: Fitted σ (maximum likelihood) [mm].
        sigma_ci_mm: Chi-square interval on σ [mm].
        length_mm: Distance L from the axis to the sensor [mm].
        theta_rad: Repeatability θ = arcsin(6σ/L) [rad].
        theta_ci_rad: Interval on θ [rad], the image of ``sigma_ci_mm``.
        shapiro: Shapiro–Wilk test.
        anderson: Anderson–Darling test.
        resolution: Rounding of the readings.
        eta: Loss factor η of the hinge, if given.
    """

    hinge: str
    n: int
    mean_mm: float
    sigma_mm: float
    sigma_ci_mm: Interval
    length_mm: float
    theta_rad: float
    theta_ci_rad: Interval
    shapiro: NormalityTest
    anderson: NormalityTest
    resolution: Resolution
    eta: float | None


@dataclass(frozen=True)
class Correlation:
    """η against θ across hinges.

    Attributes:
        hinges: Hinge names, in input order.
        eta: η per hinge, shape (n_points,).
        theta_rad: θ per hinge, shape (n_points,) [rad].
        slope_rad: dθ/dη of the line (through two points, or least squares) [rad], or None.
        slope_stderr_rad: Standard error of the slope (≥ 3 points with spread), or None.
        r: Pearson r (≥ 3 points), or None.
        p_value: Two-sided p-value of r (≥ 3 points), or None.
        relative_change: (1 − η₂/η₁, 1 − θ₂/θ₁) for two points, as the paper reports.
        note: What the numbers can and cannot show, in plain words.
    """

    hinges: tuple[str, ...]
    eta: FloatArray
    theta_rad: FloatArray
    slope_rad: float | None
    slope_stderr_rad: float | None
    r: float | None
    p_value: float | None
    relative_change: tuple[float, float] | None
    note: str


def theta_from_sigma(sigma_mm: float, length_mm: float) -> float:
    """Return the repeatability θ = arcsin(6σ/L) [rad] (Table 7's formula, see the module doc).

    Raises:
        ParameterError: If ``length_mm`` is not in (0, inf) or ``6σ ≥ L``.
    """
    check_range("length_mm", length_mm, 0.0, math.inf, lo_open=True, hi_open=True)
    if 6.0 * sigma_mm >= length_mm:
        raise ParameterError(
            f"length_mm must be > 6σ = {6.0 * sigma_mm:g} mm (arcsin needs 6σ/L < 1; "
            f"is the unit of the readings right?), got {length_mm:g}"
        )
    return math.asin(6.0 * sigma_mm / length_mm)


def sigma_interval(sigma_mm: float, n: int, confidence: float) -> Interval:
    """Return the exact chi-square interval on σ from its maximum-likelihood estimate.

    ``n σ̂²/σ² ~ χ²(n − 1)``, so ``σ ∈ [σ̂ √(n/χ²_{1−a/2}), σ̂ √(n/χ²_{a/2})]``, a = 1 − confidence.

    Args:
        sigma_mm: σ̂ (ddof = 0) [mm].
        n: Number of readings (≥ 2).
        confidence: Coverage in (0, 1).

    Raises:
        ParameterError: For ``confidence`` outside (0, 1) or ``n < 2``.
    """
    from scipy import stats  # on use: the CLI builds its parser from this module

    check_range("confidence", confidence, 0.0, 1.0, lo_open=True, hi_open=True)
    check_range("n", n, 2, math.inf)
    a = 1.0 - confidence
    chi2_hi, chi2_lo = stats.chi2.ppf([1.0 - a / 2.0, a / 2.0], n - 1)
    lo, hi = (float(sigma_mm * math.sqrt(n / c)) for c in (chi2_hi, chi2_lo))
    return Interval(lo, hi, confidence)


def theta_interval(sigma_ci_mm: Interval, length_mm: float) -> Interval:
    """Map an interval on σ through θ = arcsin(6σ/L); an upper end with 6σ ≥ L becomes None."""
    lo, hi, confidence = sigma_ci_mm.lo, sigma_ci_mm.hi, sigma_ci_mm.confidence
    if hi is not None and 6.0 * hi >= length_mm:
        reason = f"6σ at the upper end of σ's interval ({6.0 * hi:g} mm) ≥ L = {length_mm:g} mm"
        return Interval(theta_from_sigma(lo, length_mm), None, confidence, reason)
    theta_hi = None if hi is None else theta_from_sigma(hi, length_mm)
    return Interval(theta_from_sigma(lo, length_mm), theta_hi, confidence, sigma_ci_mm.reason)


def _verdict(rejects: bool, detail: str) -> str:
    return ("not normal" if rejects else "consistent with normal") + f" ({detail})"


def shapiro_wilk(x: FloatArray, alpha: float = NORMALITY_ALPHA) -> NormalityTest:
    """Shapiro–Wilk test of normality (``scipy.stats.shapiro``) on readings of shape (n,)."""
    from scipy import stats  # on use: the CLI builds its parser from this module

    w, p = stats.shapiro(x)
    rejects = bool(p < alpha)
    detail = f"W = {w:.4f}, p = {p:.3g} {'<' if rejects else '≥'} {alpha:g}"
    return NormalityTest(
        "Shapiro-Wilk", float(w), float(p), None, alpha, rejects, _verdict(rejects, detail)
    )


def anderson_darling(x: FloatArray) -> NormalityTest:
    """Anderson–Darling test of normality with estimated μ and σ, at 5 %.

    ``A² = −n − (1/n) Σ (2i − 1)[ln Φ(w_i) + ln(1 − Φ(w_{n+1−i}))]`` with
    ``w = (sorted x − x̄)/s`` (ddof = 1), as ``scipy.stats.anderson``. The modified
    ``A*² = A²(1 + 0.75/n + 2.25/n²)`` is compared with 0.752 and gives the p-value by
    D'Agostino & Stephens (1986, Table 4.9). Computed here because scipy ≥ 1.17
    reports either critical values or an interpolated p-value clipped to [0.01, 0.15].

    Args:
        x: Readings, shape (n,), any unit.
    """
    from scipy import stats  # on use: the CLI builds its parser from this module

    n = x.size
    w = np.sort((x - x.mean()) / x.std(ddof=1))
    i = np.arange(1, n + 1, dtype=np.float64)
    a2 = float(-n - np.sum((2 * i - 1) * (stats.norm.logcdf(w) + stats.norm.logsf(w[::-1]))) / n)
    factor = 1.0 + 0.75 / n + 2.25 / n**2
    a = a2 * factor
    _, c0, c1, c2 = next(row for row in _AD_P_VALUE if a >= row[0])
    e = math.exp(c0 + c1 * a + c2 * a**2)
    p = min(max(e if a >= 0.34 else 1.0 - e, 0.0), 1.0)
    crit, rejects = AD_CRITICAL_5PCT / factor, a2 > AD_CRITICAL_5PCT / factor
    detail = f"A² = {a2:.3f} {'>' if rejects else '≤'} {crit:.3f} at 5 %, p ≈ {p:.3g}"
    return NormalityTest("Anderson-Darling", a2, p, crit, 0.05, rejects, _verdict(rejects, detail))


def analyse_readings(
    readings: Readings, length_mm: float, *, confidence: float = 0.95, eta: float | None = None
) -> Repeatability:
    """Fit a normal law to one hinge's readings and turn 6σ into the repeatability θ.

    Args:
        readings: The readings ``l`` of one hinge, shape (n,) [mm].
        length_mm: Distance L from the hinge axis to the sensor [mm].
        confidence: Coverage of the intervals, in (0, 1).
        eta: The hinge's loss factor η ≥ 0, or None.

    Raises:
        DataError: Fewer than ``MIN_READINGS`` readings, a non-finite one, or all equal.
        ParameterError: ``length_mm``, ``confidence`` or ``eta`` out of range, or 6σ ≥ L.
    """
    from scipy import stats  # on use: the CLI builds its parser from this module

    x = np.asarray(readings.position_mm, dtype=np.float64).ravel()
    where = f"{readings.source}: hinge {readings.hinge!r}"
    if x.size < MIN_READINGS:
        raise DataError(f"{where}: {x.size} readings, need at least {MIN_READINGS}")
    if not np.all(np.isfinite(x)):
        raise DataError(f"{where}: reading {int(np.argmin(np.isfinite(x))) + 1} is not finite")
    if eta is not None:
        check_range(f"eta of hinge {readings.hinge!r}", eta, 0.0, math.inf, hi_open=True)
    if np.ptp(x) == 0.0:
        raise DataError(
            f"{where}: all {x.size} readings equal {x[0]:g} mm, σ = 0 (below the resolution)"
        )
    mean, sigma = (float(v) for v in stats.norm.fit(x))
    try:
        theta = theta_from_sigma(sigma, length_mm)
    except ParameterError as err:
        raise ParameterError(f"{where}: {err}") from None
    sigma_ci = sigma_interval(sigma, x.size, confidence)
    distinct = np.unique(x)
    step = float(f"{np.min(np.diff(distinct)):.12g}") if distinct.size > 1 else 0.0  # no 0.0999…
    return Repeatability(
        hinge=readings.hinge,
        n=int(x.size),
        mean_mm=mean,
        sigma_mm=sigma,
        sigma_ci_mm=sigma_ci,
        length_mm=length_mm,
        theta_rad=theta,
        theta_ci_rad=theta_interval(sigma_ci, length_mm),
        shapiro=shapiro_wilk(x),
        anderson=anderson_darling(x),
        resolution=Resolution(int(distinct.size), step, step > COARSE_STEP_RATIO * sigma),
        eta=eta,
    )


def correlate(results: tuple[Repeatability, ...]) -> Correlation | None:
    """Relate η to θ over the hinges that have η; None if fewer than two have.

    Two points: the line through them, the paper's relative changes, and a note that a
    line through two points always fits exactly (r = ±1 by construction), so there is
    no significance and no slope uncertainty. Three or more: Pearson r, its p-value and
    the least-squares slope with its standard error.
    """
    from scipy import stats  # on use: the CLI builds its parser from this module

    with_eta = [r for r in results if r.eta is not None]
    if len(with_eta) < 2:
        return None
    names = tuple(r.hinge for r in with_eta)
    eta = np.array([r.eta for r in with_eta], dtype=np.float64)
    theta = np.array([r.theta_rad for r in with_eta], dtype=np.float64)
    if np.ptp(eta) == 0.0 or np.ptp(theta) == 0.0:
        note = "η or θ is the same for every hinge: no correlation can be computed."
        return Correlation(names, eta, theta, None, None, None, None, None, note)
    if eta.size == 2:
        slope = float((theta[1] - theta[0]) / (eta[1] - eta[0]))
        change = (float(1.0 - eta[1] / eta[0]), float(1.0 - theta[1] / theta[0]))
        note = (
            f"Two hinges only: the hinge with the smaller η has the {'smaller' if slope > 0 else 'larger'} θ. "
            "A line through two points always fits exactly (|r| = 1 by construction), so two points "
            "give no significance, no slope uncertainty and no test of linearity; they show the direction only."
        )
        return Correlation(names, eta, theta, slope, None, None, None, change, note)
    fit = stats.linregress(eta, theta)
    r, p = stats.pearsonr(eta, theta)
    note = (
        f"{eta.size} hinges: Pearson r = {r:.3f}, two-sided p = {p:.3g} "
        f"({'significant' if p < 0.05 else 'not significant'} at 5 %); θ's own uncertainty is not in r."
    )
    return Correlation(
        names, eta, theta, float(fit.slope), float(fit.stderr), float(r), float(p), None, note
    )


def read_readings(
    path: Path, *, unit: ReadingUnit | None = None, label: str | None = None
) -> tuple[Readings, ...]:
    """Read repeated position readings from a CSV file, one group per hinge.

    The first non-blank line not starting with ``#`` is the header. The readings are the
    column ``reading_um`` or ``reading_mm``; otherwise the one column besides ``hinge``
    in ``unit``. An optional ``hinge`` column splits the
    rows into hinges (in order of first appearance); without it the hinge is ``label``
    (default: the file name without extension).

    Raises:
        DataError: Missing file or column, a missing, non-numeric or non-finite value
            (naming line and column), or a hinge with fewer than ``MIN_READINGS`` readings.
        ParameterError: No unit for the reading column, or ``unit`` contradicting its name.
    """
    rows = read_csv_rows(path)
    header, rows = rows[0][1], rows[1:]
    column, unit = _reading_column(path, header, unit)
    col = header.index(column)
    hinge_col = header.index(HINGE_COLUMN) if HINGE_COLUMN in header else None
    groups: dict[str, list[float]] = {}
    for line, cells in rows:
        if len(cells) != len(header):
            n, m = len(cells), len(header)
            raise DataError(f"{path}: line {line} has {n} fields, the header has {m}")
        name = (label or path.stem) if hinge_col is None else cells[hinge_col]
        if not name:
            raise DataError(f"{path}: line {line}, column {HINGE_COLUMN}: empty hinge name")
        where = f"{path}: line {line}, column {column}"
        groups.setdefault(name, []).append(_parse_value(cells[col], where))
    for name, values in (groups or {label or path.stem: []}).items():
        if len(values) < MIN_READINGS:
            n, need = len(values), MIN_READINGS
            raise DataError(f"{path}: hinge {name!r} has {n} readings, need at least {need}")
    mm = unit.mm_per_unit
    return tuple(
        Readings(h, np.array(v, dtype=np.float64) * mm, str(path)) for h, v in groups.items()
    )


def read_csv_rows(path: Path) -> list[tuple[int, list[str]]]:
    """Return (line number, stripped cells) of every non-blank line not starting with '#'."""
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    with open(path, newline="", encoding="utf-8-sig") as fh:
        rows = [(i, [c.strip() for c in raw]) for i, raw in enumerate(csv.reader(fh), start=1)]
    rows = [(i, c) for i, c in rows if any(c) and not c[0].startswith("#")]
    if not rows:
        raise DataError(f"{path}: empty file")
    return rows


def _reading_column(
    path: Path, header: list[str], unit: ReadingUnit | None
) -> tuple[str, ReadingUnit]:
    named = [h for h in header if h in {f"reading_{u.value}" for u in ReadingUnit}]
    if len(named) > 1:
        raise DataError(f"{path}: both {named[0]} and {named[1]}: keep one reading column")
    if named:
        own = ReadingUnit(named[0].removeprefix("reading_"))
        if unit is not None and unit is not own:
            raise ParameterError(f"unit {unit.value!r} contradicts column {named[0]} of {path}")
        return named[0], own
    others = [h for h in header if h != HINGE_COLUMN]
    if all(_parses(h) for h in header):
        raise DataError(f"{path}: the first line {header} looks like data; it must be a header")
    if len(others) != 1:
        raise DataError(f"{path}: missing column reading_um or reading_mm; columns are {header}")
    if unit is None:
        raise ParameterError(
            f"unit of column {others[0]!r} in {path} must be one of um, mm "
            "(name the column reading_um or reading_mm, or give --unit)"
        )
    return others[0], unit


def _parses(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _parse_value(text: str, where: str) -> float:
    if not text:
        raise DataError(f"{where}: missing value")
    try:
        value = float(text)
    except ValueError:
        raise DataError(f"{where}: not a number: {text!r}") from None
    if not math.isfinite(value):
        raise DataError(f"{where}: not a finite number: {text!r}")
    return value
