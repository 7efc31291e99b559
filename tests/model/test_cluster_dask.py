"""ClusterRunner when a worker dies: its jobs run on another one, or fail if none is left.

The task is ``slow_job`` (it sleeps and names its worker) in place of ``run_job``, so this
checks the dispatch, not the physics; the workers import it from this module (the repo on
``PYTHONPATH``).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import PLUGINS
from tests.dask_cluster import external_cluster


def slow_job(spec: Any, point: Any) -> str:
    """Stand-in for ``model.cluster.run_job``: sleep, then return this worker's address."""
    from distributed import get_worker

    time.sleep(0.5)
    return str(get_worker().address)


def _jobs(tmp_path: Path, n: int) -> list[tuple[Any, Any]]:
    """``n`` jobs of one geometry of the plug-in kind (amplitudes 100, 110, … N)."""
    from model.file import read_model
    from model.spec import DesignPoint

    path = tmp_path / "MODEL.toml"
    path.write_text(
        '[hinge]\nkind = "jenkins_pin"\nk0_n_per_mm = 2000.0\nk1_n_per_mm = 6000.0\n'
        "slip_force_n = 60.0\n"
    )
    spec = read_model(path)
    return [(spec, DesignPoint(100.0 + 10 * k)) for k in range(n)]


def _run_killing(runner: Any, jobs: list, victim: str) -> dict[int, tuple[Any, Any]]:  # type: ignore[type-arg]
    """Run ``jobs``, killing worker ``victim`` once two have arrived; fail if it hangs."""
    got: dict[int, tuple[Any, BaseException | None]] = {}
    pid = runner.client().run(os.getpid, workers=[victim])[victim]

    def handle(i: int, result: Any, err: BaseException | None) -> None:
        got[i] = (result, err)
        if len(got) == 2:  # the victim has run a job and is given its next one
            os.kill(pid, signal.SIGKILL)

    run = threading.Thread(target=runner.run, args=(jobs, handle), daemon=True)
    run.start()
    run.join(timeout=60.0)
    assert not run.is_alive(), "the runner waits for a job on a worker that died"
    return got


@pytest.mark.slow  # a LocalCluster of two processes takes a few seconds to start
def test_the_jobs_of_a_worker_that_dies_run_on_another(
    jenkins, tmp_path: Path, monkeypatch
) -> None:  # type: ignore[no-untyped-def]
    import model.cluster as cluster

    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(PLUGINS), *sys.path]))
    monkeypatch.setattr(cluster, "run_job", slow_job)
    monkeypatch.setattr(cluster, "POLL_S", 0.2)
    with cluster.ClusterRunner(cluster.Cluster(workers=2)) as runner:
        victim = sorted(runner.client().scheduler_info()["workers"])[0]
        got = _run_killing(runner, _jobs(tmp_path, 8), victim)
    assert sorted(got) == list(range(8))
    assert [err for _, err in got.values()] == [None] * 8
    where = [w for w, _ in got.values()]
    assert victim in where  # it ran jobs before it died
    assert len(set(where)) >= 2


@pytest.mark.slow
def test_the_jobs_left_fail_when_the_last_worker_dies(jenkins, tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    import model.cluster as cluster
    from cad.errors import DataError

    monkeypatch.setattr(cluster, "run_job", slow_job)
    monkeypatch.setattr(cluster, "POLL_S", 0.2)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(PLUGINS), *sys.path])}
    with (
        external_cluster(tmp_path, workers=1, env=env, nanny=False) as address,
        cluster.ClusterRunner(cluster.Cluster(scheduler=address)) as runner,
    ):
        (victim,) = runner.client().scheduler_info()["workers"]
        got = _run_killing(runner, _jobs(tmp_path, 5), victim)
    assert sorted(got) == list(range(5))
    assert [err for _, err in got.values()][:2] == [None, None]  # done before it died
    for _, err in list(got.values())[2:]:
        assert isinstance(err, DataError)
        assert "no workers left" in str(err)


@pytest.mark.slow
def test_two_local_clusters_run_side_by_side():
    """Two commands (or two test processes) each with a private cluster: no fixed port."""
    from model.cluster import local_cluster

    a = local_cluster(1)
    try:
        b = local_cluster(1)
        try:
            ports = {c.scheduler.http_server.port for c in (a, b)}
            assert len(ports) == 2
            assert 8787 not in ports
        finally:
            b.close()
    finally:
        a.close()


def _worker_environment() -> dict[str, object]:
    import os

    from distributed import get_worker

    names = ("MALLOC_TRIM_THRESHOLD_", "OPENBLAS_NUM_THREADS", "HINGELAB_LU_THREADS")
    env: dict[str, object] = {n: os.environ.get(n) for n in names}
    return env | {"callbacks": sorted(get_worker().periodic_callbacks)}


def test_local_workers_keep_glibcs_allocator_and_their_share_of_threads(monkeypatch):
    """Dask's nanny sets MALLOC_TRIM_THRESHOLD_, which froze glibc's mmap threshold: every
    large array a fresh zeroed mmap, a cycle 1.6x slower as a task (bench_worker_overhead).
    Dask's profiler sampled every task's stack every 10 ms: the workers start without it
    (an environment variable for it was set too late and left it on)."""
    from dask.distributed import Client

    from model.cluster import local_cluster

    monkeypatch.setenv("HINGELAB_LU_THREADS", "3")  # a user's choice on the client
    with local_cluster(2) as cluster, Client(cluster) as client:
        env = client.submit(_worker_environment, pure=False).result()
    assert env["MALLOC_TRIM_THRESHOLD_"] is None
    share = str(max(1, (os.cpu_count() or 1) // 2))  # the cores over the 2 workers
    assert env["OPENBLAS_NUM_THREADS"] == share
    # the LU's thread count changes numbers: the worker's is the client's, not its share
    assert env["HINGELAB_LU_THREADS"] == "3"
    assert "heartbeat" in env["callbacks"]  # the names are those of this Dask version
    assert "profile" not in env["callbacks"]
