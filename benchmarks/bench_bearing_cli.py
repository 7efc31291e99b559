"""The bearing hinge's ``hingelab cycle`` at the default mesh, end to end (issue 35, item 4).

Target: the default bearing cycle (Hertz balls, bonded fits, default mesh) ≤ 60 s on a quiet
machine; the cycle with frictional fits (``--interfaces contact``) measured beside it.

* ``cli``: each variant runs the user's command, ``python -m studies.cli.main cycle --hinge
  bearing [--interfaces contact] --json`` (CAD, mesh and its files, structure, cycle, the
  ParaView series of every 4th increment, result.json), in a fresh process, ``--repeat``
  times. Per run: wall time, CPU time (user + system, from the child's rusage: with two
  cores shared by other jobs the wall time is the machine's, the CPU time the command's),
  peak RSS, problem size, the split the command reports (mesh, assembly, ties,
  factorisation, condensation, contact phase or cycle, fields) and the rest (imports, STEP,
  mesh pictures, loop files), and the results (η, W_cycle, δ(±Fg), energy balance) so that
  runs before and after a change can be compared.
* ``stress``: the field output's stress recovery on the default bearing mesh, in this
  process: the centroid stress as ``fe.element`` now recovers it (no incompatible-mode
  recovery: the bubbles' gradients vanish at the centroid) against the old path (the modes
  recovered from each element's 33 × 33 matrix), its ratio and the largest difference.

Run: .venv/bin/python benchmarks/bench_bearing_cli.py [--repeat N] [--skip-contact]
[--skip-stress] [--reference CHECKOUT]; the load average before and after is printed.
``--reference /work/main`` runs the bonded cycle with that checkout's code too (the command
before a change), in the same way and alternating with this one.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's code
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table

ROOT = Path(__file__).resolve().parents[1]

SPLIT = ("mesh", "assembly", "ties", "factorisation", "condensation", "contact", "cycle",
         "fields")  # fmt: skip
"""The parts of the command's wall time its result.json reports [s]."""


def run_cli(interfaces: str, root: Path = ROOT) -> dict[str, Any]:
    """Run ``hingelab cycle --hinge bearing --interfaces …`` in a fresh process; one row.

    ``root``: the checkout whose code runs (its folder is the command's working directory).
    """
    with tempfile.TemporaryDirectory(prefix="bench_bearing_cli_") as out:
        cmd = [sys.executable, "-m", "studies.cli.main", "cycle", "--hinge", "bearing",
               "--interfaces", interfaces, "--out", out, "--json", "--no-progress"]  # fmt: skip
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=root, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        stdout = proc.stdout.read() if proc.stdout else b""  # before wait4: no pipe deadlock
        stderr = proc.stderr.read() if proc.stderr else b""
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed: {stderr.decode()[-2000:]}")
        s = json.loads(stdout)
    t = s["timings_s"]
    if "fields" not in t:  # a checkout before the command timed its field output
        t["fields"] = float("nan")
    split = {k: float(t.get(k, 0.0)) for k in SPLIT}
    return {
        "interfaces": interfaces,
        "code": root.name,
        "n_hex": s["n_hex"],
        "n_dof": s["n_dof"],
        "wall_s": wall,
        "cpu_s": usage.ru_utime + usage.ru_stime,
        "peak_GB": usage.ru_maxrss / 1024.0**2,
        **{f"{k}_s": v for k, v in split.items()},
        "rest_s": wall - sum(split.values()),
        "eta": s["eta"],
        "W_cycle_Nmm": s["W_cycle_Nmm"],
        "d+_um": s["disp_at_peak_mm"] * 1e3,
        "d-_um": s["disp_at_minus_peak_mm"] * 1e3,
        "balance_abs_Nmm": s.get("energy_balance_abs_Nmm", float("nan")),  # bonded only
        "balance_rel": s["energy_balance_rel_err"],
    }


def stress_reference() -> dict[str, Any]:
    """Centroid stress on the default bearing mesh: the shortcut against the mode recovery."""
    import numpy as np

    from cad.bearing import make_bearing_hinge, without_balls
    from fe.assembly import element_coords, lame_per_element, stress_field
    from fe.element import ElementType, element_stress_at_points
    from fe.kinds import hinge_kind
    from mesh.meshed import build_and_mesh
    from studies.options import params_with

    kind = hinge_kind("bearing")
    params = params_with(kind, {})
    model = without_balls(make_bearing_hinge(params))
    mesh = build_and_mesh(model, kind.mesh_settings(), None, picture=False).mesh
    x = np.asarray(mesh.nodes)
    u = 1e-3 * np.column_stack([x[:, 0] ** 2, x[:, 1] * x[:, 2], np.sin(x[:, 0])])  # smooth
    t0, c0 = time.perf_counter(), time.process_time()
    new = stress_field(mesh, u)
    t_new, c_new = time.perf_counter() - t0, time.process_time() - c0
    lam, mu = lame_per_element(mesh)
    u_e = u[mesh.hexes].reshape(mesh.n_elem, 24)
    t0, c0 = time.perf_counter(), time.process_time()
    # the centroid with a second point: the modes are recovered, as every frame did before
    old = element_stress_at_points(element_coords(mesh), u_e, lam, mu, ElementType.INCOMPATIBLE,
                                   [[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]])[:, 0]  # fmt: skip
    t_old, c_old = time.perf_counter() - t0, time.process_time() - c0
    return {
        "n_hex": mesh.n_elem,
        "new_wall_s": t_new,
        "new_cpu_s": c_new,
        "old_wall_s": t_old,
        "old_cpu_s": c_old,
        "old/new_cpu": c_old / c_new,
        "max_rel_diff": float(np.abs(new - old).max() / np.abs(old).max()),
    }


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main(argv: list[str] | None = None) -> int:
    """Run the variants; print the tables."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("--skip-contact", action="store_true", help="only the bonded cycle")
    p.add_argument("--skip-stress", action="store_true", help="no stress-recovery comparison")
    p.add_argument("--reference", type=Path, default=None, metavar="CHECKOUT",
                   help="also run the bonded cycle with another checkout's code (e.g. main "
                   "before a change), alternating with this one")  # fmt: skip
    args = p.parse_args(argv)
    print(f"load average before: {_load()}; {os.cpu_count()} cores", flush=True)
    variants = ["bonded"] + ([] if args.skip_contact else ["contact"])
    rows = []
    runs = [(v, ROOT) for v in variants]
    if args.reference is not None:
        runs.insert(0, ("bonded", args.reference.resolve()))
    for k in range(args.repeat):
        for interfaces, root in runs:
            rows.append(run_cli(interfaces, root) | {"run": k})
            print(json.dumps(rows[-1]), flush=True)  # kept if a later run fails
            print(f"{interfaces} ({root.name}) run {k}: wall {rows[-1]['wall_s']:.1f} s, cpu "
                  f"{rows[-1]['cpu_s']:.1f} s, load {_load()}", flush=True)  # fmt: skip
    print(f"load average after: {_load()}")
    print("hingelab cycle --hinge bearing (Hertz balls, default mesh, Fg 400 N, F_p 100 N, "
          "20 increments per stage, every 4th increment written)")  # fmt: skip
    print_table(rows, ["interfaces", "code", "run", "n_hex", "n_dof", "wall_s", "cpu_s", "peak_GB",
                       *(f"{k}_s" for k in SPLIT), "rest_s"])  # fmt: skip
    print_table(rows, ["interfaces", "code", "run", "eta", "W_cycle_Nmm", "d+_um", "d-_um",
                       "balance_abs_Nmm", "balance_rel"])  # fmt: skip
    if not args.skip_stress:
        row = stress_reference()
        print("centroid stress of one frame, default bearing mesh: shortcut (new) against the "
              "incompatible-mode recovery (old), this process")  # fmt: skip
        print_table([row], list(row))
    for i, row in enumerate(rows):  # results against the first run of the same variant
        first = next(r for r in rows if r["interfaces"] == row["interfaces"])
        if row is not first:
            diff = max(
                abs(row[k] - first[k]) / max(abs(first[k]), 1e-300)
                for k in ("eta", "W_cycle_Nmm", "d+_um", "d-_um", "balance_abs_Nmm")
                if math.isfinite(first[k])
            )
            print(
                f"row {i} ({row['interfaces']}, {row['code']}): largest relative difference "
                f"of η, W_cycle, δ(±Fg), energy balance from row {rows.index(first)}: {diff:.1e}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
