"""Open-point elimination: solve an increment on a working set of points, check the rest.

Internal to :mod:`fe.contact` (notation there). A point with ``p = 0`` and a gap
``w_n >= 0`` satisfies its Alart–Curnier equation exactly (the trial ``ξ_n = -r w_n <= 0``
returns ``λ = 0 = p``), whatever ``r``. So an increment can be solved on the points that
may close — the *working set*: loaded before or at the start, or with a gap at the start
within ``working_margin`` times the start's largest normal motion — with the other
forces held at zero, on ``W`` restricted to those points (a quarter of ``W`` when half the
points are open, which is what every product of the Newton loop then reads).

The sub-solution is then checked on the full problem with one exact product (the rows of
the working set, ``W`` being symmetric): every excluded point's trial status must be open
and the full ``ρ`` must be ``<= tol``. Then it *is* a solution of the full problem, to the
same tolerance. Otherwise the excluded points that closed join the working set, with a
margin from the motion the sub-solve found, and the sub-problem is solved again from where
it stopped; after ``ROUNDS`` rounds (or if the set grows past ``MAX_FRACTION`` of the
points, or a sub-solve runs out of iterations) the full problem is solved from there with
a budget of its own, so the working set never fails an increment the full solve solves.
The set is kept per ``W`` between increments while it still holds the points needed with
at most ``SLACK`` spare, so that the restricted ``W`` — and the Krylov workspace keyed by
it, with its LU — carry over. Only one set of ``W``'s blocks lives at a time: a solve on a
working set drops the whole ``W``'s Krylov workspace, a solve on all points drops the kept
set, and the base LU is handed on renumbered (a lower memory peak with the same
iterations: benchmarks/bench_cycle.txt, 'fe.contact.working').
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cad.errors import ConvergenceError
from fe.contact.dense import gather_block, is_subset
from fe.contact.krylov import Base, release, workspace_for
from fe.contact.law import ContactStatus
from fe.contact.memo import ArrayMemo
from fe.contact.residual import Iterate, Problem, Solved, evaluate, sparse_product
from fe.contact.state import ContactSettings, ContactState

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

MIN_POINTS = 32
"""Problems with fewer points are solved whole (the restriction would not pay)."""

MAX_FRACTION = 0.5
"""A working set of more than this fraction of the points is not used (solve whole).

Gathering ``W`` on a set costs a pass over its rows and fresh memory for the block (page
faults included), while the products it spares over an increment's few iterations are
worth less than that when it holds most of the points. Chosen by measurement
(benchmarks/bench_contact_profile.txt, 'MAX_FRACTION')."""

SLACK = 1.3
"""A kept working set may hold this many times the points needed (else it is rebuilt)."""

HEADROOM = 0.15
"""A rebuilt working set takes this fraction of extra points, the open ones nearest to
closing: while a contact zone grows a few points per increment (the stick/slip
transitions of a zero-clearance cycle), a set of exactly the points needed had to be
gathered again at every increment (benchmarks/bench_contact_profile.txt, 'HEADROOM')."""

ROUNDS = 3
"""Working-set solves per increment before the full problem is solved from there."""

Newton = Callable[[Problem, Iterate, FloatArray, float, ContactSettings, int, int], Solved]


class _Kept(NamedTuple):
    w_sum: float
    points: IntArray
    W_sub: FloatArray
    w_sum_sub: float


_KEPT: ArrayMemo[_Kept] = ArrayMemo(per_thread=True, learned=True)


def _dofs(points: IntArray) -> IntArray:
    return (3 * points[:, None] + np.arange(3)).ravel()


def select_points(
    prob: Problem, prev: ContactState, it: Iterate, margin_factor: float
) -> IntArray | None:
    """Points that may close in this increment, shape (n_w,), int64 sorted; None: all.

    Args:
        prob: The full problem.
        prev: The previous converged state.
        it: The starting iterate on the full problem (exact ``w``).
        margin_factor: ``working_margin``.

    Returns:
        The working set, or None if it would hold most points or none (solve the whole
        problem).
    """
    m = len(it.p)
    if m < MIN_POINTS:
        return None
    motion = float(np.max(np.abs(it.w[:, 0] - prev.w[:, 0])))
    need = it.w[:, 0] <= margin_factor * motion
    need |= (it.p[:, 0] > 0.0) | np.any(prev.p != 0.0, axis=1)
    need |= prev.status != ContactStatus.OPEN
    points = np.flatnonzero(need).astype(np.int64)
    if len(points) == 0 or len(points) > MAX_FRACTION * m:
        return None
    return points


def _restricted(
    prob: Problem, points: IntArray, gap: FloatArray | None = None
) -> tuple[IntArray, FloatArray, float]:
    """``W`` on a working set, kept per ``W`` while the set still fits (see module doc).

    ``gap``: the normal gaps ``w_n`` of all points, shape (m,) [mm]; when the set is
    rebuilt, ``HEADROOM`` of extra points with the smallest gaps are taken along. A
    rebuilt set takes over the Krylov base of the old one, or of the whole ``W``, and
    that workspace (its ``W`` block and float32 copy) is dropped before the new block
    is gathered: only one set of blocks of ``W`` lives at a time.
    """
    kept = _KEPT.get(prob.W)
    if (
        kept is not None
        and kept.w_sum == prob.w_sum
        and len(kept.points) <= max(SLACK * len(points), len(points) + 8)
        and is_subset(points, kept.points)
    ):
        return kept.points, kept.W_sub, kept.w_sum_sub
    if kept is None:
        taken = _take_base(prob.W, _everything(prob))
    else:
        del kept  # its W_sub goes with the kept set (callers hold no reference)
        taken = _drop_kept(prob)
    points = _with_headroom(points, gap)
    W_sub = gather_block(prob.W, _dofs(points))
    w_sum_sub = float(np.sum(W_sub))
    _give_base(taken, W_sub, w_sum_sub, points)
    _KEPT.put(prob.W, _Kept(prob.w_sum, points, W_sub, w_sum_sub))
    return points, W_sub, w_sum_sub


def _with_headroom(points: IntArray, gap: FloatArray | None) -> IntArray:
    """``points`` and ``HEADROOM`` of the others, smallest ``gap`` first (sorted, int64)."""
    if gap is None:
        return points
    extra = min(int(HEADROOM * len(points)), int(MAX_FRACTION * len(gap)) - len(points))
    if extra <= 0:
        return points
    outside = np.ones(len(gap), dtype=bool)
    outside[points] = False
    others = np.flatnonzero(outside)
    nearest = others[np.argpartition(gap[others], extra - 1)[:extra]]
    return np.union1d(points, nearest).astype(np.int64)


def use_whole(prob: Problem) -> None:
    """Before a solve on all points: drop the kept working set, handing its base to ``W``.

    The kept ``W_sub`` (up to a quarter of ``W``) and its workspace would otherwise live
    beside the whole problem's own ``W`` block through that solve.
    """
    taken = _drop_kept(prob)
    if taken is not None:
        _give_base(taken, prob.W, prob.w_sum, _everything(prob))


def _drop_kept(prob: Problem) -> _Taken | None:
    """Forget the working set kept for ``prob.W`` and its workspace; return its base."""
    kept = _KEPT.pop(prob.W)
    return None if kept is None else _take_base(kept.W_sub, kept.points)


def _everything(prob: Problem) -> IntArray:
    """Every point of ``prob``, shape (m,), int64 (the whole ``W`` as a working set)."""
    return np.arange(len(prob.w_free), dtype=np.int64)


class _Taken(NamedTuple):
    base: Base
    points: IntArray


def _take_base(W_old: FloatArray, old: IntArray) -> _Taken | None:
    """Forget ``W_old``'s Krylov workspace, keeping its base LU (on the points ``old``)."""
    ws = release(W_old)
    if ws is None or ws.base is None:
        return None
    return _Taken(ws.base, old)


def _give_base(taken: _Taken | None, W_new: FloatArray, w_sum_new: float, new: IntArray) -> None:
    """Hand a taken Krylov base LU to the workspace of ``W_new`` (on ``new``), renumbered.

    The base belongs to the reduced Jacobian of its closed points; if the new set holds
    them all, only their numbering changes, and monotonically (both sets sorted), so the
    factors keep their unknown order and stay valid. Without this every change of the set
    would cost a factorisation.
    """
    if taken is None:
        return
    base = taken.base
    closed = taken.points[base.closed]
    local = np.searchsorted(new, closed)
    if np.any(local >= len(new)) or not np.array_equal(
        new[np.minimum(local, len(new) - 1)], closed
    ):
        return
    point = np.searchsorted(base.closed, base.factor.keys // 3)
    keys = 3 * local[point] + base.factor.keys % 3
    ws = workspace_for(W_new, w_sum_new)
    ws.base = base._replace(factor=base.factor._replace(keys=keys), closed=local)


def solve_on_points(
    prob: Problem,
    prev: ContactState,
    it: Iterate,
    r_base: FloatArray,
    cut: float,
    settings: ContactSettings,
    increment: int,
    points: IntArray,
    newton: Newton,
) -> Solved:
    """Solve the increment on a working set, checked and grown until it holds (module doc).

    Args:
        prob: The full problem (symmetric ``W``).
        prev: The previous converged state.
        it: The starting iterate on the full problem.
        r_base: Augmentation per point, shape (m,), float64 [N/mm].
        cut: Absolute singular-value cut of the rigid-body Schur complement.
        settings: Solver options.
        increment: Index reported in a ConvergenceError.
        points: The initial working set (:func:`select_points`).
        newton: The full solver, ``newton(prob, it, r, cut, settings, increment, budget)``.

    Returns:
        The converged iterate on the full problem (exact ``w``) and the summed counts.

    Raises:
        ConvergenceError: As ``newton`` on the whole problem (the last resort).
    """
    m = len(it.p)
    it = _without(prob, it, points, r_base)
    start = it
    budget = settings.max_iter
    done: list[Solved] = []
    wasted = 0  # iterations of a sub-solve that ran out of them
    for _round in range(ROUNDS):
        points, W_sub, w_sum_sub = _restricted(prob, points, it.w[:, 0])
        sub = _sub_problem(prob, points, W_sub, w_sum_sub)
        del W_sub  # only the kept set holds it past this round (_restricted may drop it)
        sub_it = evaluate(sub, it.p[points], it.alpha, r_base[points], it.Wp[points])
        try:
            solved = newton(sub, sub_it, r_base[points], cut, settings, increment, budget)
        except ConvergenceError as err:
            # the whole problem from where the sub-solve stopped, with a budget of its own
            stopped = _force_on_all_points(err, points, m)
            if stopped is not None:
                p, alpha = stopped
                it = evaluate(prob, p, alpha, r_base, sparse_product(prob.W, p).reshape(-1, 3))
            wasted = err.iteration
            break
        finally:
            del sub
        budget -= solved.iterations
        done.append(solved)
        p = np.zeros((m, 3))
        p[points] = solved.it.p
        Wp = sparse_product(prob.W, p).reshape(-1, 3)
        it = evaluate(prob, p, solved.it.alpha, r_base, Wp)
        outside = np.ones(m, dtype=bool)
        outside[points] = False
        closing = outside & (it.law.status != ContactStatus.OPEN)
        if not np.any(closing) and it.rho <= settings.tol:
            return _summed(done, it)
        # The motion the sub-solve found sets the margin of the points added.
        motion = float(np.max(np.abs(it.w[:, 0] - start.w[:, 0])))
        near = outside & (it.w[:, 0] <= settings.working_margin * motion)
        points = np.union1d(points, np.flatnonzero(closing | near)).astype(np.int64)
        if len(points) > MAX_FRACTION * m or budget <= 0:
            break
    # The whole problem gets a budget of its own: the working set never fails an
    # increment that the whole problem solves (it only costs the rounds' iterations).
    use_whole(prob)
    done.append(newton(prob, it, r_base, cut, settings, increment, settings.max_iter))
    summed = _summed(done, done[-1].it)
    return summed._replace(iterations=summed.iterations + wasted)


def _without(prob: Problem, it: Iterate, points: IntArray, r_base: FloatArray) -> Iterate:
    """The start with zero force outside the working set (extrapolated tension there)."""
    outside = np.ones(len(it.p), dtype=bool)
    outside[points] = False
    dropped = np.flatnonzero(outside & np.any(it.p != 0.0, axis=1))
    if len(dropped) == 0:
        return it
    p = it.p.copy()
    p[dropped] = 0.0
    gone = np.zeros_like(p)
    gone[dropped] = it.p[dropped]
    Wp = it.Wp - sparse_product(prob.W, gone).reshape(-1, 3)  # W symmetric: their rows
    return evaluate(prob, p, it.alpha, r_base, Wp)


def _sub_problem(prob: Problem, points: IntArray, W_sub: FloatArray, w_sum_sub: float) -> Problem:
    mu = np.broadcast_to(np.asarray(prob.mu, dtype=np.float64), (len(prob.w_free),))
    return Problem(
        W_sub,
        prob.w_free[points],
        prob.G[_dofs(points)],
        prob.e,
        prob.w_t_prev[points],
        mu[points],
        w_sum_sub,
        True,
    )


def _summed(done: list[Solved], it: Iterate) -> Solved:
    """The counts of all solves, with the final iterate on the full problem."""
    history = tuple(rho for s in done for rho in s.history)
    return Solved(
        it,
        sum(s.iterations for s in done),
        (*history, it.rho),
        sum(s.rescues for s in done),
        sum(s.factorizations for s in done),
        sum(s.linear_iterations for s in done),
        sum(s.regularised_iterations for s in done),
    )


def _force_on_all_points(
    err: ConvergenceError, points: IntArray, m: int
) -> tuple[FloatArray, FloatArray] | None:
    """The stopped sub-solve's ``(p (m, 3), α)`` on all points (zero force outside)."""
    part = err.partial
    if not isinstance(part, ContactState):
        return None
    p = np.zeros((m, 3))
    p[points] = part.p
    return p, np.array(part.alpha)
