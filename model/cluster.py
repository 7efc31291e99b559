"""Model runs as Dask tasks: a private ``LocalCluster``, or an existing cluster by its address.

What ``compare``, ``diagnose``, ``calibrate`` and the paper's validation run through
``model.service.ModelService.run_jobs``: a batch of independent (spec, design point) jobs
(``synth``: ``ModelService.run_summarized``, whose workers also send the kind's summary,
made on the geometry they hold). A worker keeps a ``ModelService`` of its own, which
builds, meshes and factorises a geometry (``model.spec.geometry_key``) once for all the
μ, effects and amplitudes run on it. ``ClusterRunner`` gives each worker its next job as
one completes (``model.dispatch.Dispatcher``): one of a geometry it holds while there is
one; else a geometry no worker holds yet, so distinct geometries spread over the workers;
else it joins the geometry with the most jobs left per worker holding it, so one geometry
of many jobs runs on every worker, each setting it up once. A worker computes the
cycle and sends it back without the condensed operators; the calling process stores it
(``model.store.ResultStore``) the moment it arrives, so an interrupted run keeps what
finished and a rerun computes only the rest. The worker runs the same code as the
in-process service, so the numbers are the same; ``dispatch`` checks that it does
(``other_code``: hingelab's source digest, version and libraries, ``model.code``).
``dispatch`` is that loop on its own, for other tasks (``studies.sweep_dask``: a sweep's
points, whose workers write their files).

A user's effect from a file travels with the spec (``ModelSpec.effect_sources``) and is
registered on the worker when the spec is unpickled. A plug-in hinge kind must be
installed (or on ``PYTHONPATH``) on the workers.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from cad.errors import DataError, check_range
from fe.cycle.result import CycleResult
from model.code import ALL_PACKAGES, CodeVersion, code_version
from model.dispatch import Dispatcher
from model.spec import DesignPoint, ModelSpec, geometry_key, point_label

logger = logging.getLogger(__name__)

_WORKER_SERVICE: dict[str, Any] = {}
_WORKER_LOCK = threading.Lock()  # a worker with several threads prepares each geometry once

THREAD_VARIABLES = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
)
"""Thread counts a local worker is started with (its share of the cores): without them,
OpenBLAS and MKL would start a thread per core in every worker for the steps outside the
cycle's own thread limit (assembly, condensation, loop post-processing). They change no
number: a job runs OpenBLAS on one thread (``fe.linalg.threads``), and PARDISO factorises
on one thread, its solves not depending on the count (``fe.linalg.sparse``). (Measured
on the 6-case diagnosis: no change in time; the workers' slowdown was the allocator, see
``WORKER_CONFIG``.) ``HINGELAB_LU_THREADS`` is not among them: it changes a job's numbers
in the last bits (``fe.contact.dense.lu_threads``), so a worker keeps the value it inherits
from this process, and its jobs compute what they would here."""


WORKER_GEOMETRIES = 4
"""Prepared geometries a worker keeps (the least recently used is dropped). A worker runs
the jobs of the geometries it holds first and sets up another only when none of them has
a job pending; ``model.dispatch.Dispatcher`` keeps the same count, so it never sends a job
to a worker as if it held a geometry that worker has dropped."""

STEAL_MIN = 2
"""Pending jobs per worker holding a geometry from which an idle worker sets it up too."""

WORKER_CONFIG: dict[str, Any] = {
    # Dask's nannies start workers with MALLOC_TRIM_THRESHOLD_=65536 (memory handed back to
    # the OS at once); setting it also stops glibc from raising its mmap threshold, so every
    # array above 128 kB was a fresh mmap, zeroed page by page: a cycle took 1.4-1.6x its
    # time in this process. The workers get glibc's default allocator behaviour.
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    # Dask's statistical profiler samples the task thread's stack every 10 ms (measured with
    # py-spy: its callbacks were the worker's main thread's largest item). A nanny hands its
    # configuration to the worker it spawns; an environment variable set through ``env``
    # reaches the worker after its configuration is read (it left the profiler on).
    "distributed.worker.profile.enabled": False,
}
"""Dask configuration a private ``LocalCluster``'s workers start with (``local_cluster``)."""

AHEAD = 1
"""Jobs queued on a worker behind those it runs, while many are pending (``Dispatcher``)."""

MAX_LOSSES = 3
"""A job whose worker left this many times is reported as failed (it may be what kills them)."""

POLL_S = 2.0
"""How often [s] the runner asks the scheduler which workers joined or left."""


@dataclass(frozen=True)
class Cluster:
    """Where model runs go: in this process (the default), local workers, or a scheduler.

    Attributes:
        workers: Local Dask worker processes (1: in this process, no Dask).
        scheduler: Address of an existing Dask scheduler (``tcp://host:8786``), or None.
    """

    workers: int = 1
    scheduler: str | None = None

    def __post_init__(self) -> None:
        check_range("workers", self.workers, 1, 256)

    @property
    def in_process(self) -> bool:
        """True when nothing goes to Dask."""
        return self.scheduler is None and self.workers <= 1


def quiet_dask() -> None:
    """Silence Dask's INFO/WARNING chatter unless the user asked for logs (-v)."""
    if not logging.getLogger().isEnabledFor(logging.INFO):
        for name in ("distributed", "distributed.client", "distributed.worker", "tornado"):
            logging.getLogger(name).setLevel(logging.ERROR)


def connect(address: str) -> Any:
    """A ``dask.distributed.Client`` of the scheduler at ``address`` (Dask's logs quietened).

    Raises:
        DataError: If the scheduler cannot be reached (naming ``--scheduler`` and the address).
    """
    from dask.distributed import Client

    quiet_dask()
    try:
        return Client(address, timeout="10s")
    except (OSError, TimeoutError) as err:
        raise DataError(
            f"--scheduler {address}: cannot connect to a Dask scheduler ({err})"
        ) from err


def local_cluster(workers: int) -> Any:
    """A private ``LocalCluster`` of ``workers`` one-thread processes (Dask's logs quietened).

    Each worker gets its share of the cores for every BLAS/OpenMP call
    (``THREAD_VARIABLES``), so two workers never take a second thread each on two cores;
    the rest of its environment is this process's. Its dashboard listens on a free port
    (Dask's default 8787 is taken when two commands or test processes run at once).
    """
    import dask
    from dask.distributed import LocalCluster

    quiet_dask()
    share = str(max(1, (os.cpu_count() or 1) // workers))
    with dask.config.set(WORKER_CONFIG):
        return LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",  # None still binds 8787: a second cluster there failed
            # a failed cycle comes back here as its exception and is reported by the caller
            # (a non-converged candidate value is an expected outcome): the worker's own
            # "Compute Failed" traceback on stderr would only alarm the user
            silence_logs=logging.CRITICAL,
            env={name: share for name in THREAD_VARIABLES},
        )


def _worker_service() -> Any:
    """This worker's ``ModelService``, made on its first job (call under ``_WORKER_LOCK``)."""
    if "service" not in _WORKER_SERVICE:
        from model.service import ModelService

        _WORKER_SERVICE["service"] = ModelService(max_geometries=WORKER_GEOMETRIES)
    return _WORKER_SERVICE["service"]


def worker_code() -> CodeVersion:
    """The code this process runs (on a worker: ``Client.run``), as ``model.code`` sees it."""
    return code_version(ALL_PACKAGES)


def other_code(client: Any, workers: Sequence[str]) -> dict[str, list[str]]:
    """The workers among ``workers`` that run other code than this process, and how it differs.

    A worker's cycle is stored under this process's result key, which holds this
    process's code (``model.code.code_version``); a worker with another hingelab, other
    source files or other library versions would store its numbers as this code's.

    Raises:
        DataError: If the workers cannot say (hingelab not importable there).
    """
    if not workers:
        return {}
    here = worker_code()
    try:
        there = client.run(worker_code, workers=list(workers))
    except Exception as err:  # the worker's import error, re-raised here by Dask
        raise DataError(
            f"the Dask workers cannot report which hingelab they run ({type(err).__name__}: "
            f"{err}): install hingelab on every worker"
        ) from err
    return {w: here.differences(v) for w, v in sorted(there.items()) if v != here}


def _code_error(wrong: dict[str, list[str]]) -> DataError:
    w, why = next(iter(wrong.items()))
    more = f" (and {len(wrong) - 1} other worker(s))" if len(wrong) > 1 else ""
    return DataError(
        f"Dask worker {w}{more} runs other code than this process ({'; '.join(why)}): its "
        "cycles would be stored as this code's; install the same hingelab and libraries "
        "on every worker (`hingelab --version` prints the source digest)"
    )


def run_job(spec: ModelSpec, point: DesignPoint) -> CycleResult:
    """Run one point on a worker (its geometry reused across the worker's jobs).

    Returns:
        The cycle without its condensed configurations (they stay with the geometry).
    """
    with _WORKER_LOCK:
        result: CycleResult = _worker_service().run_point(spec, point)
    return dataclasses.replace(result, configs={})


def run_job_summary(spec: ModelSpec, point: DesignPoint) -> tuple[CycleResult, dict[str, Any]]:
    """Run one point on a worker and summarise it there (``ModelService.summary``).

    The kind's summary needs the prepared geometry, which stays on the worker.

    Returns:
        The cycle without its condensed configurations, and the kind's summary of it.
    """
    with _WORKER_LOCK:
        service = _worker_service()
        result = service.run_point(spec, point)
        summary = service.summary(spec, point, result)
    return dataclasses.replace(result, configs={}), summary


class ClusterRunner:
    """A Dask client for model jobs; use as a context manager (it closes its cluster).

    Args:
        cluster: Local workers or a scheduler address.
    """

    def __init__(self, cluster: Cluster) -> None:
        self.cluster = cluster
        self._client: Any = None
        self._local: Any = None
        self._held: dict[str, list[str]] = {}  # worker → geometries it holds, LRU first

    def __enter__(self) -> ClusterRunner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def client(self) -> Any:
        """The Dask client, connected on first use.

        Raises:
            DataError: If the scheduler cannot be reached (naming ``--scheduler`` and the address).
        """
        if self._client is not None:
            return self._client
        from dask.distributed import Client

        if self.cluster.scheduler is not None:
            self._client = connect(self.cluster.scheduler)
            return self._client
        self._local = local_cluster(self.cluster.workers)
        self._client = Client(self._local)
        return self._client

    def close(self) -> None:
        """Close the client and the private cluster (if any)."""
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._local is not None:
            self._local.close()
            self._local = None
        self._held = {}

    def run(
        self,
        jobs: Sequence[tuple[ModelSpec, DesignPoint]],
        handle: Callable[[int, Any, BaseException | None], None],
        *,
        summarize: bool = False,
    ) -> None:
        """Run jobs as Dask tasks, each on a worker that holds its geometry if it can.

        ``model.dispatch.Dispatcher`` picks each worker's next job (its threads' worth in
        flight); a job of a worker that leaves runs on another one, and when no worker is
        left the jobs not run are reported as failed.

        Args:
            jobs: (spec, point) pairs, each a distinct result.
            handle: Called in this process with (job index, what the task returned, None)
                or (job index, None, the error the worker raised), in completion order.
            summarize: What a worker sends back: the cycle (``run_job``), or the cycle
                and the kind's summary of it (``run_job_summary``).

        Raises:
            DataError: If the cluster has no workers.
        """
        if not jobs:
            return
        task = run_job_summary if summarize else run_job
        dispatch(self.client(), jobs, task, handle, held=self._held)


def dispatch(
    client: Any,
    jobs: Sequence[tuple[ModelSpec, DesignPoint]],
    task: Callable[..., Any],
    handle: Callable[[int, Any, BaseException | None], None],
    *,
    args: Callable[[int], tuple[Any, ...]] | None = None,
    held: dict[str, list[str]] | None = None,
    steal_min: int = STEAL_MIN,
) -> None:
    """Run ``task`` for every job on the workers of ``client`` (``model.dispatch.Dispatcher``).

    Args:
        client: A connected ``dask.distributed.Client``.
        jobs: (spec, point) pairs: their geometries steer where each runs.
        task: The function a worker runs, ``task(*args(i))``.
        handle: As ``ClusterRunner.run``'s; an error it raises cancels the jobs in flight.
        args: The task's arguments for job i (default: the job's spec and point).
        held: What each worker holds, from earlier calls; updated in place (also when a
            job's error ends the call), so the next call starts from it.
        steal_min: ``Dispatcher.steal_min``: pending jobs per holder from which a worker sets
            a held geometry up too (a very large value: never; for tasks that write a
            geometry's files into one shared folder).

    Raises:
        DataError: If the cluster has no workers, or a worker runs other code than this
            process (``other_code``).
    """
    held = {} if held is None else held
    workers = client.scheduler_info()["workers"]
    if not workers:
        raise DataError("the Dask cluster has no workers")
    wrong = other_code(client, sorted(workers))
    if wrong:
        raise _code_error(wrong)
    plan = Dispatcher(
        [geometry_key(spec, p) for spec, p in jobs],
        steal_min=steal_min,
        keep=WORKER_GEOMETRIES,
        max_losses=MAX_LOSSES,
        ahead=AHEAD,
    )
    for w in sorted(workers):
        plan.add_worker(w, workers[w].get("nthreads", 1), held.get(w, ()))
    try:
        _Drive(client, plan, jobs, handle, task, args or (lambda j: tuple(jobs[j]))).run()
    finally:  # what each worker holds now, for the next batch (a diagnosis runs many)
        held.clear()
        held.update({w: plan.holds(w) for w in plan.workers})


class _Drive:
    """One ``dispatch``: submit what the plan gives, hand back what completes."""

    def __init__(
        self,
        client: Any,
        plan: Dispatcher,
        jobs: Sequence[tuple[ModelSpec, DesignPoint]],
        handle: Callable[[int, Any, BaseException | None], None],
        task: Callable[..., Any],
        args: Callable[[int], tuple[Any, ...]],
    ) -> None:
        self.client, self.plan, self.jobs, self.handle, self.task = client, plan, jobs, handle, task
        self.args = args
        self.running: dict[Any, tuple[int, str]] = {}  # future → (job, worker)
        self.polled = time.monotonic()
        self.refused: set[str] = set()  # joined later, running other code

    def run(self) -> None:
        from dask.distributed import wait

        try:
            self._submit()
            while not self.plan.finished:
                try:
                    done, _ = wait(
                        list(self.running), timeout=POLL_S, return_when="FIRST_COMPLETED"
                    )
                except TimeoutError:
                    done = set()
                for future in sorted(done, key=lambda f: self.running[f][0]):
                    self._arrived(future)
                if not done or time.monotonic() - self.polled > POLL_S:
                    self._follow_workers()
                self._submit()
        except BaseException:
            self.client.cancel(list(self.running))
            raise

    def _submit(self) -> None:
        for w in self.plan.workers:
            while (j := self.plan.next_job(w)) is not None:
                future = self.client.submit(
                    self.task, *self.args(j), pure=False, workers=[w], allow_other_workers=False
                )
                self.running[future] = (j, w)

    def _arrived(self, future: Any) -> None:
        j, w = self.running.pop(future)
        self.plan.done(w, j)
        try:
            result = future.result()
        except Exception as err:  # the worker's error, re-raised here by Dask
            self.handle(j, None, err)
        else:
            self.handle(j, result, None)

    def _follow_workers(self) -> None:
        """Take the workers that joined; give the jobs of those that left to the others."""
        self.polled = time.monotonic()
        now = self.client.scheduler_info()["workers"]
        joined = [w for w in sorted(now) if w not in self.plan.workers and w not in self.refused]
        try:
            wrong = other_code(self.client, joined)
        except DataError as err:  # a worker without hingelab: the run goes on without it
            wrong = {w: [str(err)] for w in joined}
        for w, why in wrong.items():
            logger.warning(
                "Dask worker %s joined running other code (%s): not used", w, "; ".join(why)
            )
            self.refused.add(w)
        for w in sorted(now):
            if w not in self.refused:
                self.plan.add_worker(w, now[w].get("nthreads", 1))
        for w in [w for w in self.plan.workers if w not in now]:
            lost = [f for f, (_, at) in self.running.items() if at == w]
            self.client.cancel(lost)
            for f in lost:
                del self.running[f]
            removed = self.plan.remove_worker(w)
            logger.warning("Dask worker %s left: %d job(s) run again", w, len(removed.requeued))
            for j in removed.given_up:
                where = point_label(*self.jobs[j])
                self.handle(
                    j, None, DataError(f"{where}: {MAX_LOSSES} Dask workers left running it")
                )
        if not self.plan.workers:
            for j in self.plan.abandon():
                self.handle(j, None, DataError("the Dask cluster has no workers left"))
