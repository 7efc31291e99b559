"""Which job a Dask worker runs next (``model.dispatch.Dispatcher``), without a cluster.

The timing checks run the policy in a small discrete-event simulation: each worker runs
one job at a time and pays a set-up for a geometry it does not hold (its own LRU of four,
kept here apart from the dispatcher's bookkeeping).
"""

from __future__ import annotations

import heapq
from collections import Counter, OrderedDict

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cad.errors import ParameterError
from model.dispatch import Dispatcher


def _drain(d: Dispatcher, order: list[str]) -> dict[int, str]:
    """Complete jobs in turn over ``order``'s workers (each takes its next job at once)."""
    ran: dict[int, str] = {}
    for w in order:
        d.add_worker(w, 1)
    while not d.finished:
        for w in order:
            for j in d.in_flight(w):
                d.done(w, j)
                ran[j] = w
            j = d.next_job(w)
            assert j is None or j not in ran
    return ran


class _Workers:
    """Workers that run one job at a time, each with its own LRU of four geometries."""

    def __init__(
        self, n_workers: int, cost_s: dict[str, float], setup_s: float | dict[str, float]
    ) -> None:
        self.names = [f"w{k}" for k in range(n_workers)]
        self.prepared: dict[str, OrderedDict[str, None]] = {w: OrderedDict() for w in self.names}
        self.cost_s, self.setup_s = cost_s, setup_s
        self.events: list[tuple[float, int, str]] = []  # (finish time [s], job, worker)

    def start(self, d: Dispatcher, geometries: list[str], w: str, t: float) -> None:
        """Give ``w`` its next job at time ``t`` [s], if the dispatcher has one for it."""
        j = d.next_job(w)
        if j is None:
            return
        g = geometries[j]
        lru = self.prepared[w]
        setup = self.setup_s if isinstance(self.setup_s, float) else self.setup_s[g]
        cost = self.cost_s[g] + (0.0 if g in lru else setup)
        lru[g] = None
        lru.move_to_end(g)
        while len(lru) > 4:
            lru.popitem(last=False)
        heapq.heappush(self.events, (t + cost, j, w))


def simulate(
    batches: list[list[str]],
    cost_s: dict[str, float],
    n_workers: int,
    *,
    setup_s: float | dict[str, float] = 10.0,
    steal_min: int = 2,
) -> float:
    """Wall time [s] of batches run one after another, the holdings kept between them.

    ``setup_s``: one set-up cost for every geometry, or each geometry's own.
    """
    pool = _Workers(n_workers, cost_s, setup_s)
    held: dict[str, list[str]] = {}
    clock = 0.0
    for geometries in batches:
        d = Dispatcher(geometries, steal_min=steal_min, keep=4)
        for w in pool.names:
            d.add_worker(w, 1, held.get(w, ()))
        for w in pool.names:
            pool.start(d, geometries, w, clock)
        while pool.events:
            clock, j, w = heapq.heappop(pool.events)
            d.done(w, j)
            for v in pool.names:  # the worker that finished, and any idle one that may join now
                if not d.in_flight(v):
                    pool.start(d, geometries, v, clock)
        assert d.finished
        held = {w: d.holds(w) for w in pool.names}
    return clock


def test_one_geometry_of_twelve_jobs_runs_on_both_workers_in_order() -> None:
    d = Dispatcher(["g"] * 12)
    ran = _drain(d, ["a", "b"])
    assert Counter(ran.values()) == {"a": 6, "b": 6}
    assert d.setups == [("a", "g"), ("b", "g")]  # each sets it up once
    assert list(ran) == list(range(12))  # handed out in the order given


def test_two_balanced_geometries_go_one_to_each_worker_set_up_once() -> None:
    d = Dispatcher(["g1"] * 6 + ["g2"] * 6)
    ran = _drain(d, ["a", "b"])
    assert d.setups == [("a", "g1"), ("b", "g2")]
    assert {j for j, w in ran.items() if w == "a"} == set(range(6))


def test_distinct_geometries_spread_first_the_largest_first() -> None:
    d = Dispatcher(["g1", "g2", "g2", "g3", "g3", "g3"])
    for w in "abc":
        d.add_worker(w, 1)
    assert [d.next_job(w) for w in "abc"] == [3, 1, 0]  # g3 (3 jobs), g2 (2), g1 (1)


def test_no_set_up_for_fewer_than_steal_min_jobs_per_holder() -> None:
    d = Dispatcher(["g"] * 2)  # the holder runs job 0; one job left
    d.add_worker("a", 1)
    d.add_worker("b", 1)
    assert d.next_job("a") == 0
    assert d.next_job("b") is None  # 1 pending for 1 holder: not worth a set-up
    d3 = Dispatcher(["g"] * 3)
    d3.add_worker("a", 1)
    d3.add_worker("b", 1)
    assert (d3.next_job("a"), d3.next_job("b")) == (0, 1)  # 2 pending for 1 holder
    d4 = Dispatcher(["g"] * 6, steal_min=3)
    for w in "abc":
        d4.add_worker(w, 1)
    assert [d4.next_job(w) for w in "abc"] == [0, 1, None]  # 4 pending / 2 holders < 3


def test_a_worker_that_held_the_geometry_before_runs_its_last_job() -> None:
    d = Dispatcher(["g"] * 2)
    d.add_worker("a", 1)
    d.add_worker("b", 1, holds=["g"])  # prepared in an earlier batch
    d.add_worker("c", 1)
    assert [d.next_job(w) for w in "abc"] == [0, 1, None]
    assert d.setups == [("a", "g")]


def test_a_dropped_geometry_no_longer_counts_as_held() -> None:
    d = Dispatcher(["g1", "g2", "g3"], keep=2)
    assert _drain(d, ["a"]) == {0: "a", 1: "a", 2: "a"}
    assert d.holds("a") == ["g2", "g3"]  # g1 dropped from a's LRU of two
    later = Dispatcher(["g1"], keep=2)
    later.add_worker("a", 1, d.holds("a"))
    later.add_worker("b", 1)
    assert later.next_job("b") == 0  # g1 has no holder: b takes its one job


def test_no_more_jobs_in_flight_than_slots() -> None:
    d = Dispatcher(["g"] * 5)
    d.add_worker("a", 2)
    assert [d.next_job("a") for _ in range(3)] == [0, 1, None]
    d.done("a", 0)
    assert (d.next_job("a"), d.next_job("a")) == (2, None)
    assert d.in_flight("a") == {1, 2}


def test_a_job_waits_queued_behind_the_running_one_only_while_many_are_pending() -> None:
    d = Dispatcher(["g"] * 9, ahead=1)
    d.add_worker("a", 1)
    d.add_worker("b", 1)
    assert [d.next_job("a") for _ in range(3)] == [0, 1, None]  # 8, then 7 pending > 2 × 2
    assert [d.next_job("b") for _ in range(3)] == [2, 3, None]
    d.done("a", 0)
    assert (d.next_job("a"), d.next_job("a")) == (4, None)  # 5 pending > 4: one queued ahead
    d.done("a", 1)
    assert d.next_job("a") is None  # 4 pending, not > 4: job 4 runs, none waits behind it
    d.done("a", 4)
    assert (d.next_job("a"), d.next_job("a")) == (5, None)
    assert d.in_flight("a") == {5}
    with pytest.raises(ParameterError, match="ahead"):
        Dispatcher(["g"], ahead=-1)


def test_a_removed_workers_jobs_are_given_back_and_given_up_after_max_losses() -> None:
    d = Dispatcher(["g"] * 4, max_losses=2)
    d.add_worker("a", 2)
    assert (d.next_job("a"), d.next_job("a")) == (0, 1)
    assert d.remove_worker("a") == ([0, 1], [])
    assert d.workers == []
    d.add_worker("b", 2)
    assert (d.next_job("b"), d.next_job("b")) == (0, 1)  # again first, in order
    assert d.remove_worker("b") == ([], [0, 1])  # lost twice: given up
    assert d.abandon() == [2, 3]
    assert d.finished


def test_steal_min_below_two_is_refused_by_name() -> None:
    with pytest.raises(ParameterError, match="steal_min"):
        Dispatcher(["g"], steal_min=1)


def test_unequal_geometries_run_at_least_1_7_times_faster_on_two_workers() -> None:
    """Rounds of a diagnosis: 6 cases on a cheap and a 3× dearer geometry, five rounds."""
    batches = [["cheap"] * 6 + ["dear"] * 6] * 5
    cost = {"cheap": 2.5, "dear": 7.5}
    one = simulate(batches, cost, 1)
    assert one == pytest.approx(2 * 10.0 + 5 * 6 * 10.0)  # two set-ups, every cycle
    assert one / simulate(batches, cost, 2) >= 1.7
    pinned = simulate(batches, cost, 2, steal_min=10**6)  # never join: one geometry each
    assert one / pinned < 1.4


def test_a_diagnosis_shaped_pair_of_batches_runs_1_85_times_faster_on_two_workers() -> None:
    """The 6-case default-mesh diagnosis (benchmarks/bench_diagnose_workers.txt): 132 coarse
    grid runs on two clearances and the fine baseline, then one round on all four geometries;
    each geometry's cycle and set-up cost [s] as measured on one thread, rounded."""
    cost = {"coarse0.1": 0.95, "coarse0": 0.45, "fine0.1": 1.15, "fine0": 2.2}
    setup = {"coarse0.1": 0.8, "coarse0": 0.8, "fine0.1": 2.0, "fine0": 2.5}
    grids = ["coarse0.1"] * 66 + ["coarse0"] * 66 + ["fine0.1"] * 3 + ["fine0"] * 3
    rounds = ["fine0.1"] * 6 + ["fine0"] * 6 + ["coarse0"] * 3 + ["coarse0.1"] * 3
    one = simulate([grids, rounds], cost, 1, setup_s=setup)
    assert one == pytest.approx(sum(cost[g] for g in grids + rounds) + sum(setup.values()))
    two = simulate([grids, rounds], cost, 2, setup_s=setup)
    assert one / two >= 1.85  # ideal 2: set-ups of geometries both workers hold cost the rest
    pinned = simulate([grids, rounds], cost, 2, setup_s=setup, steal_min=10**6)
    assert one / pinned < one / two


def test_one_geometry_of_many_jobs_runs_faster_on_two_workers() -> None:
    batches = [["g"] * 12]
    one = simulate(batches, {"g": 7.5}, 1)
    assert one / simulate(batches, {"g": 7.5}, 2) == pytest.approx(100.0 / 55.0)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    geometries=st.lists(st.sampled_from("abcd"), max_size=25),
    slots=st.lists(st.integers(1, 2), min_size=1, max_size=3),
    data=st.data(),
)
def test_every_job_runs_once_within_the_rules(
    geometries: list[str], slots: list[int], data: st.DataObject
) -> None:
    d = Dispatcher(geometries, max_losses=2, keep=2)
    n_slots: dict[str, int] = {}
    for k, s in enumerate(slots):
        n_slots[f"w{k}"] = s
        d.add_worker(f"w{k}", s)
    ran: Counter[int] = Counter()
    given_up: set[int] = set()
    handed: dict[int, list[int]] = {}  # geometry → jobs in the order first handed out
    pending = Counter(geometries)
    flight: dict[int, str] = {}
    fresh = len(slots)
    while not d.finished:
        for w in d.workers:  # every free slot asks
            while True:
                before = {g: [v for v in d.workers if g in d.holds(v)] for g in pending}
                had = d.holds(w)
                j = d.next_job(w)
                if j is None:
                    break
                g = geometries[j]
                assert j not in flight
                assert j not in ran
                assert j not in given_up
                assert len(d.in_flight(w)) <= n_slots[w]
                if g not in had and before[g]:  # joined a geometry another worker holds
                    assert pending[g] / len(before[g]) >= 2
                pending[g] -= 1
                if pending[g] == 0:
                    del pending[g]
                if j not in handed.setdefault(g, []):
                    handed[g].append(j)
                flight[j] = w
        if not flight:  # nothing runs: either no worker is left or every job is done
            assert not d.workers or d.finished
            for j in d.abandon():
                given_up.add(j)
            break
        action = data.draw(st.sampled_from(["done", "done", "done", "leave", "join"]))
        if action == "done":
            j = data.draw(st.sampled_from(sorted(flight)))
            d.done(flight.pop(j), j)
            ran[j] += 1
        elif action == "leave":
            w = data.draw(st.sampled_from(sorted(set(flight.values()))))
            requeued, lost = d.remove_worker(w)
            assert sorted(requeued + lost) == sorted(j for j, v in flight.items() if v == w)
            for j in requeued + lost:
                del flight[j]
            for j in requeued:
                pending[geometries[j]] += 1
            given_up.update(lost)
        else:
            n_slots[f"w{fresh}"] = 1
            d.add_worker(f"w{fresh}", 1)
            fresh += 1
    assert d.finished
    assert all(n == 1 for n in ran.values())
    assert set(ran) | given_up == set(range(len(geometries)))
    assert not set(ran) & given_up
    for jobs in handed.values():
        assert jobs == sorted(jobs)  # a geometry's jobs first handed out in the order given
