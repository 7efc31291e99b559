"""Design sweeps: every (clearance, amplitude) point of a grid, traced, resumable, on Dask.

Points run through the model service (``fe.service``): each clearance is meshed,
factorised and condensed once and every amplitude runs on it; each point's result is
stored by its content key (``results/``) the moment it finishes and recorded in the
trace right after, by the driver, one point at a time. So an interrupted sweep keeps
every finished point, and a rerun of the same command computes only what is missing;
a rerun with another μ, mesh, protocol or effect has other keys and recomputes (the
trace keeps the earlier points; ``table.csv`` holds only this run's). Duplicate levels
run once. A point that fails is recorded with its error (and its partial loop when the
solver gave one) and the sweep goes on.

With ``workers > 1`` the points run on a Dask ``LocalCluster`` of worker processes, all
points of one clearance on the same worker (one preparation per clearance).

Layout of ``out``::

    trace.sqlite                    the trace (rsm.trace schema); solver_json holds the result key
    table.csv                       one row per ok point of this run: point_id, parameters, results
    results/KEY.npz                 each computed cycle, by result key (safe to delete: recomputed)
    geometry/c0.100/                hinge.step, mesh.msh, mesh.vtu, mesh.png
    cache/                          nodal compliances by mesh content hash (safe to delete)
    points/c0.100_F300/             loop.csv, loop.png, result.json
"""

from __future__ import annotations

import logging
import os
import sqlite3
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from cad.errors import ParameterError
from fe.hinge.protocol import DEFAULT_MU
from mesh.settings import MeshSettings

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class SweepSettings:
    """A sweep over clearance × amplitude of the general hinge.

    Attributes:
        clearances_mm: Radial clearances [mm].
        amplitudes_n: Force amplitudes [N].
        mu: Friction coefficient.
        increments_per_stage: Increments per half cycle at zero clearance.
        clearance_increments: Increments per half cycle with clearance (see CycleSettings).
        mesh: Mesh settings.
        workers: Dask worker processes; 1 runs in this process.
        study: Study name in the trace.
    """

    clearances_mm: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4)
    amplitudes_n: tuple[float, ...] = (100.0, 200.0, 300.0, 400.0, 500.0)
    mu: float = DEFAULT_MU
    increments_per_stage: int = 20
    clearance_increments: int = 60
    mesh: MeshSettings = field(default_factory=MeshSettings)
    workers: int = 1
    study: str = "general_hinge"

    def __post_init__(self) -> None:
        if not self.clearances_mm or not self.amplitudes_n:
            raise ParameterError(
                f"a sweep needs at least one clearance and one amplitude, got {self.clearances_mm} "
                f"and {self.amplitudes_n}"
            )
        if not 1 <= self.workers <= 64:
            raise ParameterError(f"--workers must be in [1, 64], got {self.workers}")
        self.spec()  # every parameter is checked now, before anything is meshed
        self.points()

    def spec(self) -> Any:
        """The ``fe.service.ModelSpec`` of the sweep (the clearance is set per point)."""
        from cad.general import GeneralHingeParams
        from fe.hinge.protocol import CycleSettings
        from fe.service import ModelSpec

        cycle = CycleSettings(
            mu=self.mu,
            increments_per_stage=self.increments_per_stage,
            clearance_increments=self.clearance_increments,
        )
        return ModelSpec("general", GeneralHingeParams(), self.mesh, cycle)

    def points(self) -> list[Any]:
        """The distinct design points, clearance-major."""
        from fe.service import design_points

        return design_points(self.clearances_mm, self.amplitudes_n)


def point_key(clearance_mm: float, amplitude_n: float) -> str:
    """Folder name of a point, e.g. ``c0.100_F300``."""
    return f"c{clearance_mm:.3f}_F{amplitude_n:g}"


def geometry_folder(out: Path) -> Callable[[float], Path]:
    """Where a sweep writes the files of the geometry with a given clearance."""
    return lambda clearance: out / "geometry" / f"c{clearance:.3f}"


def point_record(run: Any, settings: SweepSettings, out: Path) -> dict[str, Any]:
    """Write a point's files (loop CSV/PNG, result.json) and return its trace record."""
    from fe.contact.newton import LU_THREADS
    from fe.hinge.report import write_loop_csv, write_loop_png
    from studies.pipeline import dumps

    p = run.point
    folder = out / "points" / point_key(p.clearance_mm, p.amplitude_n)
    folder.mkdir(parents=True, exist_ok=True)
    geo = out / "geometry" / f"c{p.clearance_mm:.3f}"
    artifacts: dict[str, Any] = {
        "step": geo / "hinge.step",
        "mesh_msh": geo / "mesh.msh",
        "mesh_vtu": geo / "mesh.vtu",
        "mesh_png": geo / "mesh.png",
    }
    artifacts = {k: v for k, v in artifacts.items() if v.is_file()}
    mesh_stats: dict[str, Any] = {}
    if run.prepared is not None:
        r = run.prepared.meshed.report
        mesh_stats = {
            "n_hex": r.n_hex,
            "n_nodes": r.n_nodes,
            "min_scaled_jacobian": r.min_scaled_jacobian,
            "hex_fraction": r.hex_fraction,
        }
    rec: dict[str, Any] = {
        "study": settings.study,
        "params": {"clearance_mm": p.clearance_mm, "amplitude_N": p.amplitude_n},
        "solver": {
            "result_key": run.key,
            "mu": settings.mu,
            "increments_per_stage": settings.increments_per_stage,
            "clearance_increments": settings.clearance_increments,
            "mesh": asdict(settings.mesh),
            "lu_threads": LU_THREADS,  # this worker's share of the cores (timings depend on it)
            "cached": run.cached,
        },
        "mesh_stats": mesh_stats,
        "artifacts": artifacts,
    }
    if run.ok:
        result = run.result
        title = (
            f"general hinge, Δr = {p.clearance_mm:g} mm, Fg = {p.amplitude_n:g} N, "
            f"μ = {settings.mu:g}"
        )
        artifacts["loop_csv"] = write_loop_csv(result, folder / "loop.csv")
        artifacts["loop_png"] = write_loop_png(result, folder / "loop.png", title=title)
        rec["results"] = {k: v for k, v in result.metrics().items() if isinstance(v, float)} | {
            "wall_s": run.wall_s
        }
        rec["convergence"] = {
            "increments": len(result.increments),
            "iterations": [i.iterations for i in result.increments],
            "timings_s": result.timings_s,
        }
        rec["status"], rec["error"] = "ok", None
    else:
        if run.partial is not None and run.partial.increments:
            artifacts["loop_csv"] = write_loop_csv(run.partial, folder / "loop_partial.csv")
        rec["results"], rec["convergence"] = {}, {}
        rec["status"], rec["error"] = "failed", run.error
    (folder / "result.json").write_text(dumps({k: v for k, v in rec.items() if k != "artifacts"}))
    return rec


def traced_keys(db: Path, study: str) -> dict[str, int]:
    """Return result key → point id of the points the trace holds as ``ok`` for a study."""
    import json

    if not db.exists():
        return {}
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        rows = con.execute(
            "SELECT p.id, p.solver_json FROM points p JOIN studies s ON p.study_id = s.id "
            "WHERE s.name = ? AND p.status = 'ok'",
            (study,),
        ).fetchall()
    finally:
        con.close()
    out = {}
    for pid, solver in rows:
        key = json.loads(solver).get("result_key")
        if key:
            out[key] = pid
    return out


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
    """

    ok: int
    failed: int
    skipped: int
    db: Path
    table: Path
    wall_s: float
    cached: int = 0


def run_sweep(
    settings: SweepSettings, out: Path, *, on_point: Callable[[dict[str, Any]], None] | None = None
) -> SweepOutcome:
    """Run (or resume) a sweep and record every point in ``out/trace.sqlite``.

    Args:
        settings: The grid, solver and mesh settings, worker count.
        out: Output folder (created); rerunning on the same folder resumes.
        on_point: Called with each point's record as it is stored.

    Returns:
        Counts of computed, failed, skipped and cached points, and the trace and table paths.
    """
    from fe.service import result_key
    from rsm import trace

    t0 = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    db = out / "trace.sqlite"
    trace.create(db)
    spec = settings.spec()
    traced = traced_keys(db, settings.study)
    todo, ids = [], []
    for p in settings.points():
        key = result_key(spec, p)
        if key in traced:
            ids.append(traced[key])
        else:
            todo.append(p)
    counts = {"ok": 0, "failed": 0, "cached": 0}

    def store(rec: dict[str, Any]) -> None:
        ids.append(
            trace.record_point(
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

    n_geo = len({p.clearance_mm for p in todo})
    if settings.workers == 1 or n_geo <= 1:
        service = _service(out)
        service.run(spec, todo, on_result=lambda run: store(point_record(run, settings, out)))
    else:
        _run_on_dask(todo, settings, out, store)
    skipped = len(ids) - counts["ok"] - counts["failed"]
    table = out / "table.csv"
    if counts["ok"] + skipped:  # this run's points only (failed ones are left out by status)
        trace.export_table(db, table, study=settings.study, point_ids=ids)
    return SweepOutcome(
        counts["ok"] - counts["cached"],
        counts["failed"],
        skipped,
        db,
        table,
        time.perf_counter() - t0,
        counts["cached"],
    )


def _service(out: Path) -> Any:
    from fe.service import ModelService, ResultStore

    return ModelService(
        store=ResultStore(out / "results"),
        cache_dir=out / "cache",
        geometry_dir=geometry_folder(out),
        max_geometries=1,
    )


_WORKER_SERVICES: dict[str, Any] = {}


def run_point_task(settings: SweepSettings, point: Any, out: Path) -> dict[str, Any]:
    """Run one point in a worker process (its geometry reused across the worker's tasks)."""
    service = _WORKER_SERVICES.setdefault(str(out), _service(out))
    (run,) = service.run(settings.spec(), [point])
    return point_record(run, settings, out)


def _run_on_dask(
    points: list[Any],
    settings: SweepSettings,
    out: Path,
    store: Callable[[dict[str, Any]], None],
) -> None:
    """Run points on a local Dask cluster, one clearance per worker, storing each as it completes."""
    from dask.distributed import Client, LocalCluster, as_completed

    clearances = list(dict.fromkeys(p.clearance_mm for p in points))
    n = min(settings.workers, len(clearances))
    with (
        LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
            # one worker per core: a worker's large LUs must not take a second thread
            env={"HINGELAB_LU_THREADS": str(max(1, (os.cpu_count() or 1) // n))},
        ) as cluster,
        Client(cluster) as client,
    ):
        workers = sorted(client.scheduler_info()["workers"])
        home = {c: workers[i % len(workers)] for i, c in enumerate(clearances)}
        futures = [
            client.submit(
                run_point_task,
                settings,
                p,
                out,
                pure=False,
                workers=[home[p.clearance_mm]],
                allow_other_workers=False,
            )
            for p in points
        ]
        try:
            for future in as_completed(futures):
                store(future.result())
        except BaseException:
            client.cancel(futures)
            raise
