"""The bearing hinge with ``full`` (meshed) balls beside ``hertz`` balls: cost and answers.

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_bearing_full.py
       [--refinement K] [--rig-level L] [--cases FP:FG ...] [--mu X] [--out FILE]

One process per model (``benchmarks._common.run_isolated``, so each peak RSS is its own):
the structure is built through ``ModelService.prepare`` (default mesh), the one-ball rig
is built or read from its cache (``fe.bearing.ball_rig``; pass ``--cold`` to time a build
into a fresh cache folder), and each load case runs one cycle. Printed: DOF of structure
and rig, rig contact points, the rig's build times, per case wall time, Newton (outer)
iterations per increment, local contact solves, η, δ(±Fg) for full and hertz side by side
and their ratio, the loop's friction work and the energy balance.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from fe.kinds import hinge_kind

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks._common import print_table, run_isolated

COARSE: dict[str, Any] = {"size_mm": 4.0, "contact_size_mm": 0.8, "part_sizes_mm": (("ring", 1.2),)}
"""The tests' coarse structure (``--coarse``, a smoke run)."""


def run_model(
    model: str,
    refinement: int,
    level: int,
    cases: list[tuple[float, float]],
    mu: float,
    coarse: bool,
) -> dict[str, Any]:
    """Build the structure (and rig) and run every case with one ball model."""
    import dataclasses
    import math
    import resource

    import numpy as np
    from threadpoolctl import threadpool_limits

    from cad.bearing_geometry import BallModel, BearingHingeParams
    from fe.bearing import ball_rig
    from fe.bearing.cycle import run_bearing_cycle
    from fe.bearing.full_cycle import run_full_cycle
    from fe.bearing.one_ball import MESH_LEVELS
    from fe.cycle.protocol import CycleSettings
    from model.service import ModelService
    from model.spec import DesignPoint, ModelSpec

    hinge = BearingHingeParams(ball_model=BallModel(model))
    spec = ModelSpec(
        "bearing",
        hinge,
        hinge_kind("bearing").mesh_settings(refinement=refinement, **(COARSE if coarse else {})),
        CycleSettings(mu=mu),
    )
    out: dict[str, Any] = {"model": model, "cases": []}
    with threadpool_limits(1, user_api="blas"):
        t0 = time.perf_counter()
        prepared = ModelService().prepare(spec, DesignPoint(spec.cycle.amplitude_n))
        out["setup_s"] = time.perf_counter() - t0
        system = prepared.system
        out["structure_dof"] = 3 * prepared.meshed.report.n_nodes
        if model == "full":
            t0 = time.perf_counter()
            rig = ball_rig.load_or_build_rig(MESH_LEVELS[level], hinge)
            out["rig_s"] = time.perf_counter() - t0
            out["rig_dof"], out["rig_points"] = rig.n_dof, rig.n_points
            out["rig_build"] = rig.timings_s
        for fp, fg in cases:
            settings = dataclasses.replace(spec.cycle, amplitude_n=fg)
            t0 = time.perf_counter()
            if model == "full":
                fc = run_full_cycle(system, settings, fp, grid=MESH_LEVELS[level])
                r, solves, skipped = fc.cycle.result, fc.local_solves, fc.skipped
            else:
                r, solves, skipped = run_bearing_cycle(system, settings, fp).result, 0, 0
            wall = time.perf_counter() - t0
            m = r.metrics()
            its = [i.iterations for i in r.increments]
            loop = r.increments[r.last_loop().start :]
            # the hertz loop once more with the trapezoid (the full loop's rule)
            trap = dataclasses.replace(
                r,
                increments=tuple(
                    dataclasses.replace(i, stiffness_n_per_mm=math.nan) for i in r.increments
                ),
            )
            out["cases"].append(
                {
                    "Fp": fp,
                    "Fg": fg,
                    "wall_s": wall,
                    "timings": dict(r.timings_s),
                    "increments": len(its),
                    "it_mean": float(np.mean(its)),
                    "it_max": int(max(its)),
                    "solves": solves,
                    "skipped": skipped,
                    "eta": m["eta"],
                    "eta_trap": trap.metrics()["eta"],
                    "eta_friction": sum(i.friction_work for i in loop)
                    / (2 * math.pi * m["U_max_Nmm"]),
                    "d_plus_um": 1e3 * m["disp_at_peak_mm"],
                    "d_minus_um": 1e3 * m["disp_at_minus_peak_mm"],
                    "energy_balance": m["energy_balance_rel_err"],
                }
            )
    out["peak_gb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refinement", type=int, default=0)
    ap.add_argument("--rig-level", type=int, default=1)
    ap.add_argument("--cases", nargs="+", default=["0:400", "100:400"], metavar="FP:FG")
    ap.add_argument("--mu", type=float, default=0.2)
    ap.add_argument("--cold", action="store_true", help="build the rig into a fresh cache")
    ap.add_argument("--coarse", action="store_true", help="the tests' coarse structure")
    ap.add_argument("--out", type=Path, default=None, help="also write the tables here")
    args = ap.parse_args()
    cases = [(float(c.split(":")[0]), float(c.split(":")[1])) for c in args.cases]
    if args.cold:
        os.environ["HINGELAB_CACHE_DIR"] = tempfile.mkdtemp(prefix="rig_cache_")
    runs = {
        m: run_isolated(run_model, m, args.refinement, args.rig_level, cases, args.mu, args.coarse)
        for m in ("hertz", "full")
    }
    h, f = runs["hertz"], runs["full"]
    lines = [
        f"bearing hinge, bonded interfaces, refinement {args.refinement}"
        f"{' (coarse structure)' if args.coarse else ''}, μ = {args.mu}; "
        f"full balls: one-ball rig MESH_LEVELS[{args.rig_level}]",
        f"structure {h['structure_dof']} DOF (setup {h['setup_s']:.1f} s hertz, "
        f"{f['setup_s']:.1f} s full); rig {f['rig_dof']} DOF, {f['rig_points']} contact "
        f"points (half model), loaded in {f['rig_s']:.1f} s; as built: "
        + ", ".join(f"{k} {v:.1f} s" for k, v in f["rig_build"].items()),
        f"peak RSS: hertz {h['peak_gb']:.2f} GB, full {f['peak_gb']:.2f} GB",
        "",
    ]
    rows = []
    for ch, cf in zip(h["cases"], f["cases"], strict=True):
        rows.append(
            {
                "Fp": ch["Fp"],
                "Fg": ch["Fg"],
                "wall_h_s": ch["wall_s"],
                "wall_f_s": cf["wall_s"],
                "inc": cf["increments"],
                "it_h": ch["it_mean"],
                "it_f": cf["it_mean"],
                "it_f_max": cf["it_max"],
                "solves": cf["solves"],
                "skip": cf["skipped"],
                "eta_h": ch["eta"],
                "eta_h_trap": ch["eta_trap"],
                "eta_f": cf["eta"],
                "eta_f_fric": cf["eta_friction"],
                "d+_h_um": ch["d_plus_um"],
                "d+_f_um": cf["d_plus_um"],
                "d+_ratio": cf["d_plus_um"] / ch["d_plus_um"],
                "d-_h_um": ch["d_minus_um"],
                "d-_f_um": cf["d_minus_um"],
                "d-_ratio": cf["d_minus_um"] / ch["d_minus_um"],
                "balance_f": cf["energy_balance"],
            }
        )
    text = "\n".join(lines)
    print(text)
    print_table(rows, list(rows[0]))
    for cf in f["cases"]:
        print(f"full Fp {cf['Fp']:g} Fg {cf['Fg']:g}: " + ", ".join(
            f"{k} {v:.1f} s" for k, v in cf["timings"].items()))  # fmt: skip
    if args.out is not None:
        import contextlib
        import io

        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            print(text)
            print_table(rows, list(rows[0]))
            for cf in f["cases"]:
                print(f"full Fp {cf['Fp']:g} Fg {cf['Fg']:g}: " + ", ".join(
                    f"{k} {v:.1f} s" for k, v in cf["timings"].items()))  # fmt: skip
        args.out.write_text(buf.getvalue())


if __name__ == "__main__":
    main()
