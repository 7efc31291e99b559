"""Diagnose which candidate effect is missing from a model, with a control of false alarms.

Workflow (``diagnose``):

1. **Features** (``validation.features``): each measured design point becomes three
   numbers, δ_max, W_cycle and the opening at ½Fg, with σ from noise, model floor and replicates; the
   residual is ``r = (model − measured)/σ``, N = 3 × design points. Features instead of
   loop points sidestep the strong correlation of residuals along a loop. A design point
   measured by η only (an η-only table, like the paper's Table 1) is one observation,
   its η (``MeasuredFeatures``); with such data two candidates that change η alike are
   told apart only by a loop, and ``indistinguishable`` names the loop to measure.
2. **Baseline**: χ²₀ of the model file as it is (μ is taken from the model file, i.e.
   calibrated beforehand; it is not refitted here).
3. **Per candidate** (every registry effect not already in the model, applicable to all
   cases — ``interference`` and ``face_friction`` need Δr = 0, see their
   ``zero_clearance_reason``): the model's own post-only effects (no cycle
   needed) are re-tuned with it (``_retuned_features``), and its one parameter is fitted on a log grid
   (``grid_points`` values over ``grid_decades`` decades below its upper bound, features
   interpolated linearly in the parameter between grid points, scanned densely), then
   refined on the true model (bounded Brent in log10 p, ``refine_iter`` evaluations).
   Every run reuses the clearance's factorisation (``validation.evaluate``).
4. **False alarms**:

   * *significance*: ``F = Δχ² / max(1, χ²_c/(N − 1))`` (σ that is too small, e.g. from
     correlated noise, inflates χ²_c and so deflates F) against the F(1, N − 1)
     quantile at ``alpha / m``, Bonferroni over the m candidates tried;
   * *held-out*: the parameter is refitted with one fold of design points left out
     (the k-th amplitude of every clearance, or one clearance when each has a single
     amplitude), on the grid interpolant, and the left-out χ² must fall by at least ``heldout_min_gain``;
   * *bounds*: a parameter at the end of its grid is flagged (``at_bound``);
   * AIC = χ² + 2k and BIC = χ² + k ln N are reported.

5. **Verdict**: baseline consistent with noise (χ²₀ ≤ the χ²_N quantile ``1 − alpha``)
   and no significant candidate → ``no_missing_effect``; the best significant candidate
   explains at least ``explained_min`` of the excess χ²₀ − N → ``effect_missing`` (unless
   another one fits equally well, Δχ² below the 1-dof quantile ``1 − alpha`` scaled as
   above → ``indistinguishable``, with the design point where the two fitted models differ
   most); otherwise ``unexplained``, with the residual pattern in words.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import optimize, stats

from validation.evaluate import ModelEvaluator
from validation.features import FEATURES, FeatureSettings, derived, feature_sigma, loop_features
from validation.loops import process_loop
from validation.measurements import MeasurementSet
from validation.model_file import ModelSpec

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class DiagnoseSettings:
    """Fitting and decision settings (module docstring).

    Attributes:
        features: Model floor of the feature σ.
        alpha: False-alarm probability of the whole diagnosis.
        grid_points: Grid values per candidate parameter.
        grid_decades: Decades the grid spans below the parameter's upper bound.
        refine_iter: True-model evaluations of the refinement.
        heldout_min_gain: Fraction the held-out χ² must fall by.
        explained_min: Fraction of the excess χ² the best candidate must explain.
        increments_per_stage: Increments per stage of the diagnosis runs (None: model file's).
        clearance_increments: Increments across the free play (None: model file's).
    """

    features: FeatureSettings = field(default_factory=FeatureSettings)
    alpha: float = 0.01
    grid_points: int = 7
    grid_decades: float = 3.0
    refine_iter: int = 6
    heldout_min_gain: float = 0.25
    explained_min: float = 0.9
    increments_per_stage: int | None = 8
    clearance_increments: int | None = 16


@dataclass(frozen=True)
class MeasuredFeatures:
    """Measured features per design point.

    A design point measured by η only (an η-only table such as the paper's Table 1) has
    one observation, its η, kept in column 1 with columns 0 and 2 NaN; its residual is
    ``(η_model − η)/σ_η`` with ``η_model = W/(π Fg δ_max)`` from the model's features.

    Attributes:
        points: (clearance [mm], amplitude [N]) per row.
        values: Features, shape (n_points, 3) (η-only rows: [NaN, η, NaN]).
        sigma: Their σ, shape (n_points, 3).
        eta_only: Rows measured by η only, shape (n_points,).
    """

    points: tuple[tuple[float, float], ...]
    values: FloatArray
    sigma: FloatArray
    eta_only: npt.NDArray[np.bool_] | None = None

    @property
    def amplitudes(self) -> FloatArray:
        """Amplitude of each row, shape (n_points,) [N]."""
        return np.array([p[1] for p in self.points])

    @property
    def eta_rows(self) -> npt.NDArray[np.bool_]:
        """Rows measured by η only, shape (n_points,)."""
        if self.eta_only is None:
            return np.zeros(len(self.points), dtype=bool)
        return np.asarray(self.eta_only, dtype=bool)

    @property
    def n_obs(self) -> int:
        """Number of observations N: three per loop, one per η-only design point."""
        k = int(np.count_nonzero(self.eta_rows))
        return 3 * (len(self.points) - k) + k


def measured_features(data: MeasurementSet, settings: FeatureSettings) -> MeasuredFeatures:
    """Summarise every design point of a measurement set (replicates averaged).

    A design point with loops uses them (module ``validation.features``); one with only
    η values (an η-only table) becomes an η-only row: η the mean of its values, σ_η the
    replicates' standard deviation if there are several, combined in quadrature with
    ``eta_rel_sigma · η`` (the stated uncertainty: tables carry none) and the model floor
    ``rel_floor · η + eta_floor``.
    """
    points, values, sigmas, eta_only = [], [], [], []
    by_id = data.by_id()
    for (_, clearance, _, amp), ids in data.replicate_groups().items():
        loops = []
        etas = []
        for cid in ids:
            case = by_id[cid]
            if case.loop is not None:
                loops.append(
                    process_loop(case.loop.force_n, case.loop.displacement_mm, case.loop.source)
                )
            elif case.eta is not None:
                etas.append(float(case.eta))
        points.append((clearance, amp))
        if loops:
            feats = np.array([loop_features(p) for p in loops])
            rep = np.std(feats, axis=0, ddof=1) if len(loops) > 1 else None
            values.append(feats.mean(axis=0))
            sigmas.append(feature_sigma(loops, settings, rep))
            eta_only.append(False)
        elif etas:
            eta = float(np.mean(etas))
            rep_eta = float(np.std(etas, ddof=1)) if len(etas) > 1 else 0.0
            s_eta = math.sqrt(
                rep_eta**2
                + (settings.eta_rel_sigma * eta) ** 2
                + (settings.rel_floor * eta + settings.eta_floor) ** 2
            )
            values.append(np.array([np.nan, eta, np.nan]))
            sigmas.append(np.array([np.nan, s_eta, np.nan]))
            eta_only.append(True)
        else:
            points.pop()
    return MeasuredFeatures(
        tuple(points), np.array(values), np.array(sigmas), np.array(eta_only, dtype=bool)
    )


def _eta_without_free_play(model: FloatArray, meas: MeasuredFeatures) -> FloatArray:
    """η of model features with the free play taken off δ_max, shape (n_points,).

    A stated η (an η-only table, like the paper's, or ``hingelab cycle``'s report)
    excludes the free play: ``η = W / (π Fg (δ_max − 2Δr))``; the loop area W is the same
    with or without the zero-force traverse.
    """
    elastic = np.array(model, dtype=np.float64, copy=True)
    elastic[:, 0] -= 2.0 * np.array([p[0] for p in meas.points])
    return derived(elastic, meas.amplitudes)[1]


def residuals(model: FloatArray, meas: MeasuredFeatures) -> FloatArray:
    """Return (model − measured)/σ, shape (n_points, 3); a failed run (NaN) counts 1e3.

    η-only rows: ``[0, (η_model − η)/σ_η, 0]``.
    """
    model = np.asarray(model, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = (model - meas.values) / meas.sigma
        eta_rows = meas.eta_rows
        if np.any(eta_rows):
            eta_model = _eta_without_free_play(model, meas)[eta_rows]
            r_eta = (eta_model - meas.values[eta_rows, 1]) / meas.sigma[eta_rows, 1]
            r[eta_rows] = 0.0
            r[eta_rows, 1] = r_eta
    return np.where(np.isfinite(r), r, 1e3)


def chi2(
    model: FloatArray, meas: MeasuredFeatures, rows: npt.NDArray[np.bool_] | None = None
) -> float:
    """Return Σ r² over the rows selected (all by default)."""
    r = residuals(model, meas)
    return float(np.sum(r[rows] ** 2) if rows is not None else np.sum(r**2))


@dataclass(frozen=True)
class CandidateFit:
    """One candidate effect fitted to the data.

    Attributes:
        name: Effect name.
        param: Its parameter name.
        value: Fitted value.
        unit: Its unit.
        chi2: χ² with the effect.
        delta_chi2: χ²₀ − χ².
        f_stat: The inflation-robust F statistic.
        p_value: Its p-value (before the Bonferroni factor).
        significant: F beyond the Bonferroni-corrected quantile.
        heldout_chi2_base: Held-out χ² of the baseline, summed over folds.
        heldout_chi2: Held-out χ² with the effect fitted on the other folds.
        heldout_ok: Held-out χ² fell by at least ``heldout_min_gain``.
        at_bound: The fit sits at an end of the grid (or at 0: the effect switched off).
        aic: χ² + 2k.
        bic: χ² + k ln N.
        features: Model features at the fit, shape (n_points, 3).
        model_effects: The effects of that fit: the candidate and the model's own
            post-only effects as re-tuned with it.
    """

    name: str
    param: str
    value: float
    unit: str
    chi2: float
    delta_chi2: float
    f_stat: float
    p_value: float
    significant: bool
    heldout_chi2_base: float
    heldout_chi2: float
    heldout_ok: bool
    at_bound: bool
    aic: float
    bic: float
    features: FloatArray = field(repr=False, compare=False)
    model_effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    @property
    def counts(self) -> bool:
        """Significant and confirmed on held-out data."""
        return self.significant and self.heldout_ok

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dict (no arrays)."""
        out = {k: v for k, v in vars(self).items() if k not in ("features", "model_effects")}
        return out | {
            "counts": self.counts,
            "model_effects": {k: dict(v) for k, v in self.model_effects.items()},
        }


def _grid(hi: float, settings: DiagnoseSettings) -> FloatArray:
    return hi * 10.0 ** np.linspace(-settings.grid_decades, 0.0, settings.grid_points)


def _interp_features(grid: FloatArray, feats: FloatArray, p: float) -> FloatArray:
    """Linear interpolation in p of features on the grid, shape (n_points, 3)."""
    j = int(np.clip(np.searchsorted(grid, p) - 1, 0, len(grid) - 2))
    t = (p - grid[j]) / (grid[j + 1] - grid[j])
    return np.asarray((1 - t) * feats[j] + t * feats[j + 1], dtype=np.float64)


def _scan(
    grid: FloatArray,
    feats: FloatArray,
    base: FloatArray,
    meas: MeasuredFeatures,
    rows: npt.NDArray[np.bool_],
) -> tuple[float, FloatArray]:
    """Return (parameter, features) minimising χ² over ``rows`` on the interpolant.

    A dense log scan between the grid's ends; the effect switched off (p = 0, the
    baseline ``base``) competes too.
    """
    finite = np.all(np.isfinite(feats.reshape(len(grid), -1)), axis=1)
    g, f = grid[finite], feats[finite]
    best = (chi2(base, meas, rows), 0.0, base)
    if len(g) < 2:
        return best[1], best[2]
    for p in 10.0 ** np.linspace(math.log10(g[0]), math.log10(g[-1]), 301):
        fp = _interp_features(g, f, float(p))
        c = chi2(fp, meas, rows)
        if c < best[0]:
            best = (c, float(p), fp)
    return best[1], best[2]


def _folds(points: Sequence[tuple[float, float]]) -> list[npt.NDArray[np.bool_]]:
    """Held-out masks: leave-one-amplitude-rank-out, else leave-one-clearance-out.

    Fold k holds the k-th smallest amplitude of every clearance, so every training set
    still spans all clearances (leaving a whole clearance out fails to confirm an effect
    that only one clearance resolves, e.g. a tangential compliance at Δr = 0). With one
    amplitude per clearance, one fold per clearance.
    """
    rank = []
    for c, a in points:
        amps = sorted({p[1] for p in points if p[0] == c})
        rank.append(amps.index(a))
    ranks = np.array(rank)
    if len(set(rank)) >= 2:
        return [ranks == k for k in sorted(set(rank))]
    clearances = sorted({p[0] for p in points})
    return [np.array([p[0] == c for p in points]) for c in clearances]


def _retuned_features(
    evaluator: ModelEvaluator, effects: Mapping[str, Mapping[str, float]], meas: MeasuredFeatures
) -> FloatArray:
    """Features with ``effects``, the model's own post-only effects re-tuned (``_retuned``)."""
    return evaluator.features(_retuned(evaluator, effects, meas))


def _retuned(
    evaluator: ModelEvaluator, effects: Mapping[str, Mapping[str, float]], meas: MeasuredFeatures
) -> dict[str, dict[str, float]]:
    """Return ``effects`` plus the model's own post-only effects re-tuned to the data.

    A post-only effect already in the model (e.g. a fitted ``frame_compliance``) costs no
    cycle, so its parameter is refitted (bounded Brent) with every candidate value: an
    effect fitted alone in an earlier round has absorbed part of the next one, and a
    candidate judged against that frozen value would look weaker than it is.
    """
    from fe.effects import REGISTRY
    from validation.evaluate import is_post_only

    own = {n: dict(p) for n, p in evaluator.spec.effects.items() if is_post_only(n)}
    extra = {n: dict(p) for n, p in effects.items()}
    for n in own:
        for par in REGISTRY[n].params:

            def cost(v: float, n: str = n, k: str = par.name) -> float:
                trial = {**own, **extra, n: {**own[n], k: float(v)}}
                return chi2(evaluator.features(trial), meas)

            res = optimize.minimize_scalar(
                cost, bounds=(par.lo, par.hi), method="bounded", options={"xatol": par.hi * 1e-4}
            )
            own[n][par.name] = float(res.x)
    return {**own, **extra}


def fit_candidate(
    evaluator: ModelEvaluator,
    name: str,
    meas: MeasuredFeatures,
    base_features: FloatArray,
    n_tried: int,
    settings: DiagnoseSettings,
) -> CandidateFit:
    """Fit one candidate's parameter and judge it (module docstring, steps 3–4)."""
    from fe.effects import REGISTRY

    spec = REGISTRY[name].params[0]
    grid = _grid(spec.hi, settings)

    def at(p: float) -> FloatArray:
        return _retuned_features(evaluator, {name: {spec.name: p}}, meas)

    feats = np.array([at(float(p)) for p in grid])
    rows = np.ones(len(meas.points), dtype=bool)
    p0, _ = _scan(grid, feats, base_features, meas, rows)
    c0 = chi2(base_features, meas)
    if p0 == 0.0:
        p0 = float(grid[0])

    def cost(u: float) -> float:
        return chi2(at(float(10.0**u)), meas)

    u0 = math.log10(p0)
    lo, hi = math.log10(grid[0]), math.log10(grid[-1])
    res = optimize.minimize_scalar(
        cost,
        bounds=(max(lo, u0 - 0.25), min(hi, u0 + 0.25)),
        method="bounded",
        options={"maxiter": settings.refine_iter, "xatol": 0.01},
    )
    candidates = [(c0, 0.0), (float(res.fun), float(10.0**res.x))] + [
        (chi2(feats[j], meas), float(grid[j])) for j in range(len(grid))
    ]
    c2, value = min(candidates)
    fitted = at(value) if value > 0 else base_features
    model_effects = _retuned(evaluator, {name: {spec.name: value}}, meas)
    n = meas.n_obs
    d = c0 - c2
    f_stat = d / max(1.0, c2 / max(n - 1, 1))
    p_value = float(stats.f.sf(f_stat, 1, max(n - 1, 1)))
    significant = p_value < settings.alpha / max(n_tried, 1)
    held_base = held = 0.0
    for test in _folds(meas.points):
        train = ~test
        _, f_fold = _scan(grid, feats, base_features, meas, train)
        held_base += chi2(base_features, meas, test)
        held += chi2(f_fold, meas, test)
    at_bound = value <= grid[0] * 1.0001 or value >= grid[-1] * 0.9999
    return CandidateFit(
        name=name,
        param=spec.name,
        value=value,
        unit=spec.unit,
        chi2=c2,
        delta_chi2=d,
        f_stat=f_stat,
        p_value=p_value,
        significant=bool(significant),
        heldout_chi2_base=held_base,
        heldout_chi2=held,
        heldout_ok=bool(held <= (1.0 - settings.heldout_min_gain) * held_base),
        at_bound=bool(at_bound),
        aic=c2 + 2.0,
        bic=c2 + math.log(n),
        features=fitted,
        model_effects=model_effects,
    )


def residual_pattern(model: FloatArray, meas: MeasuredFeatures) -> list[str]:
    """Describe the baseline's misfit in words (stiffness, η level and trends).

    Rules, per quantity q ∈ {δ_max, η} with relative error e = (model − measured)/measured
    (for δ_max relative to its elastic part, the free play 2Δr taken off) and its σ from
    the features: "at all amplitudes" when every design point's error has
    the same sign beyond 2σ; "grows with amplitude" when, within a clearance, |e| at the
    largest amplitude exceeds |e| at the smallest by more than 2σ; likewise for clearance.
    """
    amps_all = meas.amplitudes
    clear_all = np.array([p[0] for p in meas.points])
    dm, em = derived(model, amps_all)
    dd, ed = derived(meas.values, amps_all)
    eta_rows = meas.eta_rows
    ed = np.where(eta_rows, meas.values[:, 1], ed)  # η-only rows state η itself …
    em = np.where(eta_rows, _eta_without_free_play(model, meas), em)  # … without free play
    elastic = np.maximum(np.abs(dd - 2.0 * clear_all), 1e-12)  # δ_max without the free play 2Δr
    s_delta_all = meas.sigma[:, 0] / elastic
    s_eta_all = meas.sigma[:, 1] / np.abs(meas.values[:, 1])
    words = []
    with np.errstate(invalid="ignore", divide="ignore"):
        quantities = (
            ("δ", (dm - dd) / elastic, s_delta_all, "too soft", "too stiff"),
            ("η", em / ed - 1.0, s_eta_all, "η too high", "η too low"),
        )
    for label, e_all, s_all, hi_word, lo_word in quantities:
        keep = np.isfinite(e_all) & np.isfinite(s_all)  # δ is not measured in η-only rows
        if not np.any(keep):
            continue
        e, s, amps, clear = e_all[keep], s_all[keep], amps_all[keep], clear_all[keep]
        if np.all(e > 2 * s):
            words.append(
                f"{hi_word} at all amplitudes ({label} error {np.min(e):+.0%} … {np.max(e):+.0%})"
            )
        elif np.all(e < -2 * s):
            words.append(
                f"{lo_word} at all amplitudes ({label} error {np.max(e):+.0%} … {np.min(e):+.0%})"
            )
        for c in sorted(set(clear)):
            sel = np.flatnonzero(clear == c)
            if len(sel) < 2:
                continue
            i_lo, i_hi = sel[np.argmin(amps[sel])], sel[np.argmax(amps[sel])]
            grow = abs(e[i_hi]) - abs(e[i_lo])
            if abs(grow) > 2 * math.hypot(s[i_hi], s[i_lo]):
                trend = "grows" if grow > 0 else "shrinks"
                words.append(
                    f"{label} error {trend} with amplitude at Δr = {c:g} mm "
                    f"({e[i_lo]:+.0%} at {amps[i_lo]:g} N → {e[i_hi]:+.0%} at {amps[i_hi]:g} N)"
                )
        if len(set(clear)) >= 2:
            by_c = {c: float(np.mean(np.abs(e[clear == c]))) for c in sorted(set(clear))}
            cs = list(by_c)
            if abs(by_c[cs[-1]] - by_c[cs[0]]) > 2 * float(np.mean(s)):
                trend = "grows" if by_c[cs[-1]] > by_c[cs[0]] else "shrinks"
                words.append(f"{label} error {trend} with clearance")
    return words or ["no systematic pattern beyond the noise"]


@dataclass(frozen=True)
class Diagnosis:
    """What ``diagnose`` found.

    Attributes:
        verdict: ``effect_missing``, ``no_missing_effect``, ``indistinguishable`` or
            ``unexplained``.
        effects: The effect(s) the verdict names (none for the others).
        message: The verdict in words.
        pattern: The baseline's residual pattern in words.
        n_features: N.
        chi2_base: χ²₀.
        chi2_noise_limit: The χ²_N quantile 1 − alpha.
        candidates: Fitted candidates, best (lowest χ²) first.
        skipped: Candidate → why it was not tried.
        separating_test: For ``indistinguishable``: where the two fitted models differ most.
        stats: Cycles run, times.
    """

    verdict: str
    effects: tuple[str, ...]
    message: str
    pattern: tuple[str, ...]
    n_features: int
    chi2_base: float
    chi2_noise_limit: float
    candidates: tuple[CandidateFit, ...]
    skipped: Mapping[str, str]
    separating_test: str | None
    stats: Mapping[str, float]

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dict."""
        return {
            "verdict": self.verdict,
            "effects": list(self.effects),
            "message": self.message,
            "pattern": list(self.pattern),
            "features": list(FEATURES),
            "n_features": self.n_features,
            "chi2_base": self.chi2_base,
            "chi2_noise_limit": self.chi2_noise_limit,
            "candidates": [c.to_dict() for c in self.candidates],
            "skipped": dict(self.skipped),
            "separating_test": self.separating_test,
            "stats": dict(self.stats),
        }

    def text(self) -> str:
        """Return the diagnosis as a short report."""
        lines = [
            f"verdict: {self.verdict} — {self.message}",
            "residual pattern of the model as it is:",
        ]
        lines += [f"  - {w}" for w in self.pattern]
        lines.append(
            f"χ² baseline {self.chi2_base:.1f} over N = {self.n_features} features "
            f"(noise limit {self.chi2_noise_limit:.1f})"
        )
        lines.append("candidates (best first):")
        for c in self.candidates:
            flags = ", ".join(
                f
                for f, on in (
                    ("significant", c.significant),
                    ("held-out ok", c.heldout_ok),
                    ("AT BOUND", c.at_bound),
                )
                if on
            )
            lines.append(
                f"  {c.name:<22} {c.param} = {c.value:.3g} {c.unit}: χ² {c.chi2:.1f} "
                f"(Δχ² {c.delta_chi2:.1f}, p {c.p_value:.2g}; held-out {c.heldout_chi2_base:.1f} → "
                f"{c.heldout_chi2:.1f}; BIC {c.bic:.1f}) {flags}"
            )
        for n, why in self.skipped.items():
            lines.append(f"  {n:<22} not tried: {why}")
        if self.separating_test:
            lines.append(f"to separate them: {self.separating_test}")
        return "\n".join(lines)


def _separating_test(a: CandidateFit, b: CandidateFit, meas: MeasuredFeatures) -> str:
    """Name the design point and quantity where two fitted models differ most.

    Among the measured quantities the difference is in σ; if none differs by 2 σ (the
    data cannot tell them apart), the quantity the data lack (e.g. δ_max when only η was
    measured) where the two models' predictions differ most, relatively, is named as the
    measurement to make.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        diff = np.abs(residuals(a.features, meas) - residuals(b.features, meas))
        diff[~np.isfinite(diff) | (diff >= 1e3)] = 0.0
        i, k = np.unravel_index(int(np.argmax(diff)), diff.shape)
        c, amp = meas.points[i]
        quantity = "η" if meas.eta_rows[i] else FEATURES[k]
        if diff[i, k] >= 2.0 or not np.any(meas.eta_rows):
            return (
                f"they differ most in {quantity} at Δr = {c:g} mm, Fg = {amp:g} N "
                f"({diff[i, k]:.1f} σ); repeat that test (replicates shrink σ) or add cases beyond "
                "the measured amplitudes and clearances there"
            )
        rel = np.abs(a.features - b.features) / np.maximum(np.abs(a.features), np.abs(b.features))
        rel[~np.isfinite(rel)] = 0.0
        rel[~meas.eta_rows] = 0.0  # loops measured there: already compared above
    i, k = np.unravel_index(int(np.argmax(rel)), rel.shape)
    c, amp = meas.points[i]
    return (
        f"the measured η cannot separate them; measure the loop (force and displacement) at "
        f"Δr = {c:g} mm, Fg = {amp:g} N: their {FEATURES[k]} differ by {rel[i, k]:.0%} "
        f"({a.name}: {a.features[i, k]:.4g}, {b.name}: {b.features[i, k]:.4g})"
    )


def _verdict(
    fits: list[CandidateFit],
    c0: float,
    n: int,
    limit: float,
    meas: MeasuredFeatures,
    s: DiagnoseSettings,
) -> tuple[str, tuple[str, ...], str, str | None]:
    good = [f for f in fits if f.counts]
    if not good:
        if c0 <= limit:
            return (
                "no_missing_effect",
                (),
                "the model is consistent with the data within the noise",
                None,
            )
        why = ""
        if fits and fits[0].chi2 <= limit:  # a fit that would do, but not significant at this N
            f = fits[0]
            why = (
                f"; {f.name} would fit (χ² {f.chi2:.1f}) but p = {f.p_value:.2g} is not below "
                f"α/m = {s.alpha / len(fits):.2g} with N = {n} observations: add cases"
            )
        return (
            "unexplained",
            (),
            f"a real residual (χ² {c0:.0f} > {limit:.0f}) that no candidate reduces significantly"
            + why,
            None,
        )
    best = good[0]
    explained = (c0 - best.chi2) / max(c0 - n, 1e-12)
    if best.chi2 > limit and explained < s.explained_min:
        return (
            "unexplained",
            (),
            f"the best candidate, {best.name}, explains only {explained:.0%} of the excess χ²; "
            f"χ² {best.chi2:.0f} stays above the noise limit {limit:.0f}",
            None,
        )
    inflate = max(1.0, best.chi2 / max(n - 1, 1))
    tie = float(stats.chi2.ppf(1.0 - s.alpha, 1)) * inflate
    rivals = [f for f in good[1:] if f.chi2 - best.chi2 < tie]
    if rivals:
        names = (best.name, *(r.name for r in rivals))
        return (
            "indistinguishable",
            names,
            f"{' and '.join(names)} fit equally well (Δχ² {rivals[0].chi2 - best.chi2:.1f} < {tie:.1f})",
            _separating_test(best, rivals[0], meas),
        )
    rest = "" if best.chi2 <= limit else "; a residual remains: diagnose again after adding it"
    return (
        "effect_missing",
        (best.name,),
        f"{best.name} is missing ({best.param} ≈ {best.value:.3g} {best.unit}; χ² {c0:.0f} → "
        f"{best.chi2:.0f}, noise limit {limit:.0f}){rest}",
        None,
    )


def diagnose(
    spec: ModelSpec,
    data: MeasurementSet,
    settings: DiagnoseSettings | None = None,
    evaluator: ModelEvaluator | None = None,
) -> Diagnosis:
    """Rank the registry's candidate effects and give a verdict (module docstring).

    Args:
        spec: The model as it is (its own effects stay on).
        data: The measurements.
        settings: Decision settings; defaults to ``DiagnoseSettings()``.
        evaluator: A ``ModelEvaluator`` to reuse (its cache), or None.
    """
    import time

    from fe.effects import REGISTRY

    s = settings or DiagnoseSettings()
    t0 = time.perf_counter()
    meas = measured_features(data, s.features)
    ev = evaluator or ModelEvaluator(
        spec, meas.points, s.increments_per_stage, s.clearance_increments
    )
    base = ev.features({})
    c0 = chi2(base, meas)
    n = meas.n_obs
    limit = float(stats.chi2.ppf(1.0 - s.alpha, n))
    skipped: dict[str, str] = {}
    names = []
    for name in REGISTRY:
        if name in spec.effects:
            skipped[name] = "already in the model"
        elif REGISTRY[name].zero_clearance_reason and any(p[0] > 0 for p in meas.points):
            why = REGISTRY[name].zero_clearance_reason
            skipped[name] = f"needs Δr = 0 at every case ({why})"
        else:
            names.append(name)
    fits = sorted(
        (fit_candidate(ev, name, meas, base, len(names), s) for name in names), key=lambda f: f.chi2
    )
    verdict, effects, message, sep = _verdict(fits, c0, n, limit, meas, s)
    return Diagnosis(
        verdict=verdict,
        effects=effects,
        message=message,
        pattern=tuple(residual_pattern(base, meas)),
        n_features=n,
        chi2_base=c0,
        chi2_noise_limit=limit,
        candidates=tuple(fits),
        skipped=skipped,
        separating_test=sep,
        stats={
            "n_cycles": ev.n_cycles,
            "cycle_s": ev.cycle_s,
            "setup_s": ev.setup_s,
            "wall_s": time.perf_counter() - t0,
        },
    )
