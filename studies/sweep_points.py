"""One sweep point's files and trace record, and the service that runs a sweep's points.

Shared by the in-process sweep (``studies.sweep``) and its Dask workers
(``studies.sweep_dask``), so neither imports the other's internals.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from model.service import ModelService, PointRun, Prepared
    from model.spec import DesignPoint, ModelSpec
    from studies.sweep import SweepSettings

logger = logging.getLogger(__name__)


def point_params(spec: ModelSpec, p: DesignPoint) -> dict[str, float]:
    """The trace parameters of a design point: its design variables by column, and amplitude."""
    from model.spec import complete_point

    values = complete_point(spec, p).values
    columns = {v.name: v.column for v in spec.hinge_kind.design_variables}
    return {**{columns[k]: v for k, v in values.items()}, "amplitude_N": p.amplitude_n}


def geometry_folder(out: Path) -> Callable[[str], Path]:
    """Where a sweep writes the files of a geometry, by its folder name (``c0.100-5e6f7a8b9c``)."""
    return lambda name: out / "geometry" / name


def mesh_stats_of(prepared: Prepared) -> dict[str, Any]:
    """The mesh figures a point's trace record keeps, from a prepared geometry."""
    if prepared.meshed is None:
        return {}
    r = prepared.meshed.report
    return {
        "n_hex": r.n_hex,
        "n_nodes": r.n_nodes,
        "min_scaled_jacobian": r.min_scaled_jacobian,
        "hex_fraction": r.hex_fraction,
    }


def point_record(
    run: PointRun,
    settings: SweepSettings,
    out: Path,
    *,
    mesh_stats: dict[str, Any] | None = None,
    lu_threads: int | None = None,
) -> dict[str, Any]:
    """Write a point's files (loop CSV/PNG, result.json) and return its trace record.

    The files go to ``points/<label>-<key>/`` (``model.spec.point_folder``), a folder no
    other result key shares; the geometry's to ``geometry/<label>-<geometry key>/``.

    Args:
        run: The point's ``model.service.PointRun``.
        settings: The sweep.
        out: The sweep's folder.
        mesh_stats: Mesh figures when ``run.prepared`` is None (a point run elsewhere).
        lu_threads: The LU thread count of the process that ran it (default: this one's).
    """
    from fe.cycle.loop_files import write_loop_csv, write_loop_png
    from model.jsonio import dumps, strict_json
    from studies.convergence import warning_lines

    if lu_threads is None:
        from fe.contact import newton

        lu_threads = int(newton.LU_THREADS)
    spec = settings.spec()

    from model.code import code_version
    from model.spec import describe_point, geometry_folder, point_folder, point_label

    p = run.point
    # named by the result key: a rerun with other settings never writes into this folder
    folder = out / "points" / point_folder(spec, p, run.key)
    folder.mkdir(parents=True, exist_ok=True)
    geo = out / "geometry" / geometry_folder(spec, p)
    artifacts: dict[str, Any] = {
        "step": geo / "hinge.step",
        "mesh_msh": geo / "mesh.msh",
        "mesh_vtu": geo / "mesh.vtu",
        "mesh_png": geo / "mesh.png",
    }
    artifacts = {k: v for k, v in artifacts.items() if v.is_file()}
    mesh_stats = mesh_stats_of(run.prepared) if run.prepared is not None else (mesh_stats or {})
    rec: dict[str, Any] = {
        "study": settings.study,
        "params": point_params(spec, p),
        "solver": {
            "result_key": run.key,
            "mu": spec.cycle.mu,
            "increments_per_stage": spec.cycle.increments_per_stage,
            "clearance_increments": spec.cycle.clearance_increments,
            "mesh": asdict(spec.mesh),
            "effects": {k: dict(v) for k, v in spec.effects.items()},
            "lu_threads": lu_threads,  # this worker's share of the cores (timings depend on it)
            "cached": run.cached,
            "code": code_version().short(),  # the code of the key (model.code)
        },
        "mesh_stats": mesh_stats,
        "artifacts": artifacts,
    }
    result = run.result
    if result is not None:
        title = describe_point(spec, p)
        artifacts["loop_csv"] = write_loop_csv(result, folder / "loop.csv")
        artifacts["loop_png"] = write_loop_png(result, folder / "loop.png", title=title)
        # NaN (η of a loop without energy) becomes null: strict JSON, and no NaN in the table
        rec["results"] = strict_json(
            {k: v for k, v in result.metrics().items() if isinstance(v, float)}
        ) | {"wall_s": run.wall_s}
        warnings = warning_lines(result)
        for line in warnings:
            logger.warning("%s: %s", point_label(spec, p), line)
        rec["convergence"] = strict_json(
            {
                "increments": len(result.increments),
                "iterations": [i.iterations for i in result.increments],
                "cutbacks": result.n_cutbacks,
                "warnings": warnings,
                "timings_s": result.timings_s,
            }
        )
        rec["status"], rec["error"] = "ok", None
    else:
        if run.partial is not None and run.partial.increments:
            artifacts["loop_csv"] = write_loop_csv(run.partial, folder / "loop_partial.csv")
        rec["results"], rec["convergence"] = {}, {}
        rec["status"], rec["error"] = "failed", run.error
    manifest = folder / "result.json"  # carries the result key: the report checks it
    manifest.write_text(dumps({k: v for k, v in rec.items() if k != "artifacts"}))
    artifacts["result_json"] = manifest
    return rec


def sweep_service(out: Path) -> ModelService:
    """The model service of a sweep folder: results and compliances kept, one geometry at a time."""
    from model.service import ModelService
    from model.store import ResultStore

    return ModelService(
        store=ResultStore(out / "results"),
        cache_dir=out / "cache",
        geometry_dir=geometry_folder(out),
        max_geometries=1,
    )
