"""Fitting the candidate effects of ``diagnose`` and ``calibrate``.

``fit_candidates`` fits every candidate's parameter (``validation.param_search``: a grid,
optionally on a coarser *screen* mesh, then refinement rounds on the model itself in which
all candidates' points run as one batch) and runs the false-alarm checks (significance,
held-out folds, bounds) of steps 3–4 in the ``validation.diagnose`` module docstring.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt
from scipy import optimize, stats

from cad.errors import EffectError
from fe.effects.registry import REGISTRY
from mesh.settings import MeshSettings
from model.spec import ModelSpec
from validation.candidate_fit import (
    CandidateFit,
    DiagnoseSettings,
    FloatArray,
    MeasuredFeatures,
    chi2,
    grid_effects,
    holdout_folds,
    settings_grid,
)
from validation.evaluate import ModelEvaluator, is_post_only, prefetch_together
from validation.param_search import Cost, Search, refine

__all__ = ["fit_candidate", "fit_candidates", "prefetch_grids"]


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


def _screened(names: Sequence[str], screen: ModelEvaluator | None) -> dict[str, bool]:
    """Candidate → whether its grid runs on the screen (a post-only one costs no cycle anyway)."""
    return {n: screen is not None and not is_post_only(n) for n in names}


def screen_mesh(spec: ModelSpec) -> MeshSettings | None:
    """The coarser mesh a diagnosis of ``spec`` fits its grids on, or None.

    The kind's coarse preset (``HingeKind.mesh_settings(coarse=True)``) when the model's
    mesh is finer than it (a smaller global or contact size); None when it is not (the
    grids then run on the model itself).
    """
    coarse = spec.hinge_kind.mesh_settings(coarse=True)
    m = spec.mesh
    finer = m.global_mm < coarse.global_mm or m.master_mm < coarse.master_mm
    return coarse if finer else None


def screen_evaluator(
    evaluator: ModelEvaluator, settings: DiagnoseSettings
) -> ModelEvaluator | None:
    """The model of ``evaluator`` on its ``screen_mesh`` (same points, increments, service), or None.

    None when ``settings.screen`` is off or the model's mesh is not finer than the kind's
    coarse preset. A caller that changes ``evaluator``'s model (effects, μ) changes the
    screen's the same way (``validation.calibrate``).
    """
    coarse = screen_mesh(evaluator.spec) if settings.screen else None
    if coarse is None:
        return None
    return ModelEvaluator(
        dataclasses.replace(evaluator.spec, mesh=coarse),
        evaluator.points,
        settings.increments_per_stage,
        settings.clearance_increments,
        evaluator.service,
        evaluator.clocks or None,
    )


def prefetch_grids(
    evaluator: ModelEvaluator,
    names: Sequence[str],
    settings: DiagnoseSettings,
    screen: ModelEvaluator | None = None,
    *,
    baseline: bool = False,
) -> None:
    """Every candidate's grid (and the screen's baseline) as one batch of runs.

    With ``baseline`` the model's own baseline joins the batch, so a cluster never waits
    for the baseline's last cycle before the grids start (``diagnose``).
    """
    screened = _screened(names, screen)
    grids: list[tuple[Mapping[str, Mapping[str, float]], float | None]] = (
        [({}, None)] if baseline else []
    )
    grids += [(e, None) for n in names if not screened[n] for e in grid_effects(n, settings)]
    together = [(evaluator, grids)]
    if screen is not None and any(screened.values()):  # its baseline too, in the same batch
        shots = [(e, None) for n in names if screened[n] for e in grid_effects(n, settings)]
        together.append((screen, [({}, None), *shots]))
    prefetch_together(together)


def fit_candidate(
    evaluator: ModelEvaluator,
    name: str,
    meas: MeasuredFeatures,
    base_features: FloatArray,
    n_tried: int,
    settings: DiagnoseSettings,
    screen: ModelEvaluator | None = None,
) -> CandidateFit:
    """Fit one candidate's parameter and judge it (``fit_candidates`` for one).

    Raises:
        EffectError: The candidate (a user's effect) failed.
    """
    fits, failed = fit_candidates(evaluator, [name], meas, base_features, n_tried, settings, screen)
    if name in failed:
        raise failed[name]
    return fits[0]


def fit_candidates(
    evaluator: ModelEvaluator,
    names: Sequence[str],
    meas: MeasuredFeatures,
    base_features: FloatArray,
    n_tried: int,
    settings: DiagnoseSettings,
    screen: ModelEvaluator | None = None,
) -> tuple[list[CandidateFit], dict[str, EffectError]]:
    """Fit every candidate's parameter and judge it (``validation.diagnose`` docstring, steps 3–4).

    The search (``validation.param_search``): each candidate's grid (on ``screen`` when
    given: the same model on a coarser mesh), then refinement rounds on ``evaluator``'s
    model in which all candidates' next points run as one batch.

    Args:
        evaluator: The model judged (its features give every χ² of the verdict).
        names: Candidate effects.
        meas: The measured features.
        base_features: The model's features without a candidate, shape (n_points, 3).
        n_tried: Candidates tried (the Bonferroni factor).
        settings: Grid, refinement and decision settings.
        screen: The model on a coarser mesh for the grids (coarse to fine), or None.

    Returns:
        (fits in the order of ``names``, candidate → the error of a user's effect that failed).
    """
    failed: dict[str, EffectError] = {}
    screened = _screened(names, screen)
    prefetch_grids(evaluator, names, settings, screen)
    base_screen = screen.features({}) if screen is not None and any(screened.values()) else None
    searches = []
    for name in names:
        spec = REGISTRY[name].params[0]
        values = settings_grid(spec.hi, settings)
        gridder = screen if screen is not None and screened[name] else evaluator
        try:
            feats = np.array(
                [_retuned_features(gridder, {name: {spec.name: float(p)}}, meas) for p in values]
            )
        except EffectError as err:
            failed[name] = err
            continue
        own_base = base_screen if screened[name] else None
        searches.append(Search(name, values, feats, base_features, own_base))

    def at(ev: ModelEvaluator, s: Search, p: float) -> FloatArray:
        param = REGISTRY[s.name].params[0].name
        try:
            return _retuned_features(ev, {s.name: {param: p}}, meas)
        except EffectError as err:
            failed.setdefault(s.name, err)
            return np.full_like(base_features, np.nan)

    def run(batch: Sequence[tuple[Search, float]]) -> list[tuple[FloatArray, FloatArray | None]]:
        requests = [({s.name: {REGISTRY[s.name].params[0].name: p}}, None) for s, p in batch]
        together = [(evaluator, requests)]  # every candidate's point of this round: one batch
        if screen is not None:
            together.append(
                (screen, [r for r, (s, _) in zip(requests, batch, strict=True) if s.screened])
            )
        prefetch_together(together)
        return [
            (at(evaluator, s, p), at(screen, s, p) if screen is not None and s.screened else None)
            for s, p in batch
        ]

    def cost(feats: FloatArray, rows: npt.NDArray[np.bool_] | None) -> float:
        return chi2(feats, meas, rows)

    refine(searches, run, cost, meas.sigma, meas.informative, settings.refine_iter)
    fits = [
        _judged(evaluator, s, meas, base_features, n_tried, settings, cost)
        for s in searches
        if s.name not in failed
    ]
    return fits, failed


def _judged(
    evaluator: ModelEvaluator,
    search: Search,
    meas: MeasuredFeatures,
    base_features: FloatArray,
    n_tried: int,
    settings: DiagnoseSettings,
    cost: Cost,
) -> CandidateFit:
    """The candidate's fit and its false-alarm checks, from its settled search."""
    spec = REGISTRY[search.name].params[0]
    c2, value, fitted = search.best(cost)
    c0 = chi2(base_features, meas)
    model_effects = _retuned(evaluator, {search.name: {spec.name: value}}, meas)
    n = meas.n_obs
    d = c0 - c2
    f_stat = d / max(1.0, c2 / max(n - 1, 1))
    p_value = float(stats.f.sf(f_stat, 1, max(n - 1, 1)))
    significant = p_value < settings.alpha / max(n_tried, 1)
    held_base = held = 0.0
    for test in holdout_folds(meas.points):
        _, f_fold = search.scan(cost, ~test)
        held_base += chi2(base_features, meas, test)
        held += chi2(f_fold, meas, test)
    values = search.grid
    at_bound = value <= values[0] * 1.0001 or value >= values[-1] * 0.9999
    return CandidateFit(
        name=search.name,
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
        refine_runs=search.rounds + search.polish_runs,
        polish_runs=search.polish_runs,
        error_sigma=search.error_sigma,
    )
