"""Right-preconditioned GMRES (no restart) for the Newton directions of :mod:`fe.contact.krylov`."""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla

FloatArray = npt.NDArray[np.float64]


class _Gmres(NamedTuple):
    z: FloatArray
    iterations: int
    converged: bool


def gmres(
    apply_a: Callable[[FloatArray], FloatArray],
    apply_p: Callable[[FloatArray], FloatArray],
    rhs: FloatArray,
    rtol: float,
    max_iter: int,
) -> _Gmres:
    """Right-preconditioned GMRES from zero (no restart): ``|A z - rhs| <= rtol |rhs|``.

    Args:
        apply_a: ``z ↦ A z`` on vectors of shape (n,).
        apply_p: The preconditioner ``y ↦ P y ≈ A⁻¹ y`` on vectors of shape (n,).
        rhs: Right-hand side, shape (n,).
        rtol: Relative tolerance on the true (unpreconditioned) residual.
        max_iter: Iteration cap.

    Returns:
        The solution, the iterations used, and whether ``rtol`` was reached.
    """
    beta = float(np.linalg.norm(rhs))
    if beta == 0.0:
        return _Gmres(np.zeros_like(rhs), 0, True)
    n = len(rhs)
    V = np.zeros((max_iter + 1, n))
    Z = np.zeros((max_iter, n))
    Hh = np.zeros((max_iter + 1, max_iter))
    cs, sn = np.zeros(max_iter), np.zeros(max_iter)
    g = np.zeros(max_iter + 1)
    g[0] = beta
    V[0] = rhs / beta
    j = 0
    for j in range(max_iter):
        Z[j] = apply_p(V[j])
        w = apply_a(Z[j])
        h = V[: j + 1] @ w  # classical Gram–Schmidt, twice (as stable as modified)
        w = w - h @ V[: j + 1]
        h2 = V[: j + 1] @ w
        w = w - h2 @ V[: j + 1]
        Hh[: j + 1, j] = h + h2
        h_next = float(np.linalg.norm(w))
        Hh[j + 1, j] = h_next
        if h_next > 0.0:
            V[j + 1] = w / h_next
        for i in range(j):  # earlier Givens rotations on the new column
            hi, hj = Hh[i, j], Hh[i + 1, j]
            Hh[i, j], Hh[i + 1, j] = cs[i] * hi + sn[i] * hj, -sn[i] * hi + cs[i] * hj
        rad = float(np.hypot(Hh[j, j], Hh[j + 1, j]))
        cs[j], sn[j] = (1.0, 0.0) if rad == 0.0 else (Hh[j, j] / rad, Hh[j + 1, j] / rad)
        Hh[j, j], Hh[j + 1, j] = rad, 0.0
        g[j + 1] = -sn[j] * g[j]
        g[j] = cs[j] * g[j]
        if abs(g[j + 1]) <= rtol * beta or h_next == 0.0:
            break
    k = j + 1
    if np.any(np.diag(Hh[:k, :k]) == 0.0):
        return _Gmres(np.zeros_like(rhs), k, False)
    y = sla.solve_triangular(Hh[:k, :k], g[:k])
    return _Gmres(y @ Z[:k], k, bool(abs(g[k]) <= rtol * beta))
