"""Contact solver against independently coded references and the raw conditions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls

from fe.contact import newton as contact_newton
from fe.contact import residual as contact_residual
from fe.contact import state as contact_state
from fe.contact.law import ContactStatus
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState, complementarity

CMP = 1e3 * ContactSettings().tol  # see tests/fe/contact/test_contact.py


def random_W(m, seed, coupling=0.15):
    """SPD, diagonally dominant Delassus-like operator (3m × 3m)."""
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(3 * m, 3 * m))
    W = coupling * B @ B.T / (3 * m) + np.diag(rng.uniform(1.0, 2.0, 3 * m))
    return 0.5 * (W + W.T)


def nnls_frictionless(W, w_free):
    """LCP w_n = W_nn p_n + q ⟂ p_n >= 0 as min |Lᵀ p + L⁻¹ q|², p >= 0 (W_nn = L Lᵀ)."""
    Wnn = W[0::3, 0::3]
    L = np.linalg.cholesky(Wnn)
    p, _ = nnls(L.T, -np.linalg.solve(L, w_free[:, 0]), maxiter=1000)
    return p


def pgs_reference(W, w_free, w_t_prev, mu, sweeps=5000):
    """Block nonsmooth Gauss–Seidel with a local projected fixed point per point.

    Each point solves p_i = [max(0, ξ_n), proj_{disc(μ p_n)}(ξ_t)], ξ = p_i - ρ_i g_i(p_i),
    ρ_i = 1/λ_max(W_ii), with the other points frozen; sweeps run until p stops changing.
    """
    m = len(w_free)
    p = np.zeros((m, 3))
    for _ in range(sweeps):
        old = p.copy()
        for i in range(m):
            sl = slice(3 * i, 3 * i + 3)
            Wii = W[sl, sl]
            q = w_free[i] + W[sl] @ p.ravel() - Wii @ p[i]
            q[1:] -= w_t_prev[i]
            rho = 1.0 / np.linalg.eigvalsh(Wii)[-1]
            pi = p[i].copy()
            for _ in range(2000):
                xi = pi - rho * (Wii @ pi + q)
                pn = max(xi[0], 0.0)
                t = xi[1:]
                nt = np.hypot(*t)
                pt = t if nt <= mu * pn else (t * mu * pn / nt if nt > 0 else t)
                new = np.array([pn, *pt])
                done = np.max(np.abs(new - pi)) <= 1e-15 * (1.0 + np.max(np.abs(new)))
                pi = new
                if done:
                    break
            p[i] = pi
        if np.max(np.abs(p - old)) <= 1e-14 * (1.0 + np.max(np.abs(p))):
            return p
    raise RuntimeError("reference PGS did not converge")


def check_conditions(W, w_free, prev, res, mu, G=None, e=None, tol=CMP):
    """Verify Signorini, Coulomb, the slip rule and equilibrium on a converged result."""
    p, w, alpha = res.state.p, res.state.w, res.state.alpha
    scale_p = max(1.0, np.max(np.abs(p)))
    scale_w = max(1.0, np.max(np.abs(w_free)))
    w_expect = (W @ p.ravel()).reshape(-1, 3) + w_free
    if G is not None:
        w_expect += (G @ alpha).reshape(-1, 3)
        np.testing.assert_allclose(G.T @ p.ravel(), e, atol=tol * scale_p * len(p))
    np.testing.assert_allclose(w, w_expect, atol=tol * scale_w)
    assert np.all(w[:, 0] >= -tol * scale_w)
    assert np.all(p[:, 0] >= -tol * scale_p)
    assert np.all(np.abs(p[:, 0] * w[:, 0]) <= tol * scale_p * scale_w)
    pt_norm = np.hypot(p[:, 1], p[:, 2])
    assert np.all(pt_norm <= mu * p[:, 0] + tol * scale_p)
    dwt = w[:, 1:] - prev.w[:, 1:]
    sliding = np.hypot(dwt[:, 0], dwt[:, 1]) > tol * scale_w
    # Sliding points are on the disc edge, with p_t opposite to the slip increment.
    np.testing.assert_allclose(pt_norm[sliding], mu * p[sliding, 0], atol=tol * scale_p)
    cross = p[sliding, 1] * dwt[sliding, 1] - p[sliding, 2] * dwt[sliding, 0]
    np.testing.assert_allclose(cross, 0.0, atol=tol * scale_p * scale_w)
    assert np.all(np.sum(p[sliding, 1:] * dwt[sliding], axis=1) <= tol * scale_p * scale_w)


@pytest.mark.parametrize("seed", [0, 1, 2, 3], ids=lambda s: f"seed{s}")
def test_frictionless_matches_nnls(seed):
    m = 15
    W = random_W(m, seed, coupling=0.5)
    rng = np.random.default_rng(100 + seed)
    w_free = rng.normal(size=(m, 3)) + np.array([-0.3, 0.0, 0.0])
    res = solve_increment(W, w_free, ContactState.initial(m), ContactSettings(mu=0.0))
    ref = nnls_frictionless(W, w_free)
    np.testing.assert_allclose(res.state.p[:, 0], ref, atol=CMP * np.max(ref))
    np.testing.assert_array_equal(res.state.p[:, 1:], 0.0)
    assert 0 < res.n_open < m
    check_conditions(W, w_free, ContactState.initial(m), res, 0.0)


@pytest.mark.parametrize("mu", [0.1, 0.3], ids=["mu0.1", "mu0.3"])
@pytest.mark.parametrize("seed", [0, 1, 2], ids=lambda s: f"seed{s}")
def test_frictional_two_increments_match_nonsmooth_gauss_seidel(seed, mu):
    m = 6
    W = random_W(m, seed)
    rng = np.random.default_rng(200 + seed)
    w1 = rng.normal(scale=0.5, size=(m, 3)) + np.array([-0.5, 0.0, 0.0])
    w2 = w1 + rng.normal(scale=0.4, size=(m, 3))
    state = ContactState.initial(m)
    seen = set()
    for w_free in (w1, w2):
        res = solve_increment(W, w_free, state, ContactSettings(mu=mu))
        ref = pgs_reference(W, w_free, state.w[:, 1:], mu)
        np.testing.assert_allclose(res.state.p, ref, atol=CMP * np.max(np.abs(ref)))
        check_conditions(W, w_free, state, res, mu)
        seen |= {int(s) for s in res.state.status}
        state = res.state
    assert len(seen) >= 2


def test_newton_step_equals_full_generalised_newton_direction():
    m = 7
    W = random_W(m, 5)
    rng = np.random.default_rng(5)
    w_free = rng.normal(scale=0.5, size=(m, 3)) + np.array([-0.3, 0.0, 0.0])
    prev = ContactState(
        np.zeros((m, 3)), rng.normal(scale=0.2, size=(m, 3)), np.zeros(m, np.int8), np.zeros(0)
    )
    settings = ContactSettings(mu=0.3)
    p = rng.normal(size=(m, 3)) + np.array([0.5, 0.0, 0.0])
    comp = complementarity(W, w_free, prev, p, settings)
    full = -np.linalg.solve(comp.jacobian, comp.residual.ravel())
    prob = contact_state.validate_problem(W, w_free, prev, None, None)._replace(mu=settings.mu)
    r = settings.r_scale / np.diagonal(W).reshape(m, 3).mean(axis=1)
    it = contact_residual.evaluate(prob, p, np.zeros(0), r)
    step = contact_newton.newton_step(prob, it, r, 0.0)
    assert step is not None
    np.testing.assert_allclose(step.dp.ravel(), full, atol=1e-10 * np.max(np.abs(full)))
    assert {int(s) for s in comp.status} == {0, 1, 2}


# --- floating bodies ---------------------------------------------------------------------


def flat_punch(n_side=5, spacing=1.0):
    """Half-space-like W on an n×n grid (two identical bodies, Goodman uncoupling).

    Off-diagonal 1/(π E* d) for normal and tangential blocks, self term of a square patch.
    """
    xy = np.stack(np.meshgrid(np.arange(n_side), np.arange(n_side)), -1).reshape(-1, 2) * spacing
    d = np.linalg.norm(xy[:, None] - xy[None], axis=-1)
    self_term = 4.0 * np.log(1.0 + np.sqrt(2.0)) / spacing
    kernel = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), self_term) / np.pi
    W = np.kron(kernel, np.diag([1.0, 1.2, 1.2]))
    return xy, W


def rigid_map(xy, with_spin):
    """G for a floating punch: translations (n, t1, t2) and optionally spin about n."""
    m = len(xy)
    cols = [np.tile(np.eye(3)[a], m) for a in range(3)]
    if with_spin:
        c = xy - xy.mean(axis=0)
        spin = np.zeros((m, 3))
        spin[:, 1], spin[:, 2] = -c[:, 1], c[:, 0]
        cols.append(spin.ravel())
    return np.column_stack(cols)


def test_floating_frictionless_undetermined_tangential_directions_give_min_norm_alpha():
    xy, W = flat_punch()
    m = len(xy)
    curvature = 0.3 * np.sum((xy - xy.mean(axis=0)) ** 2, axis=1)  # gap profile [mm]
    w_free = np.column_stack([curvature, np.zeros(m), np.zeros(m)])
    G = rigid_map(xy, with_spin=True)  # t1, t2 and spin: unseen without friction
    e = np.array([3.0, 0.0, 0.0, 0.0])
    prev = ContactState(
        np.zeros((m, 3)), np.zeros((m, 3)), np.zeros(m, np.int8), [0.0, 5.0, -2.0, 1.0]
    )
    res = solve_increment(W, w_free, prev, ContactSettings(mu=0.0), G=G, e=e)
    only_normal = solve_increment(
        W, w_free, ContactState.initial(m, 1), ContactSettings(mu=0.0), G=G[:, :1], e=e[:1]
    )
    np.testing.assert_allclose(res.state.p, only_normal.state.p, atol=CMP * 3.0)
    np.testing.assert_allclose(res.state.alpha[0], only_normal.state.alpha[0], rtol=CMP)
    np.testing.assert_array_equal(res.state.alpha[1:], 0.0)
    assert res.rescues >= 1  # all open at the start: the bilateral predictor found contact
    assert 0 < res.n_open < m
    check_conditions(W, w_free, prev, res, 0.0, G=G, e=e)


@pytest.mark.parametrize("tangential", [0.3, 0.85], ids=["partial-slip", "near-gross-slip"])
def test_floating_frictional_punch_with_spin_and_zero_column(tangential):
    xy, W = flat_punch()
    m, mu = len(xy), 0.3
    curvature = 0.1 * np.sum((xy - xy.mean(axis=0)) ** 2, axis=1)
    w_free = np.column_stack([curvature, np.zeros(m), np.zeros(m)])
    G = np.column_stack([rigid_map(xy, with_spin=True), np.zeros(3 * m)])  # last: unseen
    normal = 3.0
    state = ContactState.initial(m, 5)
    for q in (0.0, tangential):  # normal preload, then tangential load
        e = np.array([normal, q * mu * normal, 0.0, 0.0, 0.0])
        for r_scale in (1.0, 30.0):
            res = solve_increment(
                W, w_free, state, ContactSettings(mu=mu, r_scale=r_scale), G=G, e=e
            )
            check_conditions(W, w_free, state, res, mu, G=G, e=e)
            if r_scale == 1.0:
                ref = res
            else:
                np.testing.assert_allclose(res.state.p, ref.state.p, atol=CMP * normal)
        assert np.all(np.isfinite(ref.state.alpha))
        assert ref.state.alpha[4] == 0.0
        state = ref.state
    assert min(ref.n_open, ref.n_stick, ref.n_slip) > 0
    assert ref.state.status[m // 2] == ContactStatus.STICK  # Cattaneo: centre sticks


def pin_in_hole(m=48, clearance=0.01):
    """Floating pin in a hole: m points on the circle, α = (x, y, axial) pin motion."""
    th = np.linspace(0.0, 2 * np.pi, m, endpoint=False)
    radial = np.stack([np.cos(th), np.sin(th)], axis=1)
    tangent = np.stack([-np.sin(th), np.cos(th)], axis=1)
    d = np.abs(th[:, None] - th[None])
    d = np.minimum(d, 2 * np.pi - d)
    W = np.kron(1e-3 * np.exp(-d / 0.2), np.diag([1.0, 1.3, 1.3])) + 1e-3 * np.eye(3 * m)
    G = np.zeros((3 * m, 3))
    G[0::3, :2] = -radial  # moving the pin towards a point closes its gap
    G[1::3, :2] = tangent
    G[2::3, 2] = 1.0  # axial: seen by friction only
    w_free = np.zeros((m, 3))
    w_free[:, 0] = clearance
    return W, G, w_free


def test_pin_with_clearance_crosses_the_gap_on_every_load_reversal():
    W, G, w_free = pin_in_hole()
    m = len(w_free)
    force = np.array([50.0, 20.0, 0.0])
    lams = [i / 10 for i in range(11)] + [1 - i / 10 for i in range(1, 21)]
    lams += [-1 + i / 10 for i in range(1, 21)]
    state, alpha_at = ContactState.initial(m, 3), {}
    settings = ContactSettings(mu=0.2)
    for i, lam in enumerate(lams):
        e = -lam * force  # the pin's load is balanced by the contact forces: Gᵀp = -F
        res = solve_increment(W, w_free, state, settings, G=G, e=e, increment=i)
        check_conditions(W, w_free, state, res, settings.mu, G=G, e=e)
        state = res.state
        if abs(lam) == 1.0:
            alpha_at.setdefault(lam, []).append(state.alpha)
    # The pin presses towards ±F, beyond the clearance (0.01 mm), at every load peak.
    unit = force[:2] / np.linalg.norm(force[:2])
    assert all(a[:2] @ unit > 0.01 for a in alpha_at[1.0])
    assert all(a[:2] @ unit < -0.01 for a in alpha_at[-1.0])
    assert state.alpha[2] == 0.0  # axial motion is never excited
