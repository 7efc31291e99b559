"""Geometry + mesh of the default general hinge per refinement level (issue 2).

Prints wall time, peak memory and element counts; each case in a fresh process.
Run: .venv/bin/python benchmarks/bench_mesh.py [max_level]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, run_isolated


def case(level: int) -> dict[str, object]:
    t0 = time.perf_counter()
    from cad.general import make_general_hinge
    from cad.general_params import GeneralHingeParams
    from mesh.build import mesh_hinge
    from mesh.settings import MeshSettings

    t_import = time.perf_counter() - t0
    t1 = time.perf_counter()
    model = make_general_hinge(GeneralHingeParams(clearance_mm=0.2))
    t_cad = time.perf_counter() - t1
    mesh, rep = mesh_hinge(model, MeshSettings(refinement=level))
    return {
        "level": level,
        "n_hex": rep.n_hex,
        "n_nodes": rep.n_nodes,
        "n_dof": 3 * rep.n_nodes,
        "min_SJ": rep.min_scaled_jacobian,
        "import_s": t_import,
        "cad_s": t_cad,
        "mesh_s": rep.wall_s,
        "slave_nodes": int(sum(len(mesh.set_nodes(p.slave)) for p in mesh.pairs)),
    }


if __name__ == "__main__":
    top = int(sys.argv[1]) if len(sys.argv) > 1 else 2
    rows = [run_isolated(case, k) for k in range(top + 1)]
    print("general hinge (clearance 0.2 mm): geometry + mesh per refinement level")
    print_table(
        rows,
        [
            "level",
            "n_hex",
            "n_nodes",
            "n_dof",
            "slave_nodes",
            "min_SJ",
            "import_s",
            "cad_s",
            "mesh_s",
            "wall_s",
            "peak_MB",
        ],
    )
