"""Timing of assembly, factorisation and repeated solves on structured box meshes.

Run:  .venv/bin/python benchmarks/bench_assembly.py [--sizes 10000 30000 100000] [--threads 1 2]

For each size and BLAS/MKL thread count it prints: n_elem, n_dof, assembly wall time
(INCOMPATIBLE elements), PARDISO factorisation time of K_ff (bottom face clamped), solve time
per right-hand side one at a time and in blocks of 50 and 200, and the peak memory (tracemalloc
peak of Python/numpy allocations during assembly; process max RSS, which includes MKL).
Thread counts are set with threadpoolctl on both OpenBLAS (numpy) and MKL (PARDISO).
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_info, threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run as a script from anywhere

from fe.assembly import assemble_stiffness, dofs_of
from fe.element import ElementType
from fe.linalg.sparse import Factorization
from tests.helpers import box_mesh


def cube_divisions(n_elem: int) -> tuple[int, int, int]:
    n = round(n_elem ** (1 / 3))
    nz = max(1, round(n_elem / (n * n)))
    return n, n, nz


def best_of(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def run(n_target: int, threads: int, repeat: int) -> dict[str, float]:
    nx, ny, nz = cube_divisions(n_target)
    mesh = box_mesh(1.0, 1.0, 1.0, nx, ny, nz, distort=0.2)
    with threadpool_limits(limits=threads):
        tracemalloc.start()
        t0 = time.perf_counter()
        K = assemble_stiffness(mesh, ElementType.INCOMPATIBLE)
        t_asm_first = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        t_asm = (
            min(t_asm_first, best_of(lambda: assemble_stiffness(mesh), repeat - 1))
            if repeat > 1
            else t_asm_first
        )
        fixed = dofs_of(mesh.set_nodes("zmin"))
        free = np.setdiff1d(np.arange(K.shape[0]), fixed)
        K_ff = K[free][:, free]
        t0 = time.perf_counter()
        fac = Factorization(K_ff)
        t_fac = time.perf_counter() - t0
        rng = np.random.default_rng(0)
        B = rng.standard_normal((K_ff.shape[0], 200))
        n_single = 10
        t_single = best_of(lambda: [fac.solve(B[:, k]) for k in range(n_single)], 2) / n_single
        t_b50 = best_of(lambda: fac.solve(B[:, :50]), 2) / 50
        t_b200 = best_of(lambda: fac.solve(B), 2) / 200
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {
        "n_elem": mesh.n_elem,
        "n_dof": K.shape[0],
        "threads": threads,
        "assembly_s": t_asm,
        "factor_s": t_fac,
        "rhs1_ms": 1e3 * t_single,
        "rhs50_ms": 1e3 * t_b50,
        "rhs200_ms": 1e3 * t_b200,
        "asm_peak_mb": peak / 2**20,
        "max_rss_mb": rss_mb,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 30_000, 100_000])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--repeat", type=int, default=2, help="assemblies per case (best kept)")
    args = parser.parse_args()
    Factorization(box_mesh_k_ff())  # load MKL so threadpoolctl can see it
    libs = sorted({f"{i['internal_api']}({i['num_threads']})" for i in threadpool_info()})
    print(f"thread pools found: {', '.join(libs)}")
    cols = ["n_elem", "n_dof", "threads", "assembly_s", "factor_s", "rhs1_ms", "rhs50_ms",
            "rhs200_ms", "asm_peak_mb", "max_rss_mb"]  # fmt: skip
    print(" | ".join(f"{c:>11}" for c in cols))
    for n in args.sizes:
        for t in args.threads:
            row = run(n, t, args.repeat)
            cells = [
                f"{row[c]:>11.4g}" if isinstance(row[c], float) else f"{row[c]:>11}" for c in cols
            ]
            print(" | ".join(cells), flush=True)


def box_mesh_k_ff():
    mesh = box_mesh(1.0, 1.0, 1.0, 2, 2, 2)
    K = assemble_stiffness(mesh)
    free = np.setdiff1d(np.arange(K.shape[0]), dofs_of(mesh.set_nodes("zmin")))
    return K[free][:, free]


if __name__ == "__main__":
    main()
