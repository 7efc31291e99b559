"""Open-point elimination and single-precision bases change the path, never the solution."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from fe.contact import krylov as contact_krylov
from fe.contact import krylov_step as contact_krylov_step
from fe.contact import newton as contact_newton
from fe.contact import residual as contact_residual
from fe.contact import solve as contact_solve
from fe.contact import working as contact_working
from fe.contact.krylov import KrylovOptions
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState
from tests.fe.contact.test_krylov import iterate, punch_history, random_W


@pytest.mark.parametrize("k", [0, 3], ids=["no-rigid", "rigid"])
def test_single_precision_base_gives_the_float64_lu_step(k):
    """A fresh float32 base: the step comes from GMRES on the exact system, to 1e-10."""
    W = random_W(25, 7)
    prob, it, r = iterate(W, 9, k=k)
    opts = KrylovOptions(single_min=1, forcing=1e-12)
    ws = contact_krylov.Workspace()
    step = contact_krylov_step.krylov_step(prob, it, r, 0.0, ws, opts)
    ref = contact_newton.newton_step(prob, it, r, 0.0)
    assert step is not None
    assert ref is not None
    assert not step.reused
    assert ws.base is not None
    assert ws.base.factor.lu[0].dtype == np.float32
    assert ws.gmres_iterations > 0
    np.testing.assert_allclose(step.dp, ref.dp, atol=1e-10 * np.max(np.abs(ref.dp)))
    a_scale = 1.0 + np.max(np.abs(ref.alpha_new), initial=0.0)
    np.testing.assert_allclose(step.alpha_new, ref.alpha_new, atol=1e-10 * a_scale)


def test_single_precision_bases_give_the_same_history():
    plain = punch_history(ContactSettings(mu=0.3))
    single = punch_history(ContactSettings(mu=0.3, krylov=KrylovOptions(single_min=1)))
    for a, b in zip(plain, single, strict=True):
        np.testing.assert_allclose(b.state.p, a.state.p, atol=1e-9 * np.max(np.abs(a.state.p)))
        np.testing.assert_array_equal(b.state.status, a.state.status)


def pin_in_hole(m=96, seed=5):
    """A floating body (3 translations) touching a ring of points, most of them open."""
    rng = np.random.default_rng(seed)
    theta = np.linspace(0.0, 2.0 * np.pi, m, endpoint=False)
    W = random_W(m, seed, coupling=0.3)
    G = np.zeros((3 * m, 3))
    G[0::3, 0] = -np.cos(theta)  # the body moving +x closes the points near θ = 0
    G[0::3, 1] = -np.sin(theta)
    G[1::3, 0] = np.sin(theta)
    G[1::3, 1] = -np.cos(theta)
    G[2::3, 2] = 1.0
    w_free = np.zeros((m, 3))
    w_free[:, 0] = 0.02 * (1.0 - np.cos(theta)) + 1e-3 * rng.uniform(size=m)
    return W, G, w_free


def cycle(settings, loads):
    W, G, w_free = pin_in_hole()
    state = ContactState.initial(len(w_free), 3)
    out = []
    for i, (fx, fy) in enumerate(loads):
        e = np.array([fx, fy, 0.2 * fy])
        res = solve_increment(W, w_free, state, settings, G=G, e=e, increment=i)
        out.append(res)
        state = res.state
    return out


LOADS = [(10.0 * s, 6.0 * np.sin(3.0 * s)) for s in np.linspace(0.1, 1.0, 8)] + [
    (10.0 * np.cos(a), 10.0 * np.sin(a)) for a in np.linspace(0.0, 1.5, 8)
]


@pytest.mark.parametrize("margin", [0.0, 3.0], ids=["no-margin", "margin-3"])
def test_working_set_gives_the_full_solution(margin, monkeypatch):
    """Solved on the working set and checked: same forces, statuses, works as the full solve.

    The load turns, so the contact zone travels round the ring: points outside the working
    set close, and the check must catch every one of them (with no margin, all of them).
    """
    added = []
    solve = contact_working._restricted

    def spy(prob, points, gap=None):
        added.append(len(points))
        return solve(prob, points, gap)

    monkeypatch.setattr(contact_working, "_restricted", spy)
    full = cycle(ContactSettings(mu=0.3), LOADS)
    ws = cycle(ContactSettings(mu=0.3, working_set=True, working_margin=margin), LOADS)
    assert len(added) > 0  # the working set was used
    for a, b in zip(full, ws, strict=True):
        scale = np.max(np.abs(a.state.p))
        np.testing.assert_allclose(b.state.p, a.state.p, atol=1e-9 * scale)
        np.testing.assert_allclose(b.state.w, a.state.w, atol=1e-9 * np.max(np.abs(a.state.w)))
        np.testing.assert_array_equal(b.state.status, a.state.status)
        np.testing.assert_allclose(b.friction_work, a.friction_work, atol=1e-9 * scale)
        assert b.residuals[-1] <= ContactSettings().tol
    assert max(a.n_open for a in full) > 0.5 * len(full[0].state.p)


def test_working_set_never_drops_a_point_that_closes(monkeypatch):
    """A working set that misses every closing point is grown until none is missed."""
    monkeypatch.setattr(
        contact_working,
        "select_points",
        lambda prob, prev, it, margin: np.flatnonzero(np.any(prev.p != 0.0, axis=1)),
    )
    monkeypatch.setattr(contact_working, "HEADROOM", 0.0)  # no spare points to catch them
    sizes = []
    restrict = contact_working._restricted

    def spy(prob, points, gap=None):
        sizes.append(len(points))
        return restrict(prob, points, gap)

    monkeypatch.setattr(contact_working, "_restricted", spy)
    full = cycle(ContactSettings(mu=0.3), LOADS[:6])
    ws = cycle(ContactSettings(mu=0.3, working_set=True, working_margin=0.0), LOADS[:6])
    assert len(sizes) > 5  # rounds were added: the first sets missed closing points
    assert any(b > a for a, b in itertools.pairwise(sizes))
    for a, b in zip(full, ws, strict=True):
        np.testing.assert_allclose(b.state.p, a.state.p, atol=1e-9 * np.max(np.abs(a.state.p)))
        np.testing.assert_array_equal(b.state.status, a.state.status)


def test_a_grown_working_set_keeps_the_base_lu_on_the_same_slots():
    """The Krylov base carried to a larger set refers to the same global unknowns."""
    W = random_W(40, 11)
    prob, it, r = iterate(W, 12)
    old = np.arange(0, 40, 2, dtype=np.int64)
    new = np.union1d(old, [1, 7, 33]).astype(np.int64)

    def sub(points):
        d = contact_working._dofs(points)
        W_sub = W[np.ix_(d, d)]
        return W_sub, float(np.sum(W_sub))

    W_old, s_old = sub(old)
    sub_prob = contact_working._sub_problem(prob, old, W_old, s_old)
    sub_it = contact_residual.evaluate(sub_prob, it.p[old], it.alpha, r[old])
    ws_old = contact_krylov.workspace_for(W_old, s_old)
    assert contact_krylov_step.krylov_step(sub_prob, sub_it, r[old], 0.0, ws_old, KrylovOptions())
    base = ws_old.base
    assert base is not None
    assert len(base.factor.keys) > 0
    W_new, s_new = sub(new)
    taken = contact_working._take_base(W_old, old)
    assert contact_krylov.release(W_old) is None  # the old workspace is gone
    contact_working._give_base(taken, W_new, s_new, new)
    carried = contact_krylov.workspace_for(W_new, s_new).base
    assert carried is not None
    assert carried.factor.lu is base.factor.lu

    def slots(points, keys):
        return 3 * points[keys // 3] + keys % 3

    np.testing.assert_array_equal(slots(new, carried.factor.keys), slots(old, base.factor.keys))
    np.testing.assert_array_equal(new[carried.closed], old[base.closed])


def test_a_single_precision_predictor_lands_where_the_float64_one_does():
    """The rescue's predictor (taken unchecked) from a float32 LU: the same iterate to 1e-5."""
    from fe.contact import globalise as contact_globalise

    W = random_W(30, 13)
    prob, it, r = iterate(W, 14, k=3)
    assert np.any(it.law.status == 0)  # open points: the predictor closes them
    exact = contact_globalise._rescue(prob, it, r, r, 0.0, 0, None)
    single = contact_globalise._rescue(prob, it, r, r, 0.0, 0, None, single_min=1)
    scale = np.max(np.abs(exact.iterate.p))
    np.testing.assert_allclose(single.iterate.p, exact.iterate.p, atol=1e-5 * scale)
    assert not np.array_equal(single.iterate.p, exact.iterate.p)  # it was float32


def test_an_extrapolated_start_with_tension_outside_the_set_is_dropped(monkeypatch):
    """Points the start loads in tension (an extrapolation past opening) are zeroed first."""
    W, G, w_free = pin_in_hole()
    settings = ContactSettings(mu=0.3)
    prev = solve_increment(W, w_free, ContactState.initial(len(w_free), 3), settings,
                           G=G, e=np.array([10.0, 0.0, 0.0])).state  # fmt: skip
    e = np.array([12.0, 1.0, 0.0])
    full = solve_increment(W, w_free, prev, settings, G=G, e=e)
    far = np.flatnonzero(prev.w[:, 0] > np.quantile(prev.w[:, 0], 0.8))
    start_p = np.array(prev.p)
    start_p[far, 0] = -1e-3 * np.max(prev.p[:, 0])  # tension where the points are far open
    dropped = []
    without = contact_working._without

    def spy(prob, it, points, r):
        dropped.append(np.setdiff1d(far, points).size)
        return without(prob, it, points, r)

    monkeypatch.setattr(contact_working, "_without", spy)
    ws = solve_increment(
        W,
        w_free,
        prev,
        ContactSettings(mu=0.3, working_set=True),
        G=G,
        e=e,
        start=(start_p, np.array(prev.alpha)),
    )
    assert dropped
    assert dropped[0] > 0
    np.testing.assert_allclose(ws.state.p, full.state.p, atol=1e-9 * np.max(np.abs(full.state.p)))
    np.testing.assert_array_equal(ws.state.status, full.state.status)


def test_a_sub_solve_out_of_iterations_falls_back_to_the_whole_problem(monkeypatch):
    """A working-set solve that stops is continued on the whole problem, never raised."""
    from cad.errors import ConvergenceError
    from fe.contact import solve as contact_solve

    W, G, w_free = pin_in_hole()
    settings = ContactSettings(mu=0.3)
    state = ContactState.initial(len(w_free), 3)
    e = np.array([10.0, 0.0, 0.0])
    prev = solve_increment(W, w_free, state, settings, G=G, e=e).state
    e2 = np.array([11.0, 2.0, 0.5])
    full = solve_increment(W, w_free, prev, settings, G=G, e=e2)
    whole = contact_solve.newton
    calls = []

    def stalling(prob, it, r, cut, s, increment, max_iter=None):
        calls.append(len(prob.w_free))
        if len(prob.w_free) < len(w_free):  # a working-set sub-problem: give up at once
            raise ConvergenceError(
                "stalled",
                increment=increment,
                iteration=3,
                residual=1.0,
                partial=ContactState(it.p, it.w, it.law.status, it.alpha),
            )
        return whole(prob, it, r, cut, s, increment, max_iter)

    monkeypatch.setattr(contact_solve, "newton", stalling)
    ws = solve_increment(W, w_free, prev, ContactSettings(mu=0.3, working_set=True), G=G, e=e2)
    assert calls[0] < len(w_free)
    assert calls[-1] == len(w_free)
    np.testing.assert_allclose(ws.state.p, full.state.p, atol=1e-9 * np.max(np.abs(full.state.p)))
    np.testing.assert_array_equal(ws.state.status, full.state.status)
    assert ws.iterations >= 3


def test_loose_gmres_solves_in_float32_stay_within_their_tolerance():
    """Far from the solution (rtol >= 1e-4) GMRES takes W in float32: the step is still
    the LU step to about the forcing term, and near it (tight rtol) to 1e-10."""
    W = random_W(25, 7)
    prob, it, r = iterate(W, 9, k=3)
    assert it.rho**2 >= contact_krylov_step.SINGLE_OPERATOR_RTOL  # a loose solve
    opts = KrylovOptions(single_min=1)
    ws = contact_krylov.Workspace()
    first = contact_krylov_step.krylov_step(prob, it, r, 0.0, ws, opts)  # float32 base and block
    assert first is not None
    assert ws.W_single is not None
    step = contact_krylov_step.krylov_step(prob, it, r, 0.0, ws, opts)
    ref = contact_newton.newton_step(prob, it, r, 0.0)
    assert step is not None
    assert ref is not None
    scale = np.max(np.abs(ref.dp))
    np.testing.assert_allclose(step.dp, ref.dp, atol=1e-2 * scale)
    tight = contact_krylov_step.krylov_step(
        prob, it, r, 0.0, ws, KrylovOptions(single_min=1, forcing=1e-13)
    )
    assert tight is not None
    np.testing.assert_allclose(tight.dp, ref.dp, atol=1e-10 * scale)


def test_headroom_takes_the_nearest_open_points():
    gap = np.array([0.0, 5.0, 0.1, 3.0, 0.2, 9.0, 0.05, 4.0, 1.0, 2.0, 7.0, 6.0, 8.0, 0.3])
    gap = np.concatenate([gap, np.full(6, 10.0)])  # 20 points
    points = np.arange(0, 14, 2, dtype=np.int64)  # 7 points: one extra at 15 %
    got = contact_working._with_headroom(points, gap)
    assert got.dtype == np.int64
    # the smallest gap outside {0, 2, ..., 12} is point 13 (0.3 mm)
    np.testing.assert_array_equal(got, np.union1d(points, [13]))
    np.testing.assert_array_equal(contact_working._with_headroom(points, None), points)
    # never past MAX_FRACTION of the points (10 of 20): a set of 10 gets no spare point
    ten = np.arange(10, dtype=np.int64)
    np.testing.assert_array_equal(contact_working._with_headroom(ten, gap), ten)


def test_headroom_spares_gathers_while_the_zone_grows(monkeypatch):
    """A growing contact zone with a set of exactly the points needed is gathered at every
    increment; with spare points nearest to closing, at fewer, with the same solution."""
    counts = {}
    gather = contact_working.gather_block
    for headroom in (0.0, contact_working.HEADROOM):
        monkeypatch.setattr(contact_working, "HEADROOM", headroom)
        n = [0]

        def counted(W, idx, n=n):
            n[0] += 1
            return gather(W, idx)

        monkeypatch.setattr(contact_working, "gather_block", counted)
        settings = ContactSettings(mu=0.3, working_set=True, working_margin=0.0)
        counts[headroom] = (n, cycle(settings, LOADS[:8]))
    (n_none, plain), (n_spare, spare) = counts.values()
    assert n_spare[0] < n_none[0]
    for a, b in zip(plain, spare, strict=True):
        np.testing.assert_allclose(b.state.p, a.state.p, atol=1e-9 * np.max(np.abs(a.state.p)))
        np.testing.assert_array_equal(b.state.status, a.state.status)


def test_only_one_set_of_w_blocks_lives_at_a_time(monkeypatch):
    """Whole solves and working-set solves alternate; the idle one's blocks are dropped.

    Before a working-set solve the whole ``W``'s workspace (its gathered block, float32
    copy and base LU) is gone, and before a whole solve the kept working set (its
    ``W_sub`` and workspace) is gone; the base LU is handed on, not refactorised.
    """
    W, G, w_free = pin_in_hole()
    settings = ContactSettings(mu=0.3, working_set=True, working_margin=1.0)
    seen = {"sub": 0, "whole": 0, "handed": 0, "into_sub": 0}
    inner = contact_solve.newton
    last = [""]

    def spy(prob, it, r, cut, s, increment, max_iter=None):
        if not s.working_set:  # the reference solves
            return inner(prob, it, r, cut, s, increment, max_iter)
        kept = contact_working._KEPT.get(W)
        if prob.W is W:  # the whole problem: no working set kept beside it
            seen["whole"] += 1
            assert kept is None
            ws = contact_krylov._WORKSPACES.get(W)
            seen["handed"] += last[0] == "sub" and ws is not None and ws.base is not None
            last[0] = "whole"
        else:  # a working set: the whole W has no workspace beside it
            seen["sub"] += 1
            assert kept is not None
            assert kept.W_sub is prob.W
            assert contact_krylov._WORKSPACES.get(W) is None
            sub_ws = contact_krylov._WORKSPACES.get(prob.W)
            seen["into_sub"] += (
                last[0] == "whole" and sub_ws is not None and sub_ws.base is not None
            )
            last[0] = "sub"
        return inner(prob, it, r, cut, s, increment, max_iter)

    monkeypatch.setattr(contact_solve, "newton", spy)
    # Fewer than MAX_FRACTION closing points first (working set), then a load that
    # closes most of the ring (whole), then back: both hand-overs happen.
    loads = [(3.0, 0.0), (4.0, 0.5), (60.0, 0.0), (80.0, 5.0), (4.0, 0.0), (3.0, 1.0)]
    state = ContactState.initial(len(w_free), 3)
    ref_state = state
    for i, (fx, fy) in enumerate(loads):
        e = np.array([fx, fy, 0.2 * fy])
        state = solve_increment(W, w_free, state, settings, G=G, e=e, increment=i).state
        ref_state = solve_increment(W, w_free, ref_state, ContactSettings(mu=0.3), G=G, e=e).state
        np.testing.assert_allclose(state.p, ref_state.p, atol=1e-9 * np.max(np.abs(ref_state.p)))
    assert seen["sub"] > 0
    assert seen["whole"] > 0
    assert seen["handed"] > 0  # a whole solve after a working set started from its base
    assert seen["into_sub"] > 0  # ... and a working set after a whole solve
