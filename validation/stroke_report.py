"""The validation loop on displacement-controlled records: compare, diagnose, calibrate, hold-out.

* ``stroke_compare``: the model (its laws applied) driven by each case's own cycle
  (``validation.stroke_fit.model_loop``), every feature of ``STROKE_FEATURES`` judged
  against k σ, σ that of the case's design point (cycle scatter ⊕ noise ⊕ floor); the
  ``EXTRA_FEATURES`` are reported.
* ``stroke_ledger``: baseline → +term → … each step refitting every term so far
  (``fit_laws``), with its χ², error sqrt(χ²/N), BIC and, when asked, the held-out error
  of leave-one-condition-out (each design point predicted by a fit without it): the rows
  are ``validation.calibrate.LedgerRow``, so ``append_ledger``/``plot_ledger`` write them.
* ``stroke_diagnosis``: each candidate term added alone to the model's own laws: Δχ²,
  ΔBIC and the held-out χ²; a term the data need lowers both the BIC and the held-out χ².
* ``loo_table``: the leave-one-condition-out table (energy per cycle, mid-stroke forces,
  travels) of the last step, in words and as JSON.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from model.spec import ModelSpec
from validation.calibrate import LedgerRow
from validation.joint_laws import Laws, ParamLaw
from validation.measurements import MeasurementSet
from validation.stroke import (
    STROKE_FEATURES,
    STROKE_LABELS,
    StrokeSettings,
    stroke_features,
)
from validation.stroke_fit import (
    HeldOut,
    StrokePoint,
    Term,
    drive_path,
    fit_laws,
    held_out,
    law_coefficients,
    model_features,
    model_loop,
    n_obs,
    residuals,
    stroke_points,
)


def _chi2(spec: ModelSpec, laws: Laws, points: Sequence[StrokePoint], s: StrokeSettings) -> float:
    return float(np.sum(residuals(model_features(spec, laws, points, s), points) ** 2))


def stroke_compare(
    spec: ModelSpec, laws: Laws, data: MeasurementSet, settings: StrokeSettings
) -> dict[str, Any]:
    """Judge the model against every case (module docstring); a JSON-ready dict."""
    points = stroke_points(data, settings)
    by_id = data.by_id()
    rows: list[dict[str, Any]] = []
    for p in points:
        for cid in p.case_ids:
            case = by_id[cid]
            t, d = drive_path(case)
            F, dm = model_loop(spec, laws, case, t, d)
            loop = case.loop
            if loop is None:  # stroke_points refused a case without one
                continue
            meas = stroke_features(loop.force_n, loop.displacement_mm, settings)
            mod = stroke_features(F, dm, settings)
            z = {n: (mod[n] - meas[n]) / p.sigma[j] for j, n in enumerate(STROKE_FEATURES)}
            failed = [n for n, v in z.items() if not abs(v) <= settings.k]
            rows.append(
                {
                    "case_id": cid,
                    "record": p.label,
                    "conditions": dict(case.conditions),
                    "amplitude_mm": case.amplitude_mm,
                    "measured": meas,
                    "model": mod,
                    "sigma": {n: float(p.sigma[j]) for j, n in enumerate(STROKE_FEATURES)},
                    "z": z,
                    "W_error": (mod["W_cycle_Nmm"] - meas["W_cycle_Nmm"])
                    / abs(meas["W_cycle_Nmm"]),
                    "failed": failed,
                    "passed": not failed,
                }
            )
    w = [float(r["W_error"]) for r in rows]
    return {
        "k": settings.k,
        "laws": law_coefficients(laws),
        "n_cases": len(rows),
        "n_pass": sum(r["passed"] for r in rows),
        "W_rms_error": float(np.sqrt(np.mean(np.square(w)))) if w else math.nan,
        "cases": rows,
    }


def format_compare(report: dict[str, Any]) -> str:
    """The per-case table: W error in %, each feature's error in σ (* beyond k σ)."""
    names = [*STROKE_FEATURES]
    head = f"{'case':34} {'W err':>7} " + " ".join(f"{STROKE_LABELS[n]:>8}" for n in names)
    lines = [head]
    for r in report["cases"]:
        cells = [f"{r['z'][n]:+7.1f}{'*' if n in r['failed'] else ' '}" for n in names]
        lines.append(f"{r['case_id']:34} {r['W_error'] * 100:+6.1f}% " + " ".join(cells))
    lines.append(
        f"{report['n_pass']}/{report['n_cases']} cases pass (every feature within "
        f"{report['k']:g}σ; σ = cycle scatter ⊕ noise ⊕ floor; * beyond); "
        f"W RMS error {report['W_rms_error'] * 100:.1f} %"
    )
    return "\n".join(lines)


def stroke_ledger(
    spec: ModelSpec,
    laws: Laws,
    data: MeasurementSet,
    terms: Sequence[Term],
    settings: StrokeSettings,
    *,
    hold_out: bool = False,
) -> tuple[dict[str, ParamLaw], list[LedgerRow], HeldOut | None]:
    """Fit the terms step by step; return the laws, the ledger rows and the last hold-out."""
    points = stroke_points(data, settings)
    n = n_obs(points)
    laws = dict(laws)
    c = _chi2(spec, laws, points, settings)
    ho = held_out(spec, laws, points, [], settings) if hold_out else None
    held = math.sqrt(ho.chi2 / n) if ho else math.nan
    rows = [LedgerRow("baseline", {}, 0, c, math.sqrt(c / n), held, c, c, law_coefficients(laws))]
    k = 0
    for i, term in enumerate(terms):
        laws = fit_laws(spec, laws, points, terms[: i + 1], settings)
        k = len(law_coefficients({t.param: laws[t.param] for t in terms[: i + 1]}))
        c = _chi2(spec, laws, points, settings)
        ho = held_out(spec, laws, points, terms[: i + 1], settings) if hold_out else None
        held = math.sqrt(max(ho.chi2, c) / n) if ho else math.nan
        new = law_coefficients({term.param: laws[term.param]})
        rows.append(
            LedgerRow(
                f"+{term.text}",
                new,
                k,
                c,
                math.sqrt(c / n),
                held,
                c + 2 * k,
                c + k * math.log(n),
                law_coefficients(laws),
            )
        )
    return laws, rows, ho


@dataclass(frozen=True)
class Candidate:
    """One candidate term added alone: χ², ΔBIC against the baseline, held-out χ²."""

    term: str
    chi2: float
    delta_bic: float
    heldout_chi2: float
    heldout_chi2_base: float
    laws: dict[str, float]

    @property
    def needed(self) -> bool:
        """Lowers the BIC and the held-out χ² (by a quarter) alike."""
        return self.delta_bic < 0 and self.heldout_chi2 < 0.75 * self.heldout_chi2_base


CANDIDATE_PARAMS = (
    "slip_force_n",
    "slip_asymmetry",
    "free_play_mm",
    "k_tension_n_per_mm",
    "k_compression_n_per_mm",
    "damping_n_s_per_mm",
)
"""The element's parameters ``diagnose`` tries, each as a constant and as a law."""


def default_candidates(
    data: MeasurementSet, params: Sequence[str] = CANDIDATE_PARAMS
) -> list[Term]:
    """Every parameter as a constant and as a straight line in each varying condition."""
    varying = sorted(
        name
        for name in {k for c in data.cases for k in c.conditions}
        if len({c.conditions.get(name) for c in data.cases}) > 1
    )
    return [Term(p, conds) for p in params for conds in [(), *((v,) for v in varying)]]


def stroke_diagnosis(
    spec: ModelSpec,
    laws: Laws,
    data: MeasurementSet,
    candidates: Sequence[Term],
    settings: StrokeSettings,
) -> dict[str, Any]:
    """Each candidate added alone to the model's laws (module docstring); a JSON-ready dict."""
    points = stroke_points(data, settings)
    n = n_obs(points)
    c0 = _chi2(spec, laws, points, settings)
    base_held = held_out(spec, laws, points, [], settings).chi2
    out = []
    for term in candidates:
        fitted = fit_laws(spec, laws, points, [term], settings)
        c = _chi2(spec, fitted, points, settings)
        k = 1 + len(fitted[term.param].slopes)
        held = held_out(spec, fitted, points, [term], settings).chi2
        out.append(
            Candidate(
                term.text,
                c,
                c + k * math.log(n) - c0,
                held,
                base_held,
                law_coefficients({term.param: fitted[term.param]}),
            )
        )
    out.sort(key=lambda x: x.delta_bic)
    return {
        "baseline_chi2": c0,
        "n_obs": n,
        "candidates": [vars(x) | {"needed": x.needed} for x in out],
        "best": out[0].term if out and out[0].needed else None,
    }


def loo_table(ho: HeldOut) -> dict[str, Any]:
    """The leave-one-condition-out table: per point the predicted features against the record."""
    rows = []
    for i, p in enumerate(ho.points):
        pred = ho.predicted[i]
        row: dict[str, Any] = {
            "record": p.label,
            "conditions": dict(p.case.conditions),
            "amplitude_mm": p.case.amplitude_mm,
            "n_cycles": len(p.case_ids),
        }
        for j, name in enumerate(STROKE_FEATURES):
            row[name] = {
                "measured": float(p.values[j]),
                "predicted": float(pred[j]),
                "sigma": float(p.sigma[j]),
                "z": float((pred[j] - p.values[j]) / p.sigma[j]),
            }
        row["W_error"] = float(ho.relative_errors()[i])
        rows.append(row)
    return {"rows": rows, "W_rms_error": ho.rms(), "chi2": ho.chi2}


def format_loo(table: dict[str, Any], condition: str = "band_tension_N") -> str:
    """The table as text: W measured/predicted/error, scatter σ_W, shape features in σ."""
    lines = [
        f"{'record':34} {'W meas J':>9} {'W pred J':>9} {'error':>7} {'σ_W':>6} "
        + " ".join(f"{STROKE_LABELS[n]:>8}" for n in STROKE_FEATURES[1:])
    ]
    for r in table["rows"]:
        w = r["W_cycle_Nmm"]
        shape = " ".join(f"{r[n]['z']:+7.1f}σ" for n in STROKE_FEATURES[1:])
        lines.append(
            f"{r['record']:34} {w['measured'] / 1e3:9.1f} {w['predicted'] / 1e3:9.1f} "
            f"{r['W_error'] * 100:+6.1f}% {w['sigma'] / abs(w['measured']) * 100:5.1f}% {shape}"
        )
    lines.append(f"leave-one-condition-out RMS error of W: {table['W_rms_error'] * 100:.1f} %")
    return "\n".join(lines)
