"""Add effects to a model, fit their parameters and keep an error ledger.

``calibrate`` fits μ if asked (first), then adds the named effects one after another:
each is first fitted alone on the model that holds the ones before it
(``validation.candidates.fit_candidate``, the **greedy** value, kept in the ledger), and
then the primary parameter of **every** effect in the model is re-fitted jointly from the
previous values (``validation.joint_fit``: σ and correlations from the Jacobian, and the
parameters that moved by more than their σ). It returns the extended model and one ledger
row per step: baseline → +effect → … with the parameters, the error ``sqrt(χ²/N)`` (RMS
feature residual in σ; ≈ 1 at the noise level) and the design points within 2σ on every
feature (``validation.feature_misfit``: the same function, features and σ that
``compare`` reports for the written model), the held-out error, AIC = χ² + 2k and BIC =
χ² + k ln N (k: parameters fitted so far). ``append_ledger`` adds rows to
``ledger.json``/``ledger.csv`` in a folder and ``plot_ledger`` draws the error per step.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cad.errors import ParameterError
from model.jsonio import dumps
from model.spec import ModelSpec
from validation.candidate_fit import (
    DiagnoseSettings,
    chi2,
    measured_features,
)
from validation.candidates import fit_candidate, screen_evaluator
from validation.evaluate import ModelEvaluator
from validation.feature_misfit import feature_misfit, fitted_cases
from validation.joint_fit import joint_fit
from validation.measurements import MeasurementSet


@dataclass(frozen=True)
class LedgerRow:
    """One step of the ledger.

    Attributes:
        step: Label (``baseline`` or ``+name``).
        params: Effect parameters added in this step.
        n_params: Effect parameters fitted so far.
        chi2: χ² over the features.
        error: sqrt(χ²/N).
        heldout_error: sqrt(held-out χ² / N) (the step's parameter fitted without the fold).
        aic: χ² + 2k.
        bic: χ² + k ln N.
        model: Every parameter of the model after this step (``mu`` and
            ``effect.parameter``), re-tuned earlier ones included: what the model file
            written at this step holds.
        greedy: The step's parameter fitted alone, before the joint re-fit.
        sigma: ``effect.param`` → σ of the jointly fitted values.
        correlation: ``effect.param`` → ``effect.param`` → their correlation.
        moved: Parameters that moved by more than their σ in this step's joint re-fit.
        n_fitted: Design points within 2σ on every feature (``feature_misfit``).
        n_points: Design points.
        fitted_cases: Case ids of the fitted design points.
        file_chi2: The last row only: χ² of the written model at its own increments
            (``compare``'s runs; the fit may use fewer), None on the other rows.
        file_error: Likewise sqrt(χ²/N): the error ``compare`` reports for the model file.
        file_n_fitted: Likewise the design points within 2σ on every feature.
    """

    step: str
    params: dict[str, float]
    n_params: int
    chi2: float
    error: float
    heldout_error: float
    aic: float
    bic: float
    model: dict[str, float] = dataclasses.field(default_factory=dict)
    greedy: dict[str, float] = dataclasses.field(default_factory=dict)
    sigma: dict[str, float] = dataclasses.field(default_factory=dict)
    correlation: dict[str, dict[str, float]] = dataclasses.field(default_factory=dict)
    moved: tuple[str, ...] = ()
    n_fitted: int = 0
    n_points: int = 0
    fitted_cases: tuple[str, ...] = ()
    file_chi2: float | None = None
    file_error: float | None = None
    file_n_fitted: int | None = None


def model_parameters(spec: ModelSpec) -> dict[str, float]:
    """Return μ and every effect parameter of a model, as ``{"mu": …, "effect.param": …}``."""
    out = {"mu": float(spec.cycle.mu)}
    for name, params in sorted(spec.effects.items()):
        out.update({f"{name}.{k}": float(v) for k, v in sorted(params.items())})
    return out


MU_RANGE = (0.02, 0.8)
"""Bounds of a fitted friction coefficient (dry steel on steel lies near 0.1–0.6)."""


def _fit_mu(ev: ModelEvaluator, meas: Any, rows: Any, maxiter: int) -> float:
    """Return μ minimising χ² over ``rows`` (bounded Brent in log10 μ; the current μ competes)."""
    from scipy import optimize

    def cost(u: float) -> float:
        return chi2(ev.features({}, mu=float(10.0**u)), meas, rows)

    lo, hi = (math.log10(b) for b in MU_RANGE)
    res = optimize.minimize_scalar(
        cost, bounds=(lo, hi), method="bounded", options={"maxiter": maxiter, "xatol": 0.005}
    )
    now = ev.cycle.mu
    return float(10.0**res.x) if float(res.fun) < cost(math.log10(now)) else now


def calibrate(
    spec: ModelSpec,
    data: MeasurementSet,
    names: Sequence[str],
    settings: DiagnoseSettings | None = None,
    *,
    fit_mu: bool = False,
    service: Any = None,
) -> tuple[ModelSpec, list[LedgerRow]]:
    """Fit μ (if asked) and then the named effects in turn; return the model and the ledger.

    μ changes no operator, so its fit reuses the factorisations; it comes first (the
    baseline model of the issue is "elasticity + Coulomb contact, μ calibrated"), bounded
    to ``MU_RANGE``, with its held-out error refitted on each fold (``holdout_folds``).
    ``service``: the ``model.service.ModelService`` that runs the cycles (None: a new one
    per step, in process, nothing stored); with a runner every evaluation's design
    points run together as Dask tasks. Each effect's grid runs coarse to fine as in
    ``diagnose`` (``settings.screen``, ``validation.candidates.screen_evaluator``); its
    refinement, the joint re-fit and every error in the ledger are the model's own mesh's.

    Raises:
        ParameterError: An unknown effect or one already in the model.
    """
    from fe.effects.registry import REGISTRY

    s = settings or DiagnoseSettings()
    for n in names:
        if n not in REGISTRY:
            raise ParameterError(f"--effects: unknown effect {n!r}; known: {', '.join(REGISTRY)}")
        if n in spec.effects:
            raise ParameterError(f"--effects: {n!r} is already in the model")
    meas = measured_features(data, s.features)
    n_feat = meas.n_obs
    ev = ModelEvaluator(
        spec, meas.points, s.increments_per_stage, s.clearance_increments, service, meas.clocks
    )
    screen = screen_evaluator(ev, s) if names else None  # the grids' coarse mesh, or None
    base = ev.features({})
    c = chi2(base, meas)
    err = math.sqrt(c / n_feat)
    rows = [
        LedgerRow(
            "baseline",
            {},
            0,
            c,
            err,
            err,
            c,
            c,
            model_parameters(spec),
            **_fitted(base, meas, data),
        )
    ]
    k0 = 0
    if fit_mu:
        from validation.candidate_fit import holdout_folds

        everything = np.ones(len(meas.points), dtype=bool)
        mu = _fit_mu(ev, meas, everything, maxiter=12)
        held = 0.0
        for test in holdout_folds(meas.points):
            mu_fold = _fit_mu(ev, meas, ~test, maxiter=8)
            held += chi2(ev.features({}, mu=mu_fold), meas, test)
        spec = dataclasses.replace(spec, cycle=dataclasses.replace(spec.cycle, mu=mu))
        ev.set_mu(spec)
        if screen is not None:
            screen.set_mu(dataclasses.replace(spec, mesh=screen.spec.mesh))
        base = ev.features({})
        c = chi2(base, meas)
        held = max(held, c)
        k0 = 1
        rows.append(
            LedgerRow(
                "+mu",
                {"mu": mu},
                1,
                c,
                math.sqrt(c / n_feat),
                math.sqrt(held / n_feat),
                c + 2,
                c + math.log(n_feat),
                model_parameters(spec),
                **_fitted(base, meas, data),
            )
        )
    for k, name in enumerate(names, start=1 + k0):
        if screen is not None:  # the effects added so far, on the coarse mesh
            screen.spec = dataclasses.replace(spec, mesh=screen.spec.mesh)
        fit = fit_candidate(ev, name, meas, base, 1, s, screen)  # its grid: one batch
        before = model_parameters(spec)
        start = {n: dict(p) for n, p in spec.effects.items()}  # previous values …
        start[name] = {fit.param: fit.value}  # … and the new effect's greedy value
        joint = joint_fit(ev, start, meas, previous=before)
        spec = dataclasses.replace(spec, effects=joint.effects)
        ev.spec = spec  # its cached runs stay valid: they are keyed by the effects
        base = joint.features
        c = chi2(base, meas)
        held = max(fit.heldout_chi2, c)  # held-out never beats the in-sample fit
        rows.append(
            LedgerRow(
                f"+{name}",
                {f"{name}.{fit.param}": joint.values[f"{name}.{fit.param}"]},
                k,
                c,
                math.sqrt(c / n_feat),
                math.sqrt(held / n_feat),
                c + 2 * k,
                c + k * math.log(n_feat),
                model_parameters(spec),
                greedy={f"{name}.{fit.param}": fit.value},
                sigma=joint.sigma,
                correlation=joint.correlation,
                moved=joint.moved,
                **_fitted(base, meas, data),
            )
        )
    # the written model as compare runs it: its own increments, not the fit's
    final = feature_misfit(ModelEvaluator(spec, meas.points, clocks=meas.clocks).features({}), meas)
    rows[-1] = dataclasses.replace(
        rows[-1], file_chi2=final.chi2, file_error=final.error, file_n_fitted=final.n_fitted
    )
    return spec, rows


def _fitted(model: Any, meas: Any, data: MeasurementSet) -> dict[str, Any]:
    """The ledger's fitted design points (``validation.feature_misfit``), as row fields."""
    m = feature_misfit(model, meas)
    return {
        "n_fitted": m.n_fitted,
        "n_points": len(m.point_fitted),
        "fitted_cases": tuple(fitted_cases(m, data)),
    }


def append_ledger(out: Path, rows: Sequence[LedgerRow]) -> list[dict[str, Any]]:
    """Append rows to ``out/ledger.json`` and rewrite ``out/ledger.csv``; return all rows."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / "ledger.json"
    old: list[dict[str, Any]] = json.loads(path.read_text()) if path.is_file() else []
    new = json.loads(dumps([dataclasses.asdict(r) for r in rows]))  # tuples as JSON lists
    if old and new and new[0]["step"] == "baseline":
        new = new[1:]  # the baseline of a later round is the last step of the previous one
    every = old + new
    path.write_text(dumps(every, indent=1) + "\n")
    lines = ["step,params,n_params,chi2,error,heldout_error,aic,bic,model"]
    for r in every:
        p = ";".join(f"{k}={_g(v)}" for k, v in r["params"].items())
        m = ";".join(f"{k}={_g(v)}" for k, v in r.get("model", {}).items())
        nums = ",".join(_g(r[k]) for k in ("chi2", "error", "heldout_error", "aic", "bic"))
        lines.append(f"{r['step']},{p},{r['n_params']},{nums},{m}")
    (out / "ledger.csv").write_text("\n".join(lines) + "\n")
    rows_out: list[dict[str, Any]] = every
    return rows_out


def plot_ledger(rows: Sequence[dict[str, Any]], path: Path) -> Path:
    """Draw error and held-out error per step (log scale) with the noise level; return path."""
    from matplotlib.figure import Figure  # no pyplot: no global state, no backend to choose

    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    x = range(len(rows))
    nan = float("nan")  # null in the strict-JSON ledger: a gap in the line
    ax.semilogy(
        x,
        [nan if r["error"] is None else r["error"] for r in rows],
        "o-",
        label="error (fitted cases)",
    )
    held = [nan if r["heldout_error"] is None else r["heldout_error"] for r in rows]
    ax.semilogy(x, held, "s--", label="held-out error")
    ax.axhline(1.0, color="grey", ls=":", label="noise level")
    ax.set_xticks(list(x), [r["step"] for r in rows], rotation=20)
    ax.set_ylabel("RMS feature residual [σ]")
    ax.set_title("calibration ledger")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def _g(value: float | None) -> str:
    """A ledger number for the CSV: 6 significant digits, empty where JSON has null (NaN)."""
    return "" if value is None else f"{value:.6g}"
