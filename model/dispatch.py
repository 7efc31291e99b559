"""Which job a Dask worker runs next: the geometries it holds first, then where work piles up.

A worker keeps the geometries it prepared (``model.cluster.WORKER_GEOMETRIES`` of them, the
least recently used dropped), so a job of a geometry it holds costs only its cycle, and a
job of another geometry costs a set-up (build, mesh, factorise) first. ``Dispatcher`` is
the policy alone, without Dask, so it can be tested on its own; ``model.cluster.dispatch``
drives it with Dask futures:

* A worker has at most ``slots`` jobs in flight (its threads), plus ``ahead`` queued
  behind them while more than two jobs per slot of all workers are pending: its next job
  is there the moment one completes, not a round trip through this process later (about
  20 ms a job, measured); near the end of a batch each job goes to the worker that frees
  first. When a job completes, the runner asks for the worker's next one.
* A worker takes the next job of the geometry it ran last, or of another geometry it
  still holds, while one is pending (jobs of a geometry go in the order given).
* Else it takes a new geometry: one that no worker holds (the most pending jobs first, then
  the order given), so distinct geometries spread over the workers; or it joins the geometry
  with the most pending jobs per worker holding it, if that is at least ``steal_min``: a
  set-up is not worth one or two jobs the holder will run soon anyway.
* A worker that leaves gives its jobs in flight back (to the front of their geometry's
  queue); a job lost with ``max_losses`` workers is given up (it may be what kills them).

>>> d = Dispatcher(["a"] * 4, steal_min=2)
>>> d.add_worker("w1", slots=1)
>>> d.add_worker("w2", slots=1)
>>> d.next_job("w1"), d.next_job("w2"), d.next_job("w1")  # w2 joins: 3 pending per holder
(0, 1, None)
>>> d.done("w2", 1)
>>> d.next_job("w2"), d.next_job("w2")
(2, None)
"""

from __future__ import annotations

import math
from collections import OrderedDict, deque
from collections.abc import Sequence
from typing import NamedTuple

from cad.errors import check_range


class Removed(NamedTuple):
    """The jobs a worker had in flight when it left.

    Attributes:
        requeued: Given back, to run on another worker.
        given_up: Lost with ``max_losses`` workers: to be reported as failed.
    """

    requeued: list[int]
    given_up: list[int]


class Dispatcher:
    """Hand out jobs to workers, each job once, keeping geometries where they are prepared.

    Args:
        geometries: The geometry of each job (``model.spec.geometry_key``), job i at index i.
        steal_min: Pending jobs per holding worker from which another worker sets a held
            geometry up too (at least 2: one pending job is the holder's next).
        keep: Geometries a worker keeps prepared (the least recently used is dropped), as
            its service does; None: all.
        max_losses: A job lost with this many workers is given up.
        ahead: Jobs a worker may have queued beyond its slots while more than two per
            slot of all workers are pending (0: none).

    Raises:
        ParameterError: ``steal_min`` below 2, ``max_losses`` below 1 or ``ahead`` below 0.

    Attributes:
        setups: (worker, geometry) each time a worker was given a geometry it did not hold,
            in order.
    """

    def __init__(
        self,
        geometries: Sequence[str],
        *,
        steal_min: int = 2,
        keep: int | None = None,
        max_losses: int = 3,
        ahead: int = 0,
    ) -> None:
        check_range("steal_min", steal_min, 2, math.inf)
        check_range("max_losses", max_losses, 1, math.inf)
        check_range("ahead", ahead, 0, math.inf)
        self.ahead = ahead
        self.steal_min = steal_min
        self.keep = keep
        self.max_losses = max_losses
        self._geometry = list(geometries)
        self._pending: dict[str, deque[int]] = {}
        for job, g in enumerate(self._geometry):
            self._pending.setdefault(g, deque()).append(job)
        self._slots: dict[str, int] = {}
        self._flight: dict[str, set[int]] = {}
        self._held: dict[str, OrderedDict[str, None]] = {}
        self._losses: dict[int, int] = {}
        self.setups: list[tuple[str, str]] = []

    @property
    def workers(self) -> list[str]:
        """The workers jobs go to, in the order they were added."""
        return list(self._slots)

    @property
    def n_pending(self) -> int:
        """Jobs not handed out yet."""
        return sum(len(q) for q in self._pending.values())

    @property
    def finished(self) -> bool:
        """True when every job was handed out and is done (or given up)."""
        return not self._pending and not any(self._flight.values())

    def in_flight(self, worker: str) -> set[int]:
        """The jobs handed to ``worker`` and not done yet."""
        return set(self._flight.get(worker, ()))

    def holds(self, worker: str) -> list[str]:
        """The geometries ``worker`` holds prepared, the least recently used first."""
        return list(self._held.get(worker, ()))

    def add_worker(self, worker: str, slots: int, holds: Sequence[str] = ()) -> None:
        """Take ``worker``: ``slots`` jobs in flight at most, ``holds`` prepared already.

        Args:
            worker: Its name (a Dask worker's address).
            slots: Jobs it runs at once (its threads).
            holds: Geometries it prepared in an earlier batch, the least recently used first
                (``holds`` of that batch's dispatcher).
        """
        if worker in self._slots:
            return
        self._slots[worker] = max(1, slots)
        self._flight[worker] = set()
        held = self._held[worker] = OrderedDict.fromkeys(holds)
        while self.keep is not None and len(held) > self.keep:
            held.popitem(last=False)

    def remove_worker(self, worker: str) -> Removed:
        """Forget ``worker``: its jobs in flight go back to the front of their queues.

        Returns:
            The jobs requeued, and those given up (lost with ``max_losses`` workers).
        """
        if worker not in self._slots:
            return Removed([], [])
        flight = sorted(self._flight.pop(worker))
        del self._slots[worker], self._held[worker]
        requeued, given_up = [], []
        for job in reversed(flight):  # appendleft in reverse keeps the given order
            self._losses[job] = self._losses.get(job, 0) + 1
            if self._losses[job] >= self.max_losses:
                given_up.append(job)
                continue
            self._pending.setdefault(self._geometry[job], deque()).appendleft(job)
            requeued.append(job)
        return Removed(sorted(requeued), sorted(given_up))

    def abandon(self) -> list[int]:
        """Give up every pending job (no worker left to run them); return them in order."""
        jobs = sorted(j for q in self._pending.values() for j in q)
        self._pending.clear()
        return jobs

    def done(self, worker: str, job: int) -> None:
        """``job`` is done on ``worker`` (with a result or an error): a slot is free."""
        self._flight.get(worker, set()).discard(job)

    def next_job(self, worker: str) -> int | None:
        """The job ``worker`` runs next, or None (no free slot, or nothing worth its while)."""
        if worker not in self._slots:
            return None
        limit = self._slots[worker]
        if self.ahead and self.n_pending > 2 * sum(self._slots.values()):
            limit += self.ahead
        if len(self._flight[worker]) >= limit:
            return None
        g = self._choose(worker)
        if g is None:
            return None
        queue = self._pending[g]
        job = queue.popleft()
        if not queue:
            del self._pending[g]
        held = self._held[worker]
        if g not in held:
            self.setups.append((worker, g))
        held[g] = None
        held.move_to_end(g)
        while self.keep is not None and len(held) > self.keep:
            held.popitem(last=False)
        self._flight[worker].add(job)
        return job

    def _choose(self, worker: str) -> str | None:
        """The geometry ``worker`` takes its next job of, or None."""
        held = self._held[worker]
        for g in reversed(held):  # the one it ran last first
            if g in self._pending:
                return g
        best, best_score = None, (0.0, 0)
        for g, queue in self._pending.items():  # ties: the first given wins
            n = len(queue)
            holders = sum(g in h for h in self._held.values())
            per_holder = math.inf if holders == 0 else n / holders
            if per_holder < self.steal_min:
                continue
            if (per_holder, n) > best_score:
                best, best_score = g, (per_holder, n)
        return best
