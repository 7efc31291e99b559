"""Time the condensed contact solver on a Cattaneo–Mindlin cyclic load.

A floating rigid-ish indenter (translations + spin as rigid amplitudes, force
controlled) on an n×n grid of contact points with a half-space-like Delassus operator
(two identical bodies, Goodman uncoupling, 1/(π E* d) kernel, square-patch self term),
spherical gap profile. Load: normal preload P, then tangential Q: 0 → +Q → -Q → +Q with
Q = 0.8 μ P (partial slip with an annulus of slip). Run:

    .venv/bin/python benchmarks/bench_contact.py [--sizes 300 1000 1500] [--per-quarter 25]

On a shared or small machine set OPENBLAS_NUM_THREADS=1: the reduced systems
(n_q ≈ 3 n_stick + 2 n_slip ≲ 2000 here) gain little from threads and lose a lot to
oversubscription. "peak MiB" is tracemalloc's peak during the cycle, excluding W itself.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from fe.contact import ContactSettings, ContactState, solve_increment

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


def run(m_target: int, per_quarter: int, mu: float = 0.3, chord_rate: float = 0.1):
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
    settings = ContactSettings(mu=mu, chord_rate=chord_rate)
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sizes", type=int, nargs="+", default=[300, 1000, 1500])
    parser.add_argument("--per-quarter", type=int, default=25)
    parser.add_argument("--chord-rate", type=float, default=0.1)
    args = parser.parse_args()
    print(
        "   m  increments  iterations  it/incr  LU/incr  s/increment  peak MiB"
        "  open/stick/slip at +Q"
    )
    for m_target in args.sizes:
        m, n_inc, iters, n_lu, per, peak, counts = run(
            m_target, args.per_quarter, chord_rate=args.chord_rate
        )
        print(
            f"{m:4d}  {n_inc:10d}  {iters:10d}  {iters / n_inc:7.2f}  {n_lu / n_inc:7.2f}"
            f"  {per:11.4f}  {peak:8.1f}  {counts}"
        )


if __name__ == "__main__":
    main()
