"""Loop files: unit tables, the ``Loop`` record, readers of plain loop CSVs and Bluehill exports.

Units are part of the column name (``force_kN``, ``displacement_um``) and converted to
N, mm, s on reading; an unknown unit is refused by name. Every malformed entry raises
``DataError`` naming the file, the data row (1-based, after the header) or the line, and
the column. ``validation.measurements`` builds measurement sets from these loops.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from cad.errors import DataError

FloatArray = npt.NDArray[np.float64]

FORCE_UNITS: dict[str, float] = {"N": 1.0, "kN": 1e3, "mN": 1e-3, "lbf": 4.4482216152605}
"""Force units accepted in column names and Bluehill unit rows → factor to N."""

LENGTH_UNITS: dict[str, float] = {
    "mm": 1.0,
    "um": 1e-3,
    "µm": 1e-3,
    "μm": 1e-3,
    "m": 1e3,
    "in": 25.4,
}
"""Length units → factor to mm."""

TIME_UNITS: dict[str, float] = {"s": 1.0, "sec": 1.0, "ms": 1e-3, "min": 60.0}
"""Time units → factor to s."""

TEMPERATURE_UNITS: dict[str, float] = {"C": 1.0}
"""Temperature units (°C only; conversions other than a factor are not supported)."""

RATE_UNITS: dict[str, float] = {"mm_per_min": 1.0, "mm_per_s": 60.0}
"""Displacement-rate units → factor to mm/min."""


@dataclass(frozen=True, eq=False)
class Loop:
    """One measured (or computed) force–displacement record.

    Attributes:
        force_n: Force, shape (n,) [N].
        displacement_mm: Displacement, shape (n,) [mm].
        time_s: Time, shape (n,) [s], or None.
        source: Where it came from (file path, or ``model:<case>``).
    """

    force_n: FloatArray
    displacement_mm: FloatArray
    time_s: FloatArray | None
    source: str

    def __post_init__(self) -> None:
        for name in ("force_n", "displacement_mm", "time_s"):
            a = getattr(self, name)
            if a is None:
                continue
            a = np.array(a, dtype=np.float64)  # a private, read-only copy
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        n = self.force_n.shape
        if len(n) != 1 or self.displacement_mm.shape != n:
            raise DataError(
                f"{self.source}: force and displacement must be 1-D of equal length, got "
                f"{self.force_n.shape} and {self.displacement_mm.shape}"
            )
        if self.time_s is not None and self.time_s.shape != n:
            raise DataError(f"{self.source}: time_s has shape {self.time_s.shape}, expected {n}")

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.force_n.size)


# --------------------------------------------------------------------------- tables


@dataclass(frozen=True)
class Table:
    """Rows of a CSV file as strings, with where each row came from."""

    path: Path
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    lines: tuple[int, ...]  # 1-based line number of each row in the file
    decimal_comma: bool = False  # numbers written 1,5 (a ';' or tab separated file)

    def where(self, i: int, column: str) -> str:
        """Where a cell is, for messages: file, row (1-based), line and column."""
        return f"{self.path}: row {i + 1} (line {self.lines[i]}), column {column}"


def csv_dialect(path: Path) -> tuple[str, bool]:
    """The separator of a plain CSV and whether its numbers use a decimal comma.

    Read from the header (the first non-empty line): a ``;``-separated header, as
    spreadsheets write in locales with a decimal comma, or a tab-separated one, means the
    data may write ``1,5`` for 1.5; a ``,``-separated header means ``.`` decimals.
    """
    with open(path, encoding="utf-8-sig") as fh:
        header = next((line for line in fh if line.strip()), "")
    if "\t" in header:
        return "\t", True
    if ";" in header and "," not in header:
        return ";", True
    return ",", False


def read_table(path: Path) -> Table:
    """Read a plain CSV: the first non-empty line is the header; blank lines are skipped.

    The separator is ``,``, ``;`` or a tab (``csv_dialect``); with ``;`` or a tab, numbers
    may use a decimal comma.
    """
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    delimiter, decimal_comma = csv_dialect(path)
    with open(path, newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh, delimiter=delimiter)
        header: tuple[str, ...] | None = None
        rows, lines = [], []
        for line_no, raw in enumerate(reader, start=1):
            cells = tuple(c.strip() for c in raw)
            if not any(cells):
                continue
            if header is None:
                header = cells
                continue
            if len(cells) != len(header):
                hint = (
                    "; a decimal comma in a comma-separated file splits numbers: separate "
                    "the columns with ';' (or write decimal points)"
                    if delimiter == "," and len(cells) > len(header)
                    else ""
                )
                raise DataError(
                    f"{path}: line {line_no} has {len(cells)} fields, the header has "
                    f"{len(header)}{hint}"
                )
            rows.append(cells)
            lines.append(line_no)
    if header is None:
        raise DataError(f"{path}: empty file")
    dupes = sorted({h for h in header if header.count(h) > 1})
    if dupes:
        raise DataError(f"{path}: duplicate column(s) {dupes}")
    return Table(path, header, tuple(rows), tuple(lines), decimal_comma)


def _find_column(
    table: Table, quantity: str, units: Mapping[str, float]
) -> tuple[str, float] | None:
    """Find the column ``<quantity>_<unit>``; return (name, factor to project units) or None.

    Raises:
        DataError: If its unit is unknown or there are two.
    """
    prefix = quantity + "_"
    hits = [h for h in table.header if h.startswith(prefix) or h == quantity]
    if not hits:
        return None
    if len(hits) > 1:
        raise DataError(f"{table.path}: more than one {quantity} column: {hits}")
    name = hits[0]
    unit = name[len(prefix) :] if name != quantity else ""
    if unit not in units:
        raise DataError(
            f"{table.path}: column {name}: unknown unit {unit!r} for {quantity} "
            f"(known: {', '.join(units)})"
        )
    return name, units[unit]


def _require_column(table: Table, quantity: str, units: Mapping[str, float]) -> tuple[str, float]:
    """As ``_find_column``, and refuse a missing column naming the file and the columns."""
    col = _find_column(table, quantity, units)
    if col is None:
        raise DataError(
            f"{table.path}: missing column {quantity}_<unit> (units: {', '.join(units)}); "
            f"columns are {list(table.header)}"
        )
    return col


def _finite(text: str, where: str, shown: str | None = None) -> float:
    """Parse a finite number, or raise DataError at ``where`` quoting ``shown`` (default text)."""
    quoted = text if shown is None else shown
    try:
        value = float(text)
    except ValueError:
        raise DataError(f"{where}: not a number: {quoted!r}") from None
    if not math.isfinite(value):
        raise DataError(f"{where}: not a finite number: {quoted!r}")
    return value


def table_number(table: Table, i: int, column: str) -> float:
    """The finite number in row ``i``, ``column`` (DataError naming the cell otherwise)."""
    text = table.rows[i][table.header.index(column)]
    if table.decimal_comma:
        return _finite(text.replace(",", "."), table.where(i, column), text)
    return _finite(text, table.where(i, column))


def _column(table: Table, column: str, factor: float) -> FloatArray:
    return np.array([table_number(table, i, column) for i in range(len(table.rows))]) * factor


def table_optional(table: Table, i: int, col: tuple[str, float] | None) -> float | None:
    """The number in row ``i`` of ``col = (column, factor)`` times the factor; None if empty."""
    if col is None or table.rows[i][table.header.index(col[0])] == "":
        return None
    return table_number(table, i, col[0]) * col[1]


# --------------------------------------------------------------------------- loops


MODEL_LOOP_COLUMNS = ("stage", "increment", "side")
"""Extra columns of a ``hingelab cycle`` loop.csv, accepted (and ignored) so that a model run
reads back as a measurement. That loop is written without the free play (δ from the
touching configurations): compare it with ``hingelab compare --without-free-play``."""


def read_loop_csv(path: Path | str) -> Loop:
    """Read a plain loop CSV (``force_<unit>, displacement_<unit>[, time_<unit>]``).

    A ``hingelab cycle`` loop.csv reads too (``MODEL_LOOP_COLUMNS`` are ignored).

    Args:
        path: The file.

    Returns:
        The loop in N, mm, s.

    Raises:
        DataError: Missing column, unknown unit, non-numeric or non-finite value,
            fewer than 4 samples.
    """
    table = read_table(Path(path))
    f_col = _require_column(table, "force", FORCE_UNITS)
    d_col = _require_column(table, "displacement", LENGTH_UNITS)
    t_col = _find_column(table, "time", TIME_UNITS)
    known = {f_col[0], d_col[0]} | ({t_col[0]} if t_col else set())
    extra = [h for h in table.header if h not in known and h not in MODEL_LOOP_COLUMNS]
    if extra:
        raise DataError(
            f"{table.path}: unexpected column(s) {extra}; a loop has force_<unit>, "
            "displacement_<unit> and optionally time_<unit> (and the model loop's "
            f"{', '.join(MODEL_LOOP_COLUMNS)})"
        )
    if len(table.rows) < 4:
        raise DataError(f"{table.path}: a loop needs at least 4 rows, got {len(table.rows)}")
    time = None if t_col is None else _column(table, *t_col)
    if time is not None:
        check_time(time, str(table.path), t_col[0] if t_col else "time", table.lines)
    return Loop(_column(table, *f_col), _column(table, *d_col), time, str(table.path))


def check_time(time_s: FloatArray, where: str, column: str, lines: Sequence[int]) -> None:
    """Refuse a time column that does not increase (a record stitched or sorted wrongly).

    Raises:
        DataError: Naming the file, the line where time stops increasing and both values.
    """
    back = np.flatnonzero(np.diff(time_s) <= 0)
    if back.size:
        k = int(back[0]) + 1
        raise DataError(
            f"{where}: line {lines[k]}, column {column}: time does not increase "
            f"({time_s[k - 1]:g} s, then {time_s[k]:g} s); a record's samples must be in time order"
        )


BLUEHILL_COLUMNS: dict[str, tuple[str, ...]] = {
    "time": ("time",),
    "displacement": ("extension", "displacement", "position"),
    "force": ("load", "force"),
}
"""Bluehill channel names (lower case) read as each quantity; the first present wins."""


def _parse_units_row(cells: Sequence[str]) -> list[str] | None:
    units = []
    for c in cells:
        m = re.fullmatch(r"\((.*)\)", c.strip())
        if m is None:
            return None
        units.append(m.group(1).strip())
    return units


def read_bluehill(path: Path | str) -> Loop:
    """Read an Instron Bluehill raw-data CSV export.

    The file has a header block of ``"name","value"`` (or ``name : value``) lines, then a
    row of channel names and a row of units in parentheses, then the data, e.g.::

        "Sample ID","hinge-A"
        "Time","Extension","Load"
        "(s)","(mm)","(kN)"
        "0.000","0.00000","0.00012"

    Channels ``Extension``/``Displacement``/``Position`` are read as the displacement,
    ``Load``/``Force`` as the force, ``Time`` as the time; others are ignored (they are
    named in no output, but a Bluehill export usually carries a few). Units are
    converted to N, mm, s (force: N, kN, mN, lbf; length: mm, µm/um, m, in; time: s,
    sec, ms, min); any other unit is refused by name. Numbers may use thousands
    separators, and decimal commas (``"0,0021"``; a ``;``-separated export, as Bluehill
    writes in decimal-comma locales, reads every comma as the decimal mark).

    Args:
        path: The exported file.

    Returns:
        The loop in N, mm, s.

    Raises:
        DataError: No name/unit header rows, a missing channel, an unknown unit, a
            non-numeric or non-finite value (naming the line and the channel).
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    with open(path, newline="", encoding="utf-8-sig") as fh:
        text = fh.read()
    delimiter = _bluehill_delimiter(text)
    lines = [[c.strip() for c in row] for row in csv.reader(text.splitlines(), delimiter=delimiter)]
    start = None
    for i in range(len(lines) - 1):
        units = _parse_units_row(lines[i + 1]) if any(lines[i + 1]) else None
        if units is not None and len(units) == len(lines[i]) and len(units) >= 2:
            start = i
            break
    if start is None:
        raise DataError(
            f'{path}: no Bluehill channel-name row followed by a unit row like "(s)","(mm)","(N)"'
        )
    names = [n.lower() for n in lines[start]]
    units = _parse_units_row(lines[start + 1]) or []
    data = [(k + 1, row) for k, row in enumerate(lines) if k > start + 1 and any(row)]
    columns: dict[str, FloatArray] = {}
    for quantity, aliases in BLUEHILL_COLUMNS.items():
        j = next((names.index(a) for a in aliases if a in names), None)
        if j is None:
            if quantity == "time":
                continue
            raise DataError(
                f"{path}: line {start + 1}: no {quantity} channel (looked for "
                f"{', '.join(a.title() for a in aliases)}); channels are {lines[start]}"
            )
        table = {"time": TIME_UNITS, "displacement": LENGTH_UNITS, "force": FORCE_UNITS}[quantity]
        unit = units[j]
        if unit not in table:
            raise DataError(
                f"{path}: line {start + 2}, column {lines[start][j]}: unknown unit {unit!r} "
                f"(known: {', '.join(table)})"
            )
        columns[quantity] = (
            np.array(
                [
                    _bluehill_number(path, line, row, j, lines[start][j], delimiter)
                    for line, row in data
                ]
            )
            * table[unit]
        )
    if len(data) < 4:
        raise DataError(f"{path}: a loop needs at least 4 data lines, got {len(data)}")
    time = columns.get("time")
    if time is not None:
        check_time(time, str(path), "Time", [line for line, _ in data])
    return Loop(columns["force"], columns["displacement"], time, str(path))


_THOUSANDS = re.compile(r"[+-]?[1-9]\d{0,2}(,\d{3})+(\.\d*)?([eE][+-]?\d+)?")
_DECIMAL_COMMA = re.compile(r"[+-]?\d*,\d+([eE][+-]?\d+)?")


def _bluehill_delimiter(text: str) -> str:
    """``;`` when the unit row is semicolon-separated (a decimal-comma locale), else ``,``."""
    for line in text.splitlines()[:200]:
        cells = [c.strip().strip('"') for c in line.split(";")]
        if len(cells) >= 2 and all(re.fullmatch(r"\(.*\)", c) for c in cells):
            return ";"
    return ","


def _bluehill_number(
    path: Path, line: int, row: Sequence[str], j: int, name: str, delimiter: str = ","
) -> float:
    """One value; a decimal comma (``0,25``, or any comma in a ``;`` file) reads as a point.

    In a comma-separated file ``1,234.5`` and ``12,345`` are thousands separators, and
    ``0,002125`` (no valid grouping) a decimal comma.
    """
    if j >= len(row):
        raise DataError(f"{path}: line {line}, column {name}: missing value")
    text = row[j]
    if "," in text:
        if delimiter == ";" or (_DECIMAL_COMMA.fullmatch(text) and not _THOUSANDS.fullmatch(text)):
            text = text.replace(".", "").replace(",", ".")  # 1.234,5 → 1234.5
        else:
            text = text.replace(",", "")
    return _finite(text, f"{path}: line {line}, column {name}", row[j])


def read_loop_file(path: Path | str) -> Loop:
    """Read a loop file, plain CSV or Bluehill export (a Bluehill file has unit rows in parentheses).

    Raises:
        DataError: As ``read_loop_csv`` or ``read_bluehill``.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    with open(path, newline="", encoding="utf-8-sig") as fh:
        head = [row for row, _ in zip(csv.reader(fh), range(200), strict=False)]
    if any(_parse_units_row(r) is not None for r in head if any(r)):
        return read_bluehill(path)
    if _bluehill_delimiter(path.read_text(encoding="utf-8-sig")) == ";":  # decimal-comma locale
        return read_bluehill(path)
    return read_loop_csv(path)
