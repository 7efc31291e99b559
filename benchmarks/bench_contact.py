"""Time the condensed contact solver on a Cattaneo–Mindlin cyclic load.

A floating rigid-ish indenter (translations + spin as rigid amplitudes, force
controlled) on an n×n grid of contact points with a half-space-like Delassus operator
(two identical bodies, Goodman uncoupling, 1/(π E* d) kernel, square-patch self term),
spherical gap profile. Load: normal preload P, then tangential Q: 0 → +Q → -Q → +Q with
Q = 0.8 μ P (partial slip with an annulus of slip). Run:

    .venv/bin/python benchmarks/bench_contact.py [--sizes 300 1000 1500] [--per-quarter 25]
    .venv/bin/python benchmarks/bench_contact.py --hinge W.npz [--stage0 10 --stage1 4]
    .venv/bin/python benchmarks/bench_contact.py --hinge W.npz --threads 1 2
    .venv/bin/python benchmarks/bench_contact.py --hinge W.npz --stage0 -1   # whole cycle

Each case runs with the old path (``LinearSolver.LU``: dense LU per iteration, chord
steps) and the new one (``LinearSolver.KRYLOV``) in the same process, and prints the
ratio new/old. ``--hinge`` replays the first increments of a hinge cycle (400 N, μ 0.2)
from an .npz with the condensed ``W``, ``G`` and ``w0`` of ``fe.general.cycle.configurations``
(e.g. ``np.savez(path, W=c.W, G=c.G, w0=c.w0)``), to time refinement levels whose
condensation takes minutes.

``--threads`` runs every case under ``threadpoolctl.threadpool_limits`` with each given
number of BLAS threads (default 1, as ``CycleSettings.blas_threads``). "peak MiB" is
tracemalloc's peak during the cycle, excluding W itself.

Measured (default hinge, zero clearance, 2 shared cores, wall s as LU / KRYLOV):

    level 0, whole cycle (m = 864):            before 15.3 / 15.0, after 12.7-13.3 / 12.5-12.9
    level 1, --stage0 10 --stage1 4 (m = 3136): before 65.8 / 62.5, after 50.7 / 54.0
    level 1, the same with 2 BLAS threads:      after 74.7 / 77.7

    level 1, the same, dense LUs ≥ 2000 unknowns on 2 threads (--lu-threads 1 2, quiet
    machine, same process): LU path 65.9 → 48.9, KRYLOV 56.9 → 54.3
    level 0, whole cycle, --lu-threads 1 2 twice: 15.9-18.8 / 17.6-20.5 either way (noise)

Before: column-gather Jacobian, about three W products per Newton iteration, W block and
the finiteness check redone per increment; after: row-gather Jacobian, one W product
per iteration, block kept across increments. The two paths tie within the noise of a
shared machine (KRYLOV: fewer iterations and factorisations, more small solves), and
two BLAS threads lose.
"""

from __future__ import annotations

import argparse
import itertools
import os
import time
import tracemalloc

import numpy as np
from threadpoolctl import threadpool_limits

from fe.contact import newton as contact_newton
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState, LinearSolver

E_STAR_MPA = 110_000.0


def half_space_grid(n_side: int, spacing_mm: float):
    xy = np.stack(np.meshgrid(np.arange(n_side), np.arange(n_side)), -1).reshape(-1, 2)
    xy = (xy - (n_side - 1) / 2) * spacing_mm
    d = np.sqrt(np.sum((xy[:, None] - xy[None]) ** 2, axis=-1))
    self_term = 4.0 * np.log(1.0 + np.sqrt(2.0)) / spacing_mm
    kernel = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), self_term) / (np.pi * E_STAR_MPA)
    W = np.kron(kernel, np.diag([1.0, 1.2, 1.2]))  # tangential compliance a bit larger
    return xy, W


def rigid_map(xy):
    m = len(xy)
    G = np.zeros((3 * m, 4))
    G[0::3, 0] = G[1::3, 1] = G[2::3, 2] = 1.0
    G[1::3, 3], G[2::3, 3] = -xy[:, 1], xy[:, 0]
    return G


def run(
    m_target: int, per_quarter: int, solver: LinearSolver, mu: float = 0.3, chord_rate: float = 0.1
):
    n_side = round(np.sqrt(m_target))
    spacing = 1.0 / n_side  # grid spans 1 mm
    xy, W = half_space_grid(n_side, spacing)
    m = len(xy)
    radius_mm = 50.0  # indenter radius → Hertz contact radius ~0.41 mm at P
    w_free = np.zeros((m, 3))
    w_free[:, 0] = np.sum(xy**2, axis=1) / (2 * radius_mm)
    G = rigid_map(xy)
    P = 200.0
    q_levels = [0.0]
    for a, b in [(0.0, 1.0), (1.0, -1.0), (-1.0, 1.0)]:
        n = per_quarter * round(abs(b - a))
        q_levels += [a + (b - a) * i / n for i in range(1, n + 1)]
    settings = ContactSettings(mu=mu, chord_rate=chord_rate, linear_solver=solver)
    state = ContactState.initial(m, 4)
    iters, n_lu, counts = 0, 0, None
    tracemalloc.start()
    t0 = time.perf_counter()
    for i, q in enumerate(q_levels):
        e = np.array([P, 0.8 * mu * P * q, 0.0, 0.0])
        res = solve_increment(W, w_free, state, settings, G=G, e=e, increment=i)
        iters += res.iterations
        n_lu += res.factorizations
        state = res.state
        if q == 1.0 and counts is None:
            counts = (res.n_open, res.n_stick, res.n_slip)
    wall = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return m, len(q_levels), iters, n_lu, wall / len(q_levels), peak / 2**20, counts


def run_hinge(path: str, n_stage0: int, n_stage1: int, solver: LinearSolver):
    """Replay the first increments of stages 0 and 1 (all stages if n_stage0 < 0) on a saved W."""
    import types

    from fe.cycle.protocol import CycleSettings, stage_targets
    from fe.general.increments import advance_force

    data = np.load(path)
    cond = types.SimpleNamespace(W=np.ascontiguousarray(data["W"]), G=data["G"], w0=data["w0"])
    cyc = CycleSettings(amplitude_n=400.0)
    contact = ContactSettings(mu=cyc.mu, tol=cyc.tol, max_iter=cyc.max_iter, linear_solver=solver)
    state = ContactState.initial(len(cond.w0), 7, w=cond.w0)
    f_prev, iters, n_lu, n_inc, eta_proxy = 0.0, 0, 0, 0, 0.0
    tracemalloc.start()
    t0 = time.perf_counter()
    stages = cyc.stages()
    limits = [None] * len(stages) if n_stage0 < 0 else [n_stage0, n_stage1]
    for stage, limit in zip(stages[: len(limits)], limits, strict=True):
        previous = None
        for target in stage_targets(*stage, cyc.grading)[:limit]:
            new, res = advance_force(
                cond, state, f_prev, float(target), contact, cyc, n_inc, dict, previous
            )
            iters += res.iterations
            n_lu += res.factorizations
            eta_proxy += float(res.friction_work.sum())
            previous, state, f_prev = (f_prev, state), new, float(target)
            n_inc += 1
    wall = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    m = len(cond.w0)
    return m, n_inc, iters, n_lu, wall, peak / 2**20, (float(state.alpha[6]), eta_proxy)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sizes", type=int, nargs="+", default=[300, 1000, 1500])
    parser.add_argument("--per-quarter", type=int, default=25)
    parser.add_argument("--chord-rate", type=float, default=0.1)
    parser.add_argument("--hinge", type=str, default=None, help=".npz with W, G, w0")
    parser.add_argument("--stage0", type=int, default=10)
    parser.add_argument("--stage1", type=int, default=4)
    parser.add_argument("--threads", type=int, nargs="+", default=[1], help="BLAS threads")
    parser.add_argument(
        "--lu-threads",
        type=int,
        nargs="+",
        default=[contact_newton.LU_THREADS],
        help="BLAS threads of the large dense LUs (HINGELAB_LU_THREADS, fe.contact.dense.lu_threads)",
    )
    args = parser.parse_args()
    print(
        "     m  path  thr  LUthr  increments  iterations  LU  wall s  peak MiB  new/old wall"
        "  result (open/stick/slip at +Q, or δ_end mm and Σ friction work N·mm)"
    )
    cases = [("hinge", 0)] if args.hinge else [("grid", m) for m in args.sizes]
    for (kind, m_target), threads, lu_threads in itertools.product(
        cases, args.threads, args.lu_threads
    ):
        walls = {}
        os.environ["HINGELAB_LU_THREADS"] = str(lu_threads)  # read at each LU (fe.contact.dense)
        for solver in (LinearSolver.LU, LinearSolver.KRYLOV):
            with threadpool_limits(limits=threads, user_api="blas"):
                m, n_inc, iters, n_lu, wall, peak, out = _case(kind, m_target, solver, args)
            walls[solver] = wall
            ratio = wall / walls[LinearSolver.LU]
            print(
                f"{m:6d}  {solver.name[:3]:4s}  {threads:3d}  {lu_threads:5d}"
                f"  {n_inc:10d}  {iters:10d}  {n_lu:3d}"
                f"  {wall:6.1f}  {peak:8.1f}  {ratio:12.2f}  {out}",
                flush=True,
            )


def _case(kind: str, m_target: int, solver: LinearSolver, args: argparse.Namespace):
    if kind == "hinge":
        return run_hinge(args.hinge, args.stage0, args.stage1, solver)
    m, n_inc, iters, n_lu, per, peak, out = run(
        m_target, args.per_quarter, solver, chord_rate=args.chord_rate
    )
    return m, n_inc, iters, n_lu, per * n_inc, peak, out


if __name__ == "__main__":
    main()
