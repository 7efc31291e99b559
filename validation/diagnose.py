"""Diagnose which candidate effect is missing from a model, with a control of false alarms.

Workflow (``diagnose``):

1. **Features** (``validation.features``): each measured design point becomes three
   numbers, δ_max, W_cycle and the opening at ½Fg, with σ from noise, model floor and replicates; the
   residual is ``r = (model − measured)/σ``; N counts the informative features (a feature
   whose σ exceeds ``FeatureSettings.max_rel_sigma`` times its value is left out). Features instead of
   loop points sidestep the strong correlation of residuals along a loop. A design point
   measured by η only (an η-only table, like the paper's Table 1) is one observation,
   its η (``MeasuredFeatures``); with such data two candidates that change η alike are
   told apart only by a loop, and ``indistinguishable`` names the loop to measure.
2. **Baseline**: χ²₀ of the model file as it is (μ is taken from the model file, i.e.
   calibrated beforehand; it is not refitted here).
3. **Per candidate** (every registry effect not already in the model, applicable to all
   cases — ``interference`` and ``face_friction`` need Δr = 0, see their
   ``zero_clearance_reason``): the model's own post-only effects (no cycle
   needed) are re-tuned with it, and its one parameter is fitted on a log grid
   (``grid_points`` values over ``grid_decades`` decades below its upper bound) by an
   interpolant refined on the true model (``validation.param_search``: each round runs
   every candidate's interpolated minimum as one batch, at most ``refine_iter`` points a
   candidate, with the interpolation error at the fit stated in σ). **Coarse to fine**:
   when the model's mesh is finer than its kind's coarse preset, the grids run on the
   coarse mesh (``screen_mesh``), corrected by the ratio of the two meshes' features at the
   baseline and at each refinement point; the refinement and every χ² of the verdict are
   the model's own mesh's. Every run reuses the clearance's factorisation
   (``validation.evaluate``).
4. **False alarms**:

   * *significance*: ``F = Δχ² / max(1, χ²_c/(N − 1))`` (σ that is too small, e.g. from
     correlated noise, inflates χ²_c and so deflates F) against the F(1, N − 1)
     quantile at ``alpha / m``, Bonferroni over the m candidates tried;
   * *held-out*: the parameter is refitted with one fold of design points left out
     (the k-th amplitude of every clearance, or one clearance when each has a single
     amplitude), on the grid interpolant, and the left-out χ² must fall by at least ``heldout_min_gain``;
   * *bounds*: a parameter at the end of its grid is flagged (``at_bound``);
   * AIC = χ² + 2k and BIC = χ² + k ln N are reported.

5. **Verdict**: no significant candidate and data that could not detect a common
   relative error of ``tell_rel_error`` in the loop area / η (``validation.sensitivity``: power
   ``power`` at ``alpha``) → ``cannot_tell``; baseline consistent with noise (χ²₀ ≤ the
   χ²_N quantile ``1 − alpha``) and no significant candidate → ``no_missing_effect``,
   with the smallest errors the data would have detected; the best significant candidate
   explains at least ``explained_min`` of the excess χ²₀ − N → ``effect_missing`` (unless
   another one fits equally well, Δχ² below the 1-dof quantile ``1 − alpha`` scaled as
   above → ``indistinguishable``, with the design point where the two fitted models differ
   most); otherwise ``unexplained``, with the residual pattern in words
   (``validation.misfit``).
6. **Signatures**: after ``unexplained``, or ``effect_missing`` with a residual left, the
   residuals of the model with the best significant candidate added (if any) are tested
   against generic shapes (``validation.signatures``: compliance, stiffening, a step at
   F = 0, drift, rate, an amplitude-dependent loss) — a lead for what kind of effect to
   write, not a diagnosis.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from scipy import stats

from cad.errors import HingelabError, ParameterError
from model.spec import ModelSpec
from validation.candidate_fit import (
    CandidateFit,
    DiagnoseSettings,
    MeasuredFeatures,
    chi2,
    design_text,
    measured_features,
    residuals,
)
from validation.candidates import fit_candidates, prefetch_grids, screen_evaluator
from validation.evaluate import ModelEvaluator
from validation.features import FEATURES
from validation.measurements import MeasurementSet
from validation.misfit import residual_pattern
from validation.sensitivity import power_words, sensitivity
from validation.signature_data import signature_table
from validation.signatures import SignatureTable

__all__ = [
    "Diagnosis",
    "Verdict",
    "diagnose",
]


class Verdict(enum.StrEnum):
    """What a diagnosis concludes (the values are the words printed and written to JSON)."""

    EFFECT_MISSING = "effect_missing"
    NO_MISSING_EFFECT = "no_missing_effect"
    CANNOT_TELL = "cannot_tell"
    """Consistent with the model, but the data could not detect an error of the size that
    matters (``DiagnoseSettings.tell_rel_error`` in the loop area / η)."""
    INDISTINGUISHABLE = "indistinguishable"
    UNEXPLAINED = "unexplained"


class _Decision(NamedTuple):
    verdict: Verdict
    effects: tuple[str, ...]
    message: str
    separating_test: str | None


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
        sensitivity: Feature column → the smallest common relative error the data detect
            (``sensitivity``; None: no information).
        signatures: For ``unexplained``, or ``effect_missing`` with a residual left: the
            generic signatures (``validation.signatures``) of the residual of the model with
            the best significant candidate added (as it is when there is none); None otherwise.
    """

    verdict: Verdict
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
    sensitivity: Mapping[str, float | None] = dataclasses.field(default_factory=dict)
    signatures: SignatureTable | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "verdict", Verdict(self.verdict))  # also from its word

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dict."""
        return {
            "verdict": self.verdict.value,
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
            "sensitivity": dict(self.sensitivity),
            "signatures": None if self.signatures is None else self.signatures.to_dict(),
        }

    def text(self) -> str:
        """Return the diagnosis as a short report."""
        lines = [
            f"verdict: {self.verdict.value} — {self.message}",
            "residual pattern of the model as it is:",
        ]
        lines += [f"  - {w}" for w in self.pattern]
        lines.append(
            f"χ² baseline {self.chi2_base:.1f} over N = {self.n_features} features "
            f"(noise limit {self.chi2_noise_limit:.1f})"
        )
        if self.sensitivity:
            lines.append(
                "smallest relative error these data detect (80 % power): "
                + ", ".join(
                    f"{k.replace('_', ' ')} {'—' if v is None else f'{v:.0%}'}"
                    for k, v in self.sensitivity.items()
                )
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
                f"{c.heldout_chi2:.1f}; BIC {c.bic:.1f}{_search_words(c)}) {flags}"
            )
        for n, why in self.skipped.items():
            lines.append(f"  {n:<22} not tried: {why}")
        if self.separating_test:
            lines.append(f"to separate them: {self.separating_test}")
        if self.signatures is not None:
            lines.append(self.signatures.text())
        return "\n".join(lines)


def _search_words(c: CandidateFit) -> str:
    """The refinement in words: model runs and the interpolation error at the fit."""
    if c.refine_runs == 0 or not np.isfinite(c.error_sigma):
        return ""
    polish = f", {c.polish_runs} of them a true-model polish" if c.polish_runs else ""
    return f"; {c.refine_runs} run(s){polish}, interpolation off by {c.error_sigma:.2g}σ"


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
                f"they differ most in {quantity} at {design_text(meas, c)}, Fg = {amp:g} N "
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
        f"{design_text(meas, c)}, Fg = {amp:g} N: their {FEATURES[k]} differ by {rel[i, k]:.0%} "
        f"({a.name}: {a.features[i, k]:.4g}, {b.name}: {b.features[i, k]:.4g})"
    )


def _verdict(
    fits: list[CandidateFit],
    c0: float,
    n: int,
    limit: float,
    meas: MeasuredFeatures,
    s: DiagnoseSettings,
) -> _Decision:
    good = [f for f in fits if f.counts]
    if not good:
        sens = sensitivity(meas, s.alpha, s.power)
        power = power_words(sens, s.alpha, s.power)
        area = sens["loop_area_or_eta"]
        low_power = n == 0 or area is None or area > s.tell_rel_error
        if low_power and not c0 > limit:  # a real misfit is reported whatever the power
            what = "no feature" if n == 0 else f"N = {n} features"
            return _Decision(
                Verdict.CANNOT_TELL,
                (),
                f"no misfit found, but {what} could reveal a loop-area (η) error below "
                f"{s.tell_rel_error:.0%}: these data cannot tell ({power})",
                None,
            )
        if c0 <= limit:
            return _Decision(
                Verdict.NO_MISSING_EFFECT,
                (),
                f"the model is consistent with the data within the noise ({power})",
                None,
            )
        why = ""
        if fits and fits[0].chi2 <= limit:  # a fit that would do, but not significant at this N
            f = fits[0]
            why = (
                f"; {f.name} would fit (χ² {f.chi2:.1f}) but p = {f.p_value:.2g} is not below "
                f"α/m = {s.alpha / len(fits):.2g} with N = {n} observations: add cases"
            )
        return _Decision(
            Verdict.UNEXPLAINED,
            (),
            f"a real residual (χ² {c0:.0f} > {limit:.0f}) that no candidate reduces significantly"
            + why,
            None,
        )
    best = good[0]
    explained = (c0 - best.chi2) / max(c0 - n, 1e-12)
    if best.chi2 > limit and explained < s.explained_min:
        return _Decision(
            Verdict.UNEXPLAINED,
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
        return _Decision(
            Verdict.INDISTINGUISHABLE,
            names,
            f"{' and '.join(names)} fit equally well (Δχ² {rivals[0].chi2 - best.chi2:.1f} < {tie:.1f})",
            _separating_test(best, rivals[0], meas),
        )
    rest = "" if best.chi2 <= limit else "; a residual remains: diagnose again after adding it"
    return _Decision(
        Verdict.EFFECT_MISSING,
        (best.name,),
        f"{best.name} is missing ({best.param} ≈ {best.value:.3g} {best.unit}; χ² {c0:.0f} → "
        f"{best.chi2:.0f}, noise limit {limit:.0f}){rest}",
        None,
    )


def c_left(best: list[CandidateFit], limit: float) -> bool:
    """Whether the best candidate leaves χ² above the noise limit (a residual to look at)."""
    return bool(best) and best[0].chi2 > limit


def refusal(spec: ModelSpec, name: str) -> str | None:
    """Why the model cannot take effect ``name`` (its kind's checks), or None if it can."""
    import dataclasses

    from fe.effects.registry import REGISTRY
    from model.service import check_spec

    values = {p.name: p.default for p in REGISTRY[name].params}
    try:
        check_spec(dataclasses.replace(spec, effects={**spec.effects, name: values}))
    except ParameterError as err:
        return str(err)
    return None


def diagnose(
    spec: ModelSpec,
    data: MeasurementSet,
    settings: DiagnoseSettings | None = None,
    evaluator: ModelEvaluator | None = None,
    service: Any = None,
) -> Diagnosis:
    """Rank the registry's candidate effects and give a verdict (module docstring).

    Args:
        spec: The model as it is (its own effects stay on).
        data: The measurements.
        settings: Decision settings; defaults to ``DiagnoseSettings()``.
        evaluator: A ``ModelEvaluator`` to reuse (its cache), or None.
        service: The ``model.service.ModelService`` of a new evaluator (None: in process,
            nothing stored); with a runner the baseline and every candidate's grid run
            as one batch of Dask tasks before the fits.
    """
    import time

    from fe.effects.registry import REGISTRY

    s = settings or DiagnoseSettings()
    t0 = time.perf_counter()
    meas = measured_features(data, s.features)
    ev = evaluator or ModelEvaluator(
        spec, meas.points, s.increments_per_stage, s.clearance_increments, service, meas.clocks
    )
    skipped: dict[str, str] = {}
    names = []
    for name in REGISTRY:
        try:  # a plug-in that does not load is a failed candidate, named
            why = REGISTRY[name].zero_clearance_reason
        except HingelabError as err:
            skipped[name] = f"failed: {err}"
            continue
        if name in spec.effects:
            skipped[name] = "already in the model"
        elif why and any(c > 0 for c in meas.clearance_mm or ()):
            skipped[name] = f"needs Δr = 0 at every case ({why})"
        elif (refused := refusal(spec, name)) is not None:
            skipped[name] = refused
        elif s.candidates is not None and name not in s.candidates:
            skipped[name] = "not among the candidates asked for"
        else:
            names.append(name)
    screen = screen_evaluator(ev, s) if names else None
    prefetch_grids(ev, names, s, screen, baseline=True)  # on a cluster: one batch
    base = ev.features({})
    c0 = chi2(base, meas)
    n = meas.n_obs
    limit = float(stats.chi2.ppf(1.0 - s.alpha, n))
    fits, failed = fit_candidates(ev, names, meas, base, len(names), s, screen)
    for name, error in failed.items():  # a user's effect that fails: the others still ran
        skipped[name] = f"failed: {error}"
    fits.sort(key=lambda f: f.chi2)
    batches = ev.batches + ([] if screen is None else screen.batches)
    verdict, effects, message, sep = _verdict(fits, c0, n, limit, meas, s)
    table = None
    best = [f for f in fits if f.counts][:1]  # the residual left beside the best candidate
    if verdict is Verdict.UNEXPLAINED or (
        verdict is Verdict.EFFECT_MISSING and c_left(best, limit)
    ):
        extra = {f.name: {f.param: f.value} for f in best}
        table = signature_table(ev, data, meas, extra, s.features.rel_floor, s.alpha)
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
        sensitivity=sensitivity(meas, s.alpha, s.power),
        signatures=table,
        stats={
            "n_cycles": ev.n_cycles,
            "screen_cycles": 0 if screen is None else screen.n_cycles,
            "batches": len(batches),
            "widest_batch": max(batches, default=0),
            "n_computed": ev.service.n_computed,
            "cycle_s": ev.cycle_s,
            "setup_s": ev.setup_s,
            "wall_s": time.perf_counter() - t0,
        },
    )
