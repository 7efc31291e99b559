"""Settings, state and result of a contact increment; problem validation; a dense check.

Conventions are those of :mod:`fe.contact`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cad.errors import ParameterError, check_range
from fe.contact.krylov import KrylovOptions
from fe.contact.law import coulomb_step
from fe.contact.memo import ArrayMemo
from fe.contact.residual import Problem, evaluate

FloatArray = npt.NDArray[np.float64]


class LinearSolver(Enum):
    """How each Newton direction is computed (the converged solution is the same).

    Attributes:
        LU: Form and LU-factorise the reduced Jacobian, with chord steps (``chord_rate``).
        KRYLOV: GMRES on the exact reduced system, preconditioned by an earlier LU
            updated to the new active set (:mod:`fe.contact.krylov`); the LU is kept
            between increments on the same ``W`` and refactorised only when needed.
    """

    LU = "lu"
    KRYLOV = "krylov"


@dataclass(frozen=True)
class ProximalOptions:
    """Tuning of the regularised Newton fallback (algorithmic only; :mod:`fe.contact.proximal`).

    Attributes:
        rate: ``ε`` relative to ``mean(diag W)`` is ``rate · ρ`` (Levenberg–Marquardt:
            the regularisation follows the residual down), clipped to
            ``[eps_min, eps_start]`` and then multiplied by the rejection boost.
        eps_start: Largest relative ``ε`` before boosts (far from the solution).
        eps_min: Smallest relative ``ε`` (keeps the regularised matrix nonsingular).
        eps_max: Largest relative ``ε`` after boosts.
        grow: Factor on the boost after a rejected step, a singular matrix or a bounce.
        relax: Factor on the boost (down to 1) after any other accepted step.
        bounce: An accepted step that multiplies the merit by more than this is a bounce
            (nonmonotone acceptance; ρ grew more than ``√bounce``-fold).
        memory: The line search measures the decrease from the largest of the last
            ``memory`` merits (1: monotone).
    """

    rate: float = 1e-3
    eps_start: float = 1e-2
    eps_min: float = 1e-10
    eps_max: float = 1e2
    grow: float = 10.0
    relax: float = 0.3
    bounce: float = 4.0
    memory: int = 10

    def __post_init__(self) -> None:
        check_range("proximal.rate", self.rate, 0.0, float("inf"), lo_open=True, hi_open=True)
        check_range("proximal.eps_min", self.eps_min, 0.0, 1.0, lo_open=True)
        check_range("proximal.eps_start", self.eps_start, self.eps_min, self.eps_max)
        check_range("proximal.eps_max", self.eps_max, self.eps_min, float("inf"), hi_open=True)
        check_range("proximal.grow", self.grow, 1.0, float("inf"), lo_open=True, hi_open=True)
        check_range("proximal.relax", self.relax, 0.0, 1.0, lo_open=True, hi_open=True)
        check_range("proximal.bounce", self.bounce, 1.0, float("inf"), hi_open=True)
        check_range("proximal.memory", self.memory, 1, float("inf"))


@dataclass(frozen=True)
class ContactSettings:
    """Options of :func:`solve_increment`.

    Attributes:
        mu: Coulomb friction coefficient, ``>= 0``: one for all points, or one per point
            (a sequence or array of shape (m,), kept as a tuple of floats so that the
            settings stay hashable; its length is checked against ``W``).
        r_scale: Augmentation factor; point ``i`` uses ``r_i = r_scale / mean(diag W_ii)``
            [N/mm]. Algorithmic only: the converged solution does not depend on it.
        tol: Tolerance on the scaled residual ``ρ`` (module docstring).
        max_iter: Newton iteration cap per increment.
        warm_start: Start from the previous increment's ``p`` and ``α`` (else from zero).
        armijo: Sufficient-decrease constant of the line search.
        min_step: Smallest line-search step before a rescue is taken.
        chord_rate: Keep reusing the last factorisation (chord steps with the exact
            residual) while each such step divides ``ρ`` by at least ``1/chord_rate``
            and the unknown layout is unchanged; 0 refactorises at every iteration.
        rigid_rcond: Rigid directions whose singular value in the k×k Schur complement
            ``Gᵀ J⁻¹ G`` is below ``rigid_rcond · max_j |G_j|² / mean(diag W)`` are
            treated as undetermined (they get no component of ``α``).
        linear_solver: How the Newton directions are computed (``chord_rate`` applies
            to ``LinearSolver.LU`` only).
        krylov: Tuning of ``LinearSolver.KRYLOV``.
        lu_threads: BLAS threads of a dense LU of at least
            ``fe.contact.dense.LU_THREADED_MIN`` unknowns and of the large products;
            None: the environment variable ``HINGELAB_LU_THREADS`` read at each call,
            else 1 (the numbers depend on it in the last bits; see
            :func:`fe.contact.dense.lu_threads`).
        proximal: Tuning of the fallback for singular step matrices
            (:mod:`fe.contact.proximal`).
        working_set: Solve on the points that may close and check the others
            (:mod:`fe.contact.working`; symmetric ``W`` only). Algorithmic only: the
            solution is checked on the full problem.
        working_margin: Points whose gap at the start is within this many times the
            start's largest normal motion join the working set.
        frictionless_start: From rest (every force of ``state_prev`` zero, no ``start``
            given) with friction, first solve the increment frictionless and start the
            frictional Newton there. From ``p = 0`` the frictional Newton has no slip
            direction to start from and wanders (the hinge's first increment at zero
            clearance: 24 iterations at level 0, 30 at level 1; with the frictionless
            start 3 + 11 and 4 + 18). Algorithmic only: the solution does not depend on
            it; both solves' iterations are counted. If the frictionless solve does not
            converge, the increment is solved from rest as without it.
    """

    mu: float | tuple[float, ...] | FloatArray = 0.0
    r_scale: float = 1.0
    tol: float = 1e-10
    max_iter: int = 60
    warm_start: bool = True
    armijo: float = 1e-4
    min_step: float = 1e-4
    chord_rate: float = 0.1
    rigid_rcond: float = 1e-10
    linear_solver: LinearSolver = LinearSolver.KRYLOV
    krylov: KrylovOptions = field(default_factory=KrylovOptions)
    lu_threads: int | None = None
    proximal: ProximalOptions = field(default_factory=ProximalOptions)
    working_set: bool = False
    working_margin: float = 3.0
    frictionless_start: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "mu", _checked_mu(self.mu))
        if self.lu_threads is not None:
            check_range("lu_threads", self.lu_threads, 1, float("inf"))
        check_range("r_scale", self.r_scale, 0.0, float("inf"), lo_open=True, hi_open=True)
        check_range("tol", self.tol, 0.0, 1.0, lo_open=True, hi_open=True)
        check_range("max_iter", self.max_iter, 1, float("inf"))
        check_range("armijo", self.armijo, 0.0, 0.5, lo_open=True, hi_open=True)
        check_range("min_step", self.min_step, 0.0, 1.0, lo_open=True, hi_open=True)
        check_range("chord_rate", self.chord_rate, 0.0, 1.0, hi_open=True)
        check_range("working_margin", self.working_margin, 0.0, float("inf"), hi_open=True)
        check_range("rigid_rcond", self.rigid_rcond, 0.0, 1.0, lo_open=True, hi_open=True)

    def mu_per_point(self, m: int) -> FloatArray:
        """Return μ of every point, shape (m,), float64.

        Raises:
            ParameterError: If ``mu`` is per point but not of length ``m``.
        """
        if isinstance(self.mu, tuple):
            if len(self.mu) != m:
                raise ParameterError(
                    f"mu must be a scalar or have shape ({m},) (one per point), "
                    f"got shape ({len(self.mu)},)"
                )
            return np.array(self.mu, dtype=np.float64)
        return np.full(m, float(self.mu))


def _checked_mu(mu: object) -> float | tuple[float, ...]:
    """Return ``mu`` as a float or a tuple of floats, each checked to be in [0, inf)."""
    arr = np.asarray(mu, dtype=np.float64) if not isinstance(mu, str) else np.array(np.nan)
    if arr.ndim == 0:
        check_range("mu", float(arr), 0.0, float("inf"))
        return float(arr)
    if arr.ndim != 1 or arr.size == 0:
        raise ParameterError(
            f"mu must be a scalar or a 1-D array (one per point), got shape {arr.shape}"
        )
    bad = ~(np.isfinite(arr) & (arr >= 0.0))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ParameterError(f"mu must be in [0, inf) at every point, got {arr[i]} at point {i}")
    return tuple(float(x) for x in arr)


def _frozen(
    a: npt.ArrayLike, dtype: type, shape: tuple[int, ...], name: str
) -> npt.NDArray[np.generic]:
    arr: npt.NDArray[np.generic] = np.array(a, dtype=dtype, copy=True)
    if arr.shape != shape:
        raise ParameterError(f"{name} must have shape {shape}, got {arr.shape}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class ContactState:
    """Converged contact state after an increment (arrays are read-only copies).

    Attributes:
        p: Contact forces on the slave, shape (m, 3), float64 [N], frame [n, t1, t2].
        w: Relative displacements, shape (m, 3), float64 [mm]; ``w[:, 1:]`` is the
            tangential reference ``w_t_prev`` of the next increment.
        status: ContactStatus codes, shape (m,), int8.
        alpha: Rigid-body amplitudes, shape (k,), float64 (units set by ``G``).
    """

    p: FloatArray
    w: FloatArray
    status: npt.NDArray[np.int8]
    alpha: FloatArray

    def __post_init__(self) -> None:
        m = np.shape(self.p)[0] if np.ndim(self.p) == 2 else -1
        object.__setattr__(self, "p", _frozen(self.p, np.float64, (m, 3), "p"))
        object.__setattr__(self, "w", _frozen(self.w, np.float64, (m, 3), "w"))
        object.__setattr__(self, "status", _frozen(self.status, np.int8, (m,), "status"))
        k = np.size(self.alpha)
        object.__setattr__(self, "alpha", _frozen(np.ravel(self.alpha), np.float64, (k,), "alpha"))

    @classmethod
    def initial(cls, n_points: int, n_rigid: int = 0, w: FloatArray | None = None) -> ContactState:
        """Return the unloaded state: no force, all open, ``α = 0``.

        Args:
            n_points: Number of contact points ``m``.
            n_rigid: Number of rigid amplitudes ``k``.
            w: Relative displacement at zero load, shape (m, 3) [mm] (default zero); its
                tangential part is the slip reference, its normal part only enters
                ``normal_work`` of the first increment.

        Returns:
            The initial state.
        """
        w0 = np.zeros((n_points, 3)) if w is None else w
        status = np.zeros(n_points, dtype=np.int8)
        return cls(np.zeros((n_points, 3)), w0, status, np.zeros(n_rigid))


@dataclass(frozen=True)
class IncrementResult:
    """Outcome of one increment.

    Attributes:
        state: The converged state.
        iterations: Newton iterations used.
        residuals: Scaled residual ``ρ`` at every iterate (the last is below ``tol``).
        n_open: Number of open points.
        n_stick: Number of sticking points.
        n_slip: Number of slipping points.
        friction_work: ``-½ (p_t,prev + p_t)·Δw_t``, shape (m,), float64 [N·mm].
        normal_work: ``-½ (p_n,prev + p_n) Δw_n``, shape (m,), float64 [N·mm].
        dissipation: ``-p_t·Δw_t >= 0`` (backward Euler), shape (m,), float64 [N·mm].
        rescues: How many rescues (predictor or ``r`` change) were needed.
        factorizations: LU factorisations done (iterations minus chord and Krylov steps).
        linear_iterations: GMRES iterations done (``LinearSolver.KRYLOV``).
        regularised_iterations: Iterations of the regularised Newton fallback (included in
            ``iterations``); nonzero only where a step matrix was singular.
    """

    state: ContactState
    iterations: int
    residuals: tuple[float, ...]
    n_open: int
    n_stick: int
    n_slip: int
    friction_work: FloatArray
    normal_work: FloatArray
    dissipation: FloatArray
    rescues: int
    factorizations: int
    linear_iterations: int = 0
    regularised_iterations: int = 0


def validate_problem(
    W: FloatArray,
    w_free: FloatArray,
    state_prev: ContactState,
    G: FloatArray | None,
    e: FloatArray | None,
    symmetric: bool | None = None,
) -> Problem:
    """Check shapes and finiteness of an increment's data and return its ``Problem``.

    ``symmetric``: whether ``W`` is symmetric, when the caller knows it by construction
    (a condensed operator); None checks it (``is_symmetric``, a full pass over ``W``).

    Raises:
        ParameterError: Naming the array whose shape or values are wrong.
    """
    m = state_prev.p.shape[0]
    W = np.asarray(W, dtype=np.float64)
    if W.shape != (3 * m, 3 * m):
        raise ParameterError(f"W must have shape {(3 * m, 3 * m)} for {m} points, got {W.shape}")
    w_free = np.asarray(w_free, dtype=np.float64)
    if w_free.shape != (m, 3):
        raise ParameterError(f"w_free must have shape {(m, 3)}, got {w_free.shape}")
    w_sum = fingerprint(W)
    finite_w = np.isfinite(w_sum) or bool(np.all(np.isfinite(W)))
    if not (finite_w and np.all(np.isfinite(w_free))):
        raise ParameterError("W and w_free must be finite, got NaN or inf")
    d_n = np.diag(W)[0::3]
    if np.any(d_n <= 0.0):
        i = int(np.argmin(d_n))
        raise ParameterError(f"W_nn must be > 0 at every point, got {d_n[i]:g} at point {i}")
    k = state_prev.alpha.shape[0]
    if (G is None) != (e is None):
        raise ParameterError("G and e must be given together, got only one of them")
    G_arr = np.zeros((3 * m, k)) if G is None else np.asarray(G, dtype=np.float64)
    e_arr = np.zeros(k) if e is None else np.asarray(e, dtype=np.float64)
    if G_arr.shape != (3 * m, k) or e_arr.shape != (k,):
        raise ParameterError(
            f"G and e must have shapes {(3 * m, k)} and {(k,)} (k from state_prev.alpha), "
            f"got {G_arr.shape} and {e_arr.shape}"
        )
    w_t_prev = np.array(state_prev.w[:, 1:])
    sym = is_symmetric(W, w_sum) if symmetric is None else bool(symmetric)
    return Problem(W, w_free, G_arr, e_arr, w_t_prev, 0.0, w_sum, sym)


_FINGERPRINTS: ArrayMemo[float] = ArrayMemo()


def fingerprint(W: FloatArray) -> float:
    """The sum of the entries of ``W`` (``Problem.w_sum``), remembered for a frozen ``W``.

    One pass without a temporary: NaN and inf propagate into the sum (an overflowing sum
    of finite entries falls back to the entrywise check of the caller). It is the
    finiteness check and the fingerprint that tells the caches keyed by ``W`` whether it
    changed in place, so it is taken at every increment (a full pass over ``W``:
    benchmarks/bench_cycle.txt, 'fingerprint') unless ``W`` cannot change: read-only and
    owning its data, or a view whose every base is (the hinge's condensed ``W`` is made
    so). Then the sum of its first increment is reused while the array lives.
    """
    frozen = _unwritable(W)
    if frozen:
        kept = _FINGERPRINTS.get(W)
        if kept is not None:
            return kept
    w_sum = float(np.sum(W))
    if frozen:
        _FINGERPRINTS.put(W, w_sum)
    return w_sum


def _unwritable(W: FloatArray) -> bool:
    """Whether no write can reach ``W``'s data: read-only all the way to its owner."""
    a: object = W
    while isinstance(a, np.ndarray):
        if a.flags.writeable:
            return False
        a = a.base
    return a is None


SYMMETRY_RTOL = 1e-10
"""``W`` counts as symmetric if ``max|W - Wᵀ| <= SYMMETRY_RTOL max|W|`` (the hinge's
condensed ``W`` is symmetric to round-off; rigid-body sets with friction-dependent
impulses are not)."""

_SYMMETRY: ArrayMemo[tuple[float, bool]] = ArrayMemo()


def is_symmetric(W: FloatArray, w_sum: float = float("nan")) -> bool:
    """Whether ``W`` is symmetric to ``SYMMETRY_RTOL``, remembered while ``W`` lives.

    The check reads ``W`` once (by blocks); the answer is reused for the same array while
    its fingerprint ``w_sum`` (``Problem.w_sum``; NaN: unknown, never reused) is unchanged,
    so the increments of a cycle on one ``W`` pay for it once.

    Args:
        W: Square matrix, shape (n, n), float64.
        w_sum: Sum of its entries.
    """
    kept = _SYMMETRY.get(W)
    if kept is not None and kept[0] == w_sum:  # NaN never equals: unknown, not reused
        return kept[1]
    n, block, worst, scale = W.shape[0], 512, 0.0, 0.0
    for i in range(0, n, block):
        upper, lower = W[i : i + block, i:], W[i:, i : i + block]
        worst = max(worst, float(np.max(np.abs(upper - lower.T), initial=0.0)))
        scale = max(scale, float(np.max(np.abs(upper), initial=0.0)))
        scale = max(scale, float(np.max(np.abs(lower), initial=0.0)))
    symmetric = worst <= SYMMETRY_RTOL * scale
    _SYMMETRY.put(W, (w_sum, symmetric))
    return symmetric


class Complementarity(NamedTuple):
    """Alart–Curnier residual and its generalised Jacobian (see :func:`complementarity`).

    Attributes:
        residual: ``C``, shape (m, 3), float64 [N].
        jacobian: ``∂C/∂p`` with α fixed, shape (3m, 3m), float64 [-], node-major.
        status: ContactStatus codes of the trial, shape (m,), int8.
    """

    residual: FloatArray
    jacobian: FloatArray
    status: npt.NDArray[np.int8]


def complementarity(
    W: FloatArray,
    w_free: FloatArray,
    state_prev: ContactState,
    p: FloatArray,
    settings: ContactSettings,
    *,
    alpha: FloatArray | None = None,
    G: FloatArray | None = None,
) -> Complementarity:
    """Evaluate ``C(p) = p - λ(p - r g(p))`` and ``∂C/∂p = (I - D) + r D W`` densely.

    Meant for checks and small problems (it forms a (3m, 3m) matrix).

    Args:
        W: Delassus operator, shape (3m, 3m), float64 [mm/N].
        w_free: Free relative displacement, shape (m, 3), float64 [mm].
        state_prev: Previous converged state (``w_t_prev``).
        p: Contact forces at which to evaluate, shape (m, 3), float64 [N].
        settings: Supplies ``mu`` and ``r_scale``.
        alpha: Rigid amplitudes, shape (k,) (default zero).
        G: Rigid-body map, shape (3m, k) (default none).

    Returns:
        Residual, Jacobian and trial status.
    """
    k = state_prev.alpha.shape[0]
    e = None if G is None else np.zeros(k)
    m = p.shape[0]
    prob = validate_problem(W, w_free, state_prev, G, e)._replace(mu=settings.mu_per_point(m))
    r = settings.r_scale / np.diagonal(prob.W).reshape(m, 3).mean(axis=1)
    a = np.zeros(k) if alpha is None else np.asarray(alpha, dtype=np.float64)
    it = evaluate(prob, np.asarray(p, dtype=np.float64), a, r)
    D = coulomb_step(it.g, it.p, prob.mu, r).tangent  # (m, 3, 3)
    jac = np.zeros((3 * m, 3 * m))
    rows = np.arange(3 * m).reshape(m, 3)
    jac[rows[:, :, None], rows[:, None, :]] = np.eye(3) - D
    rD = r[:, None, None] * D
    jac += np.einsum("mab,mbj->maj", rD, prob.W.reshape(m, 3, 3 * m)).reshape(3 * m, 3 * m)
    return Complementarity(it.C, jac, it.law.status)
