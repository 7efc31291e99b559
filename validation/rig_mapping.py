r"""A test rig's file layout as data: the mapping file (``rig.toml``) and its units.

A mapping says how one rig's record files map onto hingelab's measurement format
(``validation.measurements``), so that ``validation.rig_import`` reads any rig's files the
same way (no rig is a special case)::

    [source]
    format = "json"            # "json": an object whose `rows` key holds a list of rows;
                               # "csv": a header line, then one sample per line
    rows = "data"              # json: the key that holds the rows
    glob = "*.json"            # files read when a SOURCE given on the command line is a folder
    hinge = "general"          # the hinge kind the records are compared with (cases.csv `hinge`)
    control = "displacement"   # "displacement" (cycles ±δ, replicates) or "force"

    [columns.time]             # time, force and displacement are required
    index = 0                  # json rows: the 0-based position in a row
    unit = "s"                 # any unit pint knows (kip, lbf, kN, in, um, ms, ...)
    [columns.displacement]
    index = 1
    unit_key = "displacement units"   # or: read the unit from the file's metadata key
    flip = false               # true: multiply by −1 (the rig's sign convention is opposite)
    [columns.force]
    name = "Load (kN)"         # csv: the header of the column (instead of index)
    unit = "kN"

    [name]                     # design variables from the file name: a regex, named groups
    pattern = '(?P<band_tension>[\d.]+)lbtension'

    [design.band_tension]      # one table per design variable
    group = "band_tension"     # from the file name's group (default: the table's name), or
    # key = "sampling freq"    # from the file's metadata key
    unit = "lbf"               # the unit it is written in
    to = "N"                   # the unit hingelab stores: one of PROJECT_UNITS

    [constants]                # design values the files do not carry (cases.csv columns)
    clearance_mm = 0.0

    [cycles]
    steady_tolerance = 0.02    # keep cycles whose peak-to-peak is within this of the steady one

A design variable ``<name>`` with ``to = <unit>`` becomes the cases.csv column
``<name>_<unit>`` when that is a design column of a hinge kind (``clearance_mm``), else the
test-condition column ``cond_<name>_<unit>`` (``cond_band_tension_N``).

Units are parsed with pint and converted to the project's mm, N, s at reading (never in a
numerical loop). Every problem raises ``DataError`` naming the mapping file, the key and
the value.
"""

from __future__ import annotations

import functools
import re
import tomllib
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

from cad.errors import DataError

__all__ = [
    "CONDITION_PREFIX",
    "PROJECT_UNITS",
    "ColumnSpec",
    "Control",
    "DesignSpec",
    "RigMapping",
    "parse_mapping",
    "read_mapping",
    "unit_factor",
]

CONDITION_PREFIX = "cond_"
"""Prefix of a cases.csv column that holds a test condition, not a kind's design variable."""

PROJECT_UNITS: dict[str, str] = {
    "mm": "millimeter",
    "N": "newton",
    "s": "second",
    "Hz": "hertz",
    "MPa": "megapascal",
    "deg": "degree",
    "C": "degC",
    "mm_per_s": "millimeter / second",
}
"""Units a design variable may be stored in (``to``) → their pint spelling."""

QUANTITY_UNITS: dict[str, str] = {"time": "s", "force": "N", "displacement": "mm"}
"""The three record columns and the project unit each is converted to."""

DEFAULT_STEADY_TOLERANCE = 0.02
"""Default tolerance on a cycle's peak-to-peak against the steady one (the ARTS records
reach the steady stroke to 0.1 %; their first full-stroke cycles start 3 % short, still in
the ramp)."""


class Control(Enum):
    """What the rig controls: the force (0 → +Fg → −Fg → +Fg) or the displacement (±δ sine)."""

    FORCE = "force"
    DISPLACEMENT = "displacement"


@functools.cache
def _registry() -> Any:
    import pint  # imported here: building the registry takes ~0.5 s, only an import needs it

    return pint.UnitRegistry()


def unit_factor(unit: str, target: str, where: str) -> float:
    """Return the factor from ``unit`` to ``target`` (``value_target = factor · value_unit``).

    Args:
        unit: The unit as the user wrote it (``kip``, ``in``, ``lbf``), parsed by pint.
        target: The pint spelling of the project unit (``newton``, ``millimeter``).
        where: What to name in an error (mapping file and key).

    Raises:
        DataError: An unknown unit, an offset unit (°F), or a unit of another dimension
            (``lb`` is a mass in pint: a force in pounds is ``lbf``).
    """
    import pint

    ureg = _registry()
    try:
        q = ureg.Quantity(1.0, unit)
        t = ureg.Quantity(1.0, target)
    except (pint.errors.PintError, AttributeError, TypeError, ValueError, SyntaxError) as err:
        raise DataError(f"{where}: unknown unit {unit!r} ({err})") from None
    if q.dimensionality != t.dimensionality:
        hint = " (pint reads 'lb' as a mass: write 'lbf' for pound-force)" if unit == "lb" else ""
        raise DataError(
            f"{where}: unit {unit!r} is {q.dimensionality}, expected a unit of "
            f"{t.dimensionality} like {target!r}{hint}"
        )
    if ureg.Quantity(0.0, unit).to(target).magnitude != 0.0:  # degF → degC: not a factor
        raise DataError(f"{where}: unit {unit!r} has an offset (like degF): give it in {target}")
    return float(q.to(target).magnitude)


@dataclass(frozen=True)
class ColumnSpec:
    """Where one record quantity is and how to convert it.

    Attributes:
        quantity: ``time``, ``force`` or ``displacement``.
        index: 0-based position in a JSON row, or None.
        name: CSV header of the column, or None.
        unit: The unit, or None when it is read from the file's metadata.
        unit_key: Metadata key holding the unit (JSON files), or None.
        flip: Multiply by −1 after conversion.
    """

    quantity: str
    index: int | None = None
    name: str | None = None
    unit: str | None = None
    unit_key: str | None = None
    flip: bool = False

    @property
    def label(self) -> str:
        """How to name the column in messages (``column 2 (force)``, ``column 'Load' (force)``)."""
        at = f"{self.index}" if self.index is not None else repr(self.name)
        return f"column {at} ({self.quantity})"


@dataclass(frozen=True)
class DesignSpec:
    """One design variable read from the file name or the file's metadata.

    Attributes:
        name: Its name (the cases.csv column is ``<name>_<to>`` or ``cond_<name>_<to>``).
        group: The file-name regex group, or None.
        key: The metadata key, or None.
        unit: The unit it is written in.
        to: The project unit it is stored in (a key of ``PROJECT_UNITS``).
        factor: ``unit`` → ``to``.
    """

    name: str
    group: str | None
    key: str | None
    unit: str
    to: str
    factor: float

    @property
    def column(self) -> str:
        """The column name without the condition prefix (``band_tension_N``)."""
        return f"{self.name}_{self.to}"


@dataclass(frozen=True)
class RigMapping:
    """A parsed mapping file (see the module docstring).

    Attributes:
        path: The mapping file (for messages), or a description.
        format: ``json`` or ``csv``.
        rows_key: JSON key of the rows (``data``).
        glob: Pattern of the files read from a folder.
        hinge: Hinge kind name written into cases.csv.
        control: What the rig controls.
        columns: ``time``/``force``/``displacement`` → where and in which unit.
        name_pattern: Regex matched (``re.search``) against the file name, or None.
        design: The design variables.
        constants: Fixed cases.csv values (column → value).
        steady_tolerance: Relative tolerance on a cycle's peak-to-peak (displacement
            control) against the steady peak-to-peak.
    """

    path: str
    format: str
    rows_key: str | None
    glob: str
    hinge: str
    control: Control
    columns: dict[str, ColumnSpec]
    name_pattern: re.Pattern[str] | None
    design: tuple[DesignSpec, ...] = ()
    constants: dict[str, float] = field(default_factory=dict)
    steady_tolerance: float = DEFAULT_STEADY_TOLERANCE


def read_mapping(path: Path | str) -> RigMapping:
    """Read and check a mapping file (TOML).

    Raises:
        DataError: An unreadable file, bad TOML, or any problem ``parse_mapping`` finds.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: mapping file not found")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise DataError(f"{path}: not valid TOML: {err}") from None
    return parse_mapping(data, str(path))


_TOP_KEYS = {"source", "columns", "name", "design", "constants", "cycles"}


def _table(data: dict[str, Any], key: str, where: str) -> dict[str, Any]:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise DataError(f"{where}: [{key}] must be a table, got {value!r}")
    return value


def _only(table: dict[str, Any], allowed: set[str], where: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise DataError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")


def _text(table: dict[str, Any], key: str, where: str, default: str | None = None) -> str | None:
    value = table.get(key, default)
    if value is not None and (not isinstance(value, str) or not value):
        raise DataError(f"{where}.{key}: must be a non-empty string, got {value!r}")
    return value


def parse_mapping(data: dict[str, Any], path: str) -> RigMapping:
    """Check a mapping's TOML content and build the ``RigMapping``.

    Args:
        data: The parsed TOML.
        path: The file it came from (named in errors).

    Raises:
        DataError: Naming the file, the key and the bad value.
    """
    _only(data, _TOP_KEYS, path)
    source = _table(data, "source", path)
    _only(source, {"format", "rows", "glob", "hinge", "control"}, f"{path}: [source]")
    fmt = _text(source, "format", f"{path}: source", "csv")
    if fmt not in ("json", "csv"):
        raise DataError(f"{path}: source.format must be 'json' or 'csv', got {fmt!r}")
    rows_key = _text(source, "rows", f"{path}: source")
    if fmt == "json" and rows_key is None:
        raise DataError(f"{path}: source.rows (the JSON key holding the rows) is required for json")
    control_text = _text(source, "control", f"{path}: source", "force")
    try:
        control = Control(control_text)
    except ValueError:
        raise DataError(
            f"{path}: source.control must be one of {[c.value for c in Control]}, got {control_text!r}"
        ) from None
    columns = _parse_columns(_table(data, "columns", path), fmt, path)
    pattern, design = _parse_design(data, path)
    return RigMapping(
        path=path,
        format=fmt,
        rows_key=rows_key,
        glob=_text(source, "glob", f"{path}: source", f"*.{fmt}") or "*",
        hinge=_text(source, "hinge", f"{path}: source", "general") or "general",
        control=control,
        columns=columns,
        name_pattern=pattern,
        design=design,
        constants=_parse_constants(_table(data, "constants", path), path),
        steady_tolerance=_parse_cycles(_table(data, "cycles", path), path),
    )


def _parse_columns(table: dict[str, Any], fmt: str, path: str) -> dict[str, ColumnSpec]:
    _only(table, set(QUANTITY_UNITS), f"{path}: [columns]")
    out = {}
    for quantity, target in QUANTITY_UNITS.items():
        where = f"{path}: columns.{quantity}"
        spec = table.get(quantity)
        if not isinstance(spec, dict):
            raise DataError(f"{where}: missing (a table with index or name, and unit or unit_key)")
        _only(spec, {"index", "name", "unit", "unit_key", "flip"}, where)
        index, name = spec.get("index"), _text(spec, "name", where)
        if fmt == "json" and (not isinstance(index, int) or isinstance(index, bool) or index < 0):
            raise DataError(
                f"{where}.index: a JSON row position must be an integer ≥ 0, got {index!r}"
            )
        if fmt == "csv" and name is None:
            raise DataError(f"{where}.name: a CSV column is named by its header; name is missing")
        unit, unit_key = _text(spec, "unit", where), _text(spec, "unit_key", where)
        if (unit is None) == (unit_key is None):
            raise DataError(f"{where}: give exactly one of unit and unit_key")
        if unit_key is not None and fmt != "json":
            raise DataError(f"{where}.unit_key: only JSON files carry metadata; give unit")
        if unit is not None:
            unit_factor(unit, PROJECT_UNITS[target], f"{where}.unit")
        flip = spec.get("flip", False)
        if not isinstance(flip, bool):
            raise DataError(f"{where}.flip: must be true or false, got {flip!r}")
        out[quantity] = ColumnSpec(
            quantity, index if fmt == "json" else None, name, unit, unit_key, flip
        )
    return out


def _parse_design(
    data: dict[str, Any], path: str
) -> tuple[re.Pattern[str] | None, tuple[DesignSpec, ...]]:
    name = _table(data, "name", path)
    _only(name, {"pattern"}, f"{path}: [name]")
    text = _text(name, "pattern", f"{path}: name")
    pattern = None
    if text is not None:
        try:
            pattern = re.compile(text)
        except re.error as err:
            raise DataError(
                f"{path}: name.pattern: not a valid regular expression: {err}"
            ) from None
    specs = []
    for var, spec in _table(data, "design", path).items():
        where = f"{path}: design.{var}"
        if not isinstance(spec, dict):
            raise DataError(f"{where}: must be a table (group or key, unit, to)")
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", var):
            raise DataError(f"{where}: a design variable's name must be a plain identifier")
        _only(spec, {"group", "key", "unit", "to"}, where)
        key = _text(spec, "key", where)
        group = _text(spec, "group", where, None if key is not None else var)
        if group is not None and key is not None:
            raise DataError(f"{where}: give group (file name) or key (metadata), not both")
        if group is not None and (pattern is None or group not in pattern.groupindex):
            known = sorted(pattern.groupindex) if pattern else []
            raise DataError(
                f"{where}.group: {group!r} is not a named group of name.pattern (groups: {known})"
            )
        to = _text(spec, "to", where)
        if to not in PROJECT_UNITS:
            raise DataError(f"{where}.to: must be one of {list(PROJECT_UNITS)}, got {to!r}")
        unit = _text(spec, "unit", where, to) or to
        factor = unit_factor(unit, PROJECT_UNITS[to], f"{where}.unit")
        specs.append(DesignSpec(var, group, key, unit, to, factor))
    return pattern, tuple(specs)


def _parse_constants(table: dict[str, Any], path: str) -> dict[str, float]:
    out = {}
    for key, value in table.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise DataError(f"{path}: constants.{key}: must be a number, got {value!r}")
        out[key] = float(value)
    return out


def _parse_cycles(table: dict[str, Any], path: str) -> float:
    _only(table, {"steady_tolerance"}, f"{path}: [cycles]")
    tol = table.get("steady_tolerance", DEFAULT_STEADY_TOLERANCE)
    if isinstance(tol, bool) or not isinstance(tol, int | float) or not 0 < tol < 0.5:
        raise DataError(f"{path}: cycles.steady_tolerance must be in (0, 0.5), got {tol!r}")
    return float(tol)
