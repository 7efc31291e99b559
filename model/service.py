"""The model service: a specification and design points in, one ``CycleResult`` per point out.

Every command that runs the model (``cycle``, ``sweep``, ``compare``, ``synth``,
``diagnose``, ``calibrate``, the paper validation) goes through ``ModelService``:

* each geometry (the kind's structure, ``HingeKind.structure``, + mesh settings) is built, meshed,
  assembled, factorised and condensed once (``prepare``; the nodal compliances are kept
  on disk by the mesh's content hash when ``cache_dir`` is given) and reused for every
  amplitude, μ and effect run on it;
* every point's result is keyed by ``model.spec.result_key``; with a ``ResultStore``
  a point whose key is stored is read back instead of computed (a rerun with identical
  inputs costs nothing; any changed input is another key and recomputes), and a newly
  computed point is stored atomically the moment it finishes, before ``on_result`` is
  called;
* duplicate points are run once;
* a failing point becomes a failed ``PointRun`` (with its error and partial loop) and the
  others go on (``keep_going``); a failing geometry fails its points the same way.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cad.errors import ConvergenceError, HingelabError, ParameterError
from fe.cycle.result import CycleResult
from fe.kinds import Built
from fe.linalg.threads import job_threads
from mesh.meshed import MeshedHinge
from model.code import code_version
from model.spec import (
    DesignPoint,
    ModelSpec,
    content_hash,
    geometry_folder,
    geometry_key,
    hinge_at,
    point_label,
    resolve_structural,
    result_key,
    structure_at,
)
from model.store import ResultStore

logger = logging.getLogger(__name__)

FAILURES = (HingelabError, ArithmeticError, RuntimeError, ValueError, MemoryError)
"""What makes one point fail while the others go on (``ModelService.run``)."""


@dataclass
class Prepared:
    """One geometry, built by its kind, ready for cycles.

    Attributes:
        key: Its geometry key.
        built: What the kind built (``fe.kinds.Built``: its system, mesh and caches).
        setup_s: Wall time of building, meshing and factorising [s].
    """

    key: str
    built: Built
    setup_s: float = 0.0

    @property
    def system(self) -> Any:
        """The kind's system object."""
        return self.built.system

    @property
    def meshed(self) -> MeshedHinge | None:
        """The CAD model, mesh and files (None for a kind without a mesh)."""
        return self.built.meshed


@dataclass(frozen=True)
class PointRun:
    """What happened at one design point.

    Attributes:
        point: The design point.
        key: Its result key.
        result: The cycle (None if it failed).
        error: Why it failed (None if it did not).
        cached: True if the result was read from the store, not computed.
        prepared: The geometry it ran on (None if read from the store without one).
        partial: The increments that converged before a failure (or None).
        wall_s: Wall time of this point [s] (0 when cached).
    """

    point: DesignPoint
    key: str
    result: CycleResult | None
    error: str | None = None
    cached: bool = False
    prepared: Prepared | None = None
    partial: CycleResult | None = None
    wall_s: float = 0.0

    @property
    def ok(self) -> bool:
        """True if the point has a result."""
        return self.result is not None


def check_spec(spec: ModelSpec) -> None:
    """Refuse a specification the service cannot run, naming what is wrong.

    Raises:
        ParameterError: For an effect that does not act on the model's hinge kind
            (``fe.effects.base.Effect.applies_to``), a combination the kind refuses
            (``HingeKind.check``), or a user's effect file that is missing or changed.
    """
    from fe.effects.registry import REGISTRY

    spec.register_sources()  # this spec's versions of its files (another may have replaced them)
    kind = spec.hinge_kind
    other = sorted(
        n for n in spec.effects if n in REGISTRY and not REGISTRY[n].applies_to(kind.name)
    )
    if other:
        fitting = sorted(n for n in REGISTRY if REGISTRY[n].applies_to(kind.name))
        raise ParameterError(
            f"effects {other} do not act on the {kind.title}; effects that do: {fitting}"
        )
    kind.check(spec.hinge, spec.effects)


def _ran(err: BaseException | None) -> bool:
    """Whether a job's cycle ran to an end: a result, or an increment that did not converge.

    ``n_computed`` counts those, here and on a cluster alike (a candidate value whose
    cycle does not converge counted in process and not on a cluster: the paper's
    validation 540 against 539). A refused spec, a failed set-up or a lost worker is not
    a cycle computed.
    """
    return err is None or isinstance(err, ConvergenceError)


class ModelService:
    """Run a model at design points, preparing each geometry once.

    Args:
        store: Where results are kept by key (None: nothing is kept between runs).
        cache_dir: Where nodal compliances are kept by mesh hash, in a subfolder per code
            (``model.code.code_version``; None: in memory only).
        geometry_dir: Folder for a geometry's STEP, mesh and picture files, given its
            folder name (``model.spec.geometry_folder``, e.g. ``c0.100-5e6f7a8b9c``: the
            label and the geometry key; None: no files).
        max_geometries: Prepared geometries kept in memory (the least recently used is
            dropped); None keeps all (a diagnosis revisits every clearance).
        runner: A ``model.cluster.ClusterRunner``: the points ``run`` and ``run_jobs``
            compute go to its Dask workers (None: computed in this process).

    Attributes:
        n_computed: Cycles computed (here or on the runner's workers) since it was made:
            those that gave a result or stopped at an increment that did not converge.
        n_cached: Cycles read back from the store.
    """

    def __init__(
        self,
        *,
        store: ResultStore | None = None,
        cache_dir: Path | None = None,
        geometry_dir: Callable[[str], Path] | None = None,
        max_geometries: int | None = None,
        runner: Any = None,
    ) -> None:
        self.store = store
        self.runner = runner
        self.cache_dir = cache_dir
        self.geometry_dir = geometry_dir
        self.max_geometries = max_geometries
        self._prepared: OrderedDict[str, Prepared] = OrderedDict()
        self.n_computed = 0
        self.n_cached = 0
        self._remote: dict[str, CycleResult | BaseException] = {}
        self.setup_s = 0.0
        self.cycle_s = 0.0

    def prepare(self, spec: ModelSpec, point: DesignPoint) -> Prepared:
        """Build, mesh and factorise the geometry of ``spec`` at ``point`` (memoised)."""
        check_spec(spec)
        spec = resolve_structural(spec)
        key = geometry_key(spec, point)
        if key in self._prepared:
            self._prepared.move_to_end(key)
            return self._prepared[key]
        t0 = time.perf_counter()
        out = None if self.geometry_dir is None else self.geometry_dir(geometry_folder(spec, point))
        # cached compliances are the code's that computed them: one folder per code
        cache = (
            None
            if self.cache_dir is None
            else self.cache_dir / f"code-{content_hash(code_version())[:12]}"
        )
        with job_threads():  # the same numbers in process as on a worker
            built = spec.hinge_kind.build(structure_at(spec, point), spec.mesh, out, cache)
        prepared = Prepared(key, built)
        prepared.setup_s = time.perf_counter() - t0
        self.setup_s += prepared.setup_s
        self._prepared[key] = prepared
        if self.max_geometries is not None:
            while len(self._prepared) > self.max_geometries:
                self._prepared.popitem(last=False)
        return prepared

    def cached(self, spec: ModelSpec, point: DesignPoint) -> CycleResult | None:
        """The stored result at ``point``, or None."""
        if self.store is None:
            return None
        return self.store.get(result_key(spec, point))

    def run_point(
        self,
        spec: ModelSpec,
        point: DesignPoint,
        *,
        progress: Callable[[int, int], None] | None = None,
    ) -> CycleResult:
        """Return the cycle at ``point`` (from the store, or computed and stored).

        Raises:
            ParameterError: A parameter out of range (named).
            ConvergenceError: As ``fe.general.cycle.run_cycle`` (its ``partial`` kept).
        """
        check_spec(spec)
        spec = resolve_structural(spec)
        key = result_key(spec, point)
        if self.store is not None:
            hit = self.store.get(key)
            if hit is not None:
                self.n_cached += 1
                return hit
        prepared = self.prepare(spec, point)
        result = self._compute(spec, point, prepared, progress)
        if self.store is not None:
            self.store.put(key, result)
        return result

    def _compute(
        self,
        spec: ModelSpec,
        point: DesignPoint,
        prepared: Prepared,
        progress: Callable[[int, int], None] | None,
    ) -> CycleResult:
        settings = dataclasses.replace(spec.cycle, amplitude_n=point.amplitude_n)
        t0 = time.perf_counter()
        try:
            with job_threads():  # the same numbers in process as on a worker
                result = spec.hinge_kind.run(
                    prepared.built, hinge_at(spec, point), settings, spec.effects, progress
                )
        except ConvergenceError:
            self.n_computed += 1  # as ``_ran`` counts it on a cluster
            raise
        finally:
            self.cycle_s += time.perf_counter() - t0
        self.n_computed += 1
        return result

    def run(
        self,
        spec: ModelSpec,
        points: Iterable[DesignPoint],
        *,
        on_result: Callable[[PointRun], None] | None = None,
        keep_going: bool = True,
    ) -> list[PointRun]:
        """Run every distinct point, one geometry at a time.

        Args:
            spec: The model.
            points: Design points; duplicates run once (the list returned has one entry each).
            on_result: Called with each point's outcome the moment it is known (after the
                result is stored).
            keep_going: Record a failing point and go on (else re-raise its error).

        Returns:
            One ``PointRun`` per distinct point, grouped by geometry in first-seen order.
        """
        check_spec(spec)
        spec = resolve_structural(spec)
        unique: dict[str, DesignPoint] = {}
        for p in points:
            unique.setdefault(result_key(spec, p), p)
        groups: dict[str, list[tuple[str, DesignPoint]]] = {}
        for key, p in unique.items():
            groups.setdefault(geometry_key(spec, p), []).append((key, p))
        if self.runner is not None:  # the misses computed on the cluster, then read below
            pairs = [(key, p) for members in groups.values() for key, p in members]
            outcomes = self.run_jobs([(spec, p) for _, p in pairs])
            self._remote = {key: o for (key, _), o in zip(pairs, outcomes, strict=True)}
        out: list[PointRun] = []
        for members in groups.values():
            for key, p in members:
                run = self._one(spec, key, p, keep_going)
                out.append(run)
                if on_result is not None:
                    on_result(run)
        return out

    def _one(self, spec: ModelSpec, key: str, p: DesignPoint, keep_going: bool) -> PointRun:
        remote = self._remote.pop(key, None)
        if isinstance(remote, CycleResult):  # computed on the runner's cluster in this call
            return PointRun(p, key, remote, cached=False)
        if isinstance(remote, BaseException):
            return self._failed(spec, key, p, remote, None, 0.0, keep_going)
        hit = None if self.store is None else self.store.get(key)
        if hit is not None:
            self.n_cached += 1
            prepared = self._prepared.get(geometry_key(spec, p))
            return PointRun(p, key, hit, cached=True, prepared=prepared)
        t0 = time.perf_counter()
        prepared = None
        try:
            prepared = self.prepare(spec, p)
            result = self._compute(spec, p, prepared, None)
            if self.store is not None:
                self.store.put(key, result)
            return PointRun(p, key, result, prepared=prepared, wall_s=time.perf_counter() - t0)
        except FAILURES as err:
            return self._failed(spec, key, p, err, prepared, time.perf_counter() - t0, keep_going)

    def _failed(
        self,
        spec: ModelSpec,
        key: str,
        p: DesignPoint,
        err: BaseException,
        prepared: Prepared | None,
        wall_s: float,
        keep_going: bool,
    ) -> PointRun:
        if not keep_going or not isinstance(err, FAILURES):
            raise err
        partial = getattr(err, "partial", None)
        where = "geometry" if prepared is None else "point"
        msg = f"{where} failed: {type(err).__name__}: {err}"
        logger.error("%s: %s", point_label(spec, p), msg)
        return PointRun(
            p,
            key,
            None,
            error=msg,
            prepared=prepared,
            partial=partial if isinstance(partial, CycleResult) else None,
            wall_s=wall_s,
        )

    def run_jobs(
        self, jobs: Sequence[tuple[ModelSpec, DesignPoint]]
    ) -> list[CycleResult | BaseException]:
        """Each job's cycle, or the error that stopped it; the jobs are independent.

        A stored result is read back; the others are computed, each distinct key once, on
        the runner's Dask workers (each the geometries it holds first) or else here, one
        geometry after another, and stored the moment they arrive. The specs may differ
        (μ, effects): one prepared geometry serves every spec that shares it.

        Args:
            jobs: (spec, design point) pairs.

        Returns:
            One entry per job, in order: its ``CycleResult`` or the exception it raised
            (a refused spec too).
        """
        out: list[CycleResult | BaseException | None] = [None] * len(jobs)
        resolved: list[tuple[ModelSpec, DesignPoint]] = []
        first: dict[str, int] = {}  # result key → first job with it
        keys: list[str] = []
        for i, (spec, p) in enumerate(jobs):
            try:
                check_spec(spec)
                spec = resolve_structural(spec)
                key = result_key(spec, p)
            except FAILURES as err:
                out[i], key = err, f"refused-{i}"
            resolved.append((spec, p))
            keys.append(key)
            if out[i] is not None or key in first:
                continue
            hit = None if self.store is None else self.store.get(key)
            if hit is not None:
                self.n_cached += 1
                out[i] = hit
            first[key] = i
        todo = [i for i in first.values() if out[i] is None]
        todo.sort(key=lambda i: geometry_key(*resolved[i]))  # one geometry after another
        if self.runner is not None:

            def arrived(j: int, result: CycleResult | None, err: BaseException | None) -> None:
                i = todo[j]
                if _ran(err):
                    self.n_computed += 1
                if result is not None and self.store is not None:
                    self.store.put(keys[i], result)
                out[i] = result if result is not None else err

            self.runner.run([resolved[i] for i in todo], arrived)
        else:
            for i in todo:
                try:
                    out[i] = self.run_point(*resolved[i])
                except FAILURES as err:
                    out[i] = err
        done = [out[first.get(keys[i], i)] if out[i] is None else out[i] for i in range(len(jobs))]
        return [o if o is not None else RuntimeError("job not run") for o in done]

    def summary(self, spec: ModelSpec, point: DesignPoint, result: CycleResult) -> dict[str, Any]:
        """The kind's summary of a cycle at ``point`` (``HingeKind.summary``, geometry prepared here)."""
        spec = resolve_structural(spec)
        built = self.prepare(spec, point).built
        with job_threads():  # part of the job: as on a worker (``run_summarized``)
            return spec.hinge_kind.summary(built, hinge_at(spec, point), result)

    def run_summarized(
        self, jobs: Sequence[tuple[ModelSpec, DesignPoint]]
    ) -> list[tuple[CycleResult, dict[str, Any]] | BaseException]:
        """Each job's cycle and the kind's summary of it, or the error that stopped it.

        Like ``run_jobs`` (on the runner's workers, or here), but the summary needs the
        prepared geometry, so it is made where the cycle ran. In this process the store is
        used as by ``run_point``; the workers' cycles are not stored (a stored cycle has
        no geometry beside it to summarise).

        Args:
            jobs: (spec, design point) pairs, each run once.
        """
        out: list[tuple[CycleResult, dict[str, Any]] | BaseException | None] = [None] * len(jobs)
        if self.runner is not None:

            def arrived(i: int, done: Any, err: BaseException | None) -> None:
                if _ran(err):
                    self.n_computed += 1
                out[i] = done if err is None else err

            self.runner.run(list(jobs), arrived, summarize=True)
        else:
            for i, (spec, p) in enumerate(jobs):
                try:
                    check_spec(spec)
                    result = self.run_point(spec, p)
                    out[i] = (result, self.summary(spec, p, result))
                except FAILURES as err:
                    out[i] = err
        return [o if o is not None else RuntimeError("job not run") for o in out]


def design_points(
    values: Iterable[Mapping[str, float]], amplitudes_n: Iterable[float]
) -> list[DesignPoint]:
    """The full factorial design values × amplitude, duplicates removed, in order.

    Args:
        values: Design-variable values of each level, e.g. ``[{"clearance_mm": 0.1}]``.
        amplitudes_n: Force amplitudes [N].
    """
    amps = list(amplitudes_n)
    points = [DesignPoint(a, v) for v in values for a in amps]
    return list(dict.fromkeys(points))
