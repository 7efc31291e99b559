"""The general hinge's cycle with and without the pin's band (MeshSettings.pin_band_sizes).

One row per (level, clearance, band) case, each in a fresh process, with the columns of
bench_cycle.py plus the pin's share of the nodes. ``inf`` asks for the O-grid of every
pin node at the contact size (the meshes before the band); the default is 3 slave sizes.

Run: .venv/bin/python benchmarks/bench_pin_band.py LEVELS CLEARANCES BANDS
     e.g. .venv/bin/python benchmarks/bench_pin_band.py 0,1 0,0.1 inf,3

Recorded: bench_cycle_pin_band.txt.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, run_isolated
from bench_cycle import case as cycle_case

COLUMNS = [
    "level",
    "clearance",
    "band",
    "n_dof",
    "pin_share",
    "points",
    "assembly_s",
    "factor_s",
    "compliance_s",
    "condense_s",
    "contact_s",
    "iterations",
    "wall_s",
    "peak_MB",
    "eta",
    "energy_err",
]


def case(level: int, clearance: float, band: float) -> dict[str, object]:
    """Run the default 400 N cycle at one refinement, clearance and band depth."""
    row = cycle_case(level, clearance, 1, pin_band_sizes=band)
    # six digits: the band moves η by less than 3 would show
    return row | {"clearance": clearance, "band": band, "eta": f"{row['eta_value']:.6g}"}


def main(argv: list[str]) -> None:
    """Run every combination of the comma-separated levels, clearances and bands."""
    levels = [int(v) for v in argv[0].split(",")]
    clearances = [float(v) for v in argv[1].split(",")]
    bands = [float(v) for v in argv[2].split(",")]
    rows = [
        run_isolated(case, level, clearance, band)
        for clearance in clearances
        for level in levels
        for band in bands
    ]
    print("general hinge, Fg 400 N, mu 0.2, CycleSettings defaults, 1 BLAS thread")
    print_table(rows, COLUMNS)


if __name__ == "__main__":
    main(sys.argv[1:])
