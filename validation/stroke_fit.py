"""A hinge kind against displacement-controlled records: model features, law fits, hold-outs.

Each **design point** of a displacement-controlled measurement set (the steady cycles of
one record, ``Case.design_point``) becomes a ``StrokePoint``: its mean features and σ
(``validation.stroke``), its test conditions, and the displacement that drives the
model: the first replicate's own cycle, each half made monotone (``drive_path``: the
sensor's noise would otherwise reverse the element at every sample). The kind must be
able to follow a displacement (a ``displacement_loop`` method, as the ``joint`` kind's);
the element's parameters at a point are the model file's, its design values, then its
laws (``validation.joint_laws.params_at``).

``fit_laws`` fits the coefficients of named **terms** by least squares on the features'
residuals (model − measured)/σ over the points: a term ``param`` fits a constant,
``param~cond`` a constant and a slope in the condition ``cond`` (``band_tension_N``),
``param~cond^2`` a parabola in it;
coefficients are scaled by their starting values so that one step size suits them all.
``held_out`` refits without each point in turn and predicts it (leave-one-condition-out).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import optimize

from cad.errors import DataError, HingelabError, ParameterError
from model.spec import ModelSpec
from validation.joint_laws import Laws, ParamLaw, condition_power, params_at
from validation.measurements import Case, MeasurementSet
from validation.rig_cycles import displacement_stages
from validation.rig_mapping import Control
from validation.stroke import (
    STROKE_FEATURES,
    StrokeSettings,
    feature_vector,
    stroke_features,
    stroke_sigma,
)

FloatArray = npt.NDArray[np.float64]

DEFAULT_SCALES = {
    "slip_asymmetry": 0.1,
    "damping_n_s_per_mm": 1.0,
    "free_play_mm": 1.0,
    "slip_force_n": 1000.0,
}
"""Step scale of a coefficient whose starting value is 0 (otherwise its own size)."""


@dataclass(frozen=True)
class StrokePoint:
    """One design point of a displacement-controlled set.

    Attributes:
        label: The first replicate's record name (its case_id without the cycle suffix).
        case: The first replicate (its design values and conditions give the parameters).
        case_ids: Every replicate's case_id.
        values: Mean features, shape (5,) in ``STROKE_FEATURES`` order.
        sigma: Their σ, shape (5,).
        time_s: The drive's times, shape (n,) [s].
        disp_mm: The drive's displacements, shape (n,) [mm].
    """

    label: str
    case: Case
    case_ids: tuple[str, ...]
    values: FloatArray
    sigma: FloatArray
    time_s: FloatArray
    disp_mm: FloatArray


def drive_path(case: Case) -> tuple[FloatArray, FloatArray]:
    """(t [s], δ [mm]) of a case's cycle, each half made monotone (shape (n,) each)."""
    loop = case.loop
    if loop is None:
        raise DataError(f"case {case.case_id!r}: no loop to drive the model with")
    d = np.asarray(loop.displacement_mm, dtype=np.float64)
    st = displacement_stages(d, loop.source)
    down = np.minimum.accumulate(d[: st.trough + 1])
    up = np.maximum.accumulate(d[st.trough + 1 :])
    n = d.size
    t = (
        np.asarray(loop.time_s, dtype=np.float64)
        if loop.time_s is not None
        else np.arange(n, dtype=np.float64) / n
    )
    return t, np.concatenate([down, np.maximum(up, down[-1])])


def stroke_points(data: MeasurementSet, settings: StrokeSettings) -> list[StrokePoint]:
    """Every design point of a displacement-controlled set (module docstring).

    Raises:
        DataError: A force-controlled case, or one without a loop.
    """
    by_id = data.by_id()
    points = []
    for ids in data.replicate_groups().values():
        cases = [by_id[i] for i in ids]
        for c in cases:
            if c.control is not Control.DISPLACEMENT or c.loop is None:
                raise DataError(
                    f"case {c.case_id!r}: not a displacement-controlled loop; "
                    "a set is compared by displacement only when every case is"
                )
        mean, sigma = stroke_sigma(
            [(c.loop.force_n, c.loop.displacement_mm) for c in cases if c.loop is not None],
            settings,
        )
        t, d = drive_path(cases[0])
        label = cases[0].case_id.rsplit("_c", 1)[0]
        points.append(StrokePoint(label, cases[0], tuple(ids), mean, sigma, t, d))
    return points


def is_displacement_set(data: MeasurementSet) -> bool:
    """True when every case of the set is displacement-controlled."""
    return bool(data.cases) and all(c.control is Control.DISPLACEMENT for c in data.cases)


def displacement_runner(spec: ModelSpec) -> Any:
    """The kind's ``displacement_loop`` (params, t, δ) → (F, δ).

    Raises:
        ParameterError: For a kind that cannot follow a displacement record.
    """
    kind = spec.hinge_kind
    run = getattr(kind, "displacement_loop", None)
    if run is None:
        raise ParameterError(
            f"the {kind.title} cannot be driven by a displacement record (its kind has no "
            "displacement_loop); displacement-controlled cases need a kind such as joint"
        )
    return run


def model_loop(
    spec: ModelSpec, laws: Laws, case: Case, t: FloatArray, d: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The model's (F [N], δ [mm]) along (t, d) with the parameters at ``case``."""
    return displacement_runner(spec)(params_at(spec, laws, case), t, d)  # type: ignore[no-any-return]


def model_features(
    spec: ModelSpec, laws: Laws, points: Sequence[StrokePoint], settings: StrokeSettings
) -> FloatArray:
    """The model's fitted features at every point, shape (n_points, 5); NaN rows where it fails."""
    out = np.full((len(points), len(STROKE_FEATURES)), np.nan)
    for i, p in enumerate(points):
        try:
            F, d = model_loop(spec, laws, p.case, p.time_s, p.disp_mm)
            out[i] = feature_vector(stroke_features(F, d, settings))
        except HingelabError:
            continue
    return out


def residuals(model: FloatArray, points: Sequence[StrokePoint]) -> FloatArray:
    """(model − measured)/σ, shape (n_points, 5); a failed run counts 1e3."""
    values = np.array([p.values for p in points])
    sigma = np.array([p.sigma for p in points])
    r = (model - values) / sigma
    return np.where(np.isfinite(r), r, 1e3)


@dataclass(frozen=True)
class Term:
    """A parameter to fit: a constant, plus a slope per named condition."""

    param: str
    conditions: tuple[str, ...] = ()

    @property
    def text(self) -> str:
        """``param`` or ``param~cond+cond``."""
        return self.param + ("~" + "+".join(self.conditions) if self.conditions else "")


def parse_terms(text: str, params_type: Any) -> list[Term]:
    """Terms from ``param[~cond[+cond]],…`` (``slip_force_n~band_tension_N,free_play_mm``).

    Raises:
        ParameterError: An empty list or a parameter that the hinge does not have.
    """
    names = {f.name for f in dataclasses.fields(params_type)}
    terms = []
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        param, _, conds = item.partition("~")
        if param.strip() not in names:
            raise ParameterError(
                f"--fit: {param.strip()!r} is not a parameter of the hinge; it has: "
                + ", ".join(sorted(names))
            )
        names_ = []
        for c in (c.strip() for c in conds.split("+") if c.strip()):
            base, power = condition_power(c)
            names_ += [base, c] if power == 2 else [c]  # a square brings its linear term
        terms.append(Term(param.strip(), tuple(dict.fromkeys(names_))))
    if not terms:
        raise ParameterError(f"--fit: no term in {text!r} (e.g. slip_force_n~band_tension_N)")
    return terms


def start_laws(spec: ModelSpec, laws: Laws, terms: Sequence[Term]) -> dict[str, ParamLaw]:
    """The model's laws plus a law for every term (its value so far, zero slopes added)."""
    out = dict(laws)
    for t in terms:
        old = out.get(t.param) or ParamLaw(t.param, float(getattr(spec.hinge, t.param)), {})
        slopes = {**{c: 0.0 for c in t.conditions}, **old.slopes}
        out[t.param] = ParamLaw(t.param, old.intercept, slopes)
    return out


def _coefficients(laws: Laws, terms: Sequence[Term]) -> list[tuple[str, str]]:
    """(param, key) of every fitted coefficient: ``intercept`` or a condition name."""
    out = []
    for t in terms:
        out.append((t.param, "intercept"))
        out += [(t.param, c) for c in laws[t.param].slopes]
    return out


def _with(laws: Laws, coefs: Sequence[tuple[str, str]], x: FloatArray) -> dict[str, ParamLaw]:
    out = {n: ParamLaw(n, law.intercept, dict(law.slopes)) for n, law in laws.items()}
    for (param, key), v in zip(coefs, x, strict=True):
        if key == "intercept":
            out[param] = dataclasses.replace(out[param], intercept=float(v))
        else:
            out[param].slopes[key] = float(v)  # type: ignore[index]
    return out


def fit_laws(
    spec: ModelSpec,
    laws: Laws,
    points: Sequence[StrokePoint],
    terms: Sequence[Term],
    settings: StrokeSettings,
    max_nfev: int = 400,
) -> dict[str, ParamLaw]:
    """Fit the terms' coefficients (least squares on the residuals over ``points``).

    Returns:
        The laws with the fitted coefficients (the others as given).
    """
    laws = start_laws(spec, laws, terms)
    coefs = _coefficients(laws, terms)
    x0 = np.array([laws[p].intercept if k == "intercept" else laws[p].slopes[k] for p, k in coefs])
    span = {}
    for _p, c in coefs:
        cond, power = condition_power(c)
        top = max((abs(p.case.conditions.get(cond, 0.0)) for p in points), default=1.0)
        span[c] = (top or 1.0) ** power
    base = {p: abs(laws[p].intercept) or DEFAULT_SCALES.get(p, 1.0) for p, _k in coefs}
    scale = np.array([base[p] if k == "intercept" else base[p] / span[k] for p, k in coefs])

    def cost(z: FloatArray) -> FloatArray:
        trial = _with(laws, coefs, z * scale)
        return residuals(model_features(spec, trial, points, settings), points).ravel()

    res = optimize.least_squares(cost, x0 / scale, diff_step=1e-3, max_nfev=max_nfev)
    return _with(laws, coefs, res.x * scale)


@dataclass(frozen=True)
class HeldOut:
    """Each point predicted by laws fitted without it.

    Attributes:
        points: The design points, in order.
        predicted: The model's features at each point from the fit without it, (n, 5).
        laws: The laws of each fold.
    """

    points: tuple[StrokePoint, ...]
    predicted: FloatArray
    laws: tuple[Mapping[str, ParamLaw], ...]

    @property
    def chi2(self) -> float:
        """Σ r² of the predictions."""
        return float(np.sum(residuals(self.predicted, self.points) ** 2))

    def relative_errors(self, feature: str = "W_cycle_Nmm") -> FloatArray:
        """(predicted − measured)/|measured| of one feature per point, shape (n,)."""
        j = STROKE_FEATURES.index(feature)
        meas = np.array([p.values[j] for p in self.points])
        return np.asarray((self.predicted[:, j] - meas) / np.abs(meas), dtype=np.float64)

    def rms(self, feature: str = "W_cycle_Nmm") -> float:
        """RMS relative error of one feature over the points."""
        return float(np.sqrt(np.mean(self.relative_errors(feature) ** 2)))


def held_out(
    spec: ModelSpec,
    laws: Laws,
    points: Sequence[StrokePoint],
    terms: Sequence[Term],
    settings: StrokeSettings,
) -> HeldOut:
    """Leave each point out, fit the terms on the others (from ``laws``), predict it."""
    pred = np.full((len(points), len(STROKE_FEATURES)), np.nan)
    folds = []
    for i in range(len(points)):
        train = [p for j, p in enumerate(points) if j != i]
        fold = fit_laws(spec, laws, train, terms, settings) if terms else dict(laws)
        pred[i] = model_features(spec, fold, [points[i]], settings)[0]
        folds.append(fold)
    return HeldOut(tuple(points), pred, tuple(folds))


def n_obs(points: Sequence[StrokePoint]) -> int:
    """Number of fitted observations (5 per point)."""
    return len(points) * len(STROKE_FEATURES)


def law_coefficients(laws: Laws) -> dict[str, float]:
    """Every law's coefficients, flat (``slip_force_n.intercept``, …)."""
    out: dict[str, float] = {}
    for law in laws.values():
        out.update(law.coefficients())
    return out


def rms_error(values: Sequence[float]) -> float:
    """RMS of a list of relative errors (NaN if empty)."""
    v = np.asarray(values, dtype=np.float64)
    return math.nan if v.size == 0 else float(np.sqrt(np.mean(v**2)))
