"""Sweep points on Dask: a private ``LocalCluster``, or an existing cluster by its address.

Both hand the points out with ``model.cluster.dispatch`` (a worker runs the geometries it
holds first and takes the next geometry when it is free, so the work balances however
many points each geometry has) and hand each point's record to the driver the moment it
completes, so the driver records it in the trace at once (an interrupted sweep keeps
every finished point).

* ``run_on_local_cluster``: worker processes on this machine share the sweep's folder;
  each stores its results and writes its files there itself, so one geometry runs on
  one worker only (``NEVER_STEAL``).
* ``run_on_scheduler``: the workers of an existing cluster may be other machines and need
  only the installed package. A worker computes the cycle and sends it back (without the
  condensed operators); this process stores it, writes the loop files and records the
  point. The geometry files (STEP, mesh) stay with the workers, in memory, so an idle
  worker may set up a geometry another one holds when it has many points left.

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


NEVER_STEAL = 10**9
"""``steal_min`` of a sweep on local workers: a geometry runs on one worker only, as the
workers write its files (STEP, mesh) into the sweep's one folder."""


def _stored(store: Callable[[Any], None]) -> Callable[[int, Any, BaseException | None], None]:
    """A ``model.cluster.dispatch`` handler: the task's value to ``store``; its error raised."""

    def handle(_job: int, value: Any, error: BaseException | None) -> None:
        if error is not None:
            raise error  # ends the sweep's Dask run (the jobs in flight are cancelled)
        store(value)

    return handle


def run_on_local_cluster(
    points: list[DesignPoint], settings: SweepSettings, out: Path, store: Store
) -> None:
    """Run points on a private LocalCluster of ``settings.workers`` processes."""
    from dask.distributed import Client

    from model.cluster import dispatch, local_cluster
    from model.spec import geometry_key

    spec = settings.spec()
    n = min(settings.workers, len({geometry_key(spec, p) for p in points}))
    with local_cluster(n) as cluster, Client(cluster) as client:
        dispatch(
            client,
            [(spec, p) for p in points],
            run_point_task,
            _stored(store),
            args=lambda j: (settings, points[j], out),
            steal_min=NEVER_STEAL,
        )


def run_on_scheduler(
    points: list[DesignPoint], settings: SweepSettings, out: Path, store: Store
) -> None:
    """Run points on the existing Dask cluster at ``settings.scheduler``.

    Raises:
        DataError: If the scheduler cannot be reached (naming the address and --scheduler).
    """
    from model.cluster import connect, dispatch
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
        dispatch(client, [(spec, p) for p in points], run_point_remote, _stored(handle))
