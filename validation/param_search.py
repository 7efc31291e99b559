"""One parameter per candidate effect: a grid, an interpolant, and refinement rounds on the true model.

The model's features are smooth in a candidate's parameter p, so ``validation.candidate_fit``
fits p on an interpolant of features computed on a log grid and spends true-model runs only
where the fit lands:

1. **Grid** (``grid``): features at ``grid_points`` values of p, from the model itself or,
   *coarse to fine*, from a **screen** — the same hinge on a coarser mesh, whose cycles cost
   a fraction of the model's.
2. **Interpolant** (``Search.predictor``): features between the nodes (the grid and every
   refinement point) by a monotone cubic in p (PCHIP: smooth, so a minimum does not stick
   to a node, and no overshoot between nodes). With a screen, the screen's interpolant times a correction
   ``r = model / screen`` per design point and feature, linear in log10 p between the points
   where both meshes ran: the baseline (the effect off, placed one decade below the grid)
   and each refinement point, a monotone cubic in log10 p that keeps its slope for
   ``EXTRAPOLATE_DECADES`` past the last point (a kink there would hold the minimum). The interpolant is exact at every
   point where the true model ran.
3. **Rounds** (``refine``): every candidate not yet settled proposes the minimum of χ² on its
   interpolant (``scan``); the true model runs there (all candidates' points as one batch,
   which a Dask cluster runs at once); the point joins the interpolant. A candidate is
   settled when another run promises less than ``chi2_tol`` of χ² (scaled by the misfit's
   inflation; a tenth of the Δχ² = 1 that makes a parameter's 1σ interval), when the new
   minimum is a point already run, when its interpolant prefers the effect off, or after
   ``max_rounds`` runs. Its **stated error** is the largest
   |interpolated − true| / σ over the informative features at the last point run, before
   that point joined the interpolant. **The check**: a search whose stated error exceeds
   ``error_max`` (1σ) does not trust its interpolant near the fit and is polished on the
   true model (bounded Brent within ``POLISH_DECADES`` of its best point, the search this
   one replaced), unless its best point is the baseline or a grid end.
4. **The value** (``Search.best``) is the true-model point of least χ² (grid nodes count
   when the grid ran on the model itself), or 0 — the effect off, the baseline — when none
   beats it: every χ² a verdict uses is the true model's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
Rows = npt.NDArray[np.bool_]
Cost = Callable[[FloatArray, "Rows | None"], float]
"""χ² of features (n_points, 3) over the rows selected (None: all)."""

EXTRAPOLATE_DECADES = 0.5
"""How far past the last refinement point the screen correction keeps its slope [decades]."""

POLISH_DECADES = 0.25
"""Half-width of the true-model polish around the best point [decades of p]."""

SCAN_POINTS = 301
"""Log-spaced parameter values the interpolant is scanned at, between the grid's ends."""


def grid(hi: float, points: int, decades: float) -> FloatArray:
    """The log grid of a parameter: ``points`` values over ``decades`` decades up to ``hi``."""
    return np.asarray(hi * 10.0 ** np.linspace(-decades, 0.0, points), dtype=np.float64)


def _ratio(num: FloatArray, den: FloatArray) -> FloatArray:
    """Num / den where both are finite and den ≠ 0, else 1 (no correction)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        r = num / den
    return np.asarray(np.where(np.isfinite(r) & (den != 0), r, 1.0), dtype=np.float64)


@dataclass
class Search:
    """One candidate's parameter search (mutable: the rounds add points).

    Attributes:
        name: The candidate effect.
        grid: Grid values of the parameter, shape (g,), ascending.
        grid_features: Features on the grid, shape (g, n_points, 3) (the screen's, with one).
        base: The model's baseline features (effect off), shape (n_points, 3).
        base_screen: The screen's baseline features, shape (n_points, 3); None: no screen
            (the grid ran on the model itself).
        runs: Parameter value → (the model's features, the screen's features or None) at
            the refinement points.
        settled: No more rounds.
        error_sigma: The stated error at the last point run (NaN before any).
        rounds: True-model points run by the rounds.
        polish_runs: True-model points run by the polish (``_polish``).
    """

    name: str
    grid: FloatArray
    grid_features: FloatArray
    base: FloatArray
    base_screen: FloatArray | None = None
    runs: dict[float, tuple[FloatArray, FloatArray | None]] = field(default_factory=dict)
    settled: bool = False
    error_sigma: float = math.nan
    rounds: int = 0
    polish_runs: int = 0

    @property
    def screened(self) -> bool:
        """True when the grid ran on a screen (coarser mesh)."""
        return self.base_screen is not None

    def _nodes(self) -> tuple[FloatArray, FloatArray]:
        """(p (k,), features (k, n_points, 3)) of the interpolant's nodes, finite ones only."""
        ps = list(self.grid)
        fs = list(self.grid_features)
        for p, (true, screen) in self.runs.items():
            node = screen if self.screened else true
            if node is not None:
                ps.append(p)
                fs.append(node)
        order = np.argsort(ps, kind="stable")
        p_arr = np.asarray(ps, dtype=np.float64)[order]
        f_arr = np.asarray(fs, dtype=np.float64)[order]
        ok = np.all(np.isfinite(f_arr.reshape(len(p_arr), -1)), axis=1)
        p_arr, f_arr = p_arr[ok], f_arr[ok]
        keep = np.concatenate([[True], np.diff(p_arr) > 0])  # a run on a grid node: once
        return p_arr[keep], f_arr[keep]

    def _correction(self) -> tuple[FloatArray, FloatArray] | None:
        """(log10 p (k,), model/screen ratio (k, n_points, 3)) of the correction; None: none."""
        if self.base_screen is None:
            return None
        us = [math.log10(float(self.grid[0])) - 1.0]
        rs = [_ratio(self.base, self.base_screen)]
        for p in sorted(self.runs):
            true, screen = self.runs[p]
            if screen is not None and np.all(np.isfinite(true)) and np.all(np.isfinite(screen)):
                us.append(math.log10(p))
                rs.append(_ratio(true, screen))
        return np.asarray(us), np.asarray(rs)

    def predictor(self) -> Callable[[float], FloatArray] | None:
        """The interpolant p → features (n_points, 3); None with fewer than two nodes."""
        p_nodes, f_nodes = self._nodes()
        if len(p_nodes) < 2:
            return None
        corr = self._correction()

        from scipy.interpolate import PchipInterpolator

        shape = PchipInterpolator(p_nodes, f_nodes, axis=0, extrapolate=True)
        ratio: PchipInterpolator | None = None
        if corr is not None:  # smooth in log10 p; a slope carried half a decade past the last
            us, rs = corr
            if len(us) == 1:  # the baseline's ratio everywhere
                us, rs = np.append(us, us[0] + 1.0), np.concatenate([rs, rs])
            ratio = PchipInterpolator(us, rs, axis=0, extrapolate=True)
            u_lo, u_hi = float(us[0]), float(us[-1]) + EXTRAPOLATE_DECADES

        def predict(p: float) -> FloatArray:
            f = np.asarray(shape(p), dtype=np.float64)
            if ratio is not None:
                u = min(max(math.log10(p), u_lo), u_hi)
                f = np.asarray(ratio(u), dtype=np.float64) * f
            return np.asarray(f, dtype=np.float64)

        return predict

    def scan(self, cost: Cost, rows: Rows | None = None) -> tuple[float, FloatArray]:
        """(p, features) minimising χ² over ``rows`` on the interpolant; p = 0: the effect off."""
        best = (cost(self.base, rows), 0.0, self.base)
        predict = self.predictor()
        if predict is None:
            return best[1], best[2]
        lo, hi = math.log10(float(self.grid[0])), math.log10(float(self.grid[-1]))
        p_lo, p_hi = float(self.grid[0]), float(self.grid[-1])
        # 10**log10(p) may leave the range by an ulp: a true-model run there would be refused
        for p in np.clip(10.0 ** np.linspace(lo, hi, SCAN_POINTS), p_lo, p_hi):
            fp = predict(float(p))
            c = cost(fp, rows)
            if c < best[0]:
                best = (c, float(p), fp)
        if best[1] > 0.0:  # polish between the scan's neighbours (the interpolant only)
            from scipy import optimize

            step = (hi - lo) / (SCAN_POINTS - 1)
            u0 = math.log10(best[1])
            res = optimize.minimize_scalar(
                lambda u: cost(predict(float(10.0**u)), rows),
                bounds=(max(lo, u0 - step), min(hi, u0 + step)),
                method="bounded",
                options={"xatol": 1e-5},
            )
            if float(res.fun) < best[0]:
                p = min(max(float(10.0**res.x), p_lo), p_hi)
                best = (float(res.fun), p, predict(p))
        return best[1], best[2]

    def best(self, cost: Cost) -> tuple[float, float, FloatArray]:
        """(χ², p, features) of the true-model point of least χ²; p = 0: the baseline."""
        options = [(cost(self.base, None), 0.0, self.base)]
        options += [(cost(true, None), p, true) for p, (true, _) in self.runs.items()]
        if not self.screened:
            options += [
                (cost(f, None), float(p), f)
                for p, f in zip(self.grid, self.grid_features, strict=True)
            ]
        return min(options, key=lambda o: (o[0], o[1]))


def stated_error(predicted: FloatArray, true: FloatArray, sigma: FloatArray, ok: Rows) -> float:
    """Max |predicted − true| / σ over the informative features ``ok`` (0 when none)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        e = np.abs(predicted - true) / sigma
    e = np.where(ok & np.isfinite(e), e, 0.0)
    return float(np.max(e)) if e.size else 0.0


Run = Callable[[Sequence[tuple["Search", float]]], Sequence[tuple[FloatArray, FloatArray | None]]]
"""(search, p) pairs → (the model's features, the screen's or None) for each, in order."""


def refine(
    searches: Sequence[Search],
    run: Run,
    cost: Cost,
    sigma: FloatArray,
    informative: Rows,
    max_rounds: int,
    chi2_tol: float = 0.1,
    xatol: float = 0.002,
    error_max: float = 1.0,
) -> None:
    """Run the refinement rounds (module docstring, step 3) until every search is settled.

    Args:
        searches: The candidates' searches, their grids filled.
        run: (search, p) pairs → (the model's features, the screen's or None) for each, in
            order; called once per round with every unsettled candidate's point (one batch).
        cost: χ² of features.
        sigma: Feature σ, shape (n_points, 3).
        informative: Features that count, shape (n_points, 3).
        max_rounds: True-model points per candidate at most.
        chi2_tol: Settled when another run promises a χ² gain below this (times the
            inflation max(1, χ²/(N − 1)) of the best run: a tenth of the Δχ² = 1 of a
            parameter's 1σ interval).
        xatol: Or when the interpolant's minimum is within this of a point already run
            [decades of p].
        error_max: A search whose stated error exceeds this [σ] is polished on the true
            model afterwards (``_polish``: bounded Brent, at most ``max_rounds`` runs, one
            candidate after another).
    """
    n_obs = int(np.count_nonzero(informative))
    proposal: dict[int, float] = {}
    for i, s in enumerate(searches):
        p, _ = s.scan(cost)
        if p == 0.0 or max_rounds < 1:
            s.settled = True
        else:
            proposal[i] = p
    while proposal:
        batch = [(searches[i], p) for i, p in proposal.items()]
        outcomes = run(batch)
        nxt: dict[int, float] = {}
        for (i, p), (true, screen) in zip(proposal.items(), outcomes, strict=True):
            s = searches[i]
            predict = s.predictor()
            if predict is not None:
                s.error_sigma = stated_error(predict(p), true, sigma, informative)
            s.runs[p] = (true, screen)
            s.rounds += 1
            p_new, f_new = s.scan(cost)
            best_run = min(cost(true_p, None) for true_p, _ in s.runs.values())
            gain = best_run - cost(f_new, None)  # what another run promises
            inflate = max(1.0, best_run / max(n_obs - 1, 1))
            known = [*s.runs, *([] if s.screened else s.grid)]  # where the true model ran
            fresh = p_new > 0.0 and all(
                abs(math.log10(p_new) - math.log10(float(q))) > xatol for q in known
            )
            if fresh and gain > chi2_tol * inflate and s.rounds < max_rounds:
                nxt[i] = p_new
            else:
                s.settled = True
        proposal = nxt
    for s in searches:
        if s.error_sigma > error_max:  # NaN (no run) and a trusted interpolant: done
            _polish(s, run, cost, max_rounds)


def _polish(s: Search, run: Run, cost: Cost, max_iter: int) -> None:
    """Bounded Brent on the true model within ``POLISH_DECADES`` of the best point run.

    For a search whose interpolant missed the true model at its last point by more than
    the ``refine`` threshold: the fit is then not where the interpolant says. Nothing to
    polish at p = 0 or at an end of the grid (a fit at its bound stays there).
    """
    from scipy import optimize

    _, p_best, _ = s.best(cost)
    lo, hi = math.log10(float(s.grid[0])), math.log10(float(s.grid[-1]))
    if p_best == 0.0:
        return
    u0 = math.log10(p_best)
    if u0 <= lo + 1e-9 or u0 >= hi - 1e-9:
        return
    p_lo, p_hi = float(s.grid[0]), float(s.grid[-1])

    def at(u: float) -> float:
        p = min(max(float(10.0**u), p_lo), p_hi)
        if p not in s.runs:
            s.runs[p] = run([(s, p)])[0]
            s.polish_runs += 1
        return cost(s.runs[p][0], None)

    optimize.minimize_scalar(
        at,
        bounds=(max(lo, u0 - POLISH_DECADES), min(hi, u0 + POLISH_DECADES)),
        method="bounded",
        options={"maxiter": max_iter, "xatol": 0.01},
    )
