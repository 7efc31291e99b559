"""Compare model loops with measured loops: per-case errors, uncertainty, pass/fail, fingerprint.

For every case both loops go through ``validation.loops.process_loop`` (same offsets,
stages, closing rule), then five errors are formed (``METRICS``):

* ``disp_at_peak_mm``, ``W_cycle_Nmm``, ``eta``, ``secant_stiffness_N_per_mm``: the
  relative error ``(model − measured) / |measured|``; δ(+Fg) from the **centre of the last
  loop** on both sides (``disp_at_peak_from_start_mm`` keeps δ from the first samples): a
  transducer's zero is arbitrary, and a real pin rests against one side of its clearance
  while the model's starts centred; with clearance W and η are those of
  the loop **without the free play** (``validation.hysteresis``: the zero-force crossings
  cut out of both loops at the same forces), whose area the force noise during the
  crossing no longer swamps;
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
about 95 % coverage for a normal error). η-only cases have only the η error. W and η are
judged by ``validation.hysteresis.judge``: on their relative error only where the record
measures them (``|v| > k σ_noise`` and σ ≤ ``FeatureSettings.max_rel_sigma`` · |v|);
elsewhere they are **not measurable** (neither pass nor fail, the reason in
``CaseComparison.not_measurable``), unless the model lies beyond k σ of the record in
absolute terms (a fail without a relative error). A relative σ on a near-zero hysteresis
(μ = 0, or a clearance loop's area under the model floor) is never formed.

The **fingerprint** (``validation.fingerprint``) fits the log–log slopes of W and η against
the amplitude per group of cases that differ only in amplitude.
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
from validation.feature_misfit import feature_summary
from validation.features import FeatureSettings, feature_sigma, loop_features
from validation.fingerprint import FingerprintFit, fingerprint
from validation.hysteresis import (
    HYSTERESIS_METRICS,
    Hysteresis,
    Judgement,
    Status,
    hysteresis,
    judge,
    judge_loops,
)
from validation.loop_files import Loop
from validation.loops import ProcessedLoop, loop_distance, process_loop, zero_band_n
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
        errors: Metric → error (relative; see the module docstring); W and η only where
            judged on their relative error.
        uncertainty: Metric → relative σ used (as ``errors``).
        uncertainty_source: ``"replicates (n=…)"`` or ``"stated"``.
        failed: Metrics with |error| > k σ (or, not measurable relatively, a model beyond
            k σ of the record).
        rms_loop_mm: RMS loop distance [mm], or None for an η-only case.
        measured_loop: The processed measured loop, or None.
        model_loop: The processed model loop.
        judgements: W and η (η only for an η-only case) as ``validation.hysteresis.judge``
            judged them.
        free_play_removed: True when W and η are those of the loop without the free play.
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
    judgements: dict[str, Judgement] = field(default_factory=dict, repr=False)
    free_play_removed: bool = False

    @property
    def passed(self) -> bool:
        """True when every error is within k σ."""
        return not self.failed

    @property
    def not_measurable(self) -> dict[str, str]:
        """Metric → why the record does not measure it (neither pass nor fail)."""
        return {
            m: j.reason for m, j in self.judgements.items() if j.status is Status.NOT_MEASURABLE
        }


@dataclass(frozen=True)
class Comparison:
    """All cases compared, with the overall summary and the fingerprint.

    Attributes:
        cases: Per-case comparisons in measurement order.
        settings: The judging settings.
        summary: Per metric: n, bias (mean error), rms, max |error| and its case;
            plus n_cases, n_pass, n_fail, and ``features``: the calibrate ledger's error
            (``validation.feature_misfit.feature_summary``).
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
                    "not_measurable": c.not_measurable,
                    "free_play_removed": c.free_play_removed,
                    "judged": {m: j.as_dict() for m, j in c.judgements.items()},
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


def _hyst(p: ProcessedLoop, case: Case) -> Hysteresis:
    """W, δ_max and η of a replicate's loop, without the free play for a case with clearance."""
    band = zero_band_n(p, p)
    return hysteresis(p, band, remove_free_play=case.values.get("clearance_mm", 0.0) > 0.0)


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
        hs = [_hyst(p, cases[i]) for p, i in zip(ps, ids, strict=True)]
        judged = {"W_cycle_Nmm": [h.W_Nmm for h in hs], "eta": [h.eta for h in hs]}
        for m in _LOOP_METRICS:
            v = np.array(judged.get(m) or [getattr(p.metrics, m) for p in ps])
            sigma[m] = _ratio(float(np.std(v, ddof=1)), float(np.mean(v)))
        d2 = [loop_distance(a, b) ** 2 for a, b in combinations(ps, 2)]
        delta = float(np.mean([p.metrics.delta_max_mm for p in ps]))
        sigma["rms_loop"] = math.sqrt(float(np.mean(d2)) / 2) / delta
    else:
        etas = [cases[i].eta for i in ids]
        if all(e is not None for e in etas):
            v = np.array(etas, dtype=np.float64)
            sigma["eta"] = _ratio(float(np.std(v, ddof=1)), float(np.mean(v)))
    return sigma


def _record_sigma(
    meas: ProcessedLoop | None, case: Case, rep: Mapping[str, float], s: CompareSettings
) -> dict[str, float]:
    """Relative σ of δ(+Fg), k_sec and the loop distance: noise ⊕ floor ⊕ replicates (as diagnose).

    W and η are judged on their own (``_judge_hysteresis``).
    """
    f = s.features
    if meas is None:
        return {}
    sig = feature_sigma([meas], f, None)  # absolute: δ_max, W, opening (noise ⊕ floor)
    r_delta = _ratio(sig[0], loop_features(meas)[0])
    base = {
        "disp_at_peak_mm": r_delta,  # δ(+Fg) about the loop centre is δ_max
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
    for side in (mea, mod):  # δ(+Fg) about the loop's centre: the zero is arbitrary
        side["disp_at_peak_from_start_mm"] = side["disp_at_peak_mm"]
        side["disp_at_peak_mm"] = side["delta_max_mm"]
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
        unc = {m: max(unc.get(m, math.inf), s.min_rel_uncertainty) for m in errors}
        judged, removed = _judge_hysteresis(loops[cid], case, model, rep, s, mea, mod)
        for m, j in judged.items():
            errors.pop(m, None)
            unc.pop(m, None)
            if j.relative and j.error is not None and j.sigma is not None:
                errors[m], unc[m] = j.error, j.sigma
        failed = tuple(
            m
            for m in METRICS
            if (m in judged and judged[m].status is Status.FAIL)
            or (m not in judged and m in errors and not _within(errors[m], s.k * unc[m]))
        )
        mod_all = {**mod, **{f"fe_{k}": float(v) for k, v in res.metrics.items()}}
        out.append(
            CaseComparison(
                case, mea, mod_all, errors, unc, source, failed, rms, loops[cid], model, judged,
                removed,
            )
        )  # fmt: skip
    cases = tuple(out)
    summary = _summary(cases)
    summary["features"] = feature_summary(
        measurements, {c.case.case_id: c.model_loop for c in cases}, s.features
    )
    return Comparison(cases, s, summary, fingerprint(cases))


def _judge_hysteresis(
    meas: ProcessedLoop | None,
    case: Case,
    model: ProcessedLoop,
    rep: Mapping[str, float],
    s: CompareSettings,
    mea: dict[str, float],
    mod: dict[str, float],
) -> tuple[dict[str, Judgement], bool]:
    """Judge W and η (``validation.hysteresis.judge``); add the free-play-free values to mea/mod.

    Returns:
        (metric → judgement, True when the free play was taken out).
    """
    f = s.features
    k = {"k": s.k, "max_rel_sigma": f.max_rel_sigma, "min_rel_sigma": s.min_rel_uncertainty}
    if meas is None:  # a stated η: its uncertainty ⊕ the floor ⊕ replicates
        v = abs(float(case.eta or 0.0))
        if s.uncertainty is Uncertainty.RECORD:
            floor = f.rel_floor * v + f.eta_floor
            sig = math.hypot(f.eta_rel_sigma * v, rep.get("eta", 0.0) * v, floor)
        else:
            sig = rep.get("eta", s.default_rel_uncertainty) * v
        eta = float(case.eta or 0.0)
        return {"eta": judge(eta, mod["eta"], sig, f.eta_rel_sigma * v, name="η", **k)}, False
    removed = case.values.get("clearance_mm", 0.0) > 0.0
    stated = s.default_rel_uncertainty if s.uncertainty is Uncertainty.STATED else None
    out, hm, hmod = judge_loops(
        meas, model, removed, dict(rep), f, stated, names=METRIC_LABELS, **k
    )
    if removed:
        for side, h in ((mea, hm), (mod, hmod)):
            side["W_without_free_play_Nmm"] = h.W_Nmm
            side["delta_max_without_free_play_mm"] = h.delta_max_mm
            side["eta_without_free_play"] = h.eta
            side["free_play_travel_mm"] = h.free_play_mm
    return out, removed


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
    for m in HYSTERESIS_METRICS:
        n_nm = sum(m in c.not_measurable for c in cases)
        if n_nm:
            per_metric.setdefault(m, {"n": 0, "n_fail": sum(m in c.failed for c in cases)})
            per_metric[m]["n_not_measurable"] = n_nm
    n_pass = sum(c.passed for c in cases)
    return {
        "n_cases": len(cases),
        "n_pass": n_pass,
        "n_fail": len(cases) - n_pass,
        "metrics": per_metric,
    }


def case_columns(case: Case) -> dict[str, float]:
    """The case's design values by their cases.csv columns (``clearance_mm``, ``preload_N``)."""
    columns = {v.name: v.column for v in hinge_kind(case.hinge).design_variables}
    return {columns[k]: v for k, v in case.values.items()}
