"""An increment's data and a Newton iterate evaluated on it (see fe.contact).

Internal to :mod:`fe.contact`: the increment (``Problem``), the residual evaluation of an
iterate (``evaluate``: Alart–Curnier and equilibrium residuals, merit, scaled residual
``ρ``), a converged increment (``Solved``) and the product ``W x`` they all use
(``sparse_product``). The Newton step on them is :mod:`fe.contact.newton`. Notation and
conventions are those of :mod:`fe.contact`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from fe.contact.dense import runs, wide
from fe.contact.law import CoulombStep, coulomb_step

FloatArray = npt.NDArray[np.float64]


class Problem(NamedTuple):
    """Data of one increment.

    Attributes:
        W: Delassus operator, shape (3m, 3m), float64 [mm/N].
        w_free: Free relative displacement, shape (m, 3), float64 [mm].
        G: Rigid-body map, shape (3m, k), float64 (k may be 0).
        e: Rigid-body load, shape (k,), float64 [N].
        w_t_prev: Previous tangential displacement, shape (m, 2), float64 [mm].
        mu: Friction coefficient, one for all points or shape (m,), float64.
        w_sum: Sum of the entries of ``W`` (its finiteness check, and a fingerprint that
            tells caches keyed by ``W``'s identity whether it changed in place); NaN if
            unknown, which no cache trusts.
        symmetric: Whether ``W`` is symmetric (products and Jacobians then use its
            contiguous rows for its columns); else the general products are used.
    """

    W: FloatArray
    w_free: FloatArray
    G: FloatArray
    e: FloatArray
    w_t_prev: FloatArray
    mu: float | FloatArray
    w_sum: float = float("nan")
    symmetric: bool = True


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
        Wp: ``W p``, shape (m, 3), float64 [mm] (kept so a line search along ``dp``
            needs one product ``W dp`` for all its trial steps).
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
    Wp: FloatArray


class Solved(NamedTuple):
    """A converged increment before its works are summed up (see :mod:`fe.contact.solve`).

    Attributes:
        it: The converged iterate, ``w`` from an exact product ``W p``.
        iterations: Newton iterations, regularised ones included.
        history: Scaled residual ``ρ`` at the start and after every iteration.
        rescues: Rescues taken (or regularised steps rejected).
        factorizations: LU factorisations of step matrices.
        linear_iterations: GMRES iterations.
        regularised_iterations: Iterations of the regularised fallback.
    """

    it: Iterate
    iterations: int
    history: tuple[float, ...]
    rescues: int
    factorizations: int
    linear_iterations: int
    regularised_iterations: int


def evaluate(
    prob: Problem,
    p: FloatArray,
    alpha: FloatArray,
    r: FloatArray,
    Wp: FloatArray | None = None,
) -> Iterate:
    """Evaluate residuals, merit and scaled residual at ``(p, α)``.

    Args:
        prob: Increment data.
        p: Contact forces, shape (m, 3), float64 [N].
        alpha: Rigid amplitudes, shape (k,), float64.
        r: Augmentation per point, shape (m,), float64 [N/mm].
        Wp: ``W p`` if already known (e.g. ``W p₀ + τ W dp`` in a line search), shape
            (m, 3), float64 [mm]; computed if None.

    Returns:
        The evaluated iterate.
    """
    if Wp is None:
        Wp = sparse_product(prob.W, p, prob.symmetric).reshape(-1, 3)
    Ga = (prob.G @ alpha).reshape(-1, 3)
    w = Wp + Ga + prob.w_free
    g = w.copy()
    g[:, 1:] -= prob.w_t_prev
    law = coulomb_step(g, p, prob.mu, r, tangent=False)  # the reduced step forms its own
    C = p - law.traction
    eq = prob.G.T @ p.ravel() - prob.e
    r_bar = float(np.mean(r))
    Cr = C / r[:, None]
    merit = 0.5 * float(np.sum(Cr**2)) + 0.5 * float(np.sum((eq / r_bar) ** 2))
    drift = prob.w_free.copy()
    drift[:, 1:] -= prob.w_t_prev
    d_ref = max(_amax(Wp), _amax(Ga), _amax(drift))
    # r̄ d_ref max|G|: the load a single point takes at the displacement scale; it keeps ρ
    # meaningful when e = 0 (a free body at rest) and p is round-off.
    p_scale = r_bar * d_ref * _amax(prob.G)
    f_ref = max(_amax(prob.e), _amax(np.abs(prob.G).T @ np.abs(p.ravel())), p_scale)
    rho = max(_ratio(_amax(Cr), d_ref), _ratio(_amax(eq), f_ref))
    return Iterate(p, alpha, w, g, law, C, eq, merit, rho, Wp)


def sparse_product(
    W: FloatArray, x: FloatArray, symmetric: bool = True, threads: int | None = None
) -> FloatArray:
    """Return ``W x`` from the rows (symmetric ``W``) of the points where ``x ≠ 0``.

    The rows are read in runs of consecutive points, as slices (views): gathering them
    with an index array copies them first, which on a large ``W`` with half of them
    nonzero costs more than the full product, where the runs cost less. Timings:
    benchmarks/bench_contact_profile.txt, 'sparse_product'.

    Args:
        W: Matrix, shape (3m, 3m), float64.
        x: Per-point vector, shape (m, 3), float64; typically nonzero on few points.
        symmetric: Whether ``W`` is symmetric (else the plain product is taken).
        threads: BLAS threads of a large product (:func:`fe.contact.dense.wide`).

    Returns:
        ``W x`` flattened, shape (3m,), float64.
    """
    if W.shape[0] <= PLAIN_PRODUCT_MAX:
        small: FloatArray = W @ x.ravel()
        return small
    support = np.flatnonzero(np.any(x != 0.0, axis=1))
    if not symmetric or 4 * len(support) > 3 * len(x):  # the runs would read most of W
        with wide(W.size, threads):
            out: FloatArray = W @ x.ravel()
        return out
    # W symmetric: W x = Σ_j x_j W[j, :] over the nonzero x_j, run by run.
    first, stop = runs(support)
    starts, ends = support[first], support[stop - 1] + 1
    flat = x.ravel()
    rows = np.zeros(W.shape[1])
    with wide(3 * len(support) * W.shape[1], threads):
        for a, b in zip(3 * starts, 3 * ends, strict=True):
            rows += flat[a:b] @ W[a:b]
    return rows


PLAIN_PRODUCT_MAX = 600
"""Up to this many rows :func:`sparse_product` takes the plain product: finding the runs
costs more than reading W there. Chosen by measurement (benchmarks/bench_contact.txt,
'PLAIN_PRODUCT_MAX')."""


def _amax(a: FloatArray) -> float:
    return float(np.max(np.abs(a))) if a.size else 0.0


def _ratio(num: float, ref: float) -> float:
    return 0.0 if num == 0.0 else num / max(ref, np.finfo(float).tiny)
