"""Path variants and preconditioners of the zero-clearance contact phase (issue 15).

Every variant changes only how Newton gets to the solution, never the solution: the table
prints η's relative difference from the default run, which stays at the solver tolerance
unless a variant made an increment fail and be cut back (sub-steps change the friction path).

* ``variants``: the default cycle of the general hinge at one refinement level, rerun in the
  same process (the system is prepared once) with one change each: the start of an increment
  (the linear extrapolation the cycle uses, the previous state, a quadratic extrapolation
  through the last three states), the augmentation ``r_scale``, a nonmonotone line search,
  and the Krylov path's update thresholds (``KrylovOptions``). Per run: Newton iterations,
  float32 base LUs, GMRES iterations, contact-phase time and its ratio to the default run.
* ``precond``: one Newton system of a transition increment (stick/slip fronts moving; the
  middle iteration of increment ``CAPTURE``), solved by GMRES to 1e-3 and 1e-8 with
  preconditioners that could survive status changes, beside the float32 LU of ``J`` that
  the Krylov path uses as its base: a Cholesky of ``J``'s symmetric part (slip rows
  divided by κ, the μ coupling dropped), a two-level Schwarz (LUs of clusters of points
  plus a coarse space of one column per cluster and slot), and the sparse stiffness (``W⁻¹``
  with small entries dropped, in saddle-point form). Setup time against the dense LU's.
* ``compress``: how much a block low-rank form of ``W`` would store (clusters of
  ``COMPRESS_LEAF`` points by coordinate bisection; blocks of clusters that do not overlap
  kept at the SVD rank above ``tol · |W|_F / clusters``, the others dense), as a fraction of
  the dense ``W``: the most its products could gain (they are memory-bound).
* ``oracle``: a lower bound for any Newton path with this linear algebra. The default cycle
  runs once (condensation timed as the floor, contact phase as the solver takes it); then,
  for every increment that iterated, the work of an oracle that starts at the converged
  layout and needs one step: form ``J`` from the closed points' block of ``W`` (float32, as
  the Krylov path's base; gathering the block is not counted), factorise it
  as the solver does, one solve, and two exact products with ``W`` (the residual before and
  after). Its cycle/floor is what no better start, line search or update rule can go below
  without a cheaper factorisation or product. A second row keeps the previous increment's
  LU where no point changed status (only its solve and products counted), and the share of
  points whose status changed between converged increments is printed.

It counts and swaps by wrapping the solver's internal functions in this process.

Run: .venv/bin/python benchmarks/bench_contact_variants.py [level] [variants|precond|compress|oracle|all]
"""

from __future__ import annotations

import collections
import dataclasses
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table

BASE_LU = 256
"""Reduced Jacobians with at least this many unknowns count as float32 base LUs."""

COMPRESS_LEAF = 48
"""Points per cluster of ``compress``."""

CAPTURE = 19
"""Increment whose middle Newton system ``precond`` takes (the first reversal's fronts)."""


def _prepare(level: int, condense: bool = True) -> tuple[Any, Any, Any]:
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from fe.general.cycle import configurations
    from mesh.settings import MeshSettings
    from model.service import ModelService
    from model.spec import DesignPoint, ModelSpec

    spec = ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings(refinement=level),
        CycleSettings(amplitude_n=400.0, blas_threads=1),
    )
    system = ModelService().prepare(spec, DesignPoint(spec.cycle.amplitude_n)).system
    return spec, system, configurations(system, 0.0) if condense else None


@contextmanager
def _patched(module: Any, name: str, value: Any) -> Iterator[None]:
    old = getattr(module, name)
    setattr(module, name, value)
    try:
        yield
    finally:
        setattr(module, name, old)


def _start_wrapper(mode: str, solve: Callable[..., Any]) -> Callable[..., Any]:
    """The cycle's ``solve_increment`` with another start: ``previous`` or ``quadratic``."""
    from fe.general.system import GRIP

    history: list[tuple[float, Any, Any]] = []  # (force, p, alpha) on this branch
    last_force = [0.0]

    def wrapped(W: Any, w0: Any, state: Any, contact: Any, **kw: Any) -> Any:
        force = -float(kw["e"][GRIP])  # the clevis load e[GRIP] = -F
        if kw.get("start") is None:  # a new branch (after a reversal): no extrapolation
            history.clear()
        if mode == "previous":
            kw["start"] = None
        elif mode == "quadratic" and kw.get("start") is not None and len(history) >= 3:
            (f0, p0, a0), (f1, p1, a1), (f2, p2, a2) = history[-3:]
            w = (
                (force - f1) * (force - f2) / ((f0 - f1) * (f0 - f2)),
                (force - f0) * (force - f2) / ((f1 - f0) * (f1 - f2)),
                (force - f0) * (force - f1) / ((f2 - f0) * (f2 - f1)),
            )
            kw["start"] = (w[0] * p0 + w[1] * p1 + w[2] * p2, w[0] * a0 + w[1] * a1 + w[2] * a2)
        out = solve(W, w0, state, contact, **kw)
        if not history:
            history.append((last_force[0], np.asarray(state.p), np.asarray(state.alpha)))
        history.append((force, np.asarray(out.state.p), np.asarray(out.state.alpha)))
        last_force[0] = force
        return out

    return wrapped


def _nonmonotone(search: Callable[..., Any], memory: int) -> Callable[..., Any]:
    """The line search measured from the largest of the last ``memory`` merits."""
    merits: collections.deque[float] = collections.deque(maxlen=memory)
    last: list[Any] = [None]

    def wrapped(prob: Any, it: Any, step: Any, r: Any, settings: Any, ref: Any = None) -> Any:
        if it is not last[0]:  # a new increment, a rescue or a retry: start over
            merits.clear()
            merits.append(it.merit)
        new = search(prob, it, step, r, settings, max(merits))
        if new is not None:
            merits.append(new.merit)
        last[0] = new
        return new

    return wrapped


VARIANTS: list[tuple[str, dict[str, Any]]] = [
    ("default", {}),
    ("start: previous state", {"start": "previous"}),
    ("start: quadratic extrapolation", {"start": "quadratic"}),
    ("r_scale 0.5", {"contact": {"r_scale": 0.5}}),
    ("r_scale 2", {"contact": {"r_scale": 2.0}}),
    ("r_scale 4", {"contact": {"r_scale": 4.0}}),
    ("nonmonotone line search (5)", {"nonmonotone": 5}),
    ("krylov max_update 0.3", {"krylov": {"max_update": 0.3}}),
    (
        "krylov max_update 0.5, refresh_iter 25, max_iter 60",
        {"krylov": {"max_update": 0.5, "refresh_iter": 25, "max_iter": 60}},
    ),
    ("krylov kappa_change 1 (off)", {"krylov": {"kappa_change": 1.0}}),
]
"""(name, change) of every run of ``variants``."""


def variants(level: int) -> list[dict[str, Any]]:
    """Run the cycle once per entry of ``VARIANTS``; return one row each."""
    import fe.contact.dense as dense
    import fe.contact.globalise as globalise
    import fe.contact.krylov as krylov
    import fe.contact.krylov_step as krylov_step
    import fe.general.cycle as cycle
    import fe.general.increments as increments

    spec, system, configs = _prepare(level)
    counts = {"lus": 0, "gmres": 0}
    factor, gmres = dense.sla.lu_factor, krylov_step.gmres

    def lu_counted(a: Any, *args: Any, **kw: Any) -> Any:
        if a.shape[0] >= BASE_LU and a.dtype == np.float32:
            counts["lus"] += 1
        return factor(a, *args, **kw)

    def gmres_counted(*args: Any, **kw: Any) -> Any:
        out = gmres(*args, **kw)
        counts["gmres"] += out.iterations
        return out

    rows: list[dict[str, Any]] = []
    hinge_contact = cycle.hinge_contact
    for name, change in VARIANTS:

        def contact(settings: Any, change: dict[str, Any] = change) -> Any:
            base = hinge_contact(settings)
            kr = dataclasses.replace(base.krylov, **change.get("krylov", {}))
            return dataclasses.replace(base, krylov=kr, **change.get("contact", {}))

        solve = increments.solve_increment
        if "start" in change:
            solve = _start_wrapper(change["start"], increments.solve_increment)
        search = globalise.line_search
        if "nonmonotone" in change:
            search = _nonmonotone(globalise.line_search, change["nonmonotone"])
        counts.update(lus=0, gmres=0)
        with (
            _patched(dense.sla, "lu_factor", lu_counted),
            _patched(krylov_step, "gmres", gmres_counted),
            _patched(cycle, "hinge_contact", contact),
            _patched(increments, "solve_increment", solve),
            _patched(globalise, "line_search", search),
        ):
            for cond in configs.values():  # no base LU carried over from the last run
                krylov.release(cond.W)
            t0 = time.perf_counter()
            result = cycle.run_cycle(system, 0.0, spec.cycle, configs=configs)
            wall = time.perf_counter() - t0
        rows.append(
            {
                "variant": name,
                "iterations": sum(i.iterations for i in result.increments),
                "base_lus": counts["lus"],
                "gmres": counts["gmres"],
                "contact_s": wall,
                "eta": result.metrics()["eta"],
            }
        )
        print(f"  {name}: {rows[-1]['iterations']} iterations, {wall:.1f} s", flush=True)
    ref = rows[0]
    for row in rows:
        row["vs_default"] = row["contact_s"] / ref["contact_s"]
        row["eta_rel_diff"] = f"{abs(row['eta'] / ref['eta'] - 1.0):.1e}"
    return rows


def _capture(level: int) -> tuple[Any, Any, Any]:
    """W, the closed points' coordinates and the middle Newton system of ``CAPTURE``."""
    import fe.contact.krylov_step as krylov_step
    import fe.general.cycle as cycle
    import fe.general.increments as increments

    spec, system, configs = _prepare(level)
    systems: list[Any] = []
    calls = [0]
    linearise, solve = krylov_step.linearise, increments.solve_increment

    class _Stop(Exception):
        pass

    def linearise_kept(prob: Any, it: Any, r: Any, *args: Any, **kw: Any) -> Any:
        out = linearise(prob, it, r, *args, **kw)
        if calls[0] == CAPTURE - 1:
            systems.append(out)
        return out

    def solve_counted(*args: Any, **kw: Any) -> Any:
        out = solve(*args, **kw)
        calls[0] += 1
        if calls[0] == CAPTURE:
            raise _Stop
        return out

    with (
        _patched(krylov_step, "linearise", linearise_kept),
        _patched(increments, "solve_increment", solve_counted),
        suppress(_Stop),
    ):
        cycle.run_cycle(system, 0.0, spec.cycle, configs=configs)
    cond = configs[1]
    return np.asarray(cond.W), system.mesh.nodes[cond.geo.slave], systems[len(systems) // 2]


def _clusters(X: Any, leaf: int) -> list[Any]:
    """Indices of X split by coordinate bisection into groups of at most ``leaf``."""

    def split(idx: Any) -> list[Any]:
        if len(idx) <= leaf:
            return [idx]
        P = X[idx]
        order = idx[np.argsort(P[:, int(np.argmax(np.ptp(P, axis=0)))], kind="stable")]
        return split(order[: len(order) // 2]) + split(order[len(order) // 2 :])

    return split(np.arange(len(X)))


def _iterations(J: Any, P: Callable[[Any], Any]) -> tuple[int | None, int]:
    """GMRES iterations to 1e-3 and 1e-8 (relative preconditioned residual)."""
    n = J.shape[0]
    b = np.random.default_rng(0).standard_normal(n)
    res: list[float] = []
    spla.gmres(
        spla.LinearOperator((n, n), matvec=lambda v: J @ v),
        b,
        M=spla.LinearOperator((n, n), matvec=P),
        rtol=1e-8,
        restart=300,
        maxiter=300,
        callback=res.append,
        callback_type="pr_norm",
    )
    return next((i + 1 for i, r in enumerate(res) if r < 1e-3), None), len(res)


def preconditioners(level: int) -> list[dict[str, Any]]:
    """GMRES iterations and setup time of each preconditioner on one transition system."""
    from fe.contact.newton import form_jacobian

    W, X, lin = _capture(level)
    m = len(X)
    J = form_jacobian(W, np.arange(m), lin)
    n = J.shape[0]
    rows: list[dict[str, Any]] = []

    def add(name: str, setup_s: float, P: Callable[[Any], Any]) -> None:
        loose, tight = _iterations(J, P)
        rows.append(
            {"preconditioner": name, "setup_s": setup_s, "to_1e-3": loose, "to_1e-8": tight}
        )
        print(f"  {name}: {tight} GMRES iterations", flush=True)

    W32 = W.astype(np.float32)  # kept by the solver (Workspace.W_single): not timed
    t0 = time.perf_counter()  # setup times include forming the matrix
    lu = sla.lu_factor(form_jacobian(W32, np.arange(m), lin))
    add("float32 LU of J (the base)", time.perf_counter() - t0, lambda y: sla.lu_solve(lu, y))

    # Symmetric part: slip rows (slot 1) divided by κ, the μ u coupling of T dropped.
    is_slip = lin.kind == 1
    slot_q = (np.cumsum(lin.keep.ravel()) - 1).reshape(-1, 3)
    scale = np.ones(n)
    scale[slot_q[is_slip, 1]] = 1.0 / lin.kappa[is_slip]
    t_hat = lin.t_loc.copy()
    t_hat[is_slip, 1:, 0] = 0.0
    sym = dataclasses.replace(
        lin, t_loc=t_hat, r_loc=t_hat.transpose(0, 2, 1).copy(), d=lin.d * scale
    )
    sym.__dict__.pop("_operators", None)
    t0 = time.perf_counter()
    chol = sla.cho_factor(form_jacobian(W32, np.arange(m), sym))
    add(
        "float32 Cholesky of the symmetric part",
        time.perf_counter() - t0,
        lambda y: sla.cho_solve(chol, scale * y),
    )

    # Two-level Schwarz: LUs of clusters of closed points, coarse columns per cluster and slot.
    point = np.searchsorted(lin.closed, lin.keys // 3)
    slot = lin.keys % 3
    for leaf in (16, 48):
        cluster_of = np.empty(len(lin.closed), dtype=np.int64)
        for c, idx in enumerate(_clusters(X[lin.closed], leaf)):
            cluster_of[idx] = c
        groups = [np.flatnonzero(cluster_of[point] == c) for c in range(cluster_of.max() + 1)]
        t0 = time.perf_counter()
        lus = [sla.lu_factor(J[np.ix_(g, g)]) for g in groups]
        cols = [g[slot[g] == s] for g in groups for s in range(3) if np.any(slot[g] == s)]
        Z = sp.csc_array(
            (
                np.ones(sum(len(c) for c in cols)),
                (np.concatenate(cols), np.repeat(np.arange(len(cols)), [len(c) for c in cols])),
            ),
            shape=(n, len(cols)),
        )
        coarse = sla.lu_factor(np.asarray(Z.T @ (J @ Z.toarray())))
        setup = time.perf_counter() - t0

        def local(y: Any, groups: Any = groups, lus: Any = lus) -> Any:
            x = np.zeros_like(y)
            for g, f in zip(groups, lus, strict=True):
                x[g] = sla.lu_solve(f, y[g])
            return x

        def hybrid(y: Any, local: Any = local, Z: Any = Z, coarse: Any = coarse) -> Any:
            x = Z @ sla.lu_solve(coarse, Z.T @ y)
            x = x + local(y - J @ x)
            return x + Z @ sla.lu_solve(coarse, Z.T @ (y - J @ x))

        add(f"two-level Schwarz, clusters of {leaf} points", setup, hybrid)

    # Sparse stiffness: W⁻¹ with entries below thr·sqrt(S_ii S_jj) dropped, saddle form
    # [[S, -T], [R, D]] (exact with the whole S: dw = W T dq, R dw + D dq = y).
    t0 = time.perf_counter()
    S = np.linalg.inv(W)
    S = 0.5 * (S + S.T)
    inverse_s = time.perf_counter() - t0
    d = np.sqrt(np.abs(np.diag(S)))
    for thr in (1e-2, 1e-3):
        t0 = time.perf_counter()
        S_sparse = sp.csc_array(np.where(np.abs(S) >= thr * np.outer(d, d), S, 0.0))
        K = sp.bmat([[S_sparse, -lin.T], [lin.R, sp.diags(lin.d)]], format="csc")
        f = spla.splu(K)
        setup = time.perf_counter() - t0
        add(
            f"sparse stiffness, drop < {thr:g} (W⁻¹ {inverse_s:.2f} s once)",
            setup,
            lambda y, f=f: f.solve(np.concatenate([np.zeros(3 * m), y]))[3 * m :],
        )
    print(f"Newton system of increment {CAPTURE}: {n} unknowns, {len(lin.closed)} closed points")
    return rows


def compressibility(level: int) -> list[dict[str, Any]]:
    """Stored fraction of a block low-rank ``W`` per tolerance (see the module docstring)."""
    _, system, configs = _prepare(level)
    cond = configs[1]
    W = np.asarray(cond.W)
    X = system.mesh.nodes[cond.geo.slave]
    clusters = _clusters(X, COMPRESS_LEAF)
    centre = np.array([X[c].mean(axis=0) for c in clusters])
    radius = np.array([np.linalg.norm(X[c] - X[c].mean(axis=0), axis=1).max() for c in clusters])
    dofs = [(3 * c[:, None] + np.arange(3)).ravel() for c in clusters]
    norm = float(np.linalg.norm(W))
    tols = (1e-4, 1e-6, 1e-8, 1e-10)
    stored = dict.fromkeys(tols, 0)
    near = 0
    for i, di in enumerate(dofs):
        for j, dj in enumerate(dofs):
            gap = np.linalg.norm(centre[i] - centre[j]) - radius[i] - radius[j]
            if i == j or gap <= 0.0:
                near += len(di) * len(dj)
                continue
            sv = np.linalg.svd(W[np.ix_(di, dj)], compute_uv=False)
            for tol in tols:
                stored[tol] += int(np.sum(sv > tol * norm / len(clusters))) * (len(di) + len(dj))
    print(f"W {W.shape[0]}², {len(clusters)} clusters of <= {COMPRESS_LEAF} points")
    return [
        {"tol": tol, "stored_fraction": (near + stored[tol]) / W.size, "dense_near": near / W.size}
        for tol in tols
    ]


def oracle(level: int) -> list[dict[str, Any]]:
    """The default cycle and the one-step-per-increment bound; one row each."""
    import fe.contact.solve as solve
    import fe.general.cycle as cycle
    from fe.contact.dense import factor_jacobian, gather_block, lu_solve
    from fe.contact.newton import form_jacobian, linearise
    from fe.contact.residual import sparse_product

    t0 = time.perf_counter()
    spec, system, _ = _prepare(level, condense=False)
    t1 = time.perf_counter()
    configs = cycle.configurations(system, 0.0)
    # bench_cycle's floor: the sparse factorisation (none at zero clearance) + condensation
    floor = time.perf_counter() - t1 + system.timings_s.get("factorisation", 0.0)
    print(f"prepared in {t1 - t0:.1f} s, condensed (the floor) in {floor:.1f} s", flush=True)
    finals: list[Any] = []
    newton_loop = solve.newton_loop

    def loop_kept(prob: Any, it: Any, r: Any, *args: Any, **kw: Any) -> Any:
        run = newton_loop(prob, it, r, *args, **kw)
        if run.iterations:
            finals.append((prob, run.it, run.r))
        return run

    with _patched(solve, "newton_loop", loop_kept):
        t0 = time.perf_counter()
        result = cycle.run_cycle(system, 0.0, spec.cycle, configs=configs)
        contact = time.perf_counter() - t0
    steps: list[dict[str, float]] = []  # per increment that iterated: seconds per part
    sizes, moved, last = [], [], None
    for prob, it, r in finals:
        status = it.law.status
        same = last is not None and len(last) == len(status)
        moved.append(float(np.mean(last != status)) if same else 1.0)  # share that changed
        last = status
        lin = linearise(prob, it, r)
        dofs = (3 * lin.closed[:, None] + np.arange(3)).ravel()
        block = gather_block(prob.W, dofs).astype(np.float32)  # not timed (a bound)
        t = [time.perf_counter()]
        J = form_jacobian(block, lin.closed, lin)
        t.append(time.perf_counter())
        factor = factor_jacobian(J, lin.keys, single=True)
        t.append(time.perf_counter())
        if factor is None:
            raise RuntimeError("a converged layout's J is singular in float32")
        lu_solve(factor.lu, lin.b)
        t.append(time.perf_counter())
        for _ in range(2):
            sparse_product(prob.W, it.p, prob.symmetric)
        t.append(time.perf_counter())
        steps.append(dict(zip(("form", "lu", "solve", "products"), np.diff(t), strict=True)))
        sizes.append(len(lin.keys))
    parts = {key: sum(step[key] for step in steps) for key in steps[0]}
    print(
        f"oracle over {len(sizes)} solves ({int(np.mean(sizes))} unknowns on average, "
        f"{max(sizes)} at most): " + ", ".join(f"{k} {v:.2f} s" for k, v in parts.items()),
        flush=True,
    )
    counts = np.histogram(moved[1:], bins=[0.0, 1e-9, 0.05, 0.15, 1.0])[0]
    print(
        "points whose status changed since the previous increment's converged state: "
        f"none in {counts[0]}, < 5 % in {counts[1]}, 5-15 % in {counts[2]}, "
        f"> 15 % in {counts[3]} of {len(moved) - 1} increments",
        flush=True,
    )
    # Where no status changed, the previous increment's LU could serve (J differs only by
    # the slip directions' turn): count its solve and products only.
    reuse = sum(
        step["solve"] + step["products"] + (step["form"] + step["lu"]) * (share > 0.0)
        for step, share in zip(steps, moved, strict=True)
    )
    iterations = sum(i.iterations for i in result.increments)
    rows = [
        {"path": "this solver", "iterations": iterations, "contact_s": contact},
        {
            "path": "oracle: one LU per increment",
            "iterations": len(sizes),
            "contact_s": sum(parts.values()),
        },
        {"path": "oracle: LU where a status moved", "iterations": len(sizes), "contact_s": reuse},
    ]
    return [
        {**row, "floor_s": floor, "cycle/floor": 1.0 + row["contact_s"] / floor} for row in rows
    ]


PARTS = ("variants", "precond", "compress", "oracle", "all")
"""What ``main`` can run (the second argument)."""

VARIANT_COLUMNS = ["variant", "iterations", "base_lus", "gmres", "contact_s", "vs_default"]
VARIANT_COLUMNS += ["eta_rel_diff"]


def main() -> None:
    level = int(sys.argv[1]) if len(sys.argv) > 1 else 0
    part = sys.argv[2] if len(sys.argv) > 2 else "all"
    if part not in PARTS:
        raise SystemExit(f"part must be one of {', '.join(PARTS)}, got {part!r}")
    print(f"general hinge, level {level}, clearance 0, Fg 400 N (CycleSettings defaults)")
    if part in ("variants", "all"):
        rows = variants(level)
        print_table(
            rows,
            VARIANT_COLUMNS,
        )
    if part in ("precond", "all"):
        rows = preconditioners(level)
        print_table(rows, ["preconditioner", "setup_s", "to_1e-3", "to_1e-8"])
    if part in ("compress", "all"):
        print_table(compressibility(level), ["tol", "stored_fraction", "dense_near"])
    if part in ("oracle", "all"):
        rows = oracle(level)
        print_table(rows, ["path", "iterations", "contact_s", "floor_s", "cycle/floor"])


if __name__ == "__main__":
    main()
