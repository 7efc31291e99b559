"""Design sweeps: every (clearance, amplitude) point of a grid, traced, resumable, on Dask.

One *geometry task* per clearance meshes the hinge, factorises and condenses it once,
then runs the cycle for every amplitude on it (amplitude and μ change nothing the
factorisation depends on). Tasks run in-process (``workers=1``) or on a Dask
``LocalCluster`` of worker processes. Only the driver writes the SQLite trace, as
each geometry finishes, so an interrupted sweep keeps what it finished and a rerun
skips every point the trace already holds as ``ok``. A point that fails is recorded
with its error (and its partial loop when the solver gave one) and the sweep goes on.

Layout of ``out``::

    trace.sqlite                    the trace (rsm.trace schema)
    table.csv                       one row per ok point: point_id, parameters, results
    geometry/c0.100/                hinge.step, mesh.msh, mesh.vtu, mesh.png
    cache/                          nodal compliances by mesh content hash (safe to delete)
    points/c0.100_F300/             loop.csv, loop.png, result.json
"""

from __future__ import annotations

import logging
import os
import sqlite3
import time
import traceback
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from cad.errors import ParameterError
from fe.hinge.cycle import DEFAULT_MU
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
            raise ParameterError(f"workers must be in [1, 64], got {self.workers}")


def point_key(clearance_mm: float, amplitude_n: float) -> str:
    """Folder name of a point, e.g. ``c0.100_F300``."""
    return f"c{clearance_mm:.3f}_F{amplitude_n:g}"


def run_geometry(
    clearance_mm: float, amplitudes_n: tuple[float, ...], settings: SweepSettings, out: Path
) -> list[dict[str, Any]]:
    """Mesh one clearance, factorise once, run every amplitude; return one record per point.

    Runs in a worker process. Never raises: a failure becomes a ``failed`` record.
    """
    from fe.contact.newton import LU_THREADS
    from fe.hinge.cycle import CycleSettings, run_cycle
    from fe.hinge.report import write_loop_csv, write_loop_png
    from fe.hinge.system import build_system
    from studies.pipeline import build_and_mesh, dumps, make_model

    records: list[dict[str, Any]] = []
    base = {
        "study": settings.study,
        "solver": {
            "mu": settings.mu,
            "increments_per_stage": settings.increments_per_stage,
            "mesh": asdict(settings.mesh),
            "lu_threads": LU_THREADS,  # this worker's share of the cores (timings depend on it)
        },
    }
    try:
        model = make_model("general", clearance_mm=clearance_mm)
        meshed = build_and_mesh(model, settings.mesh, out / "geometry" / f"c{clearance_mm:.3f}")
        system = build_system(meshed.mesh, cache_dir=out / "cache")
        r = meshed.report
        mesh_stats = {
            "n_hex": r.n_hex,
            "n_nodes": r.n_nodes,
            "min_scaled_jacobian": r.min_scaled_jacobian,
            "hex_fraction": r.hex_fraction,
        }
        geometry_files = {
            "step": meshed.files["step"],
            "mesh_msh": meshed.files["msh"],
            "mesh_vtu": meshed.files["vtu"],
            "mesh_png": meshed.files.get("png"),
        }
    except Exception as err:  # every point of this geometry fails, the sweep goes on
        msg = f"geometry failed: {type(err).__name__}: {err}"
        logger.error("clearance %.3f: %s", clearance_mm, msg)
        return [
            {
                **base,
                "params": {"clearance_mm": clearance_mm, "amplitude_N": a},
                "status": "failed",
                "error": msg,
                "artifacts": {},
                "mesh_stats": {},
                "convergence": {},
                "results": {},
            }
            for a in amplitudes_n
        ]
    configs = None
    for amplitude in amplitudes_n:
        folder = out / "points" / point_key(clearance_mm, amplitude)
        folder.mkdir(parents=True, exist_ok=True)
        rec: dict[str, Any] = {
            **base,
            "params": {"clearance_mm": clearance_mm, "amplitude_N": amplitude},
            "mesh_stats": mesh_stats,
            "artifacts": dict(geometry_files),
        }
        t0 = time.perf_counter()
        try:
            cyc = CycleSettings(
                amplitude_n=amplitude,
                mu=settings.mu,
                increments_per_stage=settings.increments_per_stage,
                clearance_increments=settings.clearance_increments,
            )
            result = run_cycle(system, clearance_mm, cyc, configs=configs)
            configs = result.configs  # every amplitude reuses the condensed configurations
            m = result.metrics()
            rec["artifacts"]["loop_csv"] = write_loop_csv(result, folder / "loop.csv")
            rec["artifacts"]["loop_png"] = write_loop_png(
                result,
                folder / "loop.png",
                title=f"general hinge, Δr = {clearance_mm:g} mm, Fg = {amplitude:g} N, μ = {settings.mu:g}",
            )
            rec["results"] = {k: v for k, v in m.items() if isinstance(v, float)} | {
                "wall_s": time.perf_counter() - t0
            }
            rec["convergence"] = {
                "increments": len(result.increments),
                "iterations": [i.iterations for i in result.increments],
                "timings_s": result.timings_s,
            }
            rec["status"], rec["error"] = "ok", None
        except Exception as err:
            partial = getattr(err, "partial", None)
            if partial is not None and partial.increments:
                rec["artifacts"]["loop_csv"] = write_loop_csv(partial, folder / "loop_partial.csv")
            rec["results"], rec["convergence"] = {}, {"traceback": traceback.format_exc(limit=3)}
            rec["status"], rec["error"] = "failed", f"{type(err).__name__}: {err}"
            logger.error("point %s failed: %s", point_key(clearance_mm, amplitude), rec["error"])
        (folder / "result.json").write_text(
            dumps({k: v for k, v in rec.items() if k != "artifacts"})
        )
        records.append(rec)
    return records


def done_points(db: Path, study: str) -> set[tuple[float, float]]:
    """Return the (clearance, amplitude) pairs the trace holds as ``ok`` for a study."""
    if not db.exists():
        return set()
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        rows = con.execute(
            "SELECT p.id, k.name, k.value FROM points p JOIN studies s ON p.study_id = s.id "
            "JOIN params k ON k.point_id = p.id WHERE s.name = ? AND p.status = 'ok'",
            (study,),
        ).fetchall()
    finally:
        con.close()
    by_point: dict[int, dict[str, float]] = {}
    for pid, name, value in rows:
        by_point.setdefault(pid, {})[name] = float(value)
    return {
        (round(v["clearance_mm"], 9), round(v["amplitude_N"], 9))
        for v in by_point.values()
        if "clearance_mm" in v and "amplitude_N" in v
    }


@dataclass(frozen=True)
class SweepOutcome:
    """What a sweep did.

    Attributes:
        ok: Points computed successfully in this run.
        failed: Points that failed in this run (recorded with their error).
        skipped: Points already in the trace as ok (not recomputed).
        db: The trace database.
        table: The table of ok points (input of ``hingelab rsm fit``).
        wall_s: Wall time [s].
    """

    ok: int
    failed: int
    skipped: int
    db: Path
    table: Path
    wall_s: float


def run_sweep(
    settings: SweepSettings, out: Path, *, on_point: Callable[[dict[str, Any]], None] | None = None
) -> SweepOutcome:
    """Run (or resume) a sweep and record every point in ``out/trace.sqlite``.

    Args:
        settings: The grid, solver and mesh settings, worker count.
        out: Output folder (created); rerunning on the same folder resumes.
        on_point: Called with each point's record as it is stored.

    Returns:
        Counts of computed, failed and skipped points, and the trace and table paths.
    """
    from rsm import trace

    t0 = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    db = out / "trace.sqlite"
    trace.create(db)
    done = done_points(db, settings.study)
    tasks = []
    skipped = 0
    for c in settings.clearances_mm:
        todo = tuple(a for a in settings.amplitudes_n if (round(c, 9), round(a, 9)) not in done)
        skipped += len(settings.amplitudes_n) - len(todo)
        if todo:
            tasks.append((c, todo))
    counts = {"ok": 0, "failed": 0}

    def store(records: Iterable[dict[str, Any]]) -> None:
        for rec in records:
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
            counts[rec["status"]] += 1
            if on_point is not None:
                on_point(rec)

    if settings.workers == 1 or len(tasks) <= 1:
        for c, todo in tasks:
            store(run_geometry(c, todo, settings, out))
    else:
        _run_on_dask(tasks, settings, out, store)
    table = (
        trace.export_table(db, out / "table.csv", study=settings.study)
        if counts["ok"] + skipped
        else out / "table.csv"
    )
    return SweepOutcome(
        counts["ok"], counts["failed"], skipped, db, table, time.perf_counter() - t0
    )


def _run_on_dask(
    tasks: list[tuple[float, tuple[float, ...]]],
    settings: SweepSettings,
    out: Path,
    store: Callable[[Iterable[dict[str, Any]]], None],
) -> None:
    """Run geometry tasks on a local Dask cluster, storing each as it completes."""
    from dask.distributed import Client, LocalCluster, as_completed

    n = min(settings.workers, len(tasks))
    with (
        LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            # one worker per core: a worker's large LUs must not take a second thread
            env={"HINGELAB_LU_THREADS": str(max(1, (os.cpu_count() or 1) // n))},
        ) as cluster,
        Client(cluster) as client,
    ):
        futures = [
            client.submit(run_geometry, c, todo, settings, out, pure=False) for c, todo in tasks
        ]
        for future in as_completed(futures):
            store(future.result())
