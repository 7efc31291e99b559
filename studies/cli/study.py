"""``hingelab study STUDY.toml --out DIR``: run a design study file, fit its surface, summarise.

The study varies the clearance Δr and amplitude Fg of a general-hinge model, or the axial
preload F_p and amplitude Fg of a bearing-hinge model (``[study] model``, kind = "bearing").

The study file (``studies.study_file``) is checked completely before anything is meshed.
Every point then runs through ``studies.sweep`` (traced, stored, resumable; in this
process, on ``--workers`` local processes, or on an existing Dask cluster with
``--scheduler``), with one progress line per point (done, failed, cached, ETA). At the end
the declared response surface is fitted to this run's table and recorded in the trace, its
plots and ``rsm/fit.json`` are written, and a one-screen summary names the next command.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from cad.errors import DataError, ParameterError
from model.jsonio import dumps
from studies.cluster_options import add_cluster_arguments
from studies.outputs import check_trace_db, check_writable_dir


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``study`` subcommand."""
    p = sub.add_parser(
        "study",
        help="run a design study file (STUDY.toml): points, progress, surface, summary",
        description=__doc__.splitlines()[0] if __doc__ else None,
    )
    p.add_argument("study", type=Path, metavar="STUDY.toml", help="the study file")
    p.add_argument(
        "--out", type=Path, required=True, metavar="DIR", help="output folder (rerun to resume)"
    )
    add_cluster_arguments(p)
    p.add_argument(
        "--retry-failed", action="store_true", help="run only the points that failed before"
    )
    p.add_argument(
        "--dry-run",
        action="store_true",
        help="list the points and what a run would do with each (done, stored, failed, to do)",
    )
    p.add_argument("--no-plots", action="store_true", help="fit the surface without plots")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


SYMBOLS = {"clearance_mm": ("Δr", "mm"), "preload_N": ("F_p", "N"), "amplitude_N": ("Fg", "N")}
"""How a design variable is printed: symbol and unit."""


def _fmt_point(params: dict[str, Any], width: int = 0) -> str:
    """``Δr = 0.1 mm, Fg = 400 N`` or ``F_p = 100 N, Fg = 400 N`` (``width``: parts padded)."""
    parts = [f"{SYMBOLS[k][0]} = {v:g} {SYMBOLS[k][1]}" for k, v in params.items()]
    return "  ".join(p.ljust(width) for p in parts) if width else ", ".join(parts)


def _point_params(spec: Any, point: Any) -> dict[str, float]:
    from studies.sweep_points import point_params

    return point_params(spec, point)


def _fmt_s(seconds: float) -> str:
    seconds = max(0.0, seconds)
    return f"{seconds / 60:.0f} min {seconds % 60:02.0f} s" if seconds >= 60 else f"{seconds:.0f} s"


class Progress:
    """One line per finished point on stderr: how many are done, failed, cached, and the ETA."""

    def __init__(self, total: int, quiet: bool) -> None:
        self.total, self.quiet = total, quiet
        self.done = self.failed = self.cached = 0
        self.t0 = time.perf_counter()

    def __call__(self, rec: dict[str, Any]) -> None:
        """Count one point's record and print its line."""
        if rec["status"] == "ok":
            self.done += 1
            self.cached += bool(rec["solver"].get("cached"))
        else:
            self.failed += 1
        if self.quiet:
            return
        n = self.done + self.failed
        computed = n - self.cached
        elapsed = time.perf_counter() - self.t0
        eta = elapsed / computed * (self.total - n) if computed else 0.0
        eta_value = rec["results"].get("eta")
        what = (
            f"η = {eta_value:.5g}"
            if rec["status"] == "ok" and eta_value is not None
            else ("ok" if rec["status"] == "ok" else f"FAILED: {rec['error']}")
        )
        print(
            f"[{n}/{self.total}] {_fmt_point(rec['params'])}: {what}"
            f"   (done {self.done}, failed {self.failed}, cached {self.cached}; "
            f"ETA {_fmt_s(eta)})",
            file=sys.stderr,
        )


def _dry_run(plan: list[Any], study: Any, args: argparse.Namespace) -> int:
    from collections import Counter

    counts = Counter(pp.state.value for pp in plan)
    if args.json:
        print(
            dumps(
                {
                    "study": study.name,
                    "points": [
                        _point_params(study.spec, pp.point)
                        | {
                            "state": pp.state.value,
                            "point_id": pp.point_id,
                            "result_key": pp.key,
                        }
                        for pp in plan
                    ],
                    "counts": dict(counts),
                }
            )
        )
        return 0
    print(f"study {study.name}: {len(plan)} points ({study.design})")
    for pp in plan:
        pid = "" if pp.point_id is None else f"  (trace point {pp.point_id})"
        print(f"  {_fmt_point(_point_params(study.spec, pp.point), 16)}{pp.state.value}{pid}")
    print(
        ", ".join(f"{counts.get(s, 0)} {s}" for s in ("done", "stored", "failed", "todo"))
        + " (done: in the trace; stored: read back from results/; failed and todo: run)"
    )
    return 0


def fit_surface(study: Any, table: Path, db: Path, out: Path, plots: bool) -> dict[str, Any]:
    """Fit the study's surface to ``table``, record it in the trace, write plots and fit.json."""
    import warnings

    from rsm import trace_store
    from rsm.metrics import OverfitWarning, fit_metrics
    from rsm.polynomial import fit_response_surface
    from rsm.tables import read_xy
    from studies.cli.rsm import fit_report

    spec = study.surface
    xy = read_xy(table, list(spec.x), spec.y)
    s = fit_response_surface(
        xy.x, xy.y, spec.degree, x_names=xy.x_names, y_name=xy.y_name, labels=xy.labels
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", OverfitWarning)
        m = fit_metrics(s)
    rep = fit_report(s, m, spec.threshold, True)
    rep["warnings"] = [str(w.message) for w in caught]
    ids = [int(lbl.removeprefix("point ")) for lbl in s.labels if lbl.startswith("point ")]
    rep["trace_fit_id"] = trace_store.record_fit(
        db, surface=s, metrics=m, point_ids=ids, study=study.name
    )
    folder = out / "rsm"
    folder.mkdir(parents=True, exist_ok=True)
    if plots:
        from rsm.plots import plot_all

        rep["plots"] = {
            k: str(v) for k, v in plot_all(s, m, folder, threshold=spec.threshold).items()
        }
    (folder / "fit.json").write_text(dumps(rep), encoding="utf-8")
    return rep


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab study``."""
    from studies.study_file import read_study
    from studies.sweep import PointState, plan_sweep, run_sweep

    study = read_study(args.study)  # every parameter checked here, before any meshing
    settings = study.sweep_settings(workers=args.workers, scheduler=args.scheduler or None)
    out: Path = args.out
    if args.dry_run:
        return _dry_run(plan_sweep(settings, out), study, args)
    check_writable_dir(out, "--out")
    check_trace_db(out / "trace.sqlite", "--out")
    plan = plan_sweep(settings, out)
    to_run = [pp for pp in plan if pp.state is not PointState.DONE]
    if args.retry_failed:
        to_run = [pp for pp in to_run if pp.state is PointState.FAILED]
        if not to_run:
            print(f"hingelab study: no failed points in {out}; nothing to retry", file=sys.stderr)
            return 0
    shutil.copyfile(study.path, out / "study.toml")
    progress = Progress(len(to_run), quiet=args.json)
    outcome = run_sweep(settings, out, on_point=progress, retry_failed=args.retry_failed)
    n_ok = outcome.ok + outcome.cached + outcome.skipped
    fit, not_fitted = None, None
    if study.surface is not None and outcome.table.is_file() and n_ok:
        try:
            fit = fit_surface(study, outcome.table, outcome.db, out, not args.no_plots)
        except (DataError, ParameterError) as err:  # too few ok points for the degree
            not_fitted = f"surface not fitted: {err}"
    summary = _summary(study, outcome, fit, args)
    summary["surface_not_fitted"] = not_fitted
    summary["increments_check"] = outcome.check
    for line in outcome.warnings:  # the doubled-increments check (studies.convergence)
        print(f"hingelab study: warning: {line}", file=sys.stderr)
    if args.json:
        print(dumps(summary))
    else:
        print(_summary_text(summary))
    return 0 if outcome.failed == 0 else 1


def _summary(
    study: Any, outcome: Any, fit: dict[str, Any] | None, args: argparse.Namespace
) -> dict[str, Any]:
    out = args.out
    if outcome.failed:
        nxt = f"hingelab study {study.path} --out {out} --retry-failed"
    elif fit is not None:
        worst = max(fit["points"], key=lambda p: abs(p["RE_percent"] or 0.0))
        nxt = f"hingelab trace {outcome.db} {worst['label'].removeprefix('point ')}"
    else:
        x = ",".join(study.variables)
        nxt = f"hingelab rsm fit {outcome.table} --x {x} --y eta --trace {outcome.db}"
    return {
        "study": study.name,
        "hinge": study.kind,
        "variables": list(study.variables),
        "design": study.design,
        "n_points": len(set(study.points)),
        "computed": outcome.ok,
        "cached": outcome.cached,
        "already_done": outcome.skipped,
        "failed": outcome.failed,
        "wall_s": outcome.wall_s,
        "trace": str(outcome.db),
        "table": str(outcome.table) if outcome.table.is_file() else None,
        "surface": None
        if fit is None
        else {
            "y": fit["y"],
            "x": fit["x"],
            "degree": fit["degree"],
            "metrics": fit["metrics"],
            "minimum": fit["minimum"],
            "maximum": fit["maximum"],
            "trace_fit_id": fit["trace_fit_id"],
            "plots": fit.get("plots", {}),
            "warnings": fit["warnings"],
        },
        "next": nxt,
    }


def _fmt_at(names: list[str], values: list[float]) -> str:
    return _fmt_point({k: round(v, 4) for k, v in zip(names, values, strict=True)})


def _summary_text(s: dict[str, Any]) -> str:
    lines = [
        f"study {s['study']} ({s['design']}, {s['n_points']} points): {s['computed']} computed, "
        f"{s['cached']} read back, {s['already_done']} already done, {s['failed']} failed "
        f"in {_fmt_s(s['wall_s'])}",
        f"  trace {s['trace']}" + (f"   table {s['table']}" if s["table"] else ""),
    ]
    f = s["surface"]
    if f is not None:
        m = f["metrics"]
        r2 = m.get("R2")
        lines.append(
            f"  {f['y']} = f({', '.join(f['x'])}), degree {f['degree']}: "
            f"R² = {'n/a' if r2 is None else f'{r2:.4f}'}; "
            f"min {f['minimum']['y']:.5g} at {_fmt_at(f['x'], f['minimum']['x'])}; "
            f"max {f['maximum']['y']:.5g} at {_fmt_at(f['x'], f['maximum']['x'])}"
        )
        for w in f["warnings"]:
            lines.append(f"  warning: {w}")
        if f["plots"]:
            lines.append(f"  plots in {Path(next(iter(f['plots'].values()))).parent}/")
    if s.get("surface_not_fitted"):
        lines.append(f"  {s['surface_not_fitted']}")
    lines.append(f"next: {s['next']}")
    return "\n".join(lines)
