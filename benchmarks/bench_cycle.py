"""Full three-stage cycle of the default general hinge per refinement level (issue 3).

Factorisation included. Prints DOF, contact points, the time split (assembly,
factorisation, nodal compliance, condensation, contact iterations), the floor
(factorisation + compliance + condensation: what the cycle needs before any contact
iteration) and cycle/floor = (floor + contact)/floor, wall time, peak memory, and the
fitted growth exponent of wall time vs DOF. Also a BLAS-thread
comparison of the contact phase (1 vs 2 threads) on level 0, run in the same process.

Run: .venv/bin/python benchmarks/bench_cycle.py [max_level] [clearance_mm]

Recorded runs: levels 0–2 at Δr = 0.1 mm, bench_cycle_levels_0-2_dr0.1.txt (level 2 before
the pin's fine band: 1.07 M DOF, 29 min, 20.7 GB peak; with it 0.73 M DOF, 12 min, 13.3 GB,
bench_cycle_pin_band.txt); levels 0–1 at Δr = 0 and 0.1 mm, bench_cycle_levels_0-1.txt; level 2
at Δr = 0 (a 35 712² W, condensed by pin solves: 58 min, 18.2 GB), bench_cycle_level2_dr0.txt.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, run_isolated


def case(level: int, clearance: float, threads: int = 1, **mesh: float) -> dict[str, object]:
    """Run the default 400 N cycle at one refinement; ``mesh``: other MeshSettings fields."""
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.service import ModelService
    from model.spec import DesignPoint, ModelSpec

    spec = ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings(refinement=level, **mesh),  # type: ignore[arg-type]
        CycleSettings(amplitude_n=400.0, blas_threads=threads),
    )
    service = ModelService()
    prepared = service.prepare(spec, DesignPoint(400.0, {"clearance_mm": clearance}))
    system = prepared.system
    nodes = prepared.meshed.mesh
    pin = nodes.part_names.index("pin")
    pin_nodes = len(np.unique(nodes.hexes[nodes.elem_part == pin]))
    res = service.run_point(spec, DesignPoint(400.0, {"clearance_mm": clearance}))
    m = res.metrics()
    t = {**system.timings_s, **res.timings_s}
    # The floor: what any contact solve needs first — the sparse factorisation (the window
    # check's, with clearance) and the condensation (nodal compliance + the products).
    floor = t["factorisation"] + t["condensation"]
    return {
        "level": level,
        "threads": threads,
        "n_dof": system.n_dof,
        "pin_share": pin_nodes / len(nodes.nodes),
        "points": len(res.configs[1].geo.slave),
        "assembly_s": t["assembly"],
        "factor_s": t["factorisation"],
        "compliance_s": t.get("compliance", 0.0),
        "condense_s": t["condensation"] - t.get("compliance", 0.0),
        "contact_s": t["contact"],
        "floor_s": floor,
        "cycle/floor": (floor + t["contact"]) / floor,
        "iterations": sum(i.iterations for i in res.increments),
        "eta_value": m["eta"],
        "eta": f"{m['eta']:.10g}",
        "energy_err": m["energy_balance_rel_err"],
    }


if __name__ == "__main__":
    top = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    clearance = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0
    rows = [run_isolated(case, k, clearance) for k in range(top + 1)]
    rows.append(run_isolated(case, 0, clearance, 2))
    print(
        f"general hinge, clearance {clearance} mm, Fg 400 N, mu 0.2, "
        f"{'20' if clearance == 0 else '60'} increments per stage (CycleSettings defaults)"
    )
    print_table(
        rows,
        [
            "level",
            "threads",
            "n_dof",
            "points",
            "assembly_s",
            "factor_s",
            "compliance_s",
            "condense_s",
            "contact_s",
            "floor_s",
            "cycle/floor",
            "iterations",
            "wall_s",
            "peak_MB",
            "eta",
            "energy_err",
        ],
    )
    one = [r for r in rows if r["threads"] == 1]
    if len(one) > 1:
        slope = np.polyfit(
            np.log([r["n_dof"] for r in one]), np.log([r["wall_s"] for r in one]), 1
        )[0]
        print(f"growth exponent of wall time vs DOF (levels 0..{top}): {slope:.2f}")
    print(
        f"contact phase, 2 BLAS threads vs 1 (level 0): {rows[-1]['contact_s'] / rows[0]['contact_s']:.2f}x"
    )
