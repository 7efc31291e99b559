"""Solve the FCLib / Siconos peer problems and print the table of ../shared/peers/fclib.

Each problem (``W``, ``q``, per-contact ``mu``) is solved from ``p = 0`` by
``fe.contact.solve_increment`` with default settings except ``mu`` (per contact, native)
and ``max_iter = 200``, on one BLAS thread (as Siconos' column; several threads on
tiny LUs were 10-60x slower on this shared machine), in a fresh process with a wall-time
budget (KaplasTower and RockPile are dense 1710/1389-unknown problems). "Solved" is Siconos' error
(``fc3d_compute_error``, recomputed here from ``W r + q``) ``<= 1e-8``; a problem where
``solve_increment`` raised is reported as not solved with the error of its last iterate
and the error's message. "fallback N its" counts the regularised Newton steps taken after
the first singular step matrix (each one LU; included in the iterations).
Siconos' best solver and the project's previous result are read from the README's table.

    .venv/bin/python benchmarks/bench_fclib.py [--dir ../shared/peers/fclib] [--budget 300]
    .venv/bin/python benchmarks/bench_fclib.py --only BoxesStack1 Capsules-i125
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import re
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

DEFAULT_DIR = Path(__file__).resolve().parents[2] / "shared" / "peers" / "fclib"
SOLVED = 1e-8
MAX_ITER = 200
SICONOS = ("NSN_AC", "NSN_FB", "NSGS")


def _solve(path: str, queue: Any) -> None:
    from threadpoolctl import threadpool_limits

    from cad.errors import ConvergenceError
    from fe.contact.measure import siconos_error
    from fe.contact.solve import solve_increment
    from fe.contact.state import ContactSettings, ContactState

    with np.load(path) as d:
        W, q, mu = d["W"], d["q"], d["mu"]
    m = len(mu)
    settings = ContactSettings(mu=mu, max_iter=MAX_ITER)
    t0 = time.perf_counter()
    try:
        # one BLAS thread, as the Siconos column and the hinge's contact phase
        with threadpool_limits(limits=1, user_api="blas"):
            res = solve_increment(W, q.reshape(m, 3), ContactState.initial(m), settings)
        p, iters, note = res.state.p, res.iterations, ""
        if res.regularised_iterations:
            note = f"fallback {res.regularised_iterations} its"
    except ConvergenceError as err:
        p, iters, note = err.partial.p, err.iteration, f"raised ConvergenceError: {err}"
        raised = True
    else:
        raised = False
    wall = time.perf_counter() - t0
    queue.put(
        {
            "err": siconos_error(W, q, mu, p),
            "iters": iters,
            "wall": wall,
            "raised": raised,
            "note": note,
        }
    )


def run_with_budget(path: Path, budget_s: float) -> dict[str, Any] | None:
    """Solve in a fresh process; None if it ran past the budget (then it is killed)."""
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_solve, args=(str(path), queue))
    proc.start()
    proc.join(budget_s)
    if proc.is_alive():
        proc.terminate()
        proc.join()
        return None
    return (
        queue.get()
        if not queue.empty()
        else {"err": float("nan"), "iters": 0, "wall": 0.0, "raised": True, "note": "crashed"}
    )


def read_readme(directory: Path) -> dict[str, dict[str, str]]:
    """Rows of the README's reference table, keyed by problem name."""
    rows: dict[str, dict[str, str]] = {}
    text = (directory / "README.md").read_text()
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 8 or not re.match(r"^[A-Za-z][\w.-]*$", cells[0]) or cells[0] == "problem":
            continue
        rows[cells[0]] = dict(
            zip(["kind", "contacts", "rank_def", *SICONOS, "before"], cells[1:], strict=True)
        )
    return rows


def siconos_best(row: dict[str, str]) -> str:
    solved = []
    for name in SICONOS:
        cell = row.get(name, "")
        parts = [s.strip() for s in cell.split("/")]
        if parts and parts[0] == "yes":
            solved.append((_seconds(parts[2]), name, cell))
    if not solved:
        return "none solves it"
    _, name, cell = min(solved)
    return f"{name}: {cell}"


def _seconds(text: str) -> float:
    value, unit = text.split()
    return float(value) * {"s": 1.0, "ms": 1e-3}[unit]


def _fmt_wall(s: float) -> str:
    return f"{1e3 * s:.3g} ms" if s < 1.0 else f"{s:.3g} s"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", type=Path, default=DEFAULT_DIR)
    parser.add_argument("--budget", type=float, default=300.0, help="wall seconds per problem")
    parser.add_argument("--only", nargs="+", default=None, help="name prefixes to run")
    args = parser.parse_args(argv)
    if not (args.dir / "README.md").exists():
        print(f"skipped: no peer problems at {args.dir} (a clone without ../shared)")
        return 0
    table = read_readme(args.dir)
    print(
        f"FCLib peers from {args.dir}, max_iter {MAX_ITER}, budget {args.budget:g} s, "
        f"solved = Siconos error <= {SOLVED:g}\n"
    )
    print(
        "| problem | contacts | W rank deficiency | hingelab now | error | Siconos best "
        "| hingelab e5cc858 | note |"
    )
    print("|---|--:|--:|---|--:|---|---|---|")
    n_solved = 0
    for name, row in table.items():
        if args.only and not any(name.startswith(o) for o in args.only):
            continue
        out = run_with_budget(args.dir / f"{name}.npz", args.budget)
        if out is None:
            now, err, note = f"no / - / > {args.budget:g} s", "-", "time budget"
        else:
            ok = not out["raised"] and out["err"] <= SOLVED
            n_solved += ok
            now = f"{'yes' if ok else 'no'} / {out['iters']} / {_fmt_wall(out['wall'])}"
            err, note = f"{out['err']:.1e}", out["note"]
        print(
            f"| {name} | {row['contacts']} | {row['rank_def']} | {now} | {err} "
            f"| {siconos_best(row)} | {row['before']} | {note} |"
        )
        sys.stdout.flush()
    print(f"\nsolved {n_solved}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
