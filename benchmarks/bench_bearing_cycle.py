"""The bearing hinge with ``hertz`` balls: cost of one cycle and the preload × amplitude grid.

Usage: .venv/bin/python benchmarks/bench_bearing_cycle.py [--refinement K] [--out FILE]

One process: the structure is built, meshed, tied, factorised and condensed once
(``ModelService.prepare``), then the paper's 5 × 5 grid (F_p 0–200 N × F_g 100–500 N) runs
on it. Printed: where the setup time goes, DOF, ball lines, peak memory, per-cycle wall
time and Newton iterations per increment, then the grid beside the paper's Table 4 (η
and our δ(+Fg), secant stiffness). The paper's Table 4 is read from ``rsm.paper_printed``
(a copy shipped in the package), a record to compare with, not a target.
"""

from __future__ import annotations

import argparse
import resource
import time
from pathlib import Path

import numpy as np

from cad.bearing_geometry import BearingHingeParams
from fe.cycle.protocol import CycleSettings
from fe.kinds import hinge_kind
from model.service import ModelService
from model.spec import DesignPoint, ModelSpec

PRELOADS = (0.0, 50.0, 100.0, 150.0, 200.0)
AMPLITUDES = (100.0, 200.0, 300.0, 400.0, 500.0)


def _table4() -> dict[tuple[float, float], float]:
    import csv

    from rsm.paper_printed import MODIFIED, paper_table_path

    with paper_table_path(MODIFIED.csv_name) as p, p.open() as fh:
        rows = list(csv.DictReader(fh))
    return {(float(r["preload_N"]), float(r["amplitude_N"])): float(r["eta_fe"]) for r in rows}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refinement", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None, help="also write the tables here")
    args = ap.parse_args()
    spec = ModelSpec(
        "bearing",
        BearingHingeParams(),
        hinge_kind("bearing").mesh_settings(refinement=args.refinement),
        CycleSettings(),
    )
    service = ModelService()
    t0 = time.perf_counter()
    prepared = service.prepare(spec, DesignPoint(spec.cycle.amplitude_n))
    setup = time.perf_counter() - t0
    system = prepared.system
    lines = [
        f"bearing hinge, hertz balls, bonded interfaces, refinement {args.refinement}",
        f"setup {setup:.1f} s: mesh {prepared.meshed.timings_s['mesh']:.1f} s, "
        + ", ".join(f"{k} {v:.2f} s" for k, v in system.timings_s.items()),
        f"{prepared.meshed.report.n_nodes} nodes, {3 * prepared.meshed.report.n_nodes} DOF, "
        f"{prepared.meshed.report.n_hex} hexes, {getattr(system, 'n_balls', 0)} ball lines",
    ]
    paper = _table4()
    rows = []
    t_grid = time.perf_counter()
    for fp in PRELOADS:
        for fg in AMPLITUDES:
            t = time.perf_counter()
            r = service.run_point(spec, DesignPoint(fg, {"preload_n": fp}))
            wall = time.perf_counter() - t
            m = r.metrics()
            its = [i.iterations for i in r.increments]
            rows.append(
                f"{fp:6.0f} {fg:6.0f} {m['eta']:+10.2e} {paper.get((fp, fg), float('nan')):8.4f} "
                f"{m['disp_at_peak_mm'] * 1e3:9.3f} {m['secant_stiffness_N_per_mm']:10.0f} "
                f"{wall:7.3f} {np.mean(its):6.2f} {max(its):4d}"
            )
    grid = time.perf_counter() - t_grid
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2
    lines += [
        f"grid of 25 cycles {grid:.2f} s (+ setup {setup:.1f} s = {grid + setup:.1f} s); "
        f"peak RSS {peak:.2f} GB",
        "",
        "    Fp     Fg   η (ours)  η Table4  δ(+Fg) µm   k N/mm  wall s  it/inc max",
        *rows,
    ]
    text = "\n".join(lines)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
