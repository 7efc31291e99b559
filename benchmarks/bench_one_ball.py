"""One meshed 708C ball between raceway blocks against Hertz, per mesh level (issue #11).

Usage: OMP_NUM_THREADS=1 HINGELAB_LU_THREADS=1 .venv/bin/python benchmarks/bench_one_ball.py
       [--levels 0 1 2] [--loads 50 100 200]
       [--ball-x X] [--ball-y Y] [--ring-depth D] [--ring-y Y]   (body-size sensitivity)
       [--curvature-ratio F]                                     (less conformal grooves)

Each mesh level (fe.bearing.one_ball.MESH_LEVELS) runs in a fresh process: mesh,
assembly, factorisation (PARDISO), normal condensation, then one frictionless solve per
load. Printed per level: nodes, free DOF, contact points m, wall time (build + all
loads), peak resident memory; per load and raceway the relative errors against the exact
Hertz solution (fe.bearing.hertz, elliptic integrals) of:

* ``a_mom``/``b_mom``: semi-axes from the force moments, ``a_fit``/``b_fit``: from the
  ellipsoid fit of the nodal pressures, ``a_edge``/``b_edge``: discrete edge midpoints;
* ``p0``: largest nodal pressure;
* ``d_loc``: mutual approach of the axis points ~0.2 mm deep in ball and ring against
  the half-space Hertz value at those depths;
* ``d_tot``: ball centre to the ring block's far face against the Hertz approach δ_H
  (the difference is the blocks' bulk compliance, linear in Q);
* per raceway, ``K_fit``: the constant of ``δ_tot = (Q/K)^{2/3} + c Q`` fitted over the
  loads, against Hertz's K, and the bulk compliance c.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Any

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks._common import print_table, run_isolated


def run_level(
    level: int, loads: tuple[float, ...], sizes: dict[str, float], ratio: float | None
) -> dict[str, Any]:
    """Build and solve one level; return its size, timings and per-load rows.

    ``sizes`` overrides body sizes of the level's grid (ball_x, ball_y, ring_depth, ring_y);
    ``ratio`` (if not None) sets both groove curvature ratios f_i = f_o.
    """
    import dataclasses

    from threadpoolctl import threadpool_limits

    from cad.bearing_geometry import BearingHingeParams
    from fe.bearing.one_ball import MESH_LEVELS, build_rig, solve_load

    params = BearingHingeParams()
    if ratio is not None:
        params = BearingHingeParams(inner_curvature_ratio=ratio, outer_curvature_ratio=ratio)
    with threadpool_limits(1, user_api="blas"):
        t0 = time.perf_counter()
        rig = build_rig(dataclasses.replace(MESH_LEVELS[level], **sizes), params)
        t_build = time.perf_counter() - t0
        rows = []
        for q in loads:
            t1 = time.perf_counter()
            res = solve_load(rig, q)
            t_solve = time.perf_counter() - t1
            for r in res:
                h = r.hertz
                rows.append(
                    {
                        "level": level,
                        "Q_N": q,
                        "race": r.race.value,
                        "closed": r.n_closed,
                        "a_H": h.semi_major_mm,
                        "b_H": h.semi_minor_mm,
                        "a_mom%": 100 * (r.a_moment_mm / h.semi_major_mm - 1),
                        "a_fit%": 100 * (r.a_fit_mm / h.semi_major_mm - 1),
                        "a_edge%": 100 * (r.a_edge_mm / h.semi_major_mm - 1),
                        "b_mom%": 100 * (r.b_moment_mm / h.semi_minor_mm - 1),
                        "b_fit%": 100 * (r.b_fit_mm / h.semi_minor_mm - 1),
                        "b_edge%": 100 * (r.b_edge_mm / h.semi_minor_mm - 1),
                        "p0%": 100 * (r.p0_mpa / h.max_pressure_mpa - 1),
                        "d_loc%": 100 * (r.approach_local_mm / r.approach_local_hertz_mm - 1),
                        "d_tot%": 100 * (r.approach_total_mm / h.approach_mm - 1),
                        "delta_H_um": 1000 * h.approach_mm,
                        "delta_tot_um": 1000 * r.approach_total_mm,
                        "solve_s": t_solve,
                    }
                )
    g = rig.grid
    return {
        "level": level,
        "h_x": g.h_x,
        "h_y": g.h_y,
        "h_z": g.h_z,
        "nodes": rig.mesh.n_nodes,
        "hexes": rig.mesh.n_elem,
        "dof": len(rig.system.free),
        "m": rig.n_points,
        "build_s": t_build,
        **{f"{k}_s": v for k, v in rig.timings_s.items()},
        "rows": rows,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--loads", type=float, nargs="+", default=[50.0, 100.0, 200.0])
    for name in ("ball_x", "ball_y", "ring_depth", "ring_y"):
        ap.add_argument(f"--{name.replace('_', '-')}", type=float, help="override [mm]")
    ap.add_argument("--curvature-ratio", type=float, help="f_i = f_o (default 0.52/0.53)")
    args = ap.parse_args()
    loads = tuple(args.loads)
    sizes = {
        k: getattr(args, k)
        for k in ("ball_x", "ball_y", "ring_depth", "ring_y")
        if getattr(args, k) is not None
    }

    import numpy as np

    from fe.bearing.one_ball_post import fit_contact_constant

    levels, rows, fits = [], [], []
    for level in args.levels:
        out = run_isolated(run_level, level, loads, sizes, args.curvature_ratio)
        rows.extend(out.pop("rows"))
        levels.append(out)
        for race in ("inner", "outer"):
            sel = [r for r in rows if r["level"] == level and r["race"] == race]
            q = np.array([r["Q_N"] for r in sel])
            d_fe = np.array([r["delta_tot_um"] for r in sel]) / 1000
            d_h = np.array([r["delta_H_um"] for r in sel]) / 1000
            k_h = float(np.mean(q / d_h**1.5))
            if len(q) >= 2:
                k_fit, c = fit_contact_constant(q, d_fe)
                fits.append(
                    {
                        "level": level,
                        "race": race,
                        "K_H": k_h,
                        "K_fit": k_fit,
                        "K_fit%": 100 * (k_fit / k_h - 1),
                        "c_nm_per_N": 1e6 * c,
                    }
                )
    if sizes:
        print(f"Body sizes overridden [mm]: {sizes}")
    if args.curvature_ratio is not None:
        print(f"Groove curvature ratios f_i = f_o = {args.curvature_ratio:g}")
    print("Mesh levels (wall = mesh + assembly + factorisation + condensation + all solves)")
    print_table(
        levels,
        ["level", "h_x", "h_y", "h_z", "nodes", "hexes", "dof", "m", "mesh_s", "assembly_s",
         "factorisation_s", "condensation_s", "wall_s", "peak_MB"],
    )  # fmt: skip
    print("\nErrors against Hertz (exact elliptic integrals) [%]")
    print_table(
        rows,
        ["level", "Q_N", "race", "closed", "a_H", "b_H", "a_mom%", "a_fit%", "a_edge%",
         "b_mom%", "b_fit%", "b_edge%", "p0%", "d_loc%", "d_tot%", "solve_s"],
    )  # fmt: skip
    if fits:
        print("\nTotal approach fitted as (Q/K)^(2/3) + c Q over the loads")
        print_table(fits, ["level", "race", "K_H", "K_fit", "K_fit%", "c_nm_per_N"])


if __name__ == "__main__":
    main()
