"""What every command shares: the mesh summary, strict JSON, output-folder and trace checks."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mesh.meshed import MeshedHinge


def mesh_summary(m: MeshedHinge, total_wall_s: float) -> dict[str, Any]:
    """Return the JSON summary the ``mesh`` command prints."""
    r = m.report
    return {
        "hinge": m.model.kind,
        "params": {
            k: v for k, v in vars(m.model.params).items() if isinstance(v, int | float | type(None))
        },
        "parts": {
            name: {
                "volume_mm3": p["volume_mm3"],
                "mesh_volume_mm3": p["mesh_volume_mm3"],
                "n_hex": int(p["n_hex"]),
            }
            for name, p in r.parts.items()
        },
        "n_nodes": r.n_nodes,
        "n_hex": r.n_hex,
        "hex_fraction": r.hex_fraction,
        "min_scaled_jacobian": r.min_scaled_jacobian,
        "sets": r.sets,
        "files": {k: str(v) for k, v in m.files.items()},
        "wall_s": total_wall_s,
    }


def check_writable_dir(folder: Path, option: str) -> Path:
    """Create ``folder`` if needed and check a file can be written there, before any work.

    Args:
        folder: The output folder.
        option: The command-line option that named it (``--out``), for the message.

    Returns:
        The folder.

    Raises:
        DataError: Naming the option and the path when the folder cannot be created or
            written (a read-only file system, no permission, a file in the way).
    """
    import tempfile

    from cad.errors import DataError

    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".hingelab-write-check-"):
            pass
    except OSError as err:
        why = err.strerror or type(err).__name__
        raise DataError(f"{option} {folder}: cannot write there ({why})") from err
    return folder


TRACE_TABLES = ("meta", "studies", "points")
"""Tables a hingelab trace database has (``rsm.trace`` describes the whole schema)."""


def check_trace_db(db: Path, option: str) -> Path:
    """Check that ``db`` can become (or already is) a hingelab trace, before any work.

    A missing file needs a writable folder; an existing one must be writable, an SQLite
    database, and hold the trace's tables (an empty file is accepted: SQLite creates it).

    Raises:
        DataError: Naming the option and the path, saying what is wrong.
    """
    import sqlite3

    from cad.errors import DataError

    db = Path(db)
    if db.is_dir():
        raise DataError(f"{option} {db}: is a folder, expected a trace database file")
    if not db.exists():
        check_writable_dir(db.parent, option)
        return db
    if not os.access(db, os.R_OK | os.W_OK):
        raise DataError(f"{option} {db}: cannot write the trace database (no permission)")
    with db.open("rb") as fh:
        head = fh.read(16)
    if not head:
        return db
    if head != b"SQLite format 3\x00":
        raise DataError(f"{option} {db}: not an SQLite database (not a hingelab trace)")
    try:
        con = sqlite3.connect(f"{db.resolve().as_uri()}?mode=ro", uri=True)
        try:
            names = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        finally:
            con.close()
    except sqlite3.Error as err:
        raise DataError(f"{option} {db}: not a usable SQLite database ({err})") from err
    if names and not set(TRACE_TABLES) <= names:
        raise DataError(
            f"{option} {db}: an SQLite database but not a hingelab trace "
            f"(tables {sorted(names)}; a trace has {list(TRACE_TABLES)})"
        )
    return db


COMMANDS_FILE = "commands.jsonl"
"""Where a result folder keeps the command lines that wrote into it, one JSON object a line."""


def record_command(
    folder: Path, argv: list[str], exit_status: int, program: tuple[str, ...] = ("hingelab",)
) -> Path:
    """Append the command line that ran (``program`` + ``argv``) to ``folder/commands.jsonl``.

    Each line holds the command as one shell-quoted string, its arguments, the folder it
    ran in (relative paths in it are relative to that), the time it ended (UTC), its exit
    status and hingelab's version; ``hingelab report`` shows them. One line is appended in
    one write, so a line is never half there.

    Args:
        folder: The result folder (must exist).
        argv: The arguments after ``hingelab``, as typed.
        exit_status: What the command returned (0 ok, 1 error, 130 interrupted).
        program: The words before ``argv`` (``python -m studies.paper.validation``).

    Returns:
        The file.
    """
    import datetime as dt
    import json
    import shlex

    from model.code import ALL_PACKAGES, code_version

    entry = {
        "command": shlex.join([*program, *argv]),
        "argv": list(argv),
        "cwd": os.getcwd(),
        "ended_utc": dt.datetime.now(dt.UTC).replace(microsecond=0).isoformat(),
        "exit_status": exit_status,
        "version": code_version(ALL_PACKAGES).short(),
    }
    path = Path(folder) / COMMANDS_FILE
    with path.open("a", encoding="utf-8") as fh:
        fh.write(json.dumps(entry, ensure_ascii=False) + "\n")
    return path


def recorded_commands(folder: Path) -> list[dict[str, Any]]:
    """The commands recorded in ``folder/commands.jsonl``, oldest first (unreadable lines skipped)."""
    import json

    path = Path(folder) / COMMANDS_FILE
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return []
    out = []
    for line in lines:
        try:
            entry = json.loads(line)
        except ValueError:
            continue
        if isinstance(entry, dict) and isinstance(entry.get("command"), str):
            out.append(entry)
    return out
