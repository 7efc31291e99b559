"""Analytic, energy and invariance tests of the condensed frictional-contact solver."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from cad.errors import ConvergenceError, ParameterError
from fe.contact.law import ContactStatus, coulomb_step
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState, LinearSolver, complementarity

TOL = ContactSettings().tol
# Converged quantities are compared at a few hundred times the solver tolerance: the
# residual ρ is relative to the displacement scale and W here has condition number < 10.
CMP = 1e3 * TOL


def random_structure(m, seed, extra=6):
    """Random SPD stiffness K (n×n) with slave DOFs first; returns K, C, W = C K⁻¹ Cᵀ."""
    rng = np.random.default_rng(seed)
    n = 3 * m + extra
    A = rng.normal(size=(n, n))
    K = A @ A.T / n + np.diag(rng.uniform(1.0, 2.0, n))
    C = np.eye(n)[: 3 * m]
    W = C @ np.linalg.solve(K, C.T)
    return K, C, 0.5 * (W + W.T)


def run_history(W, w_frees, settings, state=None, **kw):
    m = W.shape[0] // 3
    state = ContactState.initial(m) if state is None else state
    results = []
    for i, wf in enumerate(w_frees):
        res = solve_increment(W, wf, state, settings, increment=i, **kw)
        results.append(res)
        state = res.state
    return results


# --- single point, analytic -------------------------------------------------------------


@pytest.mark.parametrize("theta", [0.0, 2.0], ids=["along-t1", "oblique"])
@pytest.mark.parametrize(
    "drag_ratio", [0.5, 0.99, 1.01, 3.0], ids=["stick-half", "stick-edge", "slip-edge", "slip-3x"]
)
def test_single_point_sticks_below_mu_n_and_slips_above_by_exact_amount(theta, drag_ratio):
    a_n, a_t, mu, delta = 0.5, 2.0, 0.3, 0.8
    normal = delta / a_n  # N
    drag = drag_ratio * mu * normal * a_t  # mm of free tangential motion
    direction = np.array([np.cos(theta), np.sin(theta)])
    W = np.diag([a_n, a_t, a_t])
    w_free = np.array([[-delta, *(drag * direction)]])
    res = solve_increment(W, w_free, ContactState.initial(1), ContactSettings(mu=mu))
    p, w = res.state.p[0], res.state.w[0]
    assert p[0] == pytest.approx(normal, rel=CMP)
    assert w[0] == pytest.approx(0.0, abs=CMP * delta)
    if drag_ratio < 1.0:
        assert res.state.status[0] == ContactStatus.STICK
        np.testing.assert_allclose(p[1:], -drag / a_t * direction, rtol=CMP)
        np.testing.assert_allclose(w[1:], 0.0, atol=CMP * drag)
    else:
        assert res.state.status[0] == ContactStatus.SLIP
        np.testing.assert_allclose(p[1:], -mu * normal * direction, rtol=CMP)
        slip = drag - a_t * mu * normal
        np.testing.assert_allclose(w[1:], slip * direction, rtol=CMP)
        assert res.dissipation[0] == pytest.approx(mu * normal * slip, rel=CMP)


def test_single_point_opens_when_pulled_apart():
    res = solve_increment(
        np.eye(3), np.array([[0.3, 1.0, 0.0]]), ContactState.initial(1), ContactSettings(mu=0.5)
    )
    assert res.n_open == 1
    np.testing.assert_array_equal(res.state.p, 0.0)
    np.testing.assert_allclose(res.state.w, [[0.3, 1.0, 0.0]])


# --- Jenkins element: exact hysteresis loop ---------------------------------------------


def jenkins(theta, k1=1.0, k2=1.0, normal=4.0, mu=0.25, force=4.0):
    """Load node L —k1— block B on rigid ground (friction), L —k2— ground; F on L.

    DOFs [L_n, L_t1, L_t2, B_n, B_t1, B_t2]; the tangential force acts along angle theta.
    """
    Kd = np.array([[k1 + k2, -k1], [-k1, k1]])
    K = np.kron(Kd, np.eye(3))
    C = np.hstack([np.zeros((3, 3)), np.eye(3)])
    W = C @ np.linalg.solve(K, C.T)
    d = np.array([0.0, np.cos(theta), np.sin(theta)])

    def f_of(lam):
        return np.concatenate([lam * force * d, [-normal, 0.0, 0.0]])

    return K, C, W, f_of, ContactSettings(mu=mu)


def load_path(levels, per_unit):
    path = [levels[0]]
    for a, b in pairwise(levels):
        n = round(abs(b - a) * per_unit)
        path += [a + (b - a) * i / n for i in range(1, n + 1)]
    return path


def structure_history(K, C, W, f_of, settings, lams):
    m = W.shape[0] // 3
    state, out = ContactState.initial(m), []
    for i, lam in enumerate(lams):
        f = f_of(lam)
        w_free = (C @ np.linalg.solve(K, f)).reshape(m, 3)
        res = solve_increment(W, w_free, state, settings, increment=i)
        u = np.linalg.solve(K, f + C.T @ res.state.p.ravel())
        out.append((lam, f, u, res))
        state = res.state
    return out


@pytest.mark.parametrize("theta", [0.0, 0.7], ids=["t1", "oblique"])
def test_jenkins_cycle_reproduces_analytic_loop_and_friction_work(theta):
    K, C, W, f_of, settings = jenkins(theta)
    lams = load_path([0.0, 1.0, -1.0, 1.0], per_unit=20)  # slip onsets at λ = 0.5 and 0
    hist = structure_history(K, C, W, f_of, settings, lams)
    start = lams.index(1.0)
    cycle = hist[start:]
    area = sum(0.5 * (f0 + f1) @ (u1 - u0) for (_, f0, u0, _), (_, f1, u1, _) in pairwise(cycle))
    friction = sum(float(np.sum(h[3].friction_work)) for h in cycle[1:])
    # Elastic–perfectly-plastic loop: 4 μN (U - μN/k1), U = (F - μN)/k2 = 3, μN/k1 = 1.
    assert area == pytest.approx(8.0, rel=CMP)
    assert friction == pytest.approx(8.0, rel=CMP)
    np.testing.assert_allclose(cycle[-1][2], cycle[0][2], atol=CMP)
    statuses = [int(h[3].state.status[0]) for h in hist]
    assert statuses[lams.index(0.45)] == ContactStatus.STICK
    assert statuses[lams.index(0.55)] == ContactStatus.SLIP


def test_three_block_iwan_cycle_matches_masing_loop_area():
    """Load node L (spring k2 to ground) drags three blocks through springs k1_i.

    Block i sticks until its spring force reaches T_i = μ N_i. For tip force F = 5 the
    backbone F(U) = k2 U + Σ min(k1_i U, T_i) gives U = 2, and the Masing loop area is
    Σ 4 T_i (U - T_i/k1_i) = 14.5. All kinks fall on the ΔF = 0.5 load grid.
    """
    k2, k1 = 1.0, np.array([1.0, 2.0, 1.0])
    mu, normal = 0.25, np.array([2.0, 6.0, 4.0])  # T = 0.5, 1.5, 1.0
    Kd = np.zeros((4, 4))
    Kd[0, 0] = k2 + k1.sum()
    Kd[0, 1:] = Kd[1:, 0] = -k1
    Kd[1:, 1:] = np.diag(k1)
    K = np.kron(Kd, np.eye(3))
    C = np.eye(12)[3:]
    W = C @ np.linalg.solve(K, C.T)
    d = np.array([0.0, np.cos(0.3), np.sin(0.3)])

    def f_of(lam):
        f = np.zeros(12)
        f[:3] = 5.0 * lam * d
        f[3::3] = -normal
        return f

    lams = load_path([0.0, 1.0, -1.0, 1.0], per_unit=10)
    hist = structure_history(K, C, W, f_of, ContactSettings(mu=mu), lams)
    cycle = hist[lams.index(1.0) :]
    area = sum(0.5 * (a[1] + b[1]) @ (b[2] - a[2]) for a, b in pairwise(cycle))
    friction = sum(float(np.sum(h[3].friction_work)) for h in cycle[1:])
    assert area == pytest.approx(14.5, rel=CMP)
    assert friction == pytest.approx(14.5, rel=CMP)
    np.testing.assert_allclose(cycle[-1][2], cycle[0][2], atol=CMP)
    assert cycle[0][2][:3] @ d == pytest.approx(2.0, rel=CMP)  # tip displacement U


@pytest.mark.parametrize("mu", [0.0, 0.2], ids=["frictionless", "mu0.2"])
def test_energy_balance_each_increment_and_over_cycle(mu):
    m = 5
    K, C, W = random_structure(m, seed=3)
    rng = np.random.default_rng(7)
    f0 = rng.normal(size=K.shape[0])
    preload = np.zeros(K.shape[0])
    preload[0 : 3 * m : 3] = -1.0  # press every slave node onto its master

    def f_of(lam):
        return preload + 2.0 * lam * f0  # some points open, some slip

    lams = load_path([0.0, 1.0, -1.0, 1.0, -1.0, 1.0], per_unit=10)
    hist = structure_history(K, C, W, f_of, ContactSettings(mu=mu), lams)
    for (_, f0_, u0, _), (_, f1, u1, res) in pairwise(hist):
        w_ext = 0.5 * (f0_ + f1) @ (u1 - u0)
        d_energy = 0.5 * u1 @ K @ u1 - 0.5 * u0 @ K @ u0
        contact = float(np.sum(res.friction_work + res.normal_work))
        assert w_ext == pytest.approx(d_energy + contact, abs=1e-12 * max(1.0, abs(w_ext)))
        assert np.all(res.dissipation >= -CMP * np.max(np.abs(u1)))
    peaks = [i for i, lam in enumerate(lams) if lam == 1.0]
    cycle = hist[peaks[-2] :]  # the last cycle, +1 → -1 → +1
    area = sum(0.5 * (a[1] + b[1]) @ (b[2] - a[2]) for a, b in pairwise(cycle))
    friction = sum(float(np.sum(h[3].friction_work)) for h in cycle[1:])
    normal = sum(float(np.sum(h[3].normal_work)) for h in cycle[1:])
    u0, u1 = cycle[0][2], cycle[-1][2]
    d_energy = 0.5 * u1 @ K @ u1 - 0.5 * u0 @ K @ u0  # not 0: coupled W drifts slowly
    assert friction + normal + d_energy == pytest.approx(area, rel=1e-12)
    if mu == 0.0:
        assert all(np.all(h[3].friction_work == 0.0) for h in hist)
        assert all(np.all(h[3].dissipation == 0.0) for h in hist)
    else:
        assert friction > 0.0
        assert any(h[3].n_open > 0 for h in cycle)
        assert any(h[3].n_slip > 0 for h in cycle)


# --- invariances ------------------------------------------------------------------------


def frictional_case(m=8, seed=11):
    _, _, W = random_structure(m, seed)
    rng = np.random.default_rng(seed + 1)
    w1 = rng.normal(scale=0.3, size=(m, 3)) + np.array([-0.3, 0.0, 0.0])
    w2 = w1 + rng.normal(scale=0.2, size=(m, 3))
    return W, [w1, w2]


@pytest.mark.parametrize("r_scale", [1e-2, 1e2], ids=["r0.01", "r100"])
def test_solution_does_not_depend_on_r(r_scale):
    W, path = frictional_case()
    ref = run_history(W, path, ContactSettings(mu=0.3))
    alt = run_history(W, path, ContactSettings(mu=0.3, r_scale=r_scale))
    for a, b in zip(ref, alt, strict=True):
        np.testing.assert_allclose(b.state.p, a.state.p, atol=CMP * np.max(np.abs(a.state.p)))
        np.testing.assert_array_equal(b.state.status, a.state.status)
    assert {int(s) for s in ref[-1].state.status} >= {ContactStatus.STICK, ContactStatus.SLIP}


@pytest.mark.parametrize("scale", [1e-3, 2.5, 1e4], ids=["s=1e-3", "s=2.5", "s=1e4"])
def test_positive_homogeneity_from_zero_state(scale):
    W, path = frictional_case()
    m = W.shape[0] // 3
    G = np.tile(np.eye(3), (m, 1))[:, :1]  # one floating normal translation
    e = np.array([3.0])
    st = ContactState.initial(m, n_rigid=1)
    ref = run_history(W, path, ContactSettings(mu=0.3), state=st, G=G, e=e)
    scaled = run_history(
        W, [scale * w for w in path], ContactSettings(mu=0.3), state=st, G=G, e=scale * e
    )
    for a, b in zip(ref, scaled, strict=True):
        np.testing.assert_allclose(b.state.p, scale * a.state.p, rtol=0, atol=CMP * scale * 3.0)
        np.testing.assert_allclose(b.state.alpha, scale * a.state.alpha, rtol=CMP)


def test_warm_start_reduces_iterations():
    W, (w1, w2) = frictional_case(m=20, seed=5)
    path = [w1 + (w2 - w1) * t for t in np.linspace(0.0, 1.0, 15)]
    warm = run_history(W, path, ContactSettings(mu=0.3))
    cold = run_history(W, path, ContactSettings(mu=0.3, warm_start=False))
    for a, b in zip(warm, cold, strict=True):
        np.testing.assert_allclose(a.state.p, b.state.p, atol=CMP * np.max(np.abs(b.state.p)))
    n_warm = sum(r.iterations for r in warm)
    n_cold = sum(r.iterations for r in cold)
    assert n_warm < n_cold


# --- Jacobian and law tangent vs central differences -------------------------------------


def test_law_tangent_matches_central_differences_with_status_frozen():
    rng = np.random.default_rng(2)
    m = 40
    gap = rng.normal(size=(m, 3))
    p = rng.normal(size=(m, 3)) + np.array([0.5, 0.0, 0.0])
    r = rng.uniform(0.5, 2.0, m)
    step = coulomb_step(gap, p, 0.4, r)
    h = 1e-6
    for j in range(3):
        dp = np.zeros((m, 3))
        dp[:, j] = h
        plus, minus = coulomb_step(gap, p + dp, 0.4, r), coulomb_step(gap, p - dp, 0.4, r)
        same = (plus.status == step.status) & (minus.status == step.status)
        fd = (plus.traction - minus.traction) / (2 * h)
        np.testing.assert_allclose(fd[same], step.tangent[same, :, j], atol=1e-8)
    assert {int(s) for s in step.status} == {0, 1, 2}


def test_law_without_tangent_returns_the_same_traction_and_status():
    """The Newton loop's residuals skip the tangent; traction and status must not change,
    at one μ and at per-point μ (some zero: frictionless slipping)."""
    rng = np.random.default_rng(12)
    m = 60
    gap = rng.normal(size=(m, 3))
    p = rng.normal(size=(m, 3)) + np.array([0.5, 0.0, 0.0])
    r = rng.uniform(0.5, 2.0, m)
    for mu in (0.3, np.where(np.arange(m) % 4 == 0, 0.0, rng.uniform(0.1, 0.6, m))):
        full, lean = coulomb_step(gap, p, mu, r), coulomb_step(gap, p, mu, r, tangent=False)
        np.testing.assert_array_equal(lean.status, full.status)
        np.testing.assert_array_equal(lean.traction, full.traction)
        assert lean.tangent.shape == (0, 3, 3)
        assert {int(s) for s in full.status} == {0, 1, 2}


def test_complementarity_jacobian_matches_central_differences():
    W, (w1, _) = frictional_case(m=6, seed=4)
    rng = np.random.default_rng(9)
    prev = ContactState(
        np.zeros((6, 3)), rng.normal(scale=0.1, size=(6, 3)), np.zeros(6, np.int8), np.zeros(0)
    )
    p = rng.normal(size=(6, 3)) + np.array([0.4, 0.0, 0.0])
    p[:2] = [[2.0, 0.1, -0.2], [1.5, 0.0, 0.05]]  # two points inside the friction disc ...
    w_now = (W @ p.ravel()).reshape(6, 3) + w1
    prev_w = prev.w.copy()
    prev_w[:2, 1:] = w_now[:2, 1:] + 1e-3  # ... with a small slip increment: they stick
    prev = ContactState(prev.p, prev_w, prev.status, prev.alpha)
    settings = ContactSettings(mu=0.3, r_scale=0.7)
    base = complementarity(W, w1, prev, p, settings)
    h = 1e-6
    for col in range(18):
        dp = np.zeros(18)
        dp[col] = h
        plus = complementarity(W, w1, prev, p + dp.reshape(6, 3), settings)
        minus = complementarity(W, w1, prev, p - dp.reshape(6, 3), settings)
        assert np.array_equal(plus.status, base.status)
        assert np.array_equal(minus.status, base.status)
        fd = (plus.residual - minus.residual).ravel() / (2 * h)
        np.testing.assert_allclose(fd, base.jacobian[:, col], atol=1e-7)
    assert {int(s) for s in base.status} == {0, 1, 2}


# --- errors and hygiene -----------------------------------------------------------------


def test_iteration_cap_raises_convergence_error_with_details():
    W, (w1, _) = frictional_case(m=20, seed=5)
    with pytest.raises(ConvergenceError) as info:
        solve_increment(
            W, w1, ContactState.initial(20), ContactSettings(mu=0.3, max_iter=1), increment=17
        )
    err = info.value
    assert (err.increment, err.iteration) == (17, 1)
    assert err.residual > TOL
    assert isinstance(err.partial, ContactState)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"w_free": np.zeros((2, 3))}, r"w_free must have shape \(1, 3\)"),
        ({"W": np.eye(6)}, r"W must have shape \(3, 3\)"),
        ({"W": np.diag([-1.0, 1.0, 1.0])}, "W_nn must be > 0"),
        ({"G": np.ones((3, 1))}, "G and e must be given together"),
    ],
    ids=["w_free-shape", "W-shape", "W_nn-negative", "G-without-e"],
)
def test_bad_input_is_named(kwargs, match):
    args = {"W": np.eye(3), "w_free": np.zeros((1, 3))}
    args.update(kwargs)
    W, wf = args.pop("W"), args.pop("w_free")
    with pytest.raises(ParameterError, match=match):
        solve_increment(W, wf, ContactState.initial(1), ContactSettings(), **args)


def test_bad_settings_are_named():
    with pytest.raises(ParameterError, match="mu must be"):
        ContactSettings(mu=-0.1)
    with pytest.raises(ParameterError, match="r_scale must be"):
        ContactSettings(r_scale=0.0)


def test_inputs_are_not_mutated():
    W, (w1, w2) = frictional_case()
    m = W.shape[0] // 3
    G, e = np.tile(np.eye(3), (m, 1)), np.array([2.0, 0.1, 0.0])
    state = run_history(
        W, [w1], ContactSettings(mu=0.3), state=ContactState.initial(m, 3), G=G, e=e
    )[0].state
    before = [a.copy() for a in (W, w2, G, e, state.p, state.w, state.alpha)]
    solve_increment(W, w2, state, ContactSettings(mu=0.3), G=G, e=e)
    for a, b in zip(before, (W, w2, G, e, state.p, state.w, state.alpha), strict=True):
        np.testing.assert_array_equal(a, b)
    assert not state.p.flags.writeable


def test_rescue_path_converges_to_the_same_solution():
    W, path = frictional_case()
    ref = run_history(W, path, ContactSettings(mu=0.3))
    # An Armijo constant this close to ½ rejects almost every step, forcing rescues.
    hard = run_history(W, path, ContactSettings(mu=0.3, armijo=0.4999, min_step=0.99))
    assert sum(r.rescues for r in hard) >= 2
    for a, b in zip(ref, hard, strict=True):
        np.testing.assert_allclose(b.state.p, a.state.p, atol=CMP * np.max(np.abs(a.state.p)))


def test_frictionless_load_cycle_returns_to_zero_displacement():
    m = 6
    K, C, W = random_structure(m, seed=8)
    f0 = np.random.default_rng(8).normal(size=K.shape[0])
    f0[0 : 3 * m : 3] -= 2.0  # mostly pressing

    def f_of(lam):
        return lam * f0

    hist = structure_history(K, C, W, f_of, ContactSettings(mu=0.0), load_path([0, 1, 0], 10))
    assert max(h[3].n_slip for h in hist) > 0  # closed points slide freely
    p_max = max(np.max(np.abs(h[3].state.p)) for h in hist)
    u_max = max(np.max(np.abs(h[2])) for h in hist)
    np.testing.assert_allclose(hist[-1][3].state.p, 0.0, atol=CMP * p_max)
    np.testing.assert_allclose(hist[-1][2], 0.0, atol=CMP * u_max)


def test_chord_steps_save_factorisations_without_changing_the_solution():
    W, (w1, w2) = frictional_case(m=20, seed=5)
    path = [w1 + (w2 - w1) * t for t in np.linspace(0.0, 1.0, 15)]
    lu = LinearSolver.LU  # chord steps belong to the LU path
    chord = run_history(W, path, ContactSettings(mu=0.3, linear_solver=lu))
    fresh = run_history(W, path, ContactSettings(mu=0.3, chord_rate=0.0, linear_solver=lu))
    for a, b in zip(chord, fresh, strict=True):
        np.testing.assert_allclose(a.state.p, b.state.p, atol=CMP * np.max(np.abs(b.state.p)))
        assert a.residuals[-1] <= ContactSettings().tol
    assert all(r.factorizations == r.iterations for r in fresh)
    assert sum(r.factorizations for r in chord) < sum(r.factorizations for r in fresh)
