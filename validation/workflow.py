"""The model run at measured cases and judged: what ``compare``, ``calibrate`` and the paper check share."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cad.errors import DataError, ParameterError
from model.jsonio import dumps
from model.spec import DesignPoint, ModelSpec, complete_point, describe_point, point_label
from validation.compare import CompareSettings, Comparison, ModelResult
from validation.loop_files import Loop
from validation.measurements import Case


def _check_cases(spec: ModelSpec, cases: Sequence[Case]) -> None:
    """Refuse cases the model cannot be run at, naming the case and the field."""
    for c in cases:
        if c.hinge != spec.kind:
            raise DataError(
                f"case {c.case_id!r}: hinge {c.hinge!r}, but the model is the {spec.kind} hinge"
            )
        try:
            point_of(spec, c)
        except ParameterError as err:
            raise DataError(f"case {c.case_id!r}: {err}") from err


def point_of(spec: ModelSpec, case: Case) -> DesignPoint:
    """The design point of a case, complete over the kind's design variables.

    Raises:
        ParameterError: For a value out of its variable's range.
    """
    return complete_point(spec, DesignPoint(case.amplitude_n, case.values))


def run_model_for_cases(
    spec: ModelSpec,
    cases: Sequence[Case],
    *,
    with_free_play: bool = True,
    service: Any = None,
) -> tuple[dict[str, ModelResult], dict[DesignPoint, Any]]:
    """Run the model's cycle at every (clearance or preload, amplitude) of the cases.

    Through the model service (``model.service.ModelService``; a new one if None): one mesh,
    one factorisation and one pair of condensed configurations per clearance (one for
    every preload of the bearing hinge), reused for every amplitude there; replicates
    share one run. The model's effects (``spec.effects``, e.g. written by
    ``hingelab calibrate``) are switched on. A loop effect that depends on time (a damper)
    is evaluated at each record's own ``time_s`` (``_at_record_clocks``), so replicates at
    different loading rates get different model loops; the metrics stay the protocol
    clock's.

    Returns:
        (case_id → ModelResult, design point → CycleResult).
    """
    from model.service import ModelService

    service = ModelService() if service is None else service
    points = {c.case_id: point_of(spec, c) for c in cases}
    runs: dict[DesignPoint, Any] = {}
    for run in service.run(spec, points.values(), keep_going=False):
        runs[run.point] = run.result
    out = {}
    for c in cases:
        p = points[c.case_id]
        r = runs[p]
        # a stated η (an η-only table, like the paper's) excludes the free play, as
        # `hingelab cycle` reports it; a measured loop includes it (the grips see it)
        free_play = with_free_play and c.loop is not None
        F, d = r.machine_path() if free_play else r.loop_arrays()[:2]
        source = f"model: {describe_point(spec, p)}"
        out[c.case_id] = ModelResult(Loop(F, d, None, source), r.metrics())
    timed = [
        c for c in cases if with_free_play and c.loop is not None and c.loop.time_s is not None
    ]
    if timed:
        _at_record_clocks(spec, timed, points, runs, out, service)
    return out, runs


def _at_record_clocks(
    spec: ModelSpec,
    cases: Sequence[Case],
    points: dict[str, DesignPoint],
    runs: dict[DesignPoint, Any],
    out: dict[str, ModelResult],
    service: Any,
) -> None:
    """Replace the loops of ``cases`` (records with ``time_s``) by the loop at their clock.

    Only when a loop effect depends on time (``validation.evaluate.depends_on_time``, probed
    on the first run's path): the cycle is run without the loop effects, and those are
    applied at the time the record passed each force (``validation.evaluate.record_time``).
    """
    from fe.effects.registry import post_process
    from validation.evaluate import depends_on_time, record_time, split_post_only

    solve, post = split_post_only(spec.effects)
    if not post:
        return
    rate = spec.cycle.force_rate_n_per_s
    F0, d0 = runs[points[cases[0].case_id]].machine_path()
    if not depends_on_time(F0, d0, post, post_process(F0, d0, post, force_rate_n_per_s=rate), rate):
        return
    solve_spec = dataclasses.replace(spec, effects=solve)
    raw: dict[DesignPoint, tuple[Any, Any]] = {}
    for c in cases:
        p = points[c.case_id]
        if p not in raw:
            raw[p] = service.run_point(solve_spec, p).machine_path()
        F, d = raw[p]
        loop = c.loop
        if loop is None or loop.time_s is None:  # not timed: the protocol clock's loop stays
            continue
        t = record_time(F, loop.force_n, loop.time_s, c.case_id)
        source = f"model: {describe_point(spec, p)} at {c.case_id}'s clock"
        d_rec = post_process(F, d, post, time_s=t)
        out[c.case_id] = ModelResult(Loop(F, d_rec, t, source), out[c.case_id].metrics)


def _write_model_loops(
    spec: ModelSpec, runs: dict[DesignPoint, Any], out: Path, free_play: bool
) -> list[str]:
    folder = out / "model_loops"
    folder.mkdir(parents=True, exist_ok=True)
    files = []
    for point, r in runs.items():
        F, d = r.machine_path() if free_play else r.loop_arrays()[:2]
        path = folder / f"{point_label(spec, point)}.csv"
        np.savetxt(
            path,
            np.column_stack([F, d]),
            delimiter=",",
            header="force_N,displacement_mm",
            comments="",
            fmt="%.10g",
        )
        files.append(str(path))
    return files


def compare_and_write(
    spec: ModelSpec,
    data: Any,
    out: Path,
    settings: CompareSettings,
    *,
    free_play: bool = True,
    plots: bool = True,
    service: Any = None,
) -> tuple[Comparison, dict[str, Any]]:
    """Run the model at every case, compare, write ``out/comparison.json``, loops and pictures.

    Args:
        spec: The model (with its effects).
        data: The measurement set (``validation.measurements.MeasurementSet``).
        out: Output folder (created).
        settings: Pass/fail settings.
        free_play: Compare with the model loop including the 4Δr free play traverse.
        plots: Draw the pictures.
        service: The ``model.service.ModelService`` to run the cases through (None: a new
            one, in process, nothing stored; with a store a rerun reads the cycles back,
            with a runner they run as Dask tasks).

    Returns:
        (the comparison, the report written to ``comparison.json``).
    """
    from validation.compare import compare

    t0 = time.perf_counter()
    _check_cases(spec, data.cases)
    models, runs = run_model_for_cases(spec, data.cases, with_free_play=free_play, service=service)
    cmp = compare(models, data, settings)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Any] = {"model_loops": _write_model_loops(spec, runs, out, free_play)}
    if plots:
        from validation.plots import write_comparison_plots

        files.update({k: str(v) for k, v in write_comparison_plots(cmp, out).items()})
    files["comparison_json"] = str(out / "comparison.json")
    report = {
        **cmp.to_dict(),
        "model_loop_free_play": free_play,
        "files": files,
        "wall_s": time.perf_counter() - t0,
    }
    (out / "comparison.json").write_text(dumps(report))
    return cmp, report
