"""Candidate fitting for ``diagnose``: measured features, the χ² misfit and one candidate's fit.

``fit_candidate`` fits one candidate effect's parameter and runs the false-alarm checks
(significance, held-out folds, bounds) of steps 3–4 in the ``validation.diagnose`` module
docstring.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from cad.errors import ParameterError
from fe.effects.registry import REGISTRY
from fe.kinds import DEFAULT_KIND, DesignVariable, hinge_kind
from validation.evaluate import Clock
from validation.features import FeatureSettings, derived, feature_sigma, loop_features
from validation.loops import process_loop
from validation.measurements import MeasurementSet
from validation.param_search import grid

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class DiagnoseSettings:
    """Fitting and decision settings (``validation.diagnose`` module docstring).

    Attributes:
        features: Model floor of the feature σ.
        alpha: False-alarm probability of the whole diagnosis.
        grid_points: Grid values per candidate parameter.
        grid_decades: Decades the grid spans below the parameter's upper bound.
        refine_iter: True-model points of a candidate's refinement, at most
            (``validation.param_search``: usually 1–3 suffice).
        screen: Fit the grids on the kind's coarse mesh when the model's is finer (coarse
            to fine, ``validation.candidates.screen_mesh``); the refinement and every χ² of
            the verdict stay on the model's own mesh.
        heldout_min_gain: Fraction the held-out χ² must fall by.
        explained_min: Fraction of the excess χ² the best candidate must explain.
        increments_per_stage: Increments per stage of the diagnosis runs (None: model file's).
        clearance_increments: Increments across the free play (None: model file's).
        power: Detection probability of the sensitivity statement
            (``validation.sensitivity.sensitivity``).
        tell_rel_error: Without a significant candidate, the verdict is ``cannot_tell``
            unless the data would detect a common relative error of this size in the loop
            area / η (default 0.5: an error of a half moves a design across the paper's
            η = 0.05 boundary over most of its range).
        candidates: Registry effects to try (None: every one that applies); the others are
            listed as skipped. Fewer candidates cost fewer cycles and a milder multiple-test
            correction (the significance level is split over those tried).
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
    power: float = 0.8
    tell_rel_error: float = 0.5
    candidates: tuple[str, ...] | None = None
    screen: bool = True

    def __post_init__(self) -> None:  # before any model runs
        unknown = sorted(set(self.candidates or ()) - set(REGISTRY))
        if unknown:
            raise ParameterError(
                f"candidates: unknown effect(s) {unknown}; known: {', '.join(REGISTRY)}",
                parameter="candidates",
            )


@dataclass(frozen=True)
class MeasuredFeatures:
    """Measured features per design point.

    A design point measured by η only (an η-only table such as the paper's Table 1) has
    one observation, its η, kept in column 1 with columns 0 and 2 NaN; its residual is
    ``(η_model − η)/σ_η`` with ``η_model = W/(π Fg δ_max)`` from the model's features.

    Attributes:
        points: (design value, amplitude [N]) per row; the design value is the kind's
            first design variable (the general hinge's clearance [mm], the bearing hinge's
            preload [N]; 0 for a kind without one).
        values: Features, shape (n_points, 3) (η-only rows: [NaN, η, NaN]).
        sigma: Their σ, shape (n_points, 3).
        eta_only: Rows measured by η only, shape (n_points,).
        clearance_mm: Radial clearance of each row [mm], whose free play 2Δr a stated η
            excludes (0 for a kind without one); None: the first entry of ``points``.
        hinge: The hinge kind of the rows (its first design variable is in ``points``).
        max_rel_sigma: Features with σ > max_rel_sigma·|value| are uninformative
            (``FeatureSettings.max_rel_sigma``); inf keeps every finite feature.
        clocks: Per row, its loop records as ``validation.evaluate.Clock`` (case id, force,
            time; None without ``time_s``), whose clocks a time-dependent loop effect is
            evaluated at; a row without any ``time_s`` has none (the protocol's clock).
    """

    points: tuple[tuple[float, float], ...]
    values: FloatArray
    sigma: FloatArray
    eta_only: npt.NDArray[np.bool_] | None = None
    max_rel_sigma: float = math.inf
    clearance_mm: tuple[float, ...] | None = None
    hinge: str = DEFAULT_KIND
    clocks: tuple[tuple[Clock, ...], ...] = ()

    @property
    def variable(self) -> DesignVariable | None:
        """The design variable in ``points`` (None for a kind without one)."""
        variables = hinge_kind(self.hinge).design_variables
        return variables[0] if variables else None

    @property
    def design_variable(self) -> str:
        """The design variable in words (``clearance``), for messages."""
        return "design" if self.variable is None else self.variable.word

    @property
    def informative(self) -> npt.NDArray[np.bool_]:
        """Features that enter χ² and N, shape (n_points, 3), bool.

        A feature is informative when it and its σ are finite and σ ≤ max_rel_sigma·|value|.
        """
        with np.errstate(invalid="ignore"):
            finite = np.isfinite(self.values) & np.isfinite(self.sigma) & (self.sigma > 0)
            ok = finite & (self.sigma <= self.max_rel_sigma * np.abs(self.values))
        return np.asarray(ok, dtype=bool)

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
        """Number of observations N: the informative features (≤ 3 per loop, ≤ 1 per η row)."""
        return int(np.count_nonzero(self.informative))


def measured_features(data: MeasurementSet, settings: FeatureSettings) -> MeasuredFeatures:
    """Summarise every design point of a measurement set (replicates averaged).

    A design point with loops uses them (module ``validation.features``); one with only
    η values (an η-only table) becomes an η-only row: η the mean of its values, σ_η the
    replicates' standard deviation if there are several, combined in quadrature with
    ``eta_rel_sigma · η`` (the stated uncertainty: tables carry none) and the model floor
    ``rel_floor · η + eta_floor``.
    """
    points, values, sigmas, eta_only, clearances = [], [], [], [], []
    clocks: list[tuple[Clock, ...]] = []
    by_id = data.by_id()
    hinges = set()
    for (hinge, pairs, amp), ids in data.replicate_groups().items():
        hinges.add(hinge)
        design = dict(pairs)
        loops = []
        etas = []
        row: list[Clock] = []
        for cid in ids:
            case = by_id[cid]
            if case.loop is not None:
                loops.append(
                    process_loop(case.loop.force_n, case.loop.displacement_mm, case.loop.source)
                )
                t = case.loop.time_s
                row.append((cid, case.loop.force_n, t) if t is not None else (cid, None, None))
            elif case.eta is not None:
                etas.append(float(case.eta))
        variables = hinge_kind(hinge).design_variables
        points.append((design[variables[0].name] if variables else 0.0, amp))
        # the free play a stated η excludes is that of a radial clearance, of any kind
        clearances.append(design.get("clearance_mm", 0.0))
        if loops:
            feats = np.array([loop_features(p) for p in loops])
            rep = np.std(feats, axis=0, ddof=1) if len(loops) > 1 else None
            values.append(feats.mean(axis=0))
            sigmas.append(feature_sigma(loops, settings, rep))
            eta_only.append(False)
            clocks.append(tuple(row) if any(c[2] is not None for c in row) else ())
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
            clocks.append(())
        else:
            points.pop()
    return MeasuredFeatures(
        tuple(points),
        np.array(values),
        np.array(sigmas),
        np.array(eta_only, dtype=bool),
        settings.max_rel_sigma,
        tuple(clearances),
        hinges.pop() if len(hinges) == 1 else DEFAULT_KIND,
        tuple(clocks),
    )


def design_text(meas: MeasuredFeatures, x: float) -> str:
    """``Δr = 0.1 mm`` or ``F_p = 100 N``: the design variable of a row, for messages."""
    return "" if meas.variable is None else meas.variable.text(x)


def eta_without_free_play(model: FloatArray, meas: MeasuredFeatures) -> FloatArray:
    """η of model features with the free play taken off δ_max, shape (n_points,).

    A stated η (an η-only table, like the paper's, or ``hingelab cycle``'s report)
    excludes the free play: ``η = W / (π Fg (δ_max − 2Δr))``; the loop area W is the same
    with or without the zero-force traverse. A model loop whose δ_max is below Δr never
    crossed the free play (clamped faces that hold the clevis below their slip force,
    ``fe.general.freeplay``): nothing is taken off. Where the faces slide the clevis across,
    the rectangle of that slide stays in W (it is dissipation).
    """
    elastic = np.array(model, dtype=np.float64, copy=True)
    clearance = np.array(meas.clearance_mm or tuple(p[0] for p in meas.points))
    crossed = elastic[:, 0] > clearance
    elastic[:, 0] -= np.where(crossed, 2.0 * clearance, 0.0)
    return derived(elastic, meas.amplitudes)[1]


def residuals(model: FloatArray, meas: MeasuredFeatures) -> FloatArray:
    """Return (model − measured)/σ, shape (n_points, 3); a failed run (NaN) counts 1e3.

    η-only rows: ``[0, (η_model − η)/σ_η, 0]``. Uninformative features
    (``MeasuredFeatures.informative``) count 0.
    """
    model = np.asarray(model, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = (model - meas.values) / meas.sigma
        eta_rows = meas.eta_rows
        if np.any(eta_rows):
            eta_model = eta_without_free_play(model, meas)[eta_rows]
            r_eta = (eta_model - meas.values[eta_rows, 1]) / meas.sigma[eta_rows, 1]
            r[eta_rows] = 0.0
            r[eta_rows, 1] = r_eta
    r = np.where(np.isfinite(r), r, 1e3)
    return np.where(meas.informative, r, 0.0)


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
        refine_runs: True-model points the refinement ran (``validation.param_search``),
            the polish's included.
        polish_runs: Of those, the true-model polish's (run when the stated error exceeded
            1σ).
        error_sigma: The search's stated error: the largest |interpolated − true|/σ of an
            informative feature at its last refinement point (NaN: none run).
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
    refine_runs: int = 0
    polish_runs: int = 0
    error_sigma: float = math.nan

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


def settings_grid(hi: float, settings: DiagnoseSettings) -> FloatArray:
    """The log grid of a candidate parameter whose upper bound is ``hi`` (``param_search.grid``)."""
    return grid(hi, settings.grid_points, settings.grid_decades)


def grid_effects(name: str, settings: DiagnoseSettings) -> list[dict[str, dict[str, float]]]:
    """The effects ``fit_candidate`` evaluates on its grid for candidate ``name``, in order.

    Independent of one another: a cluster runs them as one batch
    (``validation.evaluate.ModelEvaluator.prefetch``) before the fit reads them.
    """
    spec = REGISTRY[name].params[0]
    return [{name: {spec.name: float(p)}} for p in settings_grid(spec.hi, settings)]


def holdout_folds(points: Sequence[tuple[float, float]]) -> list[npt.NDArray[np.bool_]]:
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
