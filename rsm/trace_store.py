"""Writing a trace: the SQLite schema, opening or creating the store, recording points and fits.

``rsm.trace`` reads the store back (``walk``, ``export_table``); its module docstring
describes the schema.
"""

from __future__ import annotations

import hashlib
import math
import sqlite3
from collections.abc import Iterator, Mapping, Sequence
from contextlib import closing, contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Literal

import numpy as np

from cad.errors import DataError, ParameterError
from model.jsonio import dumps
from rsm.metrics import FitMetrics
from rsm.polynomial import ResponseSurface

SCHEMA_VERSION = 1

_REAL = (int, float, np.integer, np.floating)

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta(key TEXT PRIMARY KEY, value TEXT);
CREATE TABLE IF NOT EXISTS studies(
    id INTEGER PRIMARY KEY, name TEXT UNIQUE NOT NULL, created_utc TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS points(
    id INTEGER PRIMARY KEY, study_id INTEGER NOT NULL REFERENCES studies(id),
    created_utc TEXT NOT NULL, status TEXT NOT NULL CHECK (status IN ('ok', 'failed')),
    error TEXT, mesh_stats_json TEXT NOT NULL, solver_json TEXT NOT NULL,
    convergence_json TEXT NOT NULL, results_json TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS params(
    point_id INTEGER NOT NULL REFERENCES points(id), name TEXT NOT NULL, value,
    PRIMARY KEY (point_id, name));
CREATE TABLE IF NOT EXISTS results(
    point_id INTEGER NOT NULL REFERENCES points(id), name TEXT NOT NULL, value REAL,
    PRIMARY KEY (point_id, name));
CREATE TABLE IF NOT EXISTS artifacts(
    point_id INTEGER NOT NULL REFERENCES points(id), kind TEXT NOT NULL, path TEXT NOT NULL,
    sha256 TEXT NOT NULL, size_bytes INTEGER NOT NULL, PRIMARY KEY (point_id, kind));
CREATE TABLE IF NOT EXISTS fits(
    id INTEGER PRIMARY KEY, study_id INTEGER REFERENCES studies(id), created_utc TEXT NOT NULL,
    y_name TEXT NOT NULL, x_names_json TEXT NOT NULL, degree INTEGER NOT NULL,
    terms_json TEXT NOT NULL, coefficients_json TEXT NOT NULL, metrics_json TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS fit_points(
    fit_id INTEGER NOT NULL REFERENCES fits(id), point_id INTEGER NOT NULL REFERENCES points(id),
    PRIMARY KEY (fit_id, point_id));
"""


def sha256_of(path: str | Path) -> str:
    """Return the SHA-256 hex digest of a file's content (read in 1 MiB blocks)."""
    h = hashlib.sha256()
    with Path(path).open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _dumps(obj: Mapping[str, object]) -> str:
    return dumps(dict(obj), indent=None, sort_keys=True)


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def create(db_path: str | Path) -> Path:
    """Create a trace database, or check an existing one has the expected schema.

    Args:
        db_path: The SQLite file; its folder is created if needed.

    Returns:
        The database path.

    Raises:
        DataError: If the file exists with a different schema version.
    """
    p = Path(db_path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with closing(sqlite3.connect(p)) as con, con:
        con.executescript(_SCHEMA)
        row = con.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
        if row is None:
            con.execute("INSERT INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
        elif row[0] != str(SCHEMA_VERSION):
            raise DataError(f"{p}: trace schema version {row[0]}, expected {SCHEMA_VERSION}")
    return p


@contextmanager
def open_trace(db_path: str | Path, *, readonly: bool) -> Iterator[sqlite3.Connection]:
    """Open the trace database (read-only, or created if missing) and close it after use."""
    p = Path(db_path)
    if readonly:
        if not p.is_file():
            raise FileNotFoundError(f"trace database {p} does not exist")
        con = sqlite3.connect(f"{p.resolve().as_uri()}?mode=ro", uri=True)
    else:
        create(p)
        con = sqlite3.connect(p)
    con.execute("PRAGMA foreign_keys = ON")
    try:
        with con:
            yield con
    except sqlite3.DatabaseError as err:
        raise DataError(f"{p}: not a usable trace database ({err})") from err
    finally:
        con.close()


def _study_id(con: sqlite3.Connection, study: str) -> int:
    row = con.execute("SELECT id FROM studies WHERE name = ?", (study,)).fetchone()
    if row is not None:
        return int(row[0])
    cur = con.execute("INSERT INTO studies(name, created_utc) VALUES (?, ?)", (study, _now()))
    return int(cur.lastrowid or 0)


def _stored_path(path: Path, db_dir: Path) -> str:
    full = path.resolve()
    try:
        return full.relative_to(db_dir.resolve()).as_posix()
    except ValueError:
        return str(full)


def record_point(
    db_path: str | Path,
    *,
    study: str,
    params: Mapping[str, float | int | str],
    artifacts: Mapping[str, str | Path | None] | None = None,
    mesh_stats: Mapping[str, object] | None = None,
    solver: Mapping[str, object] | None = None,
    convergence: Mapping[str, object] | None = None,
    results: Mapping[str, object] | None = None,
    status: Literal["ok", "failed"] = "ok",
    error: str | None = None,
) -> int:
    """Record one sample point and its chain of files.

    Args:
        db_path: The trace database (created if absent).
        study: Study name; points of one study are fitted together.
        params: Design parameters, name → value, units in the name (``clearance_mm``).
        artifacts: Kind → file path (``step``, ``mesh_msh``, ``mesh_png``, ``loop_csv``,
            ``loop_png``, or any other kind); ``None`` entries are skipped (a failed run
            may not have produced every file). Each file is hashed now.
        mesh_stats: Element counts and quality figures.
        solver: Solver settings as used.
        convergence: Convergence record (increments, iterations, residuals, cut-backs).
        results: Results; those that are real numbers (``eta``, ...) are also indexed.
        status: ``"ok"`` or ``"failed"``.
        error: Why the run failed; required when ``status`` is ``"failed"``, else None.

    Returns:
        The new point id.

    Raises:
        ParameterError: If ``status`` and ``error`` disagree or ``params`` is empty.
        FileNotFoundError: If a given artifact path does not exist.
        TypeError: If a value cannot be stored as JSON.
    """
    if status not in ("ok", "failed"):
        raise ParameterError(f"status must be 'ok' or 'failed', got {status!r}")
    if (status == "failed") != (error is not None):
        raise ParameterError(f"error must be given exactly when status is 'failed', got {error!r}")
    if not params:
        raise ParameterError("params must hold at least one design parameter")
    db = Path(db_path)
    files = []
    for kind, path in (artifacts or {}).items():
        if path is None:
            continue
        fp = Path(path)
        if not fp.is_file():
            raise FileNotFoundError(f"artifact {kind!r}: {fp} does not exist")
        files.append((kind, _stored_path(fp, db.parent), sha256_of(fp), fp.stat().st_size))
    res = dict(results or {})
    blobs = [_dumps(d or {}) for d in (mesh_stats, solver, convergence, res)]
    with open_trace(db, readonly=False) as con:
        sid = _study_id(con, study)
        cur = con.execute(
            "INSERT INTO points(study_id, created_utc, status, error, mesh_stats_json, "
            "solver_json, convergence_json, results_json) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            (sid, _now(), status, error, *blobs),
        )
        pid = int(cur.lastrowid or 0)
        con.executemany(
            "INSERT INTO params VALUES (?, ?, ?)",
            [(pid, k, v.item() if isinstance(v, np.generic) else v) for k, v in params.items()],
        )
        con.executemany(
            "INSERT INTO results VALUES (?, ?, ?)",
            [(pid, k, float(v)) for k, v in res.items() if isinstance(v, _REAL)],
        )
        con.executemany("INSERT INTO artifacts VALUES (?, ?, ?, ?, ?)", [(pid, *f) for f in files])
    return pid


def record_fit(
    db_path: str | Path,
    *,
    surface: ResponseSurface,
    metrics: FitMetrics,
    point_ids: Sequence[int],
    study: str | None = None,
) -> int:
    """Record a fitted surface and the ids of the points it was fitted to.

    Args:
        db_path: The trace database.
        surface: The fitted surface.
        metrics: Its metrics.
        point_ids: Trace ids of its sample points, in the order of ``surface.x``.
        study: Study the fit belongs to, if any.

    Returns:
        The new fit id.

    Raises:
        DataError: If the number of ids differs from the number of points, or an id
            is not in the database.
    """
    if len(point_ids) != surface.n_points:
        raise DataError(
            f"point_ids has {len(point_ids)} ids but the surface has {surface.n_points} points"
        )
    with open_trace(db_path, readonly=False) as con:
        known = {int(r[0]) for r in con.execute("SELECT id FROM points")}
        missing = [i for i in point_ids if int(i) not in known]
        if missing:
            raise DataError(f"{db_path}: point ids {missing} are not in the trace")
        sid = _study_id(con, study) if study is not None else None
        summary = {k: (v if math.isfinite(v) else None) for k, v in metrics.summary().items()}
        cur = con.execute(
            "INSERT INTO fits(study_id, created_utc, y_name, x_names_json, degree, terms_json, "
            "coefficients_json, metrics_json) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            (
                sid,
                _now(),
                surface.y_name,
                dumps(list(surface.x_names), indent=None),
                surface.degree,
                dumps(list(surface.term_names), indent=None),
                dumps([float(b) for b in surface.coefficients], indent=None),
                dumps(summary, indent=None),
            ),
        )
        fid = int(cur.lastrowid or 0)
        con.executemany("INSERT INTO fit_points VALUES (?, ?)", [(fid, int(i)) for i in point_ids])
    return fid
