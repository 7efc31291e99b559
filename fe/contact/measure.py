"""The common error measure of frictional-contact problems (Siconos' ``fc3d_compute_error``).

Independent of the solver's own residual ρ (a different equation: De Saxcé's modified
velocity and a Euclidean cone projection, not the Alart–Curnier law), so a problem solved to
ρ ≤ tol can be scored on the same scale as other codes' results.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def project_coulomb_cone(x: FloatArray, mu: FloatArray | float) -> FloatArray:
    """Euclidean projection of each row (n, t1, t2) onto the cone {|x_t| ≤ μ x_n}.

    Args:
        x: Points, shape (m, 3).
        mu: Friction coefficient, scalar or shape (m,).

    Returns:
        The projections, shape (m, 3); ``x`` is not modified.
    """
    xn, xt = x[:, 0], x[:, 1:]
    nt = np.hypot(xt[:, 0], xt[:, 1])
    out = x.copy()
    polar = mu * nt <= -xn
    side = ~(nt <= mu * xn) & ~polar
    rn = (mu * nt + xn) / (1.0 + mu**2)
    out[polar] = 0.0
    out[side, 0] = rn[side]
    out[side, 1:] = (mu * rn / np.where(nt > 0, nt, 1.0))[side, None] * xt[side]
    return out


def siconos_error(W: FloatArray, q: FloatArray, mu: FloatArray | float, r: FloatArray) -> float:
    """``|r − P_K(r − (u + μ|u_T| e_n))| / max(|q|, |r|, |u|)`` with ``u = W r + q``.

    Args:
        W: Delassus operator, shape (3m, 3m).
        q: Free local velocity/displacement, shape (3m,).
        mu: Friction coefficient, scalar or shape (m,).
        r: Contact forces, shape (m, 3).

    Returns:
        The relative error (a problem counts as solved at ≤ 1e-8).
    """
    u = (W @ r.ravel() + q).reshape(-1, 3)
    u_mod = u.copy()
    u_mod[:, 0] += mu * np.hypot(u[:, 1], u[:, 2])
    res = r - project_coulomb_cone(r - u_mod, mu)
    scale = max(np.linalg.norm(q), np.linalg.norm(r), np.linalg.norm(u))
    return float(np.linalg.norm(res) / scale)
