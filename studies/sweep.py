"""Design sweeps: every (design value, amplitude) point of a grid, traced, resumable, on Dask.

Points run through the model service (``model.service``): each geometry (a clearance of
the general hinge; one for every preload of the bearing hinge) is meshed, factorised and
condensed once and every amplitude runs on it; each point's result is
stored by its content key (``results/``) the moment it finishes and recorded in the
trace right after, by the driver, one point at a time. So an interrupted sweep keeps
every finished point, and a rerun of the same command computes only what is missing;
a rerun with another μ, mesh, protocol or effect has other keys and recomputes (the
trace keeps the earlier points; ``table.csv`` holds only this run's). Duplicate levels
run once. A point that fails is recorded with its error (and its partial loop when the
solver gave one) and the sweep goes on.

With ``workers > 1`` the points run on a Dask ``LocalCluster`` of worker processes, all
points of one geometry on the same worker (one preparation per geometry). With a
``scheduler`` address they run on that existing Dask cluster instead: the workers need
only the installed package; each point's cycle comes back to this process, which stores
it, writes its files and records it (the geometry files stay with the workers).

A sweep is a grid of the hinge kind's design variable (``fe.kinds.DesignVariable``: the
general hinge's clearance, the bearing hinge's preload, a plug-in kind's own) × amplitude,
or any list of (design value, amplitude) points (``points``: a Latin hypercube or central
composite design of a study file, ``studies.study_file``), on the default hinge of a
registered kind or on any ``ModelSpec`` (``model``). ``plan_sweep`` says, without
meshing anything, which points are done, stored, failed before, or still to run.

Layout of ``out``::

    trace.sqlite                    the trace (rsm.trace schema); solver_json holds the result key
    table.csv                       one row per ok point of this run: point_id, parameters, results
    results/KEY.npz                 each computed cycle, by result key (safe to delete: recomputed)
    geometry/c0.100-5e6f7a8b9c/     hinge.step, mesh.msh, mesh.vtu, mesh.png: the geometry's label
                                    (``base`` for a kind whose design variable does not change the
                                    mesh) and its geometry key (another mesh: another folder)
    cache/                          nodal compliances by mesh content hash (safe to delete)
    points/c0.100_F300-1f2e3d4c5b/  loop.csv, loop.png, result.json (with the full result key):
                                    the point's label and its result key, so a rerun with another
                                    μ, mesh, protocol or effect never overwrites an earlier point's
                                    files (``model.spec.point_folder``)
    commands.jsonl                  every command that wrote into the folder (the report shows it)
"""

from __future__ import annotations

import enum
import logging
import sqlite3
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cad.errors import ParameterError
from fe.cycle.protocol import DEFAULT_MU
from fe.kinds import DEFAULT_KIND, HingeKind, hinge_kind
from mesh.settings import MeshSettings
from studies.options import params_with
from studies.sweep_points import point_record, sweep_service

if TYPE_CHECKING:
    from model.service import ModelService
    from model.spec import DesignPoint, ModelSpec

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class SweepSettings:
    """A sweep of a hinge kind over its design variable × amplitude.

    Attributes:
        levels: Levels of the kind's design variable (the general hinge's clearance [mm],
            the bearing hinge's preload [N]); None: the variable's ``study_levels``.
        amplitudes_n: Force amplitudes [N].
        mu: Friction coefficient.
        increments_per_stage: Increments per half cycle at zero clearance.
        clearance_increments: Increments per half cycle with clearance (see CycleSettings).
        mesh: Mesh settings.
        workers: Dask worker processes; 1 runs in this process.
        study: Study name in the trace.
        points: Explicit (level, amplitude [N]) points; when given they replace the grid
            (``levels`` × ``amplitudes_n``).
        model: The model (``model.spec.ModelSpec``) to run instead of the default hinge of
            kind ``hinge`` with ``mu``, the increments, ``mesh`` and ``hinge_options``.
        scheduler: Address of an existing Dask scheduler (``tcp://host:8786``); None runs
            in this process or on a private LocalCluster (``workers``).
        hinge: A registered hinge kind (``fe.kinds``), when no ``model``.
        hinge_options: Parameter overrides of that default hinge, as (field, value) pairs
            (e.g. the bearing hinge's ``interfaces``).
        check_increments: After the points, run the clearance point of the largest
            amplitude at doubled clearance increments and warn if η moved by more than
            ``studies.convergence.DOUBLED_TOL`` (one extra cycle at twice the increments;
            measured cost on the coarse mesh: 0.8 s at 120 increments, after 0.4 s at 60).
    """

    levels: tuple[float, ...] | None = None
    amplitudes_n: tuple[float, ...] = (100.0, 200.0, 300.0, 400.0, 500.0)
    mu: float = DEFAULT_MU
    increments_per_stage: int = 20
    clearance_increments: int = 60
    mesh: MeshSettings = field(default_factory=MeshSettings)
    workers: int = 1
    study: str = "general_hinge"
    points: tuple[tuple[float, float], ...] = ()
    model: ModelSpec | None = None
    scheduler: str | None = None
    hinge: str = DEFAULT_KIND
    hinge_options: tuple[tuple[str, Any], ...] = ()
    check_increments: bool = True

    def __post_init__(self) -> None:
        if not self.points and (not self.grid_levels() or not self.amplitudes_n):
            raise ParameterError(
                f"a sweep needs at least one level and one amplitude, got {self.levels} "
                f"and {self.amplitudes_n}"
            )
        if not 1 <= self.workers <= 64:
            raise ParameterError(f"--workers must be in [1, 64], got {self.workers}")
        self.spec()  # every parameter is checked now, before anything is meshed
        self.design_points()

    def spec(self) -> ModelSpec:
        """The ``model.spec.ModelSpec`` of the sweep (the design variable is set per point)."""
        from model.service import check_spec

        if self.model is not None:
            check_spec(self.model)
            return self.model
        from fe.cycle.protocol import CycleSettings
        from model.spec import ModelSpec

        cycle = CycleSettings(
            mu=self.mu,
            increments_per_stage=self.increments_per_stage,
            clearance_increments=self.clearance_increments,
        )
        kind = hinge_kind(self.hinge)
        spec = ModelSpec(kind.name, params_with(kind, dict(self.hinge_options)), self.mesh, cycle)
        check_spec(spec)
        return spec

    def grid_levels(self) -> tuple[float, ...]:
        """The levels of the grid: ``levels``, or the design variable's study levels."""
        if self.levels is not None:
            return self.levels
        variables = self._kind().design_variables
        return variables[0].study_levels if variables else (0.0,)

    def _kind(self) -> HingeKind:
        return self.spec().hinge_kind if self.model is not None else hinge_kind(self.hinge)

    def design_points(self) -> list[DesignPoint]:
        """The distinct design points (the grid level-major, or ``points``).

        Raises:
            ParameterError: For a value out of its design variable's range, named with it.
        """
        from model.spec import DesignPoint, complete_point

        spec = self.spec()
        variables = spec.hinge_kind.design_variables
        pairs = self.points or tuple((x, a) for x in self.grid_levels() for a in self.amplitudes_n)
        points = [DesignPoint(a, {variables[0].name: x} if variables else {}) for x, a in pairs]
        for p in points:
            complete_point(spec, p)  # checks each value against its range
        return list(dict.fromkeys(points))


def trace_status(db: Path, study: str) -> tuple[dict[str, int], set[str]]:
    """Return (result key → point id of ``ok`` points, keys whose points only failed) of a study.

    Raises:
        DataError: If ``db`` exists but is not a readable trace.
    """
    import json

    from cad.errors import DataError

    if not db.exists():
        return {}, set()
    try:
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
        try:
            rows = con.execute(
                "SELECT p.id, p.status, p.solver_json FROM points p JOIN studies s "
                "ON p.study_id = s.id WHERE s.name = ? ORDER BY p.id",
                (study,),
            ).fetchall()
        finally:
            con.close()
    except sqlite3.Error as err:
        raise DataError(f"{db}: not a readable hingelab trace ({err})") from err
    ok: dict[str, int] = {}
    failed: set[str] = set()
    for pid, status, solver in rows:
        key = json.loads(solver).get("result_key")
        if not key:
            continue
        if status == "ok":
            ok[key] = pid
        else:
            failed.add(key)
    return ok, failed - set(ok)


def traced_keys(db: Path, study: str) -> dict[str, int]:
    """Return result key → point id of the points the trace holds as ``ok`` for a study."""
    return trace_status(db, study)[0]


class PointState(enum.StrEnum):
    """Where a sweep point stands before a run."""

    DONE = "done"
    """In the trace as ok with the same result key: not run again."""
    STORED = "stored"
    """In ``results/`` (finished by an interrupted run): read back, not computed."""
    FAILED = "failed"
    """Failed in an earlier run: run again (``--retry-failed`` runs only these)."""
    TODO = "todo"
    """Never run: computed."""


@dataclass(frozen=True)
class PlannedPoint:
    """One point of a sweep and what a run would do with it.

    Attributes:
        point: The ``model.spec.DesignPoint``.
        key: Its result key.
        state: Done, stored, failed before, or to do.
        point_id: Its trace id when done.
    """

    point: DesignPoint
    key: str
    state: PointState
    point_id: int | None = None


def plan_sweep(settings: SweepSettings, out: Path) -> list[PlannedPoint]:
    """Say what a run would do at every point, without meshing or writing anything."""
    from model.spec import result_key
    from model.store import ResultStore

    spec = settings.spec()
    ok, failed = trace_status(out / "trace.sqlite", settings.study)
    store = ResultStore(out / "results")
    plan = []
    for p in settings.design_points():
        key = result_key(spec, p)
        if key in ok:
            plan.append(PlannedPoint(p, key, PointState.DONE, ok[key]))
        elif key in store:
            plan.append(PlannedPoint(p, key, PointState.STORED))
        elif key in failed:
            plan.append(PlannedPoint(p, key, PointState.FAILED))
        else:
            plan.append(PlannedPoint(p, key, PointState.TODO))
    return plan


@dataclass(frozen=True)
class SweepOutcome:
    """What a sweep did.

    Attributes:
        ok: Points computed successfully in this run.
        failed: Points that failed in this run (recorded with their error).
        skipped: Points already in the trace as ok with the same result key (not recomputed).
        db: The trace database.
        table: The table of this run's ok points (input of ``hingelab rsm fit``).
        wall_s: Wall time [s].
        cached: Points read back from the result store (finished by an interrupted run).
        warnings: Convergence warnings: the doubled-increments check
            (``studies.convergence``) where it failed; the points' own findings are in
            their records.
        check: The doubled-increments check as plain data (also ``convergence.json``),
            or None where no point has clearance.
    """

    ok: int
    failed: int
    skipped: int
    db: Path
    table: Path
    wall_s: float
    cached: int = 0
    warnings: tuple[str, ...] = ()
    check: dict[str, Any] | None = None


def run_sweep(
    settings: SweepSettings,
    out: Path,
    *,
    on_point: Callable[[dict[str, Any]], None] | None = None,
    retry_failed: bool = False,
) -> SweepOutcome:
    """Run (or resume) a sweep and record every point in ``out/trace.sqlite``.

    Args:
        settings: The points, model, worker count or scheduler.
        out: Output folder (created); rerunning on the same folder resumes.
        on_point: Called with each point's record as it is stored.
        retry_failed: Run only the points that failed in an earlier run.

    Returns:
        Counts of computed, failed, skipped and cached points, and the trace and table paths.

    Raises:
        DataError: If ``out`` cannot be written or its trace is not a hingelab trace
            (checked before anything is meshed).
    """
    from rsm import trace, trace_store
    from studies.outputs import check_trace_db, check_writable_dir

    t0 = time.perf_counter()
    check_writable_dir(out, "--out")
    db = check_trace_db(out / "trace.sqlite", "--out")
    plan = plan_sweep(settings, out)
    trace_store.create(db)
    spec = settings.spec()
    ids = [pp.point_id for pp in plan if pp.state is PointState.DONE and pp.point_id is not None]
    wanted = (
        {PointState.FAILED}
        if retry_failed
        else {PointState.STORED, PointState.FAILED, PointState.TODO}
    )
    todo = [pp.point for pp in plan if pp.state in wanted]
    counts = {"ok": 0, "failed": 0, "cached": 0}

    def store(rec: dict[str, Any]) -> None:
        ids.append(
            trace_store.record_point(
                db,
                study=rec["study"],
                params=rec["params"],
                artifacts=rec["artifacts"],
                mesh_stats=rec["mesh_stats"],
                solver=rec["solver"],
                convergence=rec["convergence"],
                results=rec["results"],
                status=rec["status"],
                error=rec["error"],
            )
        )
        counts[rec["status"]] += 1
        counts["cached"] += bool(rec["solver"].get("cached"))
        if on_point is not None:
            on_point(rec)

    from model.spec import geometry_key

    n_geo = len({geometry_key(spec, p) for p in todo})
    service: ModelService | None = None
    if settings.scheduler is not None and todo:
        from studies.sweep_dask import run_on_scheduler

        run_on_scheduler(todo, settings, out, store)
    elif settings.workers == 1 or n_geo <= 1:
        service = sweep_service(out)
        service.run(spec, todo, on_result=lambda run: store(point_record(run, settings, out)))
    else:
        from studies.sweep_dask import run_on_local_cluster

        run_on_local_cluster(todo, settings, out, store)
    skipped = len(ids) - counts["ok"] - counts["failed"]
    table = out / "table.csv"
    if counts["ok"] + skipped:  # this run's points only (failed ones are left out by status)
        trace.export_table(db, table, study=settings.study, point_ids=ids)
    check = increments_check(settings, out, service) if settings.check_increments else None
    warnings = () if check is None or check["converged"] else (str(check["message"]),)
    return SweepOutcome(
        counts["ok"] - counts["cached"],
        counts["failed"],
        skipped,
        db,
        table,
        time.perf_counter() - t0,
        counts["cached"],
        warnings,
        check,
    )


def increments_check(
    settings: SweepSettings, out: Path, service: ModelService | None = None
) -> dict[str, Any] | None:
    """Run the sweep's clearance point of the largest amplitude at doubled increments.

    The point's own result is read from ``out/results`` (every finished point is stored
    there, whichever way it ran); the doubled run is stored there too, by its own key, so
    a rerun does not repeat it. Written to ``out/convergence.json``; None (and no file)
    where no finished point has clearance. ``service``: the in-process sweep's service,
    whose last geometry (usually the checked point's) is still prepared.
    """
    from model.jsonio import dumps
    from model.spec import result_key
    from model.store import ResultStore
    from studies.convergence import check_point, doubled_check

    spec = settings.spec()
    store = ResultStore(out / "results")
    done = [(p, store.get(result_key(spec, p))) for p in settings.design_points()]
    finished = [(p, r) for p, r in done if r is not None]
    k = check_point(finished)
    if k is None:
        return None
    point, result = finished[k]
    rec = doubled_check(service or sweep_service(out), spec, point, result).record()
    (out / "convergence.json").write_text(dumps(rec))
    return rec
