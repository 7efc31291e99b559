"""One generalised-Newton step of the condensed Alart–Curnier system (see fe.contact).

Internal to :mod:`fe.contact`: residual evaluation of an iterate and the reduced
active-set linear algebra. Notation and conventions are those of :mod:`fe.contact`.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla

from fe.contact_law import ContactStatus, CoulombStep, coulomb_step, slip_frame

FloatArray = npt.NDArray[np.float64]


class Problem(NamedTuple):
    """Data of one increment.

    Attributes:
        W: Delassus operator, shape (3m, 3m), float64 [mm/N].
        w_free: Free relative displacement, shape (m, 3), float64 [mm].
        G: Rigid-body map, shape (3m, k), float64 (k may be 0).
        e: Rigid-body load, shape (k,), float64 [N].
        w_t_prev: Previous tangential displacement, shape (m, 2), float64 [mm].
        mu: Friction coefficient.
    """

    W: FloatArray
    w_free: FloatArray
    G: FloatArray
    e: FloatArray
    w_t_prev: FloatArray
    mu: float


class Iterate(NamedTuple):
    """A Newton iterate with everything derived from it.

    Attributes:
        p: Contact forces, shape (m, 3), float64 [N].
        alpha: Rigid amplitudes, shape (k,), float64.
        w: Relative displacement ``W p + G α + w_free``, shape (m, 3), float64 [mm].
        g: Gap increment ``(w_n, Δw_t)``, shape (m, 3), float64 [mm].
        law: Return map of the trial force (status, traction, tangent).
        C: Alart–Curnier residual, shape (m, 3), float64 [N].
        eq: Equilibrium residual ``Gᵀp - e``, shape (k,), float64 [N].
        merit: ``½|C/r|² + ½|eq/r̄|²`` [mm²].
        rho: Scaled residual ``ρ`` (see fe.contact).
    """

    p: FloatArray
    alpha: FloatArray
    w: FloatArray
    g: FloatArray
    law: CoulombStep
    C: FloatArray
    eq: FloatArray
    merit: float
    rho: float


def evaluate(prob: Problem, p: FloatArray, alpha: FloatArray, r: FloatArray) -> Iterate:
    """Evaluate residuals, merit and scaled residual at ``(p, α)``.

    Args:
        prob: Increment data.
        p: Contact forces, shape (m, 3), float64 [N].
        alpha: Rigid amplitudes, shape (k,), float64.
        r: Augmentation per point, shape (m,), float64 [N/mm].

    Returns:
        The evaluated iterate.
    """
    Wp = (prob.W @ p.ravel()).reshape(-1, 3)
    Ga = (prob.G @ alpha).reshape(-1, 3)
    w = Wp + Ga + prob.w_free
    g = w.copy()
    g[:, 1:] -= prob.w_t_prev
    law = coulomb_step(g, p, prob.mu, r)
    C = p - law.traction
    eq = prob.G.T @ p.ravel() - prob.e
    r_bar = float(np.mean(r))
    Cr = C / r[:, None]
    merit = 0.5 * float(np.sum(Cr**2)) + 0.5 * float(np.sum((eq / r_bar) ** 2))
    drift = prob.w_free.copy()
    drift[:, 1:] -= prob.w_t_prev
    d_ref = max(_amax(Wp), _amax(Ga), _amax(drift))
    f_ref = max(_amax(prob.e), _amax(np.abs(prob.G).T @ np.abs(p.ravel())))
    rho = max(_ratio(_amax(Cr), d_ref), _ratio(_amax(eq), f_ref))
    return Iterate(p, alpha, w, g, law, C, eq, merit, rho)


def _amax(a: FloatArray) -> float:
    return float(np.max(np.abs(a))) if a.size else 0.0


def _ratio(num: float, ref: float) -> float:
    return 0.0 if num == 0.0 else num / max(ref, np.finfo(float).tiny)


class Step(NamedTuple):
    """A Newton direction.

    Attributes:
        dp: Force increment, shape (m, 3), float64 [N].
        alpha_new: Full-step rigid amplitudes (minimum norm), shape (k,), float64.
    """

    dp: FloatArray
    alpha_new: FloatArray


def newton_step(
    prob: Problem, it: Iterate, r: FloatArray, cut: float, *, close_open: bool = False
) -> Step | None:
    """Solve the reduced generalised-Newton system; None if it is singular.

    With ``close_open`` the open points are treated as closed and frictionless (a
    bilateral predictor that lets a floating body that touches nothing find contact).

    Unknowns per closed point (slots n, t1, t2): stick (dp_n, dp_t1, dp_t2); slip
    (dp_n, b) with ``dp_t = (μ(p_n + dp_n) - p_t·u) u + b v``; frictionless (dp_n) with
    ``dp_t = -p_t``. Rows (divided by r): ``dw_n = -w_n``; stick ``dw_t = -Δw_t``; slip
    ``(1-κ)/r b + κ v·dw_t = -C_t·v/r``. Open points get ``dp = -p``. Here
    ``u = ξ_t/|ξ_t|``, ``v`` is ``u`` turned by +90° and ``κ = μ ξ_n/|ξ_t|``.

    Args:
        prob: Increment data.
        it: Current iterate (its trial status defines the active sets).
        r: Augmentation per point, shape (m,), float64 [N/mm].
        cut: Absolute singular-value cut of the rigid-body Schur complement.
        close_open: Use the bilateral predictor described above.

    Returns:
        The full Newton step, or None if the reduced matrix is numerically singular.
    """
    status = it.law.status
    forced = status == ContactStatus.OPEN if close_open else np.zeros(len(status), dtype=bool)
    closed = np.flatnonzero((status != ContactStatus.OPEN) | forced)
    u, kappa = slip_frame(it.g, it.p, prob.mu, r)
    is_slip = (status[closed] == ContactStatus.SLIP) & (prob.mu > 0.0)
    is_free = ((status[closed] == ContactStatus.SLIP) & (prob.mu == 0.0)) | forced[closed]
    u_c, kap_c = u[closed], kappa[closed]
    v_c = np.stack([-u_c[:, 1], u_c[:, 0]], axis=1)  # (c, 2), u rotated by +90°

    s = -it.p.copy()  # shift: dp = T dq + s
    s[closed] = 0.0
    C_c = it.C[closed]
    sl = closed[is_slip]
    a0 = prob.mu * it.p[sl, 0] - np.sum(it.p[sl, 1:] * u_c[is_slip], axis=1)
    s[sl, 1:] = a0[:, None] * u_c[is_slip]
    s[closed[is_free], 1:] = -it.p[closed[is_free], 1:]

    # Target of the rows (before moving the shift to the right-hand side).
    target = -it.g[closed].copy()  # (c, 3): -w_n, -Δw_t
    target[is_slip, 1] = -np.sum(C_c[is_slip, 1:] * v_c[is_slip], axis=1) / r[sl]
    Ws = (prob.W @ s.ravel()).reshape(-1, 3)[closed]  # (c, 3)
    idx = (3 * closed[:, None] + np.arange(3)).ravel()
    J = prob.W[np.ix_(idx, idx)]  # (3c, 3c) copy
    Gc = prob.G[idx].reshape(len(closed), 3, prob.G.shape[1])  # (c, 3, k)
    jn, j1, j2 = (3 * np.flatnonzero(is_slip) + a for a in range(3))
    mu = prob.mu
    # Column transform T (slip points): n-col += μ u·t-cols, t1-col := v·t-cols.
    ux, uy = u_c[is_slip, 0], u_c[is_slip, 1]
    vx, vy = v_c[is_slip, 0], v_c[is_slip, 1]
    col1, col2 = J[:, j1], J[:, j2]
    J[:, jn] += mu * (col1 * ux + col2 * uy)
    J[:, j1] = col1 * vx + col2 * vy
    Gcol = Gc.copy()  # columns of Gᵀ T
    g1, g2 = Gc[is_slip, 1], Gc[is_slip, 2]
    Gcol[is_slip, 0] += mu * (g1 * ux[:, None] + g2 * uy[:, None])
    Gcol[is_slip, 1] = g1 * vx[:, None] + g2 * vy[:, None]
    # Row transform R (slip points): t1-row := κ v·t-rows (+ diagonal (1-κ)/r).
    ks = kap_c[is_slip]
    row1, row2 = J[j1], J[j2]
    J[j1] = ks[:, None] * (row1 * vx[:, None] + row2 * vy[:, None])
    J[j1, j1] += (1.0 - ks) / r[sl]
    Grow = Gc.copy()
    Grow[is_slip, 1] = ks[:, None] * (g1 * vx[:, None] + g2 * vy[:, None])
    rhs = target.copy()
    rhs[:, 0] -= Ws[:, 0]
    rhs[~is_slip, 1:] -= Ws[~is_slip, 1:]
    rhs[is_slip, 1] -= ks * (Ws[is_slip, 1] * vx + Ws[is_slip, 2] * vy)

    keep = np.ones((len(closed), 3), dtype=bool)
    keep[is_slip, 2] = False
    keep[is_free, 1:] = False
    kf = keep.ravel()
    if not kf.all():
        J = J[np.ix_(kf, kf)]
    Jalpha = Grow.reshape(3 * len(closed), prob.G.shape[1])[kf]  # (n_q, k)
    H = Gcol.reshape(3 * len(closed), prob.G.shape[1])[kf].T  # (k, n_q)
    b = rhs.ravel()[kf] + Jalpha @ it.alpha
    h = prob.e - prob.G.T @ (it.p + s).ravel()

    dq, alpha_new = _solve_bordered(J, Jalpha, H, b, h, cut)
    if dq is None:
        return None
    full = np.zeros(3 * len(closed))
    full[kf] = dq
    dqc = full.reshape(-1, 3)
    dp = s
    dp[closed, 0] += dqc[:, 0]
    dp[closed[~is_slip & ~is_free], 1:] += dqc[~is_slip & ~is_free, 1:]
    dp[sl, 1:] += mu * dqc[is_slip, 0, None] * u_c[is_slip] + dqc[is_slip, 1, None] * v_c[is_slip]
    return Step(dp, alpha_new)


def _solve_bordered(
    J: FloatArray,
    Jalpha: FloatArray,
    H: FloatArray,
    b: FloatArray,
    h: FloatArray,
    cut: float,
) -> tuple[FloatArray | None, FloatArray]:
    """Solve ``J x + Jα a = b, H x = h`` with min-norm ``a``; ``(None, ·)`` if J singular.

    Singular values of the k×k Schur complement ``S = H J⁻¹ Jα`` below ``cut`` are
    treated as zero (undetermined rigid directions get no component of ``a``).
    """
    k = Jalpha.shape[1]
    if J.shape[0] == 0:
        return np.zeros(0), np.zeros(k)
    with warnings.catch_warnings():
        warnings.simplefilter("error", sla.LinAlgWarning)
        try:
            # Factor Jᵀ: it is Fortran-ordered, so LAPACK works in place (no n_q² copy).
            lu = sla.lu_factor(J.T, overwrite_a=True, check_finite=False)
        except sla.LinAlgWarning:
            return None, np.zeros(k)
    diag = np.abs(np.diag(lu[0]))
    if not np.all(np.isfinite(diag)) or diag.min() <= 1e3 * np.finfo(float).eps * diag.max():
        return None, np.zeros(k)
    if k == 0:
        return sla.lu_solve(lu, b, trans=1, check_finite=False), np.zeros(0)
    Y = sla.lu_solve(lu, np.column_stack([b, Jalpha]), trans=1, check_finite=False)
    U, sv, Vt = np.linalg.svd(H @ Y[:, 1:])  # Schur complement S, (k, k)
    good = sv > max(cut, float(sv[0]) * np.finfo(float).eps * k)
    coef = (U[:, good].T @ (H @ Y[:, 0] - h)) / sv[good]
    a = Vt[good].T @ coef
    return Y[:, 0] - Y[:, 1:] @ a, a
