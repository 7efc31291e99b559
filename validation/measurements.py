"""Measured hinge loops: a folder of cases, loop CSVs, η-only tables, Instron Bluehill exports.

A **measurement set** is a folder with ``cases.csv``, one row per test::

    case_id,hinge,clearance_mm,preload_N,amplitude_N,loop_file[,replicate,rate_mm_per_min,temperature_C]

and one file per loop, named by ``loop_file`` relative to the folder: either a plain CSV
with columns ``force_N, displacement_mm`` (optional ``time_s``) or an Instron Bluehill
raw-data export (recognised by its header block, see ``read_bluehill``). A folder with
``eta.csv`` instead holds an η-only table (``read_eta_table``).

Units are part of the column name (``force_kN``, ``displacement_um``) and converted to
N, mm, s on reading; an unknown unit is refused by name. Every malformed entry raises
``DataError`` naming the file, the data row (1-based, after the header) or the line, and
the column. Nothing is dropped: a row is either read whole or the whole set is refused.

A loop must reach the stated amplitude: after removing the force offset (see
``validation.loops``), ``max F ≥ (1 − AMPLITUDE_TOL)·Fg`` and ``min F ≤ −(1 − AMPLITUDE_TOL)·Fg``,
and it must not overshoot by more than ``OVERSHOOT_TOL`` (which would mean the stated
amplitude is wrong).
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
from validation.loops import process_loop, remove_offsets

FloatArray = npt.NDArray[np.float64]

AMPLITUDE_TOL = 0.02
"""A loop must reach ±Fg within this fraction (load frames under force control reach the
set point to well under 1 %; 2 % leaves room for noise and slow sampling at the peaks)."""

OVERSHOOT_TOL = 0.10
"""A loop whose peaks exceed ±Fg by more than this fraction is refused."""

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

TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "min": 60.0}
"""Time units → factor to s."""

TEMPERATURE_UNITS: dict[str, float] = {"C": 1.0}
"""Temperature units (°C only; conversions other than a factor are not supported)."""

RATE_UNITS: dict[str, float] = {"mm_per_min": 1.0, "mm_per_s": 60.0}
"""Displacement-rate units → factor to mm/min."""

HINGE_KINDS = ("general", "bearing")


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


@dataclass(frozen=True)
class Case:
    """One test: a design point, its protocol and its loop (or its η only).

    Attributes:
        case_id: Unique name of the test.
        hinge: Hinge kind (``general`` or ``bearing``).
        clearance_mm: Radial clearance Δr [mm].
        preload_n: Bearing preload [N] (0 for the general hinge).
        amplitude_n: Stated force amplitude Fg [N].
        loop: The recorded loop, or None for an η-only row.
        replicate: Replicate number, or None.
        rate_mm_per_min: Crosshead rate [mm/min], or None.
        temperature_c: Test temperature [°C], or None.
        eta: Loss factor stated by an η-only table, or None.
    """

    case_id: str
    hinge: str
    clearance_mm: float
    preload_n: float
    amplitude_n: float
    loop: Loop | None = None
    replicate: int | None = None
    rate_mm_per_min: float | None = None
    temperature_c: float | None = None
    eta: float | None = None

    @property
    def design_point(self) -> tuple[str, float, float, float]:
        """(hinge, clearance [mm], preload [N], amplitude [N]): replicates share it."""
        return (self.hinge, self.clearance_mm, self.preload_n, self.amplitude_n)


@dataclass(frozen=True)
class MeasurementSet:
    """All cases of one measurement folder.

    Attributes:
        cases: The cases in file order.
        root: The folder (or table file) they were read from.
    """

    cases: tuple[Case, ...]
    root: Path

    def by_id(self) -> dict[str, Case]:
        """Return case_id → case."""
        return {c.case_id: c for c in self.cases}

    def replicate_groups(self) -> dict[tuple[str, float, float, float], tuple[str, ...]]:
        """Return design point → case ids of the cases measured there."""
        groups: dict[tuple[str, float, float, float], list[str]] = {}
        for c in self.cases:
            groups.setdefault(c.design_point, []).append(c.case_id)
        return {k: tuple(v) for k, v in groups.items()}


# --------------------------------------------------------------------------- tables


@dataclass(frozen=True)
class _Table:
    """Rows of a CSV file as strings, with where each row came from."""

    path: Path
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    lines: tuple[int, ...]  # 1-based line number of each row in the file

    def where(self, i: int, column: str) -> str:
        return f"{self.path}: row {i + 1} (line {self.lines[i]}), column {column}"


def _read_table(path: Path) -> _Table:
    """Read a plain CSV: the first non-empty line is the header; blank lines are skipped."""
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    with open(path, newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
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
                raise DataError(
                    f"{path}: line {line_no} has {len(cells)} fields, the header has {len(header)}"
                )
            rows.append(cells)
            lines.append(line_no)
    if header is None:
        raise DataError(f"{path}: empty file")
    dupes = sorted({h for h in header if header.count(h) > 1})
    if dupes:
        raise DataError(f"{path}: duplicate column(s) {dupes}")
    return _Table(path, header, tuple(rows), tuple(lines))


def _find_column(
    table: _Table, quantity: str, units: Mapping[str, float]
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


def _require_column(table: _Table, quantity: str, units: Mapping[str, float]) -> tuple[str, float]:
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


def _number(table: _Table, i: int, column: str) -> float:
    return _finite(table.rows[i][table.header.index(column)], table.where(i, column))


def _column(table: _Table, column: str, factor: float) -> FloatArray:
    return np.array([_number(table, i, column) for i in range(len(table.rows))]) * factor


def _optional(table: _Table, i: int, col: tuple[str, float] | None) -> float | None:
    if col is None or table.rows[i][table.header.index(col[0])] == "":
        return None
    return _number(table, i, col[0]) * col[1]


# --------------------------------------------------------------------------- loops


def read_loop_csv(path: Path | str) -> Loop:
    """Read a plain loop CSV (``force_<unit>, displacement_<unit>[, time_<unit>]``).

    Args:
        path: The file.

    Returns:
        The loop in N, mm, s.

    Raises:
        DataError: Missing column, unknown unit, non-numeric or non-finite value,
            fewer than 4 samples.
    """
    table = _read_table(Path(path))
    f_col = _require_column(table, "force", FORCE_UNITS)
    d_col = _require_column(table, "displacement", LENGTH_UNITS)
    t_col = _find_column(table, "time", TIME_UNITS)
    known = {f_col[0], d_col[0]} | ({t_col[0]} if t_col else set())
    extra = [h for h in table.header if h not in known]
    if extra:
        raise DataError(
            f"{table.path}: unexpected column(s) {extra}; a loop has force_<unit>, "
            "displacement_<unit> and optionally time_<unit>"
        )
    if len(table.rows) < 4:
        raise DataError(f"{table.path}: a loop needs at least 4 rows, got {len(table.rows)}")
    return Loop(
        _column(table, *f_col),
        _column(table, *d_col),
        None if t_col is None else _column(table, *t_col),
        str(table.path),
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
    ms, min); any other unit is refused by name. Numbers may use thousands separators.

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
        lines = [[c.strip() for c in row] for row in csv.reader(fh)]
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
            np.array([_bluehill_number(path, line, row, j, lines[start][j]) for line, row in data])
            * table[unit]
        )
    if len(data) < 4:
        raise DataError(f"{path}: a loop needs at least 4 data lines, got {len(data)}")
    return Loop(columns["force"], columns["displacement"], columns.get("time"), str(path))


def _bluehill_number(path: Path, line: int, row: Sequence[str], j: int, name: str) -> float:
    if j >= len(row):
        raise DataError(f"{path}: line {line}, column {name}: missing value")
    return _finite(row[j].replace(",", ""), f"{path}: line {line}, column {name}", row[j])


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
    return read_loop_csv(path)


def check_amplitude(loop: Loop, amplitude_n: float, where: str) -> None:
    """Check that a loop reaches ±Fg within AMPLITUDE_TOL and does not overshoot by OVERSHOOT_TOL.

    Args:
        loop: The loop.
        amplitude_n: Stated amplitude Fg [N].
        where: What to name in the error (file, case).

    Raises:
        DataError: Naming the case, the stated and the reached force.
    """
    F, _, f0, _ = remove_offsets(loop.force_n, loop.displacement_mm)
    lo, hi = float(F.min()), float(F.max())
    reach = (1 - AMPLITUDE_TOL) * amplitude_n
    if hi < reach or lo > -reach:
        raise DataError(
            f"{where}: the loop never reaches the stated amplitude ±{amplitude_n:g} N within "
            f"{AMPLITUDE_TOL:.0%}: its force spans [{lo:.4g}, {hi:.4g}] N "
            f"(offset {f0:.3g} N removed)"
        )
    over = (1 + OVERSHOOT_TOL) * amplitude_n
    if hi > over or lo < -over:
        raise DataError(
            f"{where}: the loop overshoots the stated amplitude ±{amplitude_n:g} N by more than "
            f"{OVERSHOOT_TOL:.0%}: its force spans [{lo:.4g}, {hi:.4g}] N"
        )


# --------------------------------------------------------------------------- sets

CASE_COLUMNS = ("case_id", "hinge", "clearance_mm", "preload_N", "amplitude_N", "loop_file")
OPTIONAL_CASE_COLUMNS = ("replicate", "rate_mm_per_min", "temperature_C")


def read_measurement_set(folder: Path | str) -> MeasurementSet:
    """Read a measurement folder (``cases.csv`` + loop files, or ``eta.csv``), or an η table file.

    Every loop is checked: readable, finite, reaching the stated amplitude, and split
    into the stages 0 → +Fg → −Fg → +Fg.

    Args:
        folder: The folder, or the path of an η-only table.

    Returns:
        The cases, in file order.

    Raises:
        DataError: Naming file, row and column of the first problem found.
    """
    root = Path(folder)
    if root.is_file():
        return read_eta_table(root)
    if not root.is_dir():
        raise DataError(f"{root}: no such measurement folder")
    if not (root / "cases.csv").is_file():
        if (root / "eta.csv").is_file():
            return read_eta_table(root / "eta.csv")
        raise DataError(f"{root}: no cases.csv (or eta.csv) in the measurement folder")
    table = _read_table(root / "cases.csv")
    allowed = CASE_COLUMNS + OPTIONAL_CASE_COLUMNS
    missing = [c for c in CASE_COLUMNS if c not in table.header]
    if missing:
        raise DataError(
            f"{table.path}: missing column(s) {missing}; columns are {list(table.header)}"
        )
    unknown = [h for h in table.header if h not in allowed]
    if unknown:
        raise DataError(f"{table.path}: unknown column(s) {unknown}; allowed: {list(allowed)}")
    cases: list[Case] = []
    seen: dict[str, int] = {}
    for i, row in enumerate(table.rows):
        cell = dict(zip(table.header, row, strict=True))
        case_id = cell["case_id"]
        if not case_id:
            raise DataError(f"{table.where(i, 'case_id')}: empty case_id")
        if case_id in seen:
            raise DataError(
                f"{table.where(i, 'case_id')}: duplicate case_id {case_id!r} (first in row {seen[case_id] + 1})"
            )
        seen[case_id] = i
        cases.append(_case_from_row(table, i, cell, root))
    if not cases:
        raise DataError(f"{table.path}: no cases")
    return MeasurementSet(tuple(cases), root)


def _case_from_row(table: _Table, i: int, cell: dict[str, str], root: Path) -> Case:
    hinge = cell["hinge"]
    if hinge not in HINGE_KINDS:
        raise DataError(
            f"{table.where(i, 'hinge')}: hinge must be one of {HINGE_KINDS}, got {hinge!r}"
        )
    values = {c: _number(table, i, c) for c in ("clearance_mm", "preload_N", "amplitude_N")}
    for c, v in values.items():
        if v < 0 or (c == "amplitude_N" and v == 0):
            raise DataError(
                f"{table.where(i, c)}: must be {'> 0' if c == 'amplitude_N' else '≥ 0'}, got {v:g}"
            )
    loop_file = cell["loop_file"]
    if not loop_file:
        raise DataError(f"{table.where(i, 'loop_file')}: empty loop_file")
    loop_path = root / loop_file
    if not loop_path.is_file():
        raise DataError(f"{table.where(i, 'loop_file')}: loop file {loop_path} not found")
    loop = read_loop_file(loop_path)
    where = f"{loop_path} (case {cell['case_id']!r}, {table.path.name} row {i + 1})"
    check_amplitude(loop, values["amplitude_N"], where)
    process_loop(loop.force_n, loop.displacement_mm, where)  # refuses a record without the stages
    replicate = None
    if cell.get("replicate", ""):
        r = _number(table, i, "replicate")
        if r != int(r) or r < 0:
            raise DataError(f"{table.where(i, 'replicate')}: must be a whole number ≥ 0, got {r:g}")
        replicate = int(r)
    rate = _optional(table, i, ("rate_mm_per_min", 1.0) if "rate_mm_per_min" in cell else None)
    temp = _optional(table, i, ("temperature_C", 1.0) if "temperature_C" in cell else None)
    return Case(
        case_id=cell["case_id"],
        hinge=hinge,
        clearance_mm=values["clearance_mm"],
        preload_n=values["preload_N"],
        amplitude_n=values["amplitude_N"],
        loop=loop,
        replicate=replicate,
        rate_mm_per_min=rate,
        temperature_c=temp,
    )


def read_eta_table(path: Path | str, *, hinge: str = "general") -> MeasurementSet:
    """Read an η-only table (``clearance_mm, preload_N, amplitude_N, eta``), like the paper's Table 1.

    ``clearance_mm`` or ``preload_N`` may be absent (the paper's general-hinge table has
    no preload, its bearing-hinge table no clearance); an absent one is 0 for every row.
    Other columns (``num``, a reference value) are kept out of the cases but allowed.
    Case ids are ``row<N>`` with N the 1-based data row.

    Args:
        path: The table.
        hinge: Hinge kind of every row.

    Raises:
        DataError: Missing ``amplitude_N``/``eta`` or both design columns, a non-numeric
            or non-finite value, η outside (0, 1], a negative design value.
    """
    table = _read_table(Path(path))
    if hinge not in HINGE_KINDS:
        raise DataError(f"{table.path}: hinge must be one of {HINGE_KINDS}, got {hinge!r}")
    missing = [c for c in ("amplitude_N", "eta") if c not in table.header]
    if "clearance_mm" not in table.header and "preload_N" not in table.header:
        missing.append("clearance_mm or preload_N")
    if missing:
        raise DataError(
            f"{table.path}: missing column(s) {missing}; columns are {list(table.header)}"
        )
    cases = []
    for i in range(len(table.rows)):
        v = {
            c: _number(table, i, c) if c in table.header else 0.0
            for c in ("clearance_mm", "preload_N", "amplitude_N", "eta")
        }
        if not 0 < v["eta"] <= 1:
            raise DataError(f"{table.where(i, 'eta')}: η must be in (0, 1], got {v['eta']:g}")
        for c in ("clearance_mm", "preload_N", "amplitude_N"):
            if v[c] < 0 or (c == "amplitude_N" and v[c] == 0):
                raise DataError(
                    f"{table.where(i, c)}: must be {'> 0' if c == 'amplitude_N' else '≥ 0'}, got {v[c]:g}"
                )
        cases.append(
            Case(
                case_id=f"row{i + 1}",
                hinge=hinge,
                clearance_mm=v["clearance_mm"],
                preload_n=v["preload_N"],
                amplitude_n=v["amplitude_N"],
                eta=v["eta"],
            )
        )
    if not cases:
        raise DataError(f"{table.path}: no rows")
    return MeasurementSet(tuple(cases), Path(path))
