"""The Krylov path of the contact Newton solver: same directions, same solutions as LU."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from fe.contact import krylov as contact_krylov
from fe.contact import krylov_step as contact_krylov_step
from fe.contact import newton as contact_newton
from fe.contact import preconditioner as contact_preconditioner
from fe.contact import residual as contact_residual
from fe.contact.dense import factor_jacobian
from fe.contact.gmres import gmres
from fe.contact.krylov import KrylovOptions
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState, LinearSolver


def random_W(m, seed, coupling=0.15):
    """SPD, diagonally dominant Delassus-like operator (3m × 3m)."""
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(3 * m, 3 * m))
    W = coupling * B @ B.T / (3 * m) + np.diag(rng.uniform(1.0, 2.0, 3 * m))
    return 0.5 * (W + W.T)


def iterate(W, seed, mu=0.3, k=0):
    """A frictional problem and an iterate with open, stick and slip points."""
    m = W.shape[0] // 3
    rng = np.random.default_rng(seed)
    w_free = rng.normal(scale=0.5, size=(m, 3)) + np.array([-0.3, 0.0, 0.0])
    prev_w = rng.normal(scale=0.2, size=(m, 3))
    G = rng.normal(size=(3 * m, k))
    prob = contact_residual.Problem(W, w_free, G, rng.normal(size=k), prev_w[:, 1:], mu)
    r = 1.0 / np.diagonal(W).reshape(m, 3).mean(axis=1)
    p = rng.normal(size=(m, 3)) + np.array([0.5, 0.0, 0.0])
    it = contact_residual.evaluate(prob, p, rng.normal(size=k), r)
    return prob, it, r


def dense_j(prob, lin):
    return contact_newton.form_jacobian(prob.W, np.arange(len(prob.w_free)), lin)


def test_preconditioner_inverts_the_updated_matrix_exactly():
    """M = J_new with its (same-status) S×S block taken from the base; M⁻¹ M = I."""
    W = random_W(30, 1)
    prob_a, it_a, r = iterate(W, 2)
    prob_b, it_b, _ = iterate(W, 3)  # another iterate: many points change status
    lin_a = contact_newton.linearise(prob_a, it_a, r)
    lin_b = contact_newton.linearise(prob_b, it_b, r)
    J_a, J_b = dense_j(prob_a, lin_a), dense_j(prob_b, lin_b)
    factor = factor_jacobian(J_a.copy(), lin_a.keys)
    base = contact_krylov.Base(factor, lin_a.closed, lin_a.kind, lin_a.u, lin_a.kappa)
    ws = contact_krylov.Workspace()
    ops = contact_preconditioner.operators(prob_b, lin_b, ws)
    opts = KrylovOptions(max_update=1.0, turn_cos=-1.0, kappa_change=1.0)  # keep every slip point
    pc = contact_preconditioner.precondition(base, lin_b, ops, opts)
    assert pc is not None
    assert len(pc.qN) > 0
    assert len(pc.qO) > 0
    assert len(pc.qS_new) > 0
    M = J_b.copy()
    M[np.ix_(pc.qS_new, pc.qS_new)] = J_a[np.ix_(pc.qS_old, pc.qS_old)]
    X = np.random.default_rng(4).normal(size=(len(lin_b.keys), 3))
    np.testing.assert_allclose(contact_preconditioner._solve_m(pc, M @ X), X, atol=1e-9)
    # Rows and columns of the changed unknowns are those of the exact matrix.
    np.testing.assert_allclose(contact_preconditioner._rows(ops, pc.qN), J_b[pc.qN], atol=1e-13)
    np.testing.assert_allclose(contact_preconditioner._cols(ops, pc.qN), J_b[:, pc.qN], atol=1e-13)


def test_slip_point_whose_kappa_moved_is_made_exact():
    """Same status and direction, another slip ratio κ: that point's unknowns are changed
    (exact in M) beyond ``kappa_change``, kept from the base below it."""
    W = random_W(30, 1)
    prob, it, r = iterate(W, 2)
    lin = contact_newton.linearise(prob, it, r)
    slipping = np.flatnonzero(lin.kind == 1)
    assert len(slipping) >= 2
    factor = factor_jacobian(dense_j(prob, lin), lin.keys)
    kappa = lin.kappa.copy()
    moved, nudged = slipping[0], slipping[1]
    kappa[moved] = 0.5 if kappa[moved] < 0.25 else kappa[moved] - 0.25
    kappa[nudged] += 0.01 if kappa[nudged] < 0.5 else -0.01
    base = contact_krylov.Base(factor, lin.closed, lin.kind, lin.u, kappa)
    ops = contact_preconditioner.operators(prob, lin, contact_krylov.Workspace())
    pc = contact_preconditioner.precondition(base, lin, ops, KrylovOptions(max_update=1.0))
    assert pc is not None
    changed = set(lin.keys[pc.qN] // 3)
    assert lin.closed[moved] in changed
    assert lin.closed[nudged] not in changed
    assert len(changed) == 1
    off = contact_preconditioner.precondition(
        base, lin, ops, KrylovOptions(max_update=1.0, kappa_change=1.0)
    )
    assert off is not None
    assert len(off.qN) == 0


def test_gmres_solves_a_nonsymmetric_system_to_its_tolerance():
    rng = np.random.default_rng(0)
    A = np.eye(40) * 4.0 + rng.normal(size=(40, 40))
    b = rng.normal(size=40)
    sol = gmres(lambda z: A @ z, lambda z: z, b, 1e-12, 40)
    assert sol.converged
    np.testing.assert_allclose(sol.z, np.linalg.solve(A, b), rtol=1e-9)
    exact = gmres(lambda z: A @ z, lambda z: np.linalg.solve(A, z), b, 1e-12, 40)
    assert exact.iterations == 1
    stalled = gmres(lambda z: A @ z, lambda z: z, b, 1e-14, 3)
    assert not stalled.converged


@pytest.mark.parametrize("k", [0, 3], ids=["no-rigid", "rigid"])
def test_krylov_step_equals_the_lu_step(k):
    W = random_W(25, 7)
    prob_a, it_a, r = iterate(W, 8, k=k)
    prob_b, it_b, _ = iterate(W, 9, k=k)
    ws = contact_krylov.Workspace()
    # Every slip point kept from the base (any turn, any κ): GMRES does the rest.
    opts = KrylovOptions(
        max_update=1.0, forcing=1e-12, max_iter=200, turn_cos=-1.0, kappa_change=1.0
    )
    first = contact_krylov_step.krylov_step(prob_a, it_a, r, 0.0, ws, opts)  # no base: factorises
    assert first is not None
    assert not first.reused
    step = contact_krylov_step.krylov_step(prob_b, it_b, r, 0.0, ws, opts)  # GMRES on the base
    ref = contact_newton.newton_step(prob_b, it_b, r, 0.0)
    assert step is not None
    assert ref is not None
    assert step.reused
    scale = np.max(np.abs(ref.dp))
    np.testing.assert_allclose(step.dp, ref.dp, atol=1e-9 * scale)
    a_scale = 1.0 + np.max(np.abs(ref.alpha_new), initial=0.0)
    np.testing.assert_allclose(step.alpha_new, ref.alpha_new, atol=1e-9 * a_scale)


def punch_history(settings, n=12):
    """Floating punch (3 translations) on a random W, loaded normally then dragged back and forth."""
    m = 40
    W = random_W(m, 21, coupling=0.3)
    G = np.zeros((3 * m, 3))
    G[0::3, 0] = G[1::3, 1] = G[2::3, 2] = 1.0
    rng = np.random.default_rng(22)
    w_free = np.zeros((m, 3))
    w_free[:, 0] = rng.uniform(0.0, 1.0, m)
    state = ContactState.initial(m, 3)
    out = []
    for i, q in enumerate(np.sin(np.linspace(0.0, 2.0 * np.pi, n))):
        e = np.array([10.0, 2.5 * q, 1.0 * q])
        res = solve_increment(W, w_free, state, settings, G=G, e=e, increment=i)
        out.append(res)
        state = res.state
    return out


def test_krylov_path_gives_the_lu_solution_with_fewer_factorisations():
    lu = punch_history(ContactSettings(mu=0.3, linear_solver=LinearSolver.LU, chord_rate=0.0))
    kr = punch_history(ContactSettings(mu=0.3, linear_solver=LinearSolver.KRYLOV))
    assert max(r.n_slip for r in lu) > 0
    assert max(r.n_stick for r in lu) > 0
    assert max(r.n_open for r in lu) > 0
    for a, b in zip(lu, kr, strict=True):
        np.testing.assert_allclose(b.state.p, a.state.p, atol=1e-9 * np.max(np.abs(a.state.p)))
        np.testing.assert_allclose(
            b.state.alpha, a.state.alpha, atol=1e-9 * np.max(np.abs(a.state.alpha))
        )
        np.testing.assert_array_equal(b.state.status, a.state.status)
        assert b.residuals[-1] <= ContactSettings().tol
    assert sum(r.linear_iterations for r in kr) > 0
    assert sum(r.factorizations for r in kr) < sum(r.factorizations for r in lu)
    assert sum(r.iterations for r in kr) <= 1.5 * sum(r.iterations for r in lu)


def test_workspace_is_dropped_with_its_operator():
    gc.collect()
    before = len(contact_krylov._WORKSPACES)
    W = random_W(5, 3)
    ws = contact_krylov.workspace_for(W)
    assert len(contact_krylov._WORKSPACES) == before + 1
    assert contact_krylov.workspace_for(W) is ws
    del W
    gc.collect()
    assert len(contact_krylov._WORKSPACES) == before


def test_default_is_the_krylov_path():
    assert ContactSettings().linear_solver is LinearSolver.KRYLOV
    assert LinearSolver.LU.value == "lu"


def test_linear_blocks_agree_with_its_sparse_operators():
    """The blockwise R G, (Tᵀ G)ᵀ, R W s and T dq + s of ``linearise`` equal the products
    with its sparse T and R (assembled separately from the same 3×3 blocks)."""
    W = random_W(20, 8)
    prob, it, r = iterate(W, 9, k=4)
    forced = np.zeros(len(prob.w_free), dtype=bool)
    forced[::2] = True  # open ones among them are closed frictionless
    lin = contact_newton.linearise(prob, it, r, forced)
    assert set(lin.kind.tolist()) == {0, 1, 2}
    np.testing.assert_allclose(lin.Jalpha, lin.R @ prob.G, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lin.H, (lin.T.T @ prob.G).T, rtol=0, atol=1e-12)
    own = -it.g[lin.closed]
    own_rows = own[lin.keep]
    slip_row = (np.cumsum(lin.keep.ravel()) - 1).reshape(-1, 3)[lin.kind == 1, 1]
    b_ref = -lin.R @ (W @ lin.s.ravel()) + lin.Jalpha @ it.alpha
    rest = np.setdiff1d(np.arange(len(lin.keys)), slip_row)  # slip rows' own target differs
    np.testing.assert_allclose(lin.b[rest], (own_rows + b_ref)[rest], rtol=0, atol=1e-12)
    dq = np.random.default_rng(10).normal(size=len(lin.keys))
    np.testing.assert_allclose(
        lin.expand(dq), lin.s + (lin.T @ dq).reshape(-1, 3), rtol=0, atol=1e-13
    )


@pytest.mark.parametrize("path", ["blocks", "sparse"])
@pytest.mark.parametrize("block_kind", ["all", "closed", "superset"])
@pytest.mark.parametrize("symmetric", [True, False], ids=["symmetric", "general"])
def test_form_jacobian_equals_r_w_t(path, block_kind, symmetric, monkeypatch):
    """Both ways of forming J (3×3 blocks; chunked row gathers of sparse T) equal R W T +
    diag(d) for any block holding the closed set."""
    monkeypatch.setattr(contact_newton, "_CHUNK", 7)  # several chunks, a ragged last one
    if path == "sparse":
        monkeypatch.setattr(contact_newton, "LOCAL_MAX", 0)
    W = random_W(25, 5)
    prob, it, r = iterate(W, 6)
    forced = np.zeros(len(prob.w_free), dtype=bool)
    forced[::3] = True  # open points closed frictionless, as in a predictor step
    lin = contact_newton.linearise(prob, it, r, forced)
    assert np.any(lin.kind == 2)
    assert np.any(lin.kind == 1)
    assert np.any(lin.kind == 0)
    J_ref = lin.R.toarray() @ W @ lin.T.toarray() + np.diag(lin.d)
    m = len(prob.w_free)
    block = {
        "all": np.arange(m),
        "closed": lin.closed,
        "superset": np.union1d(lin.closed, np.arange(0, m, 4)),
    }[block_kind]
    dofs = (3 * block[:, None] + np.arange(3)).ravel()
    J = contact_newton.form_jacobian(W[np.ix_(dofs, dofs)], block, lin, symmetric=symmetric)
    np.testing.assert_allclose(J, J_ref, rtol=0, atol=1e-13 * np.abs(J_ref).max())
    if symmetric:  # a float32 block gives J in float32, to single precision
        J32 = contact_newton.form_jacobian(W[np.ix_(dofs, dofs)].astype(np.float32), block, lin)
        assert J32.dtype == np.float32
        np.testing.assert_allclose(J32, J_ref, rtol=0, atol=1e-6 * np.abs(J_ref).max())
    assert J.flags.c_contiguous


@pytest.mark.parametrize("plain_max", [0, 600])  # by runs of rows; plain below 600 rows
@pytest.mark.parametrize("n_nonzero", [0, 1, 4, 20])
def test_sparse_product_equals_the_full_product(n_nonzero, plain_max, monkeypatch):
    """W x from the rows of x's support (or the full product when x is dense) is W x."""
    monkeypatch.setattr(contact_residual, "PLAIN_PRODUCT_MAX", plain_max)
    W = random_W(30, 7)
    rng = np.random.default_rng(8)
    x = np.zeros((30, 3))
    x[rng.choice(30, n_nonzero, replace=False)] = rng.normal(size=(n_nonzero, 3))
    np.testing.assert_allclose(contact_residual.sparse_product(W, x), W @ x.ravel(), atol=1e-13)


@pytest.mark.parametrize("max_runs", [200, 3])  # as rectangles of runs; by chunks of rows
def test_gather_block_is_the_ix_block(monkeypatch, max_runs):
    from fe.contact import dense as contact_dense

    monkeypatch.setattr(contact_dense, "GATHER_ROWS", 7)  # several chunks, a ragged last one
    monkeypatch.setattr(contact_dense, "GATHER_RUNS", max_runs)  # idx has 6 runs
    W = random_W(30, 7)
    idx = np.array([0, 3, 4, 5, 11, 12, 20, 21, 22, 23, 24, 25, 26, 28, 29, 30, 60, 89])
    out = contact_dense.gather_block(W, idx)
    np.testing.assert_array_equal(out, W[np.ix_(idx, idx)])
    assert out.flags.c_contiguous


def test_is_subset_agrees_with_isin():
    """The sorted-array subset test the block and working-set caches use, against np.isin."""
    from fe.contact import dense as contact_dense

    rng = np.random.default_rng(3)
    empty = np.zeros(0, dtype=np.int64)
    assert contact_dense.is_subset(empty, empty)
    assert not contact_dense.is_subset(np.array([2]), empty)
    for _ in range(300):
        b = np.unique(rng.integers(0, 40, size=rng.integers(0, 25)))
        a = np.unique(rng.choice(np.arange(45), size=rng.integers(0, 8), replace=False))
        assert contact_dense.is_subset(a, b) == bool(np.all(np.isin(a, b))), (a, b)
        assert contact_dense.is_subset(b[::2], b)


def test_sparse_product_reads_runs_of_rows(monkeypatch):
    """Support in runs of consecutive points, at both ends and alone: still W x."""
    monkeypatch.setattr(contact_residual, "PLAIN_PRODUCT_MAX", 0)  # 90 rows: by runs
    W = random_W(30, 7)
    x = np.zeros((30, 3))
    x[[0, 1, 2, 7, 12, 13, 14, 15, 29]] = np.random.default_rng(9).normal(size=(9, 3))
    np.testing.assert_allclose(contact_residual.sparse_product(W, x), W @ x.ravel(), atol=1e-13)


def test_state_w_is_the_exact_product_after_line_searches():
    """The line search updates W p incrementally; the reported w is W p + G α + w_free."""
    W = random_W(40, 9)
    m = 40
    rng = np.random.default_rng(10)
    w_free = rng.normal(scale=0.5, size=(m, 3)) + np.array([-0.3, 0.0, 0.0])
    G = rng.normal(size=(3 * m, 2))
    e = np.array([2.0, -1.0])
    res = solve_increment(W, w_free, ContactState.initial(m, 2), ContactSettings(mu=0.3), G=G, e=e)
    assert res.iterations > 2
    exact = (W @ res.state.p.ravel() + G @ res.state.alpha).reshape(-1, 3) + w_free
    np.testing.assert_array_equal(res.state.w, exact)


def test_w_block_is_kept_only_while_it_holds_the_closed_points():
    """A kept block is reused if it holds the closed set (with little slack), else regathered."""
    W = random_W(40, 11)
    prob_a, it_a, r = iterate(W, 12)
    prob_b, it_b, _ = iterate(W, 13)  # another closed set
    lin_a = contact_newton.linearise(prob_a, it_a, r)
    lin_b = contact_newton.linearise(prob_b, it_b, r)
    assert not np.all(np.isin(lin_b.closed, lin_a.closed))
    ws = contact_krylov.Workspace()
    ops_a = contact_preconditioner.operators(prob_a, lin_a, ws)
    assert ops_a.W_b is contact_preconditioner.operators(prob_a, lin_a, ws).W_b  # same set: kept
    ops_b = contact_preconditioner.operators(prob_b, lin_b, ws)
    assert np.all(np.isin(lin_b.closed, ops_b.block))
    dofs = (3 * ops_b.block[:, None] + np.arange(3)).ravel()
    np.testing.assert_array_equal(ops_b.W_b, W[np.ix_(dofs, dofs)])
    x = np.random.default_rng(14).normal(size=len(lin_b.keys))
    J_b = dense_j(prob_b, lin_b)
    np.testing.assert_allclose(contact_preconditioner._apply(ops_b, x), J_b @ x, atol=1e-12)


def test_w_block_is_dropped_when_w_changes_in_place():
    W = random_W(20, 15)
    ws = contact_krylov.workspace_for(W, float(W.sum()))
    ws.block, ws.W_block = np.arange(3), W[:9, :9].copy()
    assert contact_krylov.workspace_for(W, float(W.sum())).W_block is not None
    W[0, 0] += 1.0
    assert contact_krylov.workspace_for(W, float(W.sum())).W_block is None
    ws.block, ws.W_block = np.arange(3), W[:9, :9].copy()
    assert contact_krylov.workspace_for(W).W_block is None  # unknown fingerprint


def test_increments_on_one_w_equal_fresh_workspaces():
    """Kept blocks and base LU across increments (closed set growing, then shrinking)
    give the solutions of fresh workspaces and of the LU path."""
    m = 60
    W = random_W(m, 16, coupling=0.3)
    rng = np.random.default_rng(17)
    profile = rng.uniform(0.0, 1.0, m)
    G = np.zeros((3 * m, 1))
    G[0::3, 0] = 1.0
    krylov = ContactSettings(mu=0.3, krylov=KrylovOptions(max_update=0.5))
    lu = ContactSettings(mu=0.3, linear_solver=LinearSolver.LU)
    states = {"kept": ContactState.initial(m, 1), "fresh": ContactState.initial(m, 1)}
    state_lu = ContactState.initial(m, 1)
    for i, load in enumerate([5.0, 20.0, 60.0, 30.0, 10.0]):
        w_free = np.column_stack([profile, 0.01 * i * np.ones(m), np.zeros(m)])
        e = np.array([load])
        res = {
            "kept": solve_increment(W, w_free, states["kept"], krylov, G=G, e=e),
            "fresh": solve_increment(W.copy(), w_free, states["fresh"], krylov, G=G, e=e),
        }
        res_lu = solve_increment(W, w_free, state_lu, lu, G=G, e=e)
        states = {k: v.state for k, v in res.items()}
        state_lu = res_lu.state
        scale = np.abs(state_lu.p).max()
        for v in states.values():
            np.testing.assert_allclose(v.p, state_lu.p, atol=1e-9 * scale)
            np.testing.assert_array_equal(v.status, state_lu.status)
    assert 0 < res_lu.n_stick + res_lu.n_slip < m


def test_block_product_is_w_s_on_the_closed_dofs():
    """R W s from the kept block (plus rows of opened points outside it) equals R (W s)."""
    W = random_W(40, 18)
    prob, it, r = iterate(W, 19)
    lin = contact_newton.linearise(prob, it, r)
    ws = contact_krylov.Workspace()
    contact_preconditioner.ensure_block(prob, lin.closed, ws)
    assert ws.W_block is not None  # a gathered block, not W itself
    x = lin.s.copy()
    outside = np.setdiff1d(np.arange(40), ws.block)
    x[outside[:4]] = 1.0  # points that just opened carry force outside the block
    got = contact_preconditioner.block_product(prob, ws, x)
    np.testing.assert_allclose(lin.R @ got, lin.R @ (W @ x.ravel()), atol=1e-12)
    lin_block = contact_newton.linearise(
        prob, it, r, w_times=lambda v: contact_preconditioner.block_product(prob, ws, v)
    )
    np.testing.assert_allclose(lin_block.b, lin.b, atol=1e-12)


def test_block_product_reads_the_rows_of_opened_points_in_place():
    """Many opened points outside the block: their rows are not copied (exact product too).

    Where the contact zone changes sides thousands of points open at once; copying their
    rows of ``W`` had put a third of ``W`` on the contact phase's memory peak.
    """
    import tracemalloc

    m = 400
    W = random_W(m, 21)
    prob, it, r = iterate(W, 22)
    lin = contact_newton.linearise(prob, it, r)
    ws = contact_krylov.Workspace()
    contact_preconditioner.ensure_block(prob, lin.closed, ws)
    assert ws.W_block is not None
    x = lin.s.copy()
    outside = np.setdiff1d(np.arange(m), ws.block)
    assert len(outside) > 100
    x[outside[::2]] = 1.0  # every other point outside: many runs of rows
    tracemalloc.start()
    try:
        got = contact_preconditioner.block_product(prob, ws, x)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 0.02 * W.nbytes  # copying their rows would take len(outside)/(2m) of W
    dofs = (3 * ws.block[:, None] + np.arange(3)).ravel()
    np.testing.assert_allclose(got[dofs], (W @ x.ravel())[dofs], rtol=1e-12, atol=1e-12)
    assert not np.any(np.delete(got, dofs))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"forcing": 0.0}, r"krylov\.forcing must be in \(0, 1\)"),
        ({"turn_cos": 1.5}, r"krylov\.turn_cos must be in \[-1, 1\], got 1\.5"),
        ({"max_iter": 0}, r"krylov\.max_iter"),
        ({"max_update": -0.1}, r"krylov\.max_update"),
        ({"oversolve": 2.0}, r"krylov\.oversolve must be in \[0, 1\], got 2"),
        ({"kappa_change": -0.1}, r"krylov\.kappa_change must be in \[0, 1\], got -0\.1"),
    ],
)
def test_bad_krylov_option_names_itself(kwargs, match):
    from cad.errors import ParameterError

    with pytest.raises(ParameterError, match=match):
        KrylovOptions(**kwargs)


def test_oversolving_safeguard_keeps_the_solution_with_fewer_gmres_iterations():
    """GMRES stops at about ``tol/ρ`` in the last steps instead of ``ρ²``: every increment
    still ends below ``tol``, on the same forces, with fewer linear iterations."""
    tight = KrylovOptions(oversolve=0.0)
    loose = KrylovOptions(oversolve=1e-2)
    ref = punch_history(ContactSettings(mu=0.3, linear_solver=LinearSolver.KRYLOV, krylov=tight))
    new = punch_history(ContactSettings(mu=0.3, linear_solver=LinearSolver.KRYLOV, krylov=loose))
    for a, b in zip(ref, new, strict=True):
        assert b.residuals[-1] <= ContactSettings().tol
        np.testing.assert_allclose(b.state.p, a.state.p, atol=1e-8 * np.max(np.abs(a.state.p)))
        np.testing.assert_array_equal(b.state.status, a.state.status)
    assert sum(b.linear_iterations for b in new) < sum(a.linear_iterations for a in ref)


def test_systems_below_min_size_are_factorised_at_every_step():
    """Below ``min_size`` unknowns no base is updated: an LU per step, no GMRES, same forces."""
    kept = punch_history(ContactSettings(mu=0.3, linear_solver=LinearSolver.KRYLOV))
    fresh = punch_history(
        ContactSettings(
            mu=0.3, linear_solver=LinearSolver.KRYLOV, krylov=KrylovOptions(min_size=10**6)
        )
    )
    assert sum(a.linear_iterations for a in kept) > 0
    assert sum(b.linear_iterations for b in fresh) == 0
    assert sum(b.factorizations for b in fresh) == sum(b.iterations for b in fresh)
    for a, b in zip(kept, fresh, strict=True):
        np.testing.assert_allclose(b.state.p, a.state.p, atol=1e-9 * np.max(np.abs(a.state.p)))
        np.testing.assert_array_equal(b.state.status, a.state.status)
