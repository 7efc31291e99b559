"""Trace every sample point of a response surface back to the files that produced it.

A study records each finite-element run as one *point*: its design parameters,
the files it wrote (STEP, mesh, mesh picture, loop table, loop picture) with a
SHA-256 of their content, the mesh statistics, the solver settings, the
convergence record and the results (η, ...). A fit records which points it
used. :func:`walk` then prints the chain of one point and checks every file is
still where it was and still has the same content.

The store is one SQLite file (standard library ``sqlite3``), by convention
``trace.sqlite`` next to the study's results. Artifact paths inside the
directory holding the database are stored relative to it, so a study directory
can be moved or copied as a whole; other paths are stored absolute.

Schema (version 1; ``*_json`` columns hold JSON objects exactly as the study gave them)::

    meta(key TEXT PRIMARY KEY, value TEXT)         -- 'schema_version' = '1'
    studies(id INTEGER PRIMARY KEY, name TEXT UNIQUE NOT NULL, created_utc TEXT NOT NULL)
    points(id INTEGER PRIMARY KEY,                 -- the POINT of `hingelab trace DB POINT`
           study_id INTEGER NOT NULL REFERENCES studies(id),
           created_utc TEXT NOT NULL,              -- ISO 8601, UTC
           status TEXT NOT NULL CHECK (status IN ('ok', 'failed')),
           error TEXT,                             -- why a failed point failed, else NULL
           mesh_stats_json TEXT NOT NULL,          -- element counts, min scaled Jacobian, ...
           solver_json TEXT NOT NULL,              -- the solver settings
           convergence_json TEXT NOT NULL,         -- increments, iterations, residuals, ...
           results_json TEXT NOT NULL)             -- every result
    params(point_id INTEGER NOT NULL REFERENCES points(id), name TEXT NOT NULL, value,
           PRIMARY KEY (point_id, name))           -- design parameters, one row each
    results(point_id INTEGER NOT NULL REFERENCES points(id), name TEXT NOT NULL,
           value REAL, PRIMARY KEY (point_id, name))  -- numeric results (eta, ...)
    artifacts(point_id INTEGER NOT NULL REFERENCES points(id),
           kind TEXT NOT NULL,                     -- step, mesh_msh, mesh_png, loop_csv, ...
           path TEXT NOT NULL,                     -- relative to the database's folder, or absolute
           sha256 TEXT NOT NULL, size_bytes INTEGER NOT NULL,
           PRIMARY KEY (point_id, kind))
    fits(id INTEGER PRIMARY KEY, study_id INTEGER REFERENCES studies(id),
           created_utc TEXT NOT NULL, y_name TEXT NOT NULL, x_names_json TEXT NOT NULL,
           degree INTEGER NOT NULL, terms_json TEXT NOT NULL,
           coefficients_json TEXT NOT NULL,        -- physical units, paper term order
           metrics_json TEXT NOT NULL)
    fit_points(fit_id INTEGER NOT NULL REFERENCES fits(id),
           point_id INTEGER NOT NULL REFERENCES points(id), PRIMARY KEY (fit_id, point_id))

Example:
    >>> import tempfile, pathlib
    >>> from rsm.trace_store import record_point
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "loop.csv").write_text("u_mm,f_N")
    >>> pid = record_point(d / "trace.sqlite", study="demo", params={"clearance_mm": 0.1},
    ...                    artifacts={"loop_csv": d / "loop.csv"}, results={"eta": 0.0989})
    >>> t = walk(d / "trace.sqlite", pid)
    >>> t.params["clearance_mm"], t.artifacts[0].state.value, t.results["eta"]
    (0.1, 'ok', 0.0989)
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

from cad.errors import DataError
from rsm.trace_store import (
    open_trace,
    sha256_of,
)

__all__ = [
    "ARTIFACT_ORDER",
    "ArtifactCheck",
    "ArtifactState",
    "PointTrace",
    "export_table",
    "format_trace",
    "trace_as_dict",
    "walk",
]

ARTIFACT_ORDER = ("step", "mesh_msh", "mesh_png", "loop_csv", "loop_png", "result_json")
"""The chain's order: geometry → mesh → (solver) → loop. Other kinds follow these."""


class ArtifactState(Enum):
    """What the walker found at an artifact's recorded path."""

    OK = "ok"
    MISSING = "missing"
    CHANGED = "changed"


@dataclass(frozen=True)
class ArtifactCheck:
    """One file of a point's chain, as recorded and as found now.

    Attributes:
        kind: ``step``, ``mesh_msh``, ``mesh_png``, ``loop_csv``, ``loop_png`` or another kind.
        path: Where the file should be now (relative paths resolved against the database's folder).
        recorded_path: The path as stored.
        sha256: Content hash when recorded.
        size_bytes: Size when recorded.
        state: OK, MISSING or CHANGED (present but different content).
        message: One sentence for a user; empty when OK.
    """

    kind: str
    path: Path
    recorded_path: str
    sha256: str
    size_bytes: int
    state: ArtifactState
    message: str


@dataclass(frozen=True)
class PointTrace:
    """Everything recorded about one sample point."""

    point_id: int
    study: str
    created_utc: str
    status: str
    error: str | None
    params: Mapping[str, object]
    artifacts: tuple[ArtifactCheck, ...]
    mesh_stats: Mapping[str, object]
    solver: Mapping[str, object]
    convergence: Mapping[str, object]
    results: Mapping[str, object]
    fit_ids: tuple[int, ...]

    @property
    def intact(self) -> bool:
        """True if every recorded file is present with its recorded content."""
        return all(a.state is ArtifactState.OK for a in self.artifacts)


def _check_artifact(db_dir: Path, kind: str, stored: str, digest: str, size: int) -> ArtifactCheck:
    p = Path(stored)
    full = p if p.is_absolute() else db_dir / p
    if not full.is_file():
        state = ArtifactState.MISSING
        msg = f"{kind}: {full} is missing (moved or deleted since it was recorded); not opened"
    elif sha256_of(full) != digest:
        state = ArtifactState.CHANGED
        msg = (
            f"{kind}: {full} has changed since it was recorded "
            f"(sha256 {digest[:12]}… recorded, now different); it is not the file of this point"
        )
    else:
        state, msg = ArtifactState.OK, ""
    return ArtifactCheck(kind, full, stored, digest, size, state, msg)


def _kind_rank(kind: str) -> tuple[int, str]:
    return (ARTIFACT_ORDER.index(kind) if kind in ARTIFACT_ORDER else len(ARTIFACT_ORDER), kind)


def walk(db_path: str | Path, point_id: int) -> PointTrace:
    """Read one point's chain and check each file still exists with the same content.

    Args:
        db_path: The trace database (opened read-only; never created).
        point_id: The point.

    Returns:
        The point's record with the state of every file.

    Raises:
        FileNotFoundError: If the database does not exist.
        DataError: If the point is not in the database or the file is not a trace.
    """
    db = Path(db_path)
    with open_trace(db, readonly=True) as con:
        row = con.execute(
            "SELECT p.id, s.name, p.created_utc, p.status, p.error, p.mesh_stats_json, "
            "p.solver_json, p.convergence_json, p.results_json "
            "FROM points p JOIN studies s ON s.id = p.study_id WHERE p.id = ?",
            (point_id,),
        ).fetchone()
        if row is None:
            n, lo, hi = con.execute("SELECT count(*), min(id), max(id) FROM points").fetchone()
            span = f"ids {lo} to {hi}" if n else "no points"
            raise DataError(f"{db}: no point {point_id} in the trace ({n} points, {span})")
        params = dict(con.execute("SELECT name, value FROM params WHERE point_id = ?", (point_id,)))
        arts = con.execute(
            "SELECT kind, path, sha256, size_bytes FROM artifacts WHERE point_id = ?", (point_id,)
        ).fetchall()
        fits = tuple(
            int(r[0])
            for r in con.execute(
                "SELECT fit_id FROM fit_points WHERE point_id = ? ORDER BY fit_id", (point_id,)
            )
        )
    checks = tuple(
        _check_artifact(db.parent, *a) for a in sorted(arts, key=lambda a: _kind_rank(a[0]))
    )
    return PointTrace(
        point_id=int(row[0]),
        study=row[1],
        created_utc=row[2],
        status=row[3],
        error=row[4],
        params=params,
        artifacts=checks,
        mesh_stats=json.loads(row[5]),
        solver=json.loads(row[6]),
        convergence=json.loads(row[7]),
        results=json.loads(row[8]),
        fit_ids=fits,
    )


def _kv(d: Mapping[str, object]) -> str:
    return ", ".join(f"{k} = {v}" for k, v in d.items()) if d else "(none recorded)"


def format_trace(t: PointTrace) -> str:
    """Write a point's chain as text, one link per line, in pipeline order."""
    lines = [
        f"point {t.point_id}  study {t.study!r}  recorded {t.created_utc}  status {t.status}",
    ]
    if t.error:
        lines.append(f"  error: {t.error}")
    lines.append(f"  design parameters: {_kv(t.params)}")
    by_kind = {a.kind: a for a in t.artifacts}

    def art(kind: str) -> None:
        a = by_kind.pop(kind, None)
        if a is None:
            lines.append(f"  -> {kind:<11} (not recorded)")
        elif a.state is ArtifactState.OK:
            lines.append(
                f"  -> {kind:<11} {a.path}  [sha256 {a.sha256[:12]}…, {a.size_bytes} B, ok]"
            )
        else:
            lines.append(f"  -> {kind:<11} {a.state.value.upper()}: {a.message}")

    art("step")
    art("mesh_msh")
    lines.append(f"     mesh: {_kv(t.mesh_stats)}")
    art("mesh_png")
    lines.append(f"  -> solver settings: {_kv(t.solver)}")
    lines.append(f"  -> convergence: {_kv(t.convergence)}")
    art("loop_csv")
    art("loop_png")
    for kind in list(by_kind):
        art(kind)
    lines.append(f"  -> results: {_kv(t.results)}")
    if t.fit_ids:
        lines.append(f"  used by fits: {', '.join(str(i) for i in t.fit_ids)}")
    bad = [a for a in t.artifacts if a.state is not ArtifactState.OK]
    if bad:
        lines.append(f"  WARNING: {len(bad)} file(s) of this chain are missing or changed.")
    return "\n".join(lines)


def trace_as_dict(t: PointTrace) -> dict[str, object]:
    """Return a point's chain as JSON-ready data."""
    return {
        "point_id": t.point_id,
        "study": t.study,
        "created_utc": t.created_utc,
        "status": t.status,
        "error": t.error,
        "params": dict(t.params),
        "artifacts": [
            {
                "kind": a.kind,
                "path": str(a.path),
                "recorded_path": a.recorded_path,
                "sha256": a.sha256,
                "size_bytes": a.size_bytes,
                "state": a.state.value,
                "message": a.message,
            }
            for a in t.artifacts
        ],
        "mesh_stats": dict(t.mesh_stats),
        "solver": dict(t.solver),
        "convergence": dict(t.convergence),
        "results": dict(t.results),
        "fit_ids": list(t.fit_ids),
        "intact": t.intact,
    }


def export_table(
    db_path: str | Path,
    csv_path: str | Path,
    *,
    study: str,
    include_failed: bool = False,
    point_ids: Sequence[int] | None = None,
) -> Path:
    """Write a study's points as a CSV table that ``hingelab rsm fit`` can read.

    Columns: ``point_id``, ``status``, then every parameter, then every numeric
    result, sorted by name. Because the table carries ``point_id``, a fitted
    surface labels each of its points with its trace id, and
    ``hingelab trace DB POINT`` leads from a surprising value to its files.

    Args:
        db_path: The trace database.
        csv_path: The table to write.
        study: The study to export.
        include_failed: Also export failed points (their results are usually blank).
        point_ids: Export only these points (e.g. the points of one run of a study
            whose earlier runs used other settings); None exports all.

    Returns:
        The CSV path.

    Raises:
        DataError: If the study is not in the database.
    """
    import csv

    with open_trace(db_path, readonly=True) as con:
        row = con.execute("SELECT id FROM studies WHERE name = ?", (study,)).fetchone()
        if row is None:
            names = [r[0] for r in con.execute("SELECT name FROM studies")]
            raise DataError(f"{db_path}: no study {study!r}; studies are {names}")
        statuses = ("ok", "failed") if include_failed else ("ok",)
        pts = con.execute(
            f"SELECT id, status FROM points WHERE study_id = ? AND status IN "
            f"({', '.join('?' * len(statuses))}) ORDER BY id",
            (row[0], *statuses),
        ).fetchall()
        par = {(p, n): v for p, n, v in con.execute("SELECT point_id, name, value FROM params")}
        res = {(p, n): v for p, n, v in con.execute("SELECT point_id, name, value FROM results")}
    if point_ids is not None:
        wanted = set(point_ids)
        pts = [(p, st) for p, st in pts if p in wanted]
    ids = {p for p, _ in pts}
    pnames = sorted({n for p, n in par if p in ids})
    rnames = sorted({n for p, n in res if p in ids})
    out = Path(csv_path)
    with out.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["point_id", "status", *pnames, *rnames])
        for pid, status in pts:
            w.writerow(
                [pid, status]
                + [par.get((pid, n), "") for n in pnames]
                + [res.get((pid, n), "") for n in rnames]
            )
    return out
