"""Sections of the HTML report for a sweep or design study: its trace, checked file by file.

A sweep folder can hold the points of several runs (another μ, mesh, increments or
effect each time). The page shows a point's files only when they are that point's: a
file is embedded or linked under a point's name only if its SHA-256 is the one the trace
recorded for the point (``rsm.trace_store``), and a point folder's ``result.json`` only if
it carries the point's result key. Any other file is named on the page as replaced or
missing, never shown. The settings that differ between the points (μ, increments, mesh,
effects, from the trace's solver records) are columns of the trace table, part of each
loop's caption and split the η grid; those equal for every point are in "What was run".
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cad.errors import DataError
from studies.report.parts import Html, Section, esc, figures, fmt, join, link, scroll, table, tag
from studies.report.sections import ReportBody
from studies.report.surfaces import rsm_fit_sections

NOT_SETTINGS = ("result_key", "cached", "lu_threads", "code")
"""Solver-record entries that are not settings (the key, whether read back, threads, code)."""

SETTING_WORDS = {
    "mu": "friction coefficient μ",
    "increments_per_stage": "increments per half cycle",
    "clearance_increments": "increments per half cycle with clearance",
    "effects": "effects",
}
"""How a setting is named in the header; a mesh setting is ``mesh <field>``."""

SETTING_HEADS = {
    "mu": "μ",
    "increments_per_stage": "increments",
    "clearance_increments": "increments (clearance)",
}
"""How a setting is named as a column."""


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
        solver: Solver settings as recorded (with the result key).
        artifacts: Kind → file (absolute).
        sha256: Kind → the file's SHA-256 when it was recorded.
    """

    point_id: int
    study: str
    status: str
    error: str | None
    params: dict[str, Any]
    results: dict[str, Any]
    solver: dict[str, Any]
    artifacts: dict[str, Path]
    sha256: dict[str, str]


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
    hashes: dict[int, dict[str, str]] = {}
    for pid, kind, path, digest in con.execute(
        "SELECT point_id, kind, path, sha256 FROM artifacts"
    ):
        p = Path(path)
        arts.setdefault(pid, {})[kind] = p if p.is_absolute() else root / p
        hashes.setdefault(pid, {})[kind] = digest
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
            hashes.get(pid, {}),
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


# ---------------------------------------------------------------- files checked


class FileCheck:
    """Check a point's files against the trace (each file hashed once per page)."""

    def __init__(self) -> None:
        self._sha: dict[Path, str | None] = {}

    def sha256(self, path: Path) -> str | None:
        """The file's SHA-256 now, or None if it is missing."""
        if path not in self._sha:
            from rsm.trace_store import sha256_of

            self._sha[path] = sha256_of(path) if path.is_file() else None
        return self._sha[path]

    def why_not(self, p: TracePoint, kind: str) -> str | None:
        """Why the file ``kind`` of point ``p`` cannot be shown as its own; None if it can."""
        path = p.artifacts[kind]
        now = self.sha256(path)
        if now is None:
            return "missing"
        return None if now == p.sha256.get(kind) else "replaced by another run"

    def own(self, p: TracePoint, kind: str) -> Path | None:
        """The point's file ``kind`` if it holds what was recorded for the point, else None."""
        if kind not in p.artifacts or self.why_not(p, kind) is not None:
            return None
        return p.artifacts[kind]

    def manifest(self, p: TracePoint) -> Path | None:
        """The point folder's ``result.json`` if it belongs to the point (its result key)."""
        if "result_json" in p.artifacts:
            return self.own(p, "result_json")
        if "loop_csv" not in p.artifacts or not p.solver.get("result_key"):
            return None
        path = p.artifacts["loop_csv"].parent / "result.json"
        try:
            key = json.loads(path.read_text(encoding="utf-8"))["solver"]["result_key"]
        except (OSError, ValueError, KeyError, TypeError):
            return None
        return path if key == p.solver["result_key"] else None


# ---------------------------------------------------------------- settings


def _plain(value: Any) -> Any:
    """A setting as one table value: a mapping (effects) as compact text, ``none`` if empty."""
    if isinstance(value, Mapping):
        if not value:
            return "none"
        return "; ".join(f"{k}({_plain(v)})" if isinstance(v, Mapping) else f"{k}={fmt(v)}"
                         for k, v in sorted(value.items()))  # fmt: skip
    if isinstance(value, list):
        return ", ".join(fmt(v) for v in value) or "—"
    return value


def point_settings(p: TracePoint) -> dict[str, Any]:
    """The settings a point ran with, flat (``mu``, ``increments_per_stage``, ``mesh size_mm``)."""
    flat: dict[str, Any] = {}
    for k, v in p.solver.items():
        if k in NOT_SETTINGS:
            continue
        if k == "mesh" and isinstance(v, Mapping):
            flat.update({f"mesh {mk}": _plain(mv) for mk, mv in v.items()})
        else:
            flat[k] = _plain(v)
    return flat


def split_settings(points: list[TracePoint]) -> tuple[dict[str, Any], list[str]]:
    """(settings equal for every point → value, names of the settings that differ)."""
    each = [point_settings(p) for p in points]
    names = list(dict.fromkeys(n for s in each for n in s))
    common: dict[str, Any] = {}
    differ: list[str] = []
    for n in names:
        values = {json.dumps(s.get(n), sort_keys=True, default=str) for s in each}
        if len(values) == 1:
            common[n] = each[0].get(n)
        else:
            differ.append(n)
    return common, differ


def _head(name: str) -> str:
    return SETTING_HEADS.get(name, name)


def _settings_text(p: TracePoint, names: list[str]) -> str:
    s = point_settings(p)
    return ", ".join(f"{_head(n)} = {fmt(s.get(n))}" for n in names)


# ---------------------------------------------------------------- sections


def _point_links(p: TracePoint, check: FileCheck, report_dir: Path) -> Html:
    items = [
        ("STEP", "step"),
        ("VTU", "mesh_vtu"),
        ("mesh.png", "mesh_png"),
        ("loop.csv", "loop_csv"),
        ("loop.png", "loop_png"),
    ]
    parts = []
    for label, kind in items:
        if kind not in p.artifacts:
            continue
        why = check.why_not(p, kind)
        if why is None:
            parts.append(link(p.artifacts[kind], report_dir, label))
        else:
            parts.append(tag("span", f"{label}: {why}", cls="missing"))
    manifest = check.manifest(p)
    if manifest is not None:
        parts.append(link(manifest, report_dir, "result.json"))
    return Html(" ".join(parts))


def _trace_table(
    points: list[TracePoint], differ: list[str], check: FileCheck, report_dir: Path
) -> Html:
    names = sorted({n for p in points for n in p.params})
    heads = ["point", "study", "status", *names, *(_head(n) for n in differ)]
    heads += ["η", "W_cycle [N·mm]", "δ(+Fg) [µm]", "energy bal.", "wall [s]", "files"]
    rows = []
    for p in points:
        r, s = p.results, point_settings(p)
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
                *(s.get(n) for n in differ),
                r.get("eta"),
                r.get("W_cycle_Nmm"),
                d * 1000.0 if isinstance(d, int | float) else None,
                r.get("energy_balance_rel_err"),
                r.get("wall_s"),
                _point_links(p, check, report_dir),
            ]
        )
    return scroll(table(heads, rows))


def _eta_grid(points: list[TracePoint], differ: list[str]) -> Html:
    """η over clearance (rows) × amplitude (columns): one grid per set of differing settings."""
    groups: dict[str, dict[tuple[Any, Any], Any]] = {}
    for p in points:
        if p.status == "ok" and "clearance_mm" in p.params and "amplitude_N" in p.params:
            grid = groups.setdefault(_settings_text(p, differ), {})
            grid[(p.params["clearance_mm"], p.params["amplitude_N"])] = p.results.get("eta")
    parts = []
    for settings, grid in groups.items():
        cs = sorted({c for c, _ in grid})
        amps = sorted({a for _, a in grid})
        rows = [[Html(tag("b", fmt(c))), *(grid.get((c, a)) for a in amps)] for c in cs]
        caption = "Loss factor η over the design grid" + (f" ({settings})" if settings else "")
        parts.append(table(["Δr [mm] \\ Fg [N]", *amps], rows, caption=caption))
    return join(parts)


def _loops(points: list[TracePoint], differ: list[str], check: FileCheck) -> Html:
    shown, not_shown = [], []
    for p in points:
        if p.status != "ok" or "loop_png" not in p.artifacts:
            continue
        path = check.own(p, "loop_png")
        what = ", ".join(f"{k} = {fmt(v)}" for k, v in p.params.items())
        settings = _settings_text(p, differ)
        caption = f"point {p.point_id}: {what}" + (f"; {settings}" if settings else "")
        if path is None:
            not_shown.append(f"point {p.point_id} ({check.why_not(p, 'loop_png')})")
        else:
            shown.append((path, caption))
    note = (
        tag(
            "p",
            "Not shown, because the file at the recorded path is not the one recorded for the "
            f"point: {', '.join(not_shown)}. hingelab trace trace.sqlite POINT says more.",
            cls="missing",
        )
        if not_shown
        else ""
    )
    grid = figures(shown)
    return join([note, grid or tag("p", "no loop pictures", cls="note")])


def _run_of_sweep(
    points: list[TracePoint], common: dict[str, Any], differ: list[str], table_csv: Path
) -> list[tuple[str, object]]:
    ok = sum(p.status == "ok" for p in points)
    names = sorted({n for p in points for n in p.params})
    values = {n: sorted({p.params[n] for p in points if n in p.params}, key=str) for n in names}
    mesh = [
        f"{k.removeprefix('mesh ')} = {fmt(v)}" for k, v in common.items() if k.startswith("mesh ")
    ]
    order = list(SETTING_WORDS)
    others = [
        (SETTING_WORDS.get(k, k), v)
        for k, v in sorted(
            common.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else len(order)
        )
        if not k.startswith("mesh ")
    ]
    run: list[tuple[str, object]] = [
        ("command", "hingelab sweep (design study over the design variable × amplitude)"),
        ("studies in the trace", ", ".join(sorted({p.study for p in points})) or "—"),
        ("points", f"{len(points)} ({ok} ok, {len(points) - ok} failed)"),
        *((f"{n} (values)", ", ".join(fmt(v) for v in values[n])) for n in names),
        *others,
    ]
    if mesh:
        run.append(("mesh (all points)", ", ".join(mesh)))
    run.append(
        (
            "settings that differ between the points",
            ", ".join(_head(n) for n in differ) + " (columns of the trace table)"
            if differ
            else "none: every point ran with the settings above",
        )
    )
    run.append(
        ("table of the last run", "table.csv" if table_csv.is_file() else "— (no table.csv)")
    )
    return run


def sweep_report(folder: Path, report_dir: Path) -> ReportBody:
    """Read a ``hingelab sweep`` folder (trace.sqlite, table.csv, points/, geometry/)."""
    points, fits = read_trace(folder / "trace.sqlite")
    common, differ = split_settings(points)
    check = FileCheck()
    meshes = figures(
        (g / "mesh.png", f"geometry/{g.name}/mesh.png")
        for g in sorted((folder / "geometry").glob("*"))
    )
    sections = [
        Section("eta", "Loss factor over the grid", _eta_grid(points, differ)),
        Section(
            "trace",
            "Trace: every point and its files",
            join(
                [
                    tag(
                        "p",
                        "Links are relative to this page; a file is linked only when its content "
                        "is the one recorded for the point. Reproduce any point with "
                        "hingelab trace trace.sqlite POINT.",
                        cls="note",
                    ),
                    _trace_table(points, differ, check, report_dir),
                ]
            ),
        ),
        Section("loops", "Loops", _loops(points, differ, check)),
        *rsm_fit_sections(folder, fits, report_dir),
        Section(
            "geometry", "Geometries and meshes", meshes or tag("p", "no mesh pictures", cls="note")
        ),
    ]
    run = _run_of_sweep(points, common, differ, folder / "table.csv")
    study = folder / "study.toml"  # hingelab study copies its study file here
    if not study.is_file():
        return ReportBody("Design sweep", run, sections)
    run.insert(0, ("study file (of the last run)", link(study, report_dir, "study.toml")))
    run[1] = ("command", "hingelab study STUDY.toml (a design study file, run as a sweep)")
    text = study.read_text(encoding="utf-8")
    sections.insert(0, Section("study", "Study file (of the last run)", scroll(tag("pre", text))))
    return ReportBody("Design study", run, sections)
