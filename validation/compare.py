"""Compare model loops with measured loops: per-case errors, uncertainty, pass/fail, fingerprint.

For every case both loops go through ``validation.loops.process_loop`` (same offsets,
stages, closing rule), then five errors are formed (``METRICS``):

* ``disp_at_peak_mm``, ``W_cycle_Nmm``, ``eta``, ``secant_stiffness_N_per_mm``: the
  relative error ``(model − measured) / |measured|``;
* ``rms_loop``: the RMS loop distance (``validation.loops.loop_distance``) divided by the
  measured δ_max, so it too is a fraction (≥ 0).

Each is judged against the relative uncertainty σ of that metric. By default
(``Uncertainty.RECORD``) it is the same uncertainty model that ``diagnose`` and
``calibrate`` use (``validation.features``), so a model that diagnose accepts passes
compare, and the reverse:

* the **noise of the record** (estimated from the loop, ``features.noise_sigma``),
  propagated to δ_max and W; η and the secant stiffness combine the two;
* ⊕ the **model floor** (``FeatureSettings.rel_floor``, ``eta_floor``);
* ⊕ the **replicate scatter** when two or more cases share a design point (hinge,
  clearance, preload, amplitude): their sample standard deviation (ddof = 1) over
  |mean|; for ``rms_loop`` it is ``sqrt(mean d_ij² / 2) / mean δ_max`` over the pairwise
  loop distances d_ij (the distance of two independent draws has twice the variance);
* an η-only case has σ_η = ``FeatureSettings.eta_rel_sigma`` ⊕ floor ⊕ replicates (as
  ``diagnose``); ``rms_loop`` has no noise model: replicates, else
  ``default_rel_uncertainty``.

``Uncertainty.STATED`` keeps the earlier rule: replicates if any, else
``CompareSettings.default_rel_uncertainty`` for every metric. Either way σ is never below
``CompareSettings.min_rel_uncertainty`` (two replicates that agree by chance would
otherwise demand an exact model).

A case **passes** when every available error satisfies ``|e| ≤ k σ`` (k = 2 by default:
about 95 % coverage for a normal error). η-only cases have only the η error.

The **fingerprint** fits ``log W = a + s_W log Fg`` and ``log η = b + s_η log Fg`` for each
group of cases that differ only in amplitude, for the measured and the model values. A
positively homogeneous model (Coulomb friction, linear elasticity, zero clearance) has
s_W = 2 and s_η = 0 exactly; measured slopes that differ point to the missing physics.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from itertools import combinations
from typing import Any

import numpy as np

from cad.errors import DataError, check_range
from fe.kinds import hinge_kind
from validation.features import FeatureSettings, feature_sigma, loop_features
from validation.loop_files import Loop
from validation.loops import ProcessedLoop, loop_distance, noise_level, process_loop
from validation.measurements import Case, MeasurementSet

METRICS = ("disp_at_peak_mm", "W_cycle_Nmm", "eta", "secant_stiffness_N_per_mm", "rms_loop")
"""The errors formed per case, in report order."""

METRIC_LABELS = {
    "disp_at_peak_mm": "δ(+Fg)",
    "W_cycle_Nmm": "W_cycle",
    "eta": "η",
    "secant_stiffness_N_per_mm": "k_sec",
    "rms_loop": "RMS loop / δ_max",
}
"""Short names for tables and plots."""

_LOOP_METRICS = METRICS[:4]


class Uncertainty(Enum):
    """Where a metric's σ comes from (module docstring)."""

    RECORD = "record"
    """Noise of the record ⊕ model floor ⊕ replicates: the model diagnose uses."""
    STATED = "stated"
    """Replicates if any, else one stated relative σ for every metric."""


@dataclass(frozen=True)
class CompareSettings:
    """How errors are judged.

    Attributes:
        k: Coverage factor: a metric passes when |error| ≤ k σ.
        default_rel_uncertainty: Stated relative σ: of every metric of a case without
            replicates (``Uncertainty.STATED``), of ``rms_loop`` (``RECORD``).
        min_rel_uncertainty: Floor on σ.
        uncertainty: Which uncertainty model (module docstring).
        features: Model floor and stated η uncertainty of the ``RECORD`` model (the
            settings diagnose and calibrate use).
    """

    k: float = 2.0
    default_rel_uncertainty: float = 0.05
    min_rel_uncertainty: float = 0.005
    uncertainty: Uncertainty = Uncertainty.RECORD
    features: FeatureSettings = field(default_factory=FeatureSettings)

    def __post_init__(self) -> None:
        check_range("k", self.k, 0.0, 10.0, lo_open=True)
        check_range("default_rel_uncertainty", self.default_rel_uncertainty, 0.0, 1.0, lo_open=True)
        check_range("min_rel_uncertainty", self.min_rel_uncertainty, 0.0, 1.0)


@dataclass(frozen=True)
class ModelResult:
    """The model's answer for one case, as plain data (no FE objects).

    Attributes:
        loop: The computed loop 0 → +Fg → −Fg → +Fg (``CycleResult.loop_arrays``).
        metrics: The FE's own metrics (``CycleResult.metrics()``), kept for the report.
    """

    loop: Loop
    metrics: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class CaseComparison:
    """Model against measurement for one case.

    Attributes:
        case: The measured case.
        measured: Measured metrics (``LoopMetrics`` names; only ``eta`` for η-only cases).
        model: Model metrics, measured on the model loop the same way.
        errors: Metric → error (relative; see the module docstring).
        uncertainty: Metric → relative σ used.
        uncertainty_source: ``"replicates (n=…)"`` or ``"stated"``.
        failed: Metrics with |error| > k σ.
        rms_loop_mm: RMS loop distance [mm], or None for an η-only case.
        measured_loop: The processed measured loop, or None.
        model_loop: The processed model loop.
    """

    case: Case
    measured: dict[str, float]
    model: dict[str, float]
    errors: dict[str, float]
    uncertainty: dict[str, float]
    uncertainty_source: str
    failed: tuple[str, ...]
    rms_loop_mm: float | None
    measured_loop: ProcessedLoop | None = field(repr=False, compare=False)
    model_loop: ProcessedLoop = field(repr=False, compare=False)

    @property
    def passed(self) -> bool:
        """True when every error is within k σ."""
        return not self.failed


@dataclass(frozen=True)
class FingerprintFit:
    """Log–log slopes of W and η against amplitude for one group of cases.

    Attributes:
        group: Label of the group (what is held fixed).
        amplitudes_n: The amplitudes fitted [N].
        slope_W_measured: d log W / d log Fg of the measurements (NaN for η-only data).
        slope_W_model: Same for the model.
        slope_eta_measured: d log η / d log Fg of the measurements.
        slope_eta_model: Same for the model.
    """

    group: str
    amplitudes_n: tuple[float, ...]
    slope_W_measured: float
    slope_W_model: float
    slope_eta_measured: float
    slope_eta_model: float


@dataclass(frozen=True)
class Comparison:
    """All cases compared, with the overall summary and the fingerprint.

    Attributes:
        cases: Per-case comparisons in measurement order.
        settings: The judging settings.
        summary: Per metric: n, bias (mean error), rms, max |error| and its case;
            plus n_cases, n_pass, n_fail.
        fingerprint: One fit per group of cases differing only in amplitude (≥ 2 amplitudes).
    """

    cases: tuple[CaseComparison, ...]
    settings: CompareSettings
    summary: dict[str, Any]
    fingerprint: tuple[FingerprintFit, ...]

    @property
    def passed(self) -> bool:
        """True when every case passes."""
        return all(c.passed for c in self.cases)

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dict (no arrays)."""
        return {
            "settings": {
                **{
                    k: v
                    for k, v in vars(self.settings).items()
                    if k not in ("uncertainty", "features")
                },
                "uncertainty": self.settings.uncertainty.value,
                "features": vars(self.settings.features),
            },
            "passed": self.passed,
            "summary": self.summary,
            "cases": [
                {
                    "case_id": c.case.case_id,
                    "hinge": c.case.hinge,
                    **case_columns(c.case),
                    "amplitude_N": c.case.amplitude_n,
                    "replicate": c.case.replicate,
                    "source": None if c.case.loop is None else c.case.loop.source,
                    "passed": c.passed,
                    "failed": list(c.failed),
                    "errors": c.errors,
                    "uncertainty": c.uncertainty,
                    "uncertainty_source": c.uncertainty_source,
                    "rms_loop_mm": c.rms_loop_mm,
                    "measured": c.measured,
                    "model": c.model,
                }
                for c in self.cases
            ],
            "fingerprint": [vars(f) for f in self.fingerprint],
        }


def _processed(case: Case) -> ProcessedLoop | None:
    if case.loop is None:
        return None
    return process_loop(case.loop.force_n, case.loop.displacement_mm, case.loop.source)


def _replicate_sigma(
    ids: tuple[str, ...], loops: Mapping[str, ProcessedLoop | None], cases: Mapping[str, Case]
) -> dict[str, float]:
    """Relative std of each metric over one replicate group (only metrics all replicates have)."""
    sigma: dict[str, float] = {}
    processed = [loops[i] for i in ids]
    if all(p is not None for p in processed):
        ps = [p for p in processed if p is not None]
        for m in _LOOP_METRICS:
            v = np.array([getattr(p.metrics, m) for p in ps])
            sigma[m] = float(np.std(v, ddof=1) / abs(np.mean(v)))
        d2 = [loop_distance(a, b) ** 2 for a, b in combinations(ps, 2)]
        delta = float(np.mean([p.metrics.delta_max_mm for p in ps]))
        sigma["rms_loop"] = math.sqrt(float(np.mean(d2)) / 2) / delta
    else:
        etas = [cases[i].eta for i in ids]
        if all(e is not None for e in etas):
            v = np.array(etas, dtype=np.float64)
            sigma["eta"] = float(np.std(v, ddof=1) / abs(np.mean(v)))
    return sigma


def _record_sigma(
    meas: ProcessedLoop | None, case: Case, rep: Mapping[str, float], s: CompareSettings
) -> dict[str, float]:
    """Relative σ per metric: noise of the record ⊕ model floor ⊕ replicates (as diagnose)."""
    f = s.features
    if meas is None:
        eta = abs(float(case.eta or 0.0))
        floor = f.rel_floor + f.eta_floor / max(eta, 1e-300)
        return {"eta": math.sqrt(f.eta_rel_sigma**2 + floor**2 + rep.get("eta", 0.0) ** 2)}
    sig = feature_sigma([meas], f, None)  # absolute: δ_max, W, opening (noise ⊕ floor)
    feats = loop_features(meas)
    r_delta = _ratio(sig[0], feats[0])
    r_W = _ratio(sig[1], feats[1])
    m = meas.metrics
    peak = max(abs(m.disp_at_peak_mm), 1e-300)
    # δ(+Fg) is one sample (δ_max averages two peaks): its full displacement noise counts
    s_peak = math.hypot(
        noise_level(meas.displacement_mm),
        _ratio(m.delta_max_mm, m.f_max_n) * noise_level(meas.force_n),
    )
    base = {
        "disp_at_peak_mm": _ratio(math.hypot(s_peak, f.rel_floor * m.delta_max_mm), peak),
        "W_cycle_Nmm": r_W,
        "eta": math.hypot(r_W, r_delta),
        "secant_stiffness_N_per_mm": r_delta,
        "rms_loop": s.default_rel_uncertainty if "rms_loop" not in rep else 0.0,
    }
    return {m: math.hypot(v, rep.get(m, 0.0)) for m, v in base.items()}


def relative_error(model: float, measured: float) -> float:
    """``(model − measured) / |measured|``; 0 when both are 0, ±inf when only ``measured`` is.

    A metric the record cannot give a scale for (a zero loop area) is a failure of that
    metric with an infinite error, never a division by zero after the model has run.
    """
    if measured != 0.0 and math.isfinite(measured):
        return (model - measured) / abs(measured)
    if model == measured:
        return 0.0
    return math.copysign(math.inf, model - measured) if math.isfinite(model) else math.nan


def _within(error: float, band: float) -> bool:
    """A metric passes when its error is finite and inside the band.

    An error without a scale (±inf or NaN) fails, whatever the uncertainty.
    """
    return math.isfinite(error) and abs(error) <= band


def _ratio(a: float, b: float) -> float:
    """``a / |b|``, inf where ``b`` is 0 (a relative σ without a scale)."""
    return float(a) / abs(float(b)) if b != 0.0 and math.isfinite(b) else math.inf


def _case_errors(
    meas: ProcessedLoop | None, case: Case, model: ProcessedLoop
) -> tuple[dict[str, float], dict[str, float], dict[str, float], float | None]:
    """Return (measured metrics, model metrics, errors, rms [mm] or None)."""
    mod = model.metrics.as_dict()
    if meas is None:
        if case.eta is None:
            raise DataError(f"case {case.case_id!r}: neither a loop nor η to compare with")
        return {"eta": case.eta}, mod, {"eta": relative_error(mod["eta"], case.eta)}, None
    mea = meas.metrics.as_dict()
    errors = {m: relative_error(mod[m], mea[m]) for m in _LOOP_METRICS}
    rms = loop_distance(meas, model)
    errors["rms_loop"] = relative_error(rms + meas.metrics.delta_max_mm, meas.metrics.delta_max_mm)
    return mea, mod, errors, rms


def compare(
    model_results: Mapping[str, ModelResult],
    measurements: MeasurementSet,
    settings: CompareSettings | None = None,
) -> Comparison:
    """Compare the model's loop with the measurement for every case.

    Args:
        model_results: case_id → the model's loop and metrics for that case's design point.
        measurements: The measured cases.
        settings: Coverage factor and uncertainties; defaults to ``CompareSettings()``.

    Returns:
        The comparison (see the module docstring for every definition).

    Raises:
        DataError: A case without a model result, or a loop that cannot be processed.
    """
    s = settings or CompareSettings()
    by_id = measurements.by_id()
    missing = [c for c in by_id if c not in model_results]
    if missing:
        raise DataError(f"no model result for case(s) {missing}")
    loops = {cid: _processed(c) for cid, c in by_id.items()}
    sigma_of: dict[str, tuple[dict[str, float], str]] = {}
    for ids in measurements.replicate_groups().values():
        rep = _replicate_sigma(ids, loops, by_id) if len(ids) > 1 else {}
        for cid in ids:
            sigma_of[cid] = (rep, f"replicates (n={len(ids)})" if rep else "stated")
    out = []
    for cid, case in by_id.items():
        res = model_results[cid]
        model = process_loop(res.loop.force_n, res.loop.displacement_mm, f"model:{cid}")
        mea, mod, errors, rms = _case_errors(loops[cid], case, model)
        rep, source = sigma_of[cid]
        if s.uncertainty is Uncertainty.RECORD:
            unc = _record_sigma(loops[cid], case, rep, s)
            source = f"record ⊕ floor{' ⊕ ' + source if rep else ''}"
        else:
            unc = {m: rep.get(m, s.default_rel_uncertainty) for m in errors}
        unc = {m: max(unc[m], s.min_rel_uncertainty) for m in errors}
        failed = tuple(m for m in METRICS if m in errors and not _within(errors[m], s.k * unc[m]))
        mod_all = {**mod, **{f"fe_{k}": float(v) for k, v in res.metrics.items()}}
        out.append(
            CaseComparison(case, mea, mod_all, errors, unc, source, failed, rms, loops[cid], model)
        )
    cases = tuple(out)
    return Comparison(cases, s, _summary(cases), fingerprint(cases))


def _summary(cases: tuple[CaseComparison, ...]) -> dict[str, Any]:
    per_metric: dict[str, Any] = {}
    for m in METRICS:
        have = [c for c in cases if m in c.errors]
        if not have:
            continue
        e = np.array([c.errors[m] for c in have])
        worst = have[int(np.argmax(np.abs(e)))]
        per_metric[m] = {
            "n": len(have),
            "bias": float(np.mean(e)),
            "rms": float(np.sqrt(np.mean(e**2))),
            "max_abs": float(np.max(np.abs(e))),
            "worst_case": worst.case.case_id,
            "n_fail": sum(m in c.failed for c in have),
        }
    n_pass = sum(c.passed for c in cases)
    return {
        "n_cases": len(cases),
        "n_pass": n_pass,
        "n_fail": len(cases) - n_pass,
        "metrics": per_metric,
    }


def _slope(x: list[float], y: list[float]) -> float:
    xa, ya = np.asarray(x), np.asarray(y)
    ok = (xa > 0) & (ya > 0) & np.isfinite(ya)
    if len(np.unique(xa[ok])) < 2:
        return math.nan
    return float(np.polyfit(np.log(xa[ok]), np.log(ya[ok]), 1)[0])


def _values(members: list[CaseComparison], side: str, key: str) -> list[float]:
    """One metric of one side ("measured" or "model") of each case; NaN where absent."""
    return [getattr(c, side).get(key, math.nan) for c in members]


def case_columns(case: Case) -> dict[str, float]:
    """The case's design values by their cases.csv columns (``clearance_mm``, ``preload_N``)."""
    columns = {v.name: v.column for v in hinge_kind(case.hinge).design_variables}
    return {columns[k]: v for k, v in case.values.items()}


def group_name(case: Case) -> str:
    """The case's design point without its amplitude, e.g. ``general, Δr = 0.1 mm``."""
    return ", ".join(filter(None, [case.hinge, case.describe()]))


def fingerprint(cases: tuple[CaseComparison, ...]) -> tuple[FingerprintFit, ...]:
    """Fit log–log slopes of W and η against amplitude per design group (``group_name``).

    Groups with fewer than two distinct amplitudes are skipped.
    """
    groups: dict[str, list[CaseComparison]] = {}
    for c in cases:
        groups.setdefault(group_name(c.case), []).append(c)
    fits = []
    for group, members in groups.items():
        amps = [c.case.amplitude_n for c in members]
        if len(set(amps)) < 2:
            continue

        fits.append(
            FingerprintFit(
                group=group,
                amplitudes_n=tuple(sorted(set(amps))),
                slope_W_measured=_slope(amps, _values(members, "measured", "W_cycle_Nmm")),
                slope_W_model=_slope(amps, _values(members, "model", "W_cycle_Nmm")),
                slope_eta_measured=_slope(amps, _values(members, "measured", "eta")),
                slope_eta_model=_slope(amps, _values(members, "model", "eta")),
            )
        )
    return tuple(fits)
