"""Sweep points on Dask: a private ``LocalCluster``, or an existing cluster by its address.

Both pin every point of one geometry to one worker (one preparation per geometry) and
hand each point's record to the driver the moment it completes, so the driver records it
in the trace at once (an interrupted sweep keeps every finished point).

* ``run_on_local_cluster``: worker processes on this machine share the sweep's folder;
  each stores its results and writes its files there itself.
* ``run_on_scheduler``: the workers of an existing cluster may be other machines and need
  only the installed package. A worker computes the cycle and sends it back (without the
  condensed operators); this process stores it, writes the loop files and records the
  point. The geometry files (STEP, mesh) stay with the workers, in memory.

Dask logs (connections, "killing worker" on shutdown) are silenced unless the root logger
is at INFO (``hingelab -v``).
"""

from __future__ import annotations

import dataclasses
import logging
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cad.errors import DataError

if TYPE_CHECKING:
    from model.spec import DesignPoint, ModelSpec
    from studies.sweep import SweepSettings

logger = logging.getLogger(__name__)

Store = Callable[[dict[str, Any]], None]

_WORKER_SERVICES: dict[str, Any] = {}
_WORKER_LOCK = threading.Lock()  # a worker with several threads prepares each geometry once


def run_point_task(settings: SweepSettings, point: DesignPoint, out: Path) -> dict[str, Any]:
    """Run one point in a LocalCluster worker (its geometry reused across the worker's tasks)."""
    from studies.sweep_points import point_record, sweep_service

    with _WORKER_LOCK:
        service = _WORKER_SERVICES.setdefault(str(out), sweep_service(out))
        (run,) = service.run(settings.spec(), [point])
    return point_record(run, settings, out)


def run_point_remote(spec: ModelSpec, point: DesignPoint) -> dict[str, Any]:
    """Run one point on a worker of an existing cluster; return the cycle, not files.

    Returns:
        ``run`` (the ``PointRun`` without its geometry and condensed operators),
        ``mesh_stats`` and ``lu_threads`` of this worker.
    """
    from fe.contact.newton import LU_THREADS
    from model.service import ModelService
    from model.spec import content_hash
    from studies.sweep_points import mesh_stats_of

    with _WORKER_LOCK:
        key = content_hash({"spec": spec})
        service = _WORKER_SERVICES.get(key)
        if service is None:
            _WORKER_SERVICES.clear()  # one model at a time per worker (memory)
            service = _WORKER_SERVICES[key] = ModelService(max_geometries=1)
        (run,) = service.run(spec, [point])
    stats = mesh_stats_of(run.prepared) if run.prepared is not None else {}
    light = dataclasses.replace(
        run,
        result=None if run.result is None else dataclasses.replace(run.result, configs={}),
        partial=None if run.partial is None else dataclasses.replace(run.partial, configs={}),
        prepared=None,
    )
    return {"run": light, "mesh_stats": stats, "lu_threads": LU_THREADS}


def _submit_pinned(
    client: Any,
    spec: ModelSpec,
    points: list[DesignPoint],
    task: Callable[..., Any],
    args: Callable[[Any], tuple[Any, ...]],
) -> list[Any]:
    """Submit ``task(*args(point))`` for every point, all points of a geometry on one worker."""
    from model.spec import geometry_key

    geometry = {p: geometry_key(spec, p) for p in points}
    keys = list(dict.fromkeys(geometry.values()))
    workers = sorted(client.scheduler_info()["workers"])
    if not workers:
        raise DataError("the Dask cluster has no workers")
    home = {g: workers[i % len(workers)] for i, g in enumerate(keys)}
    return [
        client.submit(
            task, *args(p), pure=False, workers=[home[geometry[p]]], allow_other_workers=False
        )
        for p in points
    ]


def _drain(client: Any, futures: list[Any], handle: Callable[[Any], None]) -> None:
    """Hand each finished task's value to ``handle`` in completion order; cancel the rest on error."""
    from dask.distributed import as_completed

    try:
        for future in as_completed(futures):
            handle(future.result())
    except BaseException:
        client.cancel(futures)
        raise


def run_on_local_cluster(
    points: list[DesignPoint], settings: SweepSettings, out: Path, store: Store
) -> None:
    """Run points on a private LocalCluster of ``settings.workers`` processes."""
    from dask.distributed import Client

    from model.cluster import local_cluster
    from model.spec import geometry_key

    spec = settings.spec()
    n = min(settings.workers, len({geometry_key(spec, p) for p in points}))
    with local_cluster(n) as cluster, Client(cluster) as client:
        futures = _submit_pinned(client, spec, points, run_point_task, lambda p: (settings, p, out))
        _drain(client, futures, store)


def run_on_scheduler(
    points: list[DesignPoint], settings: SweepSettings, out: Path, store: Store
) -> None:
    """Run points on the existing Dask cluster at ``settings.scheduler``.

    Raises:
        DataError: If the scheduler cannot be reached (naming the address and --scheduler).
    """
    from model.cluster import connect
    from model.store import ResultStore
    from studies.sweep_points import point_record

    spec = settings.spec()
    results = ResultStore(out / "results")
    assert settings.scheduler is not None  # the caller chose this path for it
    client = connect(settings.scheduler)

    def handle(value: dict[str, Any]) -> None:
        run = value["run"]
        if run.result is not None:
            results.put(run.key, run.result)  # stored before it is recorded, as in-process
        rec = point_record(
            run, settings, out, mesh_stats=value["mesh_stats"], lu_threads=value["lu_threads"]
        )
        store(rec)

    with client:
        futures = _submit_pinned(client, spec, points, run_point_remote, lambda p: (spec, p))
        _drain(client, futures, handle)
