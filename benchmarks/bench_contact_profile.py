"""Where the contact phase of the default cycle spends its Newton iterations (issue 15).

Runs the default 400 N cycle of the general hinge at one refinement level and clearance
and prints, per increment: stage, force, Newton iterations, float32 base LUs of the Krylov
path (reduced Jacobians of at least ``BIG_LU`` unknowns), preconditioner updates refused
(the layout changed by more than ``KrylovOptions.max_update``), block gathers and their
time, the increment's wall time, and the status counts. Then totals per kind of increment:
the first one (from rest), the proportional ones (no iteration: the extrapolated start is
the solution) and the transition ones (stick/slip fronts moving). It counts by wrapping
the solver's internal functions in this process; the solution is not changed (η printed).

Run: .venv/bin/python benchmarks/bench_contact_profile.py [level] [clearance_mm]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table

SUMMED = ("iterations", "settled", "base_lus", "refused", "gathers", "gather_s", "lu_s", "wall_s")
"""Columns summed per kind of increment."""

BIG_LU = 300
"""Reduced Jacobians with at least this many unknowns count as base LUs."""


def profile(level: int, clearance_mm: float) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Run the cycle with counting wrappers; return per-increment rows and the totals."""
    import fe.contact.dense as dense
    import fe.contact.globalise as globalise
    import fe.contact.krylov_step as krylov_step
    import fe.contact.preconditioner as preconditioner
    import fe.contact.working as working
    import fe.general.cycle as cycle
    import fe.general.increments as increments
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.service import ModelService
    from model.spec import DesignPoint, ModelSpec

    now: dict[str, float] = {}

    def count(name: str, value: float = 1.0) -> None:
        now[name] = now.get(name, 0.0) + value

    factor, precondition, gather = (
        dense.factor_jacobian,
        preconditioner.precondition,
        dense.gather_block,
    )

    def factor_counted(J: Any, keys: Any, threads: Any = None, *, single: bool = False) -> Any:
        t0 = time.perf_counter()
        out = factor(J, keys, threads, single=single)
        if J.shape[0] >= BIG_LU:
            count("base_lus")
            count("lu_s", time.perf_counter() - t0)
        return out

    def precondition_counted(*args: Any) -> Any:
        out = precondition(*args)
        count("refused" if out is None else "updated")
        return out

    def gather_counted(W: Any, idx: Any) -> Any:
        t0 = time.perf_counter()
        out = gather(W, idx)
        count("gathers")
        count("gather_s", time.perf_counter() - t0)
        return out

    direction = globalise._direction
    changes: list[int] = []  # points whose trial status changed, per iteration

    def direction_counted(prob: Any, it: Any, *args: Any, **kwargs: Any) -> Any:
        step, new = direction(prob, it, *args, **kwargs)
        changes.append(-1 if new is None else int(np.sum(new.law.status != it.law.status)))
        return step, new

    globalise._direction = direction_counted
    krylov_step.factor_jacobian = factor_counted  # the base LUs
    preconditioner.factor_jacobian = factor_counted  # the updates' small LUs (below BIG_LU)
    krylov_step.precondition = precondition_counted
    preconditioner.gather_block = gather_counted
    working.gather_block = gather_counted
    rows: list[dict[str, Any]] = []
    solve = increments.solve_increment

    def solve_counted(*args: Any, **kwargs: Any) -> Any:
        now.clear()
        changes.clear()
        t0 = time.perf_counter()
        res = solve(*args, **kwargs)
        settled = 0
        for changed in reversed(changes):
            if changed != 0:
                break
            settled += 1
        rows.append(
            {
                "force_N": float(-kwargs["e"][cycle.GRIP]),
                "iterations": res.iterations,
                "settled": settled,
                "base_lus": int(now.get("base_lus", 0)),
                "lu_s": now.get("lu_s", 0.0),
                "refused": int(now.get("refused", 0)),
                "gathers": int(now.get("gathers", 0)),
                "gather_s": now.get("gather_s", 0.0),
                "wall_s": time.perf_counter() - t0,
                "stick": res.n_stick,
                "slip": res.n_slip,
                "open": res.n_open,
            }
        )
        return res

    increments.solve_increment = solve_counted
    spec = ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings(refinement=level),
        CycleSettings(amplitude_n=400.0, blas_threads=1),
    )
    service = ModelService()
    service.prepare(spec, DesignPoint(400.0, {"clearance_mm": clearance_mm}))
    res = service.run_point(spec, DesignPoint(400.0, {"clearance_mm": clearance_mm}))
    for row, inc in zip(rows, res.increments, strict=False):
        row["stage"] = inc.stage
    first = True
    for row in rows:
        row["kind"] = (
            "first" if first else "proportional" if row["iterations"] == 0 else "transition"
        )
        first = False
    totals = {
        "eta": res.metrics()["eta"],
        "contact_s": res.timings_s["contact"],
        "points": len(res.configs[1].geo.slave),
    }
    return rows, totals


if __name__ == "__main__":
    level = int(sys.argv[1]) if len(sys.argv) > 1 else 0
    clearance = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0
    rows, totals = profile(level, clearance)
    cols = ["stage", "force_N", "iterations", "settled", "base_lus", "refused", "gathers",
            "gather_s", "lu_s", "wall_s", "stick", "slip", "open"]  # fmt: skip
    print(
        f"general hinge, level {level}, clearance {clearance} mm, Fg 400 N, mu 0.2, "
        f"{totals['points']} contact points, 1 BLAS thread (large LUs: lu_threads)"
    )
    print_table(rows, cols)
    print()
    summary = []
    for kind in ("first", "proportional", "transition"):
        sel = [r for r in rows if r["kind"] == kind]
        summary.append(
            {
                "kind": kind,
                "increments": len(sel),
                **{k: sum(r[k] for r in sel) for k in SUMMED},
            }
        )
    all_wall = sum(r["wall_s"] for r in rows)
    for s in summary:
        s["share"] = f"{s['wall_s'] / all_wall:.0%}"
    print_table(summary, ["kind", "increments", "iterations", "settled", "base_lus", "refused",
                          "gathers", "gather_s", "lu_s", "wall_s", "share"])  # fmt: skip
    its = np.array([r["iterations"] for r in rows if r["kind"] == "transition"])
    settled = sum(r["settled"] for r in rows if r["kind"] == "transition")
    print(
        f"transition increments: {len(its)}, iterations per increment median {np.median(its):g}, "
        f"max {its.max() if len(its) else 0}, settled {settled} of {its.sum()} "
        f"({settled / max(its.sum(), 1):.0%}: no status changed in them); contact phase "
        f"{totals['contact_s']:.3g} s; eta {totals['eta']:.10g}"
    )
