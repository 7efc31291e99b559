"""The residuals a signature table is tested on, from measured records and model loops.

``validation.signatures`` holds the statistics; this module makes its inputs for
``diagnose``: each measured record's branch residuals against the model's loop at its
design point (``loop_residual``) and the loss-factor residuals of the features
(``loss_residual``), then the table (``signature_table``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from cad.errors import HingelabError
from fe.kinds import hinge_kind
from validation.candidate_fit import FloatArray, MeasuredFeatures, eta_without_free_play
from validation.evaluate import ModelEvaluator
from validation.features import derived
from validation.loops import ProcessedLoop, branch_residuals, noise_level, process_loop
from validation.measurements import MeasurementSet
from validation.rig_mapping import Control
from validation.signatures import LoopResidual, LossResidual, SignatureTable, loop_signatures

GRID = 41
"""Force levels per branch (about 20 on each side of F = 0): few enough that neighbouring
levels come from different samples of a record, so their noise is independent."""


def _at_grid(F: FloatArray, values: FloatArray, grid: FloatArray) -> FloatArray:
    """``values`` of one branch at the grid forces, the samples sorted by force."""
    order = np.argsort(F, kind="stable")
    return np.asarray(np.interp(grid, F[order], values[order]), dtype=np.float64)


def loop_residual(
    measured: ProcessedLoop,
    model: ProcessedLoop,
    time_s: FloatArray | None,
    case_id: str,
    rel_floor: float,
) -> LoopResidual:
    """One record's branch residuals (measured − model) with σ, clock and dF/dt.

    σ per point is the record's displacement noise, its force noise through the secant
    slope, and the model floor ``rel_floor · δ_max``, in quadrature (as the features' σ).
    The clock is ``time_s`` or, without it, the sample index.

    Args:
        measured: The processed record.
        model: The processed model loop at its design point.
        time_s: The record's time, shape (n,) [s] (the raw record's samples), or None.
        case_id: The record's case.
        rel_floor: The model floor (``FeatureSettings.rel_floor``).
    """
    grid, r_down, r_up = branch_residuals(measured, model, GRID)
    m = measured.metrics
    s_d, s_F = noise_level(measured.displacement_mm), noise_level(measured.force_n)
    sigma = math.sqrt(
        s_d**2 + (m.delta_max_mm / m.f_max_n * s_F) ** 2 + (rel_floor * m.delta_max_mm) ** 2
    )
    st = measured.stages
    clock = np.arange(len(measured.force_n), dtype=np.float64) if time_s is None else time_s
    span = clock[st.peak_last] - clock[st.peak_first]
    F = measured.force_n
    progress, rates = [], []
    for sl in (slice(st.peak_first, st.trough + 1), slice(st.trough, st.peak_last + 1)):
        t = _at_grid(F[sl], clock[sl], grid)
        progress.append((t - clock[st.peak_first]) / span)
        rate = np.empty_like(grid)
        for side in (grid < 0.0, grid > 0.0):  # not across the band left out at F = 0
            with np.errstate(divide="ignore", invalid="ignore"):
                rate[side] = np.gradient(grid[side], t[side])
        rates.append(rate)
    return LoopResidual(
        case_id=case_id,
        force_n=np.concatenate([grid, grid]),
        branch=np.concatenate([np.ones(grid.size), -np.ones(grid.size)]),
        residual_mm=-np.concatenate([r_down, r_up]),  # branch_residuals gives model − measured
        sigma_mm=np.full(2 * grid.size, sigma),
        progress=np.concatenate(progress),
        rate_n_per_s=None if time_s is None else np.concatenate(rates),
    )


def loss_residual(model: FloatArray, meas: MeasuredFeatures) -> LossResidual:
    """ln(η_measured/η_model) per design point, with σ from the loop-area (or η) σ.

    Design points with a non-positive η on either side or an uninformative loop area
    are left out.
    """
    amps = meas.amplitudes
    _, eta_m = derived(model, amps)
    _, eta_d = derived(meas.values, amps)
    rows = meas.eta_rows
    eta_d = np.where(rows, meas.values[:, 1], eta_d)
    eta_m = np.where(rows, eta_without_free_play(model, meas), eta_m)
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma = meas.sigma[:, 1] / np.abs(meas.values[:, 1])
        keep = meas.informative[:, 1] & (eta_d > 0) & (eta_m > 0) & np.isfinite(sigma)
        y = np.log(eta_d / eta_m)
    group = np.array([p[0] for p in meas.points], dtype=np.float64)
    return LossResidual(amps[keep], group[keep], y[keep], sigma[keep])


def signature_table(
    ev: ModelEvaluator,
    data: MeasurementSet,
    meas: MeasuredFeatures,
    effects: Mapping[str, Mapping[str, float]],
    rel_floor: float,
    alpha: float,
) -> SignatureTable:
    """Test the residuals of the model with ``effects`` added against every signature.

    Args:
        ev: The diagnosis' evaluator (its design points are ``meas.points``).
        data: The measurements (each force-controlled record is used, replicates too).
        meas: Their features.
        effects: Extra effects of the model whose residuals are tested ({} for the model
            as it is).
        rel_floor: The model floor of the σ.
        alpha: False-alarm probability of the table.
    """
    model_rows = ev.record_loops(effects)
    # a time-dependent effect: the model's loop at each record's own clock
    at_clock = {cid: loop for row in model_rows for cid, loop in row if cid is not None}
    by_id = data.by_id()
    loops = []
    for (hinge, pairs, amp), ids in data.replicate_groups().items():
        variables = hinge_kind(hinge).design_variables
        point = (dict(pairs)[variables[0].name] if variables else 0.0, amp)
        if point not in ev.points:
            continue
        row = model_rows[ev.points.index(point)]
        for cid in ids:
            case = by_id[cid]
            model = at_clock.get(cid, row[0][1])
            if model is None or case.loop is None or case.control is not Control.FORCE:
                continue
            rec = case.loop
            try:
                measured = process_loop(rec.force_n, rec.displacement_mm, rec.source)
                loops.append(loop_residual(measured, model, rec.time_s, cid, rel_floor))
            except HingelabError:
                continue
    added = ", ".join(
        f"{n} ({', '.join(f'{k} = {v:.3g}' for k, v in p.items())})" for n, p in effects.items()
    )
    of = f"the model with {added} added" if added else "the model as it is"
    return loop_signatures(loops, loss_residual(ev.features(effects), meas), alpha, of)
