"""Pointwise Coulomb contact law in Alart–Curnier form (the contact "material update").

Conventions (shared with :mod:`fe.contact`): every contact point has a local frame
ordered ``[n, t1, t2]``. The contact force ``p = (p_n, p_t1, p_t2)`` [N] acts on the
slave body (its reaction ``-p`` acts on the master); ``p_n >= 0`` is compressive. The
relative displacement ``w = (w_n, w_t1, w_t2)`` [mm] of slave w.r.t. master has the
normal gap ``w_n`` (``>= 0`` open) and the tangential part ``w_t``.

The law works on the *gap increment* ``g = (w_n, Δw_t)`` — the current normal gap and
the tangential slip increment ``Δw_t = w_t - w_t_prev`` since the last converged
increment — and on the current multiplier ``p``. With the augmentation ``r > 0`` [N/mm]
the trial (augmented) force is ``ξ = p - r g`` and the returned traction is

    λ_n = max(0, ξ_n),      λ_t = proj_{disc(μ λ_n)}(ξ_t),

(``μ`` one coefficient for all points or one per point), which is a return map onto
the Coulomb set exactly like an elastic-predictor / plastic-corrector material update.
The Alart–Curnier complementarity function is ``C(p, g) = p - λ(p - r g)``; ``C = 0``
is equivalent to Signorini (``w_n >= 0, p_n >= 0, w_n p_n = 0``) and Coulomb
(``|p_t| <= μ p_n``; ``Δw_t = 0`` where ``|p_t| < μ p_n``; otherwise
``Δw_t = -γ p_t/|p_t|`` with ``γ >= 0``) for any ``r > 0``. The disc radius uses the
augmented normal force ``μ max(0, ξ_n)``, which equals ``μ p_n`` at every solution and
makes the open case decouple (λ = 0).

Example:
    >>> import numpy as np
    >>> step = coulomb_step(np.array([[0.0, 0.5, 0.0]]), np.array([[1.0, 0.0, 0.0]]),
    ...                     mu=0.3, r=np.array([1.0]))
    >>> step.traction.round(3).tolist(), ContactStatus(int(step.status[0])).name
    ([[1.0, -0.3, 0.0]], 'SLIP')
"""

from __future__ import annotations

import enum
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


class ContactStatus(enum.IntEnum):
    """Status of a contact point; stored as int8 codes in status arrays."""

    OPEN = 0
    """Gap open (or opening): no force."""
    STICK = 1
    """Closed, no slip increment, ``|p_t| <= μ p_n``."""
    SLIP = 2
    """Closed and sliding, ``|p_t| = μ p_n`` (always the case for a closed point at μ = 0)."""


class CoulombStep(NamedTuple):
    """Result of :func:`coulomb_step` for ``m`` points.

    Attributes:
        traction: Returned force ``λ``, shape (m, 3), float64 [N].
        status: ContactStatus codes, shape (m,), int8.
        tangent: ``D = ∂λ/∂ξ``, shape (m, 3, 3), float64 [-]; the complementarity
            function ``C = p - λ`` then has ``∂C/∂p = I - D`` and ``∂C/∂g = r D``.
            Empty, shape (0, 3, 3), where it was not asked for (``tangent=False``).
    """

    traction: FloatArray
    status: npt.NDArray[np.int8]
    tangent: FloatArray


def coulomb_step(
    gap_increment: FloatArray,
    p: FloatArray,
    mu: float | FloatArray,
    r: FloatArray,
    *,
    tangent: bool = True,
) -> CoulombStep:
    """Return-map the augmented force onto the Coulomb set (vectorised over points).

    Args:
        gap_increment: ``g = (w_n, Δw_t1, Δw_t2)``, shape (m, 3), float64 [mm].
        p: Current contact force, shape (m, 3), float64 [N].
        mu: Friction coefficient ``μ >= 0``, one for all points or shape (m,), float64.
        r: Augmentation per point, shape (m,), float64 [N/mm], all > 0.
        tangent: Whether to form the tangent ``D``; if False (the Newton loop's
            residuals, which never read it and are cheaper without it:
            benchmarks/bench_contact.txt, 'coulomb_step') it is returned empty,
            shape (0, 3, 3).

    Returns:
        Traction, status and tangent; see :class:`CoulombStep`.
    """
    trial = p - r[:, None] * gap_increment  # ξ, (m, 3)
    lam_n = np.maximum(trial[:, 0], 0.0)
    radius = mu * lam_n  # μ λ_n, (m,)
    xi_t = trial[:, 1:]
    norm_t = np.sqrt(xi_t[:, 0] ** 2 + xi_t[:, 1] ** 2)
    closed = lam_n > 0.0
    stick = closed & (radius > 0.0) & (norm_t <= radius)
    slip = closed & ~stick
    safe = np.where(norm_t > 0.0, norm_t, 1.0)
    # λ_t = s ξ_t: s = 1 sticking, κ = μ λ_n/|ξ_t| < 1 slipping (0 at ξ_t = 0, then also
    # μ λ_n = 0), 0 open.
    scale = np.where(slip, radius / safe, np.where(stick, 1.0, 0.0))
    traction = np.empty_like(trial)
    traction[:, 0] = lam_n
    np.multiply(xi_t, scale[:, None], out=traction[:, 1:])
    status = stick.astype(np.int8) * np.int8(ContactStatus.STICK)
    status[slip] = ContactStatus.SLIP
    if not tangent:
        return CoulombStep(traction, status, np.zeros((0, 3, 3)))

    # Unit slip direction u = ξ_t/|ξ_t| and ratio κ = μ λ_n/|ξ_t| on slipping points.
    u = np.where(slip[:, None] & (norm_t[:, None] > 0.0), xi_t / safe[:, None], 0.0)
    mu_pt = per_point(mu, len(p))
    D = np.zeros((len(p), 3, 3))
    D[stick] = np.eye(3)
    D[slip, 0, 0] = 1.0
    D[slip, 1:, 0] = mu_pt[slip, None] * u[slip]
    proj_perp = np.eye(2) - np.einsum("mi,mj->mij", u, u)  # (m, 2, 2)
    D[slip, 1:, 1:] = scale[slip, None, None] * proj_perp[slip]
    return CoulombStep(traction, status, D)


def slip_frame(
    gap_increment: FloatArray, p: FloatArray, mu: float | FloatArray, r: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Return the slip direction ``u = ξ_t/|ξ_t|`` and ratio ``κ = μ max(0, ξ_n)/|ξ_t|``.

    Args:
        gap_increment: ``(w_n, Δw_t1, Δw_t2)``, shape (m, 3), float64 [mm].
        p: Contact force, shape (m, 3), float64 [N].
        mu: Friction coefficient, one for all points or shape (m,), float64.
        r: Augmentation, shape (m,), float64 [N/mm].

    Returns:
        ``u`` with shape (m, 2) (zero where ``ξ_t = 0``) and ``κ`` with shape (m,)
        (zero where ``ξ_t = 0``); only meaningful on slipping points.
    """
    trial = p - r[:, None] * gap_increment
    xi_t = trial[:, 1:]
    norm_t = np.hypot(xi_t[:, 0], xi_t[:, 1])
    safe = np.where(norm_t > 0.0, norm_t, 1.0)
    u = np.where(norm_t[:, None] > 0.0, xi_t / safe[:, None], 0.0)
    radius = per_point(mu, len(p)) * np.maximum(trial[:, 0], 0.0)
    kappa = np.where(norm_t > 0.0, radius / safe, 0.0)
    return u, kappa


def per_point(mu: float | FloatArray, m: int) -> FloatArray:
    """Return the friction coefficient of every point, shape (m,), float64 (a read-only view).

    Args:
        mu: One coefficient for all points, or one per point with shape (m,).
        m: Number of points.
    """
    return np.broadcast_to(np.asarray(mu, dtype=np.float64), (m,))
