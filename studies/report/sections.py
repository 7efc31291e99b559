"""Sections of the HTML report for a load cycle and for a sweep (with its response surfaces).

Each ``*_report`` function reads one kind of result folder and returns a
:class:`ReportBody`: what was run (name → value pairs) and the page's sections.
Nothing here writes files; the page is assembled by ``studies.report.page``.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cad.errors import DataError
from studies.report.parts import (
    Html,
    Section,
    cards,
    esc,
    figure,
    figures,
    fmt,
    join,
    kv_table,
    link,
    links,
    scroll,
    table,
    tag,
)
from studies.report.surfaces import rsm_fit_sections


@dataclass(frozen=True)
class ReportBody:
    """What a result folder holds, ready for the page.

    Attributes:
        title: Heading of the page.
        run: What was run, as (name, value) pairs.
        sections: The page's sections in order.
    """

    title: str
    run: list[tuple[str, object]]
    sections: list[Section]


def read_json(path: Path) -> Any:
    """Read a JSON file (NaN allowed, as older result files hold it).

    Raises:
        DataError: Naming the file, if it is not valid JSON.
    """
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as err:
        raise DataError(f"{path}: not valid JSON ({err})") from err


def _um(mm: object) -> str:
    return f"{mm * 1e3:.4g} µm" if isinstance(mm, int | float) else "—"


def _float(d: Mapping[str, Any], key: str) -> float | None:
    v = d.get(key)
    return float(v) if isinstance(v, int | float) else None


def _energy(r: Mapping[str, Any]) -> Html:
    """The energy balance of the reported loop: loop area = friction work + ΔU_elastic."""
    w, fric, du = (
        _float(r, k) for k in ("W_cycle_Nmm", "friction_work_Nmm", "elastic_energy_change_Nmm")
    )
    rest = None if w is None or fric is None or du is None else w - fric - du
    return table(
        ["quantity", "value [N·mm]"],
        [
            ["loop area W_cycle = ∮F dδ", w],
            ["friction work (sum over all contact points)", fric],
            ["change of elastic energy over the loop", du],
            ["W_cycle − friction work − ΔU", rest],
            [Html("relative error |W − W<sub>f</sub> − ΔU| / W"), r.get("energy_balance_rel_err")],
        ],
        caption="Energy balance of the reported loop",
    )


def cycle_headline(r: Mapping[str, Any]) -> Html:
    """Headline numbers of one cycle: η, W, U, δ(+Fg), stiffness, free play."""
    k = r.get("secant_stiffness_N_per_mm")
    return cards(
        [
            ("loss factor η = W/(2π U_max)", fmt(r.get("eta"))),
            ("W_cycle [N·mm]", fmt(r.get("W_cycle_Nmm"))),
            ("U_max [N·mm]", fmt(r.get("U_max_Nmm"))),
            ("δ(+Fg)", _um(r.get("disp_at_peak_mm"))),
            ("δ(−Fg)", _um(r.get("disp_at_minus_peak_mm"))),
            ("secant stiffness [N/mm]", fmt(k)),
            ("free play (removed)", _um(r.get("free_play_mm"))),
        ]
    )


def _increments(incs: list[Mapping[str, Any]]) -> Html:
    rows = [
        [
            n,
            i.get("stage"),
            i.get("force_N"),
            i.get("disp_mm"),
            i.get("iterations"),
            i.get("open"),
            i.get("stick"),
            i.get("slip"),
        ]
        for n, i in enumerate(incs, start=1)
    ]
    heads = ["increment", "stage", "force [N]", "δ [mm]", "Newton it.", "open", "stick", "slip"]
    return scroll(table(heads, rows))


def cycle_report(folder: Path, report_dir: Path) -> ReportBody:
    """Read a ``hingelab cycle`` folder (result.json, loop.png, mesh files)."""
    r = read_json(folder / "result.json")
    incs = r.get("increments") or []
    run: list[tuple[str, object]] = [
        ("command", "hingelab cycle (load cycle 0 → +Fg → −Fg → +Fg)"),
        ("hinge", "general hinge"),
        ("radial clearance Δr [mm]", r.get("clearance_mm")),
        ("force amplitude Fg [N]", r.get("amplitude_N")),
        ("friction coefficient μ", r.get("mu")),
        ("increments (all stages)", len(incs)),
        ("mesh", f"{fmt(r.get('n_hex'))} hexahedra, {fmt(r.get('n_dof'))} DOF"),
        (
            "contact points / surface pairs",
            f"{fmt(r.get('n_contact_pairs'))} / {fmt(r.get('n_surface_pairs'))}",
        ),
        ("Newton iterations (total)", r.get("total_iterations")),
        ("wall time [s]", r.get("wall_s")),
    ]
    files = [
        ("STEP geometry", folder / "hinge.step"),
        ("mesh (VTU)", folder / "mesh.vtu"),
        ("mesh (gmsh .msh)", folder / "mesh.msh"),
        ("loop (CSV)", folder / "loop.csv"),
        ("loop (PNG)", folder / "loop.png"),
        ("fields (ParaView .pvd)", folder / "fields" / "cycle.pvd"),
        ("result.json", folder / "result.json"),
    ]
    timings = r.get("timings_s") or {}
    sections = [
        Section(
            "results",
            "Loss factor and loop",
            join(
                [
                    cycle_headline(r),
                    tag("p", r.get("delta_definition", ""), cls="note"),
                    figure(folder / "loop.png", "Force–displacement loop (loop.png)", wide=True),
                ]
            ),
        ),
        Section("energy", "Energy balance", _energy(r)),
        Section(
            "mesh", "Geometry and mesh", figure(folder / "mesh.png", "Mesh (mesh.png)", wide=True)
        ),
        Section(
            "increments",
            "Contact state per increment",
            join(
                [
                    tag(
                        "p",
                        "Contact points open, sticking and slipping after each increment.",
                        cls="note",
                    ),
                    _increments(incs),
                ]
            ),
        ),
        Section(
            "files",
            "Files",
            join(
                [
                    table(["file", "link"], [[lbl, link(p, report_dir)] for lbl, p in files]),
                    kv_table((f"time: {k} [s]", v) for k, v in timings.items()),
                ]
            ),
        ),
    ]
    return ReportBody("Load cycle", run, sections)


# ---------------------------------------------------------------- sweep


@dataclass(frozen=True)
class TracePoint:
    """One point of a sweep's trace.

    Attributes:
        point_id: Its id in the trace.
        study: Study name.
        status: ``ok`` or ``failed``.
        error: The failure message, if any.
        params: Design parameters.
        results: Results (η, W, …).
        solver: Solver settings as recorded.
        artifacts: Kind → file (absolute).
    """

    point_id: int
    study: str
    status: str
    error: str | None
    params: dict[str, Any]
    results: dict[str, Any]
    solver: dict[str, Any]
    artifacts: dict[str, Path]


def read_trace(db: Path) -> tuple[list[TracePoint], list[dict[str, Any]]]:
    """Read every point and fit of a trace database (read-only).

    Raises:
        DataError: Naming the database, if it cannot be read as a trace.
    """
    try:
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
        try:
            points = _trace_points(con, db.parent)
            fits = _trace_fits(con)
        finally:
            con.close()
    except sqlite3.Error as err:
        raise DataError(f"{db}: not a readable trace database ({err})") from err
    return points, fits


def _trace_points(con: sqlite3.Connection, root: Path) -> list[TracePoint]:
    params: dict[int, dict[str, Any]] = {}
    for pid, name, value in con.execute("SELECT point_id, name, value FROM params"):
        params.setdefault(pid, {})[name] = value
    arts: dict[int, dict[str, Path]] = {}
    for pid, kind, path in con.execute("SELECT point_id, kind, path FROM artifacts"):
        p = Path(path)
        arts.setdefault(pid, {})[kind] = p if p.is_absolute() else root / p
    rows = con.execute(
        "SELECT p.id, s.name, p.status, p.error, p.solver_json, p.results_json "
        "FROM points p JOIN studies s ON p.study_id = s.id ORDER BY p.id"
    ).fetchall()
    return [
        TracePoint(
            pid,
            study,
            status,
            error,
            params.get(pid, {}),
            json.loads(res),
            json.loads(solver),
            arts.get(pid, {}),
        )
        for pid, study, status, error, solver, res in rows
    ]


def _trace_fits(con: sqlite3.Connection) -> list[dict[str, Any]]:
    rows = con.execute(
        "SELECT f.id, f.created_utc, f.y_name, f.x_names_json, f.degree, f.terms_json, "
        "f.coefficients_json, f.metrics_json, (SELECT COUNT(*) FROM fit_points q "
        "WHERE q.fit_id = f.id) FROM fits f ORDER BY f.id"
    ).fetchall()
    keys = ("id", "created_utc", "y", "x", "degree", "terms", "coefficients", "metrics", "n")
    out = []
    for row in rows:
        d = dict(zip(keys, row, strict=True))
        for k in ("x", "terms", "coefficients", "metrics"):
            d[k] = json.loads(d[k])
        out.append(d)
    return out


def _point_links(p: TracePoint, report_dir: Path) -> Html:
    a = p.artifacts
    loop_dir = a["loop_csv"].parent if "loop_csv" in a else None
    items = [
        ("STEP", a.get("step")),
        ("VTU", a.get("mesh_vtu")),
        ("mesh.png", a.get("mesh_png")),
        ("loop.csv", a.get("loop_csv")),
        ("loop.png", a.get("loop_png")),
        ("result.json", loop_dir / "result.json" if loop_dir else None),
    ]
    return links(((lbl, path) for lbl, path in items if path is not None), report_dir)


def _trace_table(points: list[TracePoint], report_dir: Path) -> Html:
    names = sorted({n for p in points for n in p.params})
    heads = ["point", "study", "status", *names, "η", "W_cycle [N·mm]", "δ(+Fg) [µm]"]
    heads += ["energy bal.", "wall [s]", "files"]
    rows = []
    for p in points:
        r = p.results
        status: object = (
            p.status
            if p.error is None
            else Html(f"{tag('span', 'failed', cls='fail')}: {esc(p.error)}")
        )
        d = r.get("disp_at_peak_mm")
        rows.append(
            [
                p.point_id,
                p.study,
                status,
                *(p.params.get(n) for n in names),
                r.get("eta"),
                r.get("W_cycle_Nmm"),
                d * 1000.0 if isinstance(d, int | float) else None,
                r.get("energy_balance_rel_err"),
                r.get("wall_s"),
                _point_links(p, report_dir),
            ]
        )
    return scroll(table(heads, rows))


def _eta_grid(points: list[TracePoint]) -> Html:
    """η over clearance (rows) × amplitude (columns), the latest ok point of each pair."""
    grid: dict[tuple[Any, Any], Any] = {}
    for p in points:
        if p.status == "ok" and "clearance_mm" in p.params and "amplitude_N" in p.params:
            grid[(p.params["clearance_mm"], p.params["amplitude_N"])] = p.results.get("eta")
    if not grid:
        return Html("")
    cs = sorted({c for c, _ in grid})
    amps = sorted({a for _, a in grid})
    rows = [[Html(tag("b", fmt(c))), *(grid.get((c, a)) for a in amps)] for c in cs]
    return table(["Δr [mm] \\ Fg [N]", *amps], rows, caption="Loss factor η over the design grid")


def _run_of_sweep(points: list[TracePoint], table_csv: Path) -> list[tuple[str, object]]:
    solver = points[-1].solver if points else {}
    mesh = solver.get("mesh") or {}
    ok = sum(p.status == "ok" for p in points)
    values = {
        n: sorted({p.params[n] for p in points if n in p.params})
        for n in ("clearance_mm", "amplitude_N")
    }
    return [
        ("command", "hingelab sweep (design study over clearance × amplitude)"),
        ("studies in the trace", ", ".join(sorted({p.study for p in points})) or "—"),
        ("points", f"{len(points)} ({ok} ok, {len(points) - ok} failed)"),
        ("clearances Δr [mm]", ", ".join(fmt(v) for v in values["clearance_mm"])),
        ("amplitudes Fg [N]", ", ".join(fmt(v) for v in values["amplitude_N"])),
        ("friction coefficient μ", solver.get("mu")),
        (
            "increments per half cycle (Δr = 0 / Δr > 0)",
            f"{fmt(solver.get('increments_per_stage'))} / {fmt(solver.get('clearance_increments'))}",
        ),
        ("mesh", ", ".join(f"{k} = {fmt(v)}" for k, v in mesh.items()) or "—"),
        ("table of this run", "table.csv" if table_csv.is_file() else "— (no table.csv)"),
    ]


def sweep_report(folder: Path, report_dir: Path) -> ReportBody:
    """Read a ``hingelab sweep`` folder (trace.sqlite, table.csv, points/, geometry/)."""
    points, fits = read_trace(folder / "trace.sqlite")
    ok = [p for p in points if p.status == "ok" and "loop_png" in p.artifacts]
    loops = figures(
        (
            p.artifacts["loop_png"],
            f"point {p.point_id}: " + ", ".join(f"{k} = {fmt(v)}" for k, v in p.params.items()),
        )
        for p in ok
    )
    meshes = figures(
        (g / "mesh.png", f"geometry/{g.name}/mesh.png")
        for g in sorted((folder / "geometry").glob("*"))
    )
    sections = [
        Section("eta", "Loss factor over the grid", _eta_grid(points)),
        Section(
            "trace",
            "Trace: every point and its files",
            join(
                [
                    tag(
                        "p",
                        "Links are relative to this page. Reproduce any point with "
                        "hingelab trace trace.sqlite POINT.",
                        cls="note",
                    ),
                    _trace_table(points, report_dir),
                ]
            ),
        ),
        Section("loops", "Loops", loops or tag("p", "no loop pictures", cls="note")),
        *rsm_fit_sections(folder, fits, report_dir),
        Section(
            "geometry", "Geometries and meshes", meshes or tag("p", "no mesh pictures", cls="note")
        ),
    ]
    run = _run_of_sweep(points, folder / "table.csv")
    study = folder / "study.toml"  # hingelab study copies its study file here
    if not study.is_file():
        return ReportBody("Design sweep", run, sections)
    run.insert(0, ("study file", link(study, report_dir, "study.toml")))
    run[1] = ("command", "hingelab study STUDY.toml (a design study file, run as a sweep)")
    text = study.read_text(encoding="utf-8")
    sections.insert(0, Section("study", "Study file", scroll(tag("pre", text))))
    return ReportBody("Design study", run, sections)
