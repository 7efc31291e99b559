"""Model features at the measured design points, with effects, cached.

``ModelEvaluator`` meshes, factorises and condenses the model once per clearance (lazily)
and then runs the cycle for any set of effects (``fe.effects.cycle.run_cycle_with_effects``
with the reused base configurations: effects never refactorise). Effects that act only
after the solve (their ``apply`` is the identity, e.g. ``frame_compliance``) cost no
cycle: the loop computed without them is post-processed. Every run is cached by
(design point, effects), so the baseline and the grid points of a fit are computed once.

**Record clocks.** A loop effect that depends on time (a damper) is evaluated at each
measured record's own clock when the record has ``time_s`` (``clocks``; the time at which
the record passed the model's force on the same ramp, ``fe.effects.history``), else at
the protocol's (``[cycle] force_rate_n_per_s``). The measured features of a design point
are the mean over its records (``validation.candidate_fit.measured_features``), so the
model's are too: one model loop per record, its features averaged over the records of
the row. Records loaded at different rates are therefore best kept apart as design points
(a ``cond_rate_N_per_s`` column in ``cases.csv`` makes the rate part of the design point;
as replicates, their scatter would include the rate's effect). An effect that does not
depend on time (the output is the same on a warped clock, ``depends_on_time``) gives
exactly the protocol-clock numbers, one loop per row, as before.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from cad.errors import DataError, EffectError, HingelabError
from model.spec import ModelSpec
from validation.features import loop_features
from validation.loops import ProcessedLoop, process_loop

FloatArray = npt.NDArray[np.float64]
Effects = Mapping[str, Mapping[str, float]]
Clock = tuple[str, FloatArray | None, FloatArray | None]
"""A record of a design point: (case id, its force (m,) [N], its time (m,) [s]); no time: None."""
logger = logging.getLogger(__name__)


def _key(effects: Effects) -> tuple[tuple[str, tuple[tuple[str, float], ...]], ...]:
    return tuple(
        sorted((n, tuple(sorted((k, float(v)) for k, v in p.items()))) for n, p in effects.items())
    )


def is_post_only(name: str) -> bool:
    """True when the registry effect ``name`` acts only after the solve (``apply`` is identity)."""
    from fe.effects.base import Effect
    from fe.effects.registry import REGISTRY

    return type(REGISTRY[name]).apply is Effect.apply


class ModelEvaluator:
    """Features of a model (with effects) at design points (clearance, amplitude).

    Args:
        spec: The model (its own effects are always on; extra effects add to them).
        points: Design points (clearance [mm], amplitude [N]), in row order; for the bearing
            hinge (preload [N], amplitude [N]).
        increments_per_stage: Increments per load stage of the diagnosis runs (None:
            the model file's).
        clearance_increments: Increments across the free play (None: the model file's).
        service: The ``model.service.ModelService`` that runs the cycles (None: a new
            one keeping every geometry, no store). One with a store reads back what a
            previous run computed; one with a runner computes on Dask (``prefetch``).
        clocks: Per design point, its loop records (``Clock``; ``MeasuredFeatures.clocks``),
            whose clocks a time-dependent loop effect is evaluated at (module docstring);
            None or empty: the protocol's clock.
    """

    def __init__(
        self,
        spec: ModelSpec,
        points: Sequence[tuple[float, float]],
        increments_per_stage: int | None = None,
        clearance_increments: int | None = None,
        service: Any = None,
        clocks: Sequence[Sequence[Clock]] | None = None,
    ) -> None:
        self.spec = spec
        self.points = tuple(points)
        self.clocks = tuple(tuple(c) for c in clocks) if clocks else ()
        if self.clocks and len(self.clocks) != len(self.points):
            raise ValueError(f"{len(self.clocks)} clocks for {len(self.points)} design points")
        self._times: dict[tuple[Any, ...], FloatArray] = {}
        cycle = spec.cycle
        if increments_per_stage is not None:
            cycle = dataclasses.replace(cycle, increments_per_stage=increments_per_stage)
        if clearance_increments is not None:
            cycle = dataclasses.replace(cycle, clearance_increments=clearance_increments)
        self.cycle = cycle
        from model.service import ModelService

        # every clearance's geometry kept: fits revisit them
        self.service = ModelService() if service is None else service
        self._loops: dict[tuple[Any, ...], tuple[FloatArray, FloatArray] | None] = {}
        self.n_cycles = 0
        self.batches: list[int] = []
        """Runs not yet made per ``prefetch`` batch, in order: the widths of the task graph.
        In process a run is counted in the first batch that asks for it (it is made later,
        when ``features`` needs it), as a cluster would have run it there."""
        self._announced: set[tuple[Any, ...]] = set()  # in process: runs counted in a batch
        self.cycle_s = 0.0
        self.setup_s = 0.0

    def set_mu(self, spec: ModelSpec) -> None:
        """Make ``spec`` (the same model with another μ) the model evaluated from now on.

        μ changes no operator, and runs are cached by μ, so the meshes, factorisations,
        condensations and runs already made stay valid.
        """
        self.spec = spec
        self.cycle = dataclasses.replace(self.cycle, mu=spec.cycle.mu)

    def _raw_loop(
        self, point: tuple[float, float], solve_effects: Effects, mu: float | None = None
    ) -> tuple[FloatArray, FloatArray] | None:
        """(F, δ with free play) of the cycle with the solve-side effects; None if it fails."""
        mu = self.cycle.mu if mu is None else float(mu)
        key = (point, _key(solve_effects), mu)
        if key not in self._loops:
            spec, design = self._job(point, solve_effects, mu)
            t0 = time.perf_counter()
            setup0 = self.service.setup_s
            res: Any
            try:
                res = self.service.run_point(spec, design)
            except EffectError:  # a broken user effect: its candidate fails, named
                raise
            except HingelabError as err:  # a refused or non-converged effect value
                res = err
            setup = self.service.setup_s - setup0
            self.setup_s += setup
            self._accept(key, res, time.perf_counter() - t0 - setup)
        return self._loops[key]

    def _job(
        self, point: tuple[float, float], solve_effects: Effects, mu: float
    ) -> tuple[Any, Any]:
        """The (spec, design point) of one raw loop."""
        from model.spec import DesignPoint

        x, amp = point
        spec = dataclasses.replace(
            self.spec,
            cycle=dataclasses.replace(self.cycle, amplitude_n=amp, mu=mu),
            effects=solve_effects,
        )
        variables = self.spec.hinge_kind.design_variables[:1]
        return spec, DesignPoint(amp, {v.name: x for v in variables})

    def prefetch(self, requests: Sequence[tuple[Effects, float | None]]) -> None:
        """Compute the loops ``features`` will need for each (effects, μ), as one batch.

        Only with a service that has a runner (``model.cluster.ClusterRunner``): the
        missing (design point, effects, μ) runs go to the Dask workers together, each
        worker running the geometries it holds first; the loops they return are the ones
        ``features`` would have computed, kept in the same cache. In process this only
        counts the batch (``batches``; the runs are made when asked for, as before). A
        request whose effects are refused,
        or a run that fails, is left to ``features`` (which words the failure).
        ``prefetch_together`` makes one batch of several evaluators' requests.

        Args:
            requests: (extra effects, μ or None) pairs, as ``features`` takes them.
        """
        prefetch_together([(self, requests)])

    def _wanted(
        self, requests: Sequence[tuple[Effects, float | None]]
    ) -> dict[tuple[Any, ...], tuple[Any, Any]]:
        """The runs ``requests`` need that are not cached: key → (spec, design point)."""
        from fe.effects.registry import validate_effects

        wanted: dict[tuple[Any, ...], tuple[Any, Any]] = {}
        for effects, mu in requests:
            try:
                every = validate_effects({**self.spec.effects, **effects})
            except HingelabError:
                continue
            solve = {n: p for n, p in every.items() if not is_post_only(n)}
            m = self.cycle.mu if mu is None else float(mu)
            for point in self.points:
                key = (point, _key(solve), m)
                if key not in self._loops and key not in wanted:
                    wanted[key] = self._job(point, solve, m)
        return wanted

    def _accept(self, key: tuple[Any, ...], res: Any, seconds: float) -> None:
        """Keep the outcome of run ``key``: a cycle, or the error it raised (a worker's or ours).

        A cycle is kept as its machine path (the free play crossed at zero force, as the
        grips see it: no chord area); a refused or non-converged run as None (logged); a
        user effect's error is left to ``features``, which names it.
        """
        from validation.synth import machine_path

        if not isinstance(res, BaseException):
            self._loops[key] = machine_path(res)
            self.n_cycles += 1
        elif isinstance(res, HingelabError) and not isinstance(res, EffectError):
            logger.info("cycle failed at %s with %s: %s", key[0], dict(key[1]), res)
            self._loops[key] = None
            self.n_cycles += 1
        self.cycle_s += seconds

    def features(self, effects: Effects, mu: float | None = None) -> FloatArray:
        """Return the features at every design point, shape (n_points, 3); NaN rows where it fails.

        Args:
            effects: Extra effects (name → parameter → value), added to the model's own.
            mu: Friction coefficient of the runs (None: the model file's). μ changes no
                operator, so every value reuses the same factorisation and condensation.
        """
        out = np.full((len(self.points), 3), np.nan)
        for i, row in enumerate(self.record_loops(effects, mu)):
            feats = [loop_features(loop) for _, loop in row if loop is not None]
            if len(feats) == len(row) and feats:
                out[i] = average_features(feats)
        return out

    def loops(self, effects: Effects, mu: float | None = None) -> list[ProcessedLoop | None]:
        """Return the processed model loop at every design point; None where it fails.

        With a time-dependent loop effect and record clocks, the loop at the row's first
        record's clock (``record_loops`` has them all).

        Args:
            effects: Extra effects, as in ``features``.
            mu: Friction coefficient, as in ``features``.
        """
        return [row[0][1] for row in self.record_loops(effects, mu)]

    def record_loops(
        self, effects: Effects, mu: float | None = None
    ) -> list[list[tuple[str | None, ProcessedLoop | None]]]:
        """Return, per design point, (case id, processed model loop) per record clock.

        One entry (case id None) at the protocol's clock when no loop effect depends on
        time or the row has no clocks; else one per record of the row, each at that
        record's ``time_s`` (the protocol's clock for a record without it).

        Raises:
            DataError: A record whose ramps the model's path cannot be timed on.
        """
        from fe.effects.registry import post_process, validate_effects

        every = validate_effects({**self.spec.effects, **effects})
        solve = {n: p for n, p in every.items() if not is_post_only(n)}
        post = {n: p for n, p in every.items() if is_post_only(n)}
        self.prefetch([(effects, mu)])  # on a cluster: every point at once
        out: list[list[tuple[str | None, ProcessedLoop | None]]] = []
        for i, point in enumerate(self.points):
            raw = self._raw_loop(point, solve, mu)
            if raw is None:
                out.append([(None, None)])
                continue
            F, d = raw
            rate = self.cycle.force_rate_n_per_s  # the protocol's clock
            d2 = post_process(F, d, post, force_rate_n_per_s=rate) if post else d
            clocks = self.clocks[i] if self.clocks else ()
            if not clocks or not post or not depends_on_time(F, d, post, d2, rate):
                out.append([(None, _processed(F, d2, f"model {point}"))])
                continue
            row: list[tuple[str | None, ProcessedLoop | None]] = []
            for cid, ref_F, ref_t in clocks:
                if ref_F is None or ref_t is None:
                    row.append((cid, _processed(F, d2, f"model {point}")))
                    continue
                tkey = (point, _key(solve), self.cycle.mu if mu is None else float(mu), cid)
                if tkey not in self._times:
                    self._times[tkey] = record_time(F, ref_F, ref_t, cid)
                d_rec = post_process(F, d, post, time_s=self._times[tkey])
                row.append((cid, _processed(F, d_rec, f"model {point} at {cid}'s clock")))
            out.append(row)
        return out


def prefetch_together(
    batches: Sequence[tuple[ModelEvaluator, Sequence[tuple[Effects, float | None]]]],
) -> None:
    """``ModelEvaluator.prefetch`` of several evaluators' requests as one batch per service.

    Evaluators of one model on two meshes (``diagnose``'s coarse-to-fine screen) share a
    service: their runs go to the workers together, not one evaluator after the other.
    Each evaluator records the width of the batch it took part in (``batches``).
    """
    by_service: dict[int, list[tuple[ModelEvaluator, tuple[Any, ...], tuple[Any, Any]]]] = {}
    services: dict[int, Any] = {}
    for ev, requests in batches:
        for key, job in ev._wanted(requests).items():
            by_service.setdefault(id(ev.service), []).append((ev, key, job))
            services[id(ev.service)] = ev.service
    for sid, jobs in by_service.items():
        service = services[sid]
        lazy = getattr(service, "runner", None) is None
        if lazy:  # a run announced by an earlier batch and not made yet is not counted again
            jobs = [(ev, key, job) for ev, key, job in jobs if key not in ev._announced]
            for ev, key, _ in jobs:
                ev._announced.add(key)
        for ev in {id(e): e for e, _, _ in jobs}.values():
            ev.batches.append(len(jobs))
        if lazy:
            continue  # in process: each run is made when ``features`` asks for it
        t0 = time.perf_counter()
        outcomes = service.run_jobs([job for _, _, job in jobs])
        share = (time.perf_counter() - t0) / len(jobs)
        for (ev, key, _), res in zip(jobs, outcomes, strict=True):
            ev._accept(key, res, share)


def _processed(F: FloatArray, d: FloatArray, source: str) -> ProcessedLoop | None:
    try:
        return process_loop(F, d, source)
    except HingelabError:
        return None


def average_features(feats: Sequence[FloatArray]) -> FloatArray:
    """The mean of the features of a row's model loops, as measured replicates are averaged.

    Identical rows (no time-dependent effect) give the first exactly, not a rounded mean.
    """
    first = np.asarray(feats[0], dtype=np.float64)
    if all(np.array_equal(first, f, equal_nan=True) for f in feats[1:]):
        return first
    return np.asarray(np.mean(np.asarray(feats, dtype=np.float64), axis=0), dtype=np.float64)


def depends_on_time(
    force_n: FloatArray,
    disp_mm: FloatArray,
    post: Effects,
    at_protocol: FloatArray,
    rate_n_per_s: float,
) -> bool:
    """True when the loop effects ``post`` give another loop on another clock.

    The effects are evaluated once more on a warped protocol clock (t (1 + t/t_end):
    other rates, other ratios) and compared with ``at_protocol`` (their output on the
    protocol's clock): an effect that never reads ``time_s`` gives the same array.
    """
    from fe.effects.history import protocol_time
    from fe.effects.registry import post_process

    t = protocol_time(force_n, rate_n_per_s)
    end = float(t[-1]) if t.size and t[-1] > 0 else 1.0
    warped = post_process(force_n, disp_mm, post, time_s=t * (1.0 + t / end))
    return not np.array_equal(warped, at_protocol)


def record_time(
    force_n: FloatArray, ref_force_n: FloatArray, ref_time_s: FloatArray, case_id: str
) -> FloatArray:
    """The time of a model path on record ``case_id``'s clock (``time_from_reference``).

    Raises:
        DataError: Naming the case, when its ramps cannot time the model's path.
    """
    from fe.effects.history import time_from_reference

    try:
        return time_from_reference(force_n, ref_force_n, ref_time_s)
    except DataError as err:
        raise DataError(f"case {case_id!r}: {err}") from err


def split_post_only(effects: Effects) -> tuple[Effects, Effects]:
    """(effects that change the solve, effects that act on the loop only), in registry order."""
    from fe.effects.registry import validate_effects

    every = validate_effects(effects)
    solve = {n: p for n, p in every.items() if not is_post_only(n)}
    post = {n: p for n, p in every.items() if is_post_only(n)}
    return solve, post


def loop_at_record_times(
    spec: ModelSpec,
    point: Any,
    ref_force_n: FloatArray,
    ref_time_s: FloatArray,
    service: Any = None,
) -> tuple[FloatArray, FloatArray]:
    """The model's loop with its loop effects evaluated at a measured record's clock.

    The cycle is run (through ``service``, a ``model.service.ModelService``) with the
    effects that change the solve; its machine path (free play crossed at zero force) gets
    the time at which the record passed the same force on the same ramp
    (``fe.effects.history.time_from_reference``), and the loop effects (``post``) are
    applied at those times. Without a time-dependent effect this is the loop the spec's
    own run gives. ``compare`` does the same per case (``validation.workflow``), the
    evaluator per record clock (``ModelEvaluator.record_loops``).

    Args:
        spec: The model (its effects on).
        point: The case's design point (``model.spec.DesignPoint``).
        ref_force_n: The record's force, shape (m,) [N].
        ref_time_s: The record's time, shape (m,) [s].
        service: A ``ModelService`` to reuse (None: a new one).

    Returns:
        (force (n,) [N], displacement (n,) [mm]) of the model's path.

    Raises:
        DataError: A record with fewer load ramps than the model's path.
        EffectError: A user's effect that fails.
    """
    from fe.effects.history import time_from_reference
    from fe.effects.registry import post_process
    from model.service import ModelService

    solve, post = split_post_only(spec.effects)
    run_spec = dataclasses.replace(spec, effects=solve)
    result = (service or ModelService()).run_point(run_spec, point)
    F, d = result.machine_path()
    if not post:
        return F, d
    t = time_from_reference(F, ref_force_n, ref_time_s)
    return F, post_process(F, d, post, time_s=t)
