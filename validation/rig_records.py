"""Read one test rig's record file through a mapping (``validation.rig_mapping``).

``read_record`` reads a JSON or CSV record, converts time, force and displacement to s, N,
mm, applies the sign flips, checks the record (finite, time increasing, long enough) and
reads its design variables from the file name and the metadata. Every problem raises one
``DataError`` line naming the file, the column (as the mapping names it: ``column 2
(force)``) and the problem.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from cad.errors import DataError
from validation.loop_files import read_table
from validation.rig_mapping import (
    PROJECT_UNITS,
    QUANTITY_UNITS,
    ColumnSpec,
    RigMapping,
    unit_factor,
)

FloatArray = npt.NDArray[np.float64]

MIN_SAMPLES = 16
"""A record shorter than this cannot hold a cycle worth splitting."""


@dataclass(frozen=True, eq=False)
class RigRecord:
    """One record in project units.

    Attributes:
        path: The file.
        time_s: Time, shape (n,) [s], strictly increasing.
        force_n: Force, shape (n,) [N].
        displacement_mm: Displacement, shape (n,) [mm].
        design: Design variable name → value in its project unit (``band_tension`` → N).
    """

    path: Path
    time_s: FloatArray
    force_n: FloatArray
    displacement_mm: FloatArray
    design: dict[str, float] = field(default_factory=dict)


def read_record(path: Path | str, mapping: RigMapping) -> RigRecord:
    """Read one record file through ``mapping``.

    Args:
        path: The record file.
        mapping: How its columns, units and name map to the project's.

    Returns:
        The record in s, N, mm with its design variables.

    Raises:
        DataError: Naming the file, the column and the problem: file missing or not
            JSON/CSV, rows key or column missing, unknown unit, non-numeric or non-finite
            value, time not increasing, too short, design variable not in the name or
            metadata.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    raw, metadata = (
        _read_json(path, mapping) if mapping.format == "json" else _read_csv(path, mapping)
    )
    values = {}
    for quantity, spec in mapping.columns.items():
        unit = (
            spec.unit
            if spec.unit is not None
            else _meta_unit(path, metadata, spec.unit_key, spec.label)
        )
        factor = unit_factor(unit, PROJECT_UNITS[QUANTITY_UNITS[quantity]], f"{path}: {spec.label}")
        a = raw[quantity] * factor
        values[quantity] = -a if spec.flip else a
    n = values["time"].size
    if n < MIN_SAMPLES:
        raise DataError(f"{path}: too short: {n} rows, a record needs at least {MIN_SAMPLES}")
    t = values["time"]
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        k = int(back[0]) + 1
        raise DataError(
            f"{path}: row {k + 1}, {mapping.columns['time'].label}: time does not increase "
            f"({t[k - 1]:g} s, then {t[k]:g} s)"
        )
    return RigRecord(
        path, t, values["force"], values["displacement"], _design(path, metadata, mapping)
    )


def _meta_unit(path: Path, metadata: dict[str, Any], key: str | None, label: str) -> str:
    value = metadata.get(key or "")
    if not isinstance(value, str) or not value:
        raise DataError(f"{path}: {label}: its unit's metadata key {key!r} is missing or empty")
    return value


def _read_json(path: Path, mapping: RigMapping) -> tuple[dict[str, FloatArray], dict[str, Any]]:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise DataError(f"{path}: not a JSON file: {err}") from None
    if not isinstance(doc, dict):
        raise DataError(f"{path}: expected a JSON object with key {mapping.rows_key!r}")
    rows = doc.get(mapping.rows_key or "")
    if not isinstance(rows, list):
        raise DataError(
            f"{path}: key {mapping.rows_key!r} (source.rows) missing or not a list of rows"
        )
    if len(rows) < MIN_SAMPLES:
        raise DataError(
            f"{path}: too short: {len(rows)} rows, a record needs at least {MIN_SAMPLES}"
        )
    width = 1 + max(s.index or 0 for s in mapping.columns.values())
    for i, row in enumerate(rows):
        if not isinstance(row, list) or len(row) < width:
            n = len(row) if isinstance(row, list) else 0
            missing = [s.label for s in mapping.columns.values() if (s.index or 0) >= n]
            raise DataError(
                f"{path}: row {i + 1}: missing {', '.join(missing)} (the row has {n} values)"
            )
    specs = list(mapping.columns.values())
    try:
        whole = np.array(rows)  # float64 when every value is a number (the fast path)
    except ValueError:  # rows of unequal length
        whole = np.zeros(0)
    if whole.dtype == np.float64 and whole.ndim == 2:
        table = whole[:, [s.index or 0 for s in specs]]
    else:
        table = _slow_table(path, rows, specs)
    cols = {q: table[:, k] for k, q in enumerate(mapping.columns)}
    for q, a in cols.items():
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise DataError(
                f"{path}: row {bad[0] + 1}, {mapping.columns[q].label}: not a finite number ({a[bad[0]]})"
            )
    return cols, {k: v for k, v in doc.items() if k != mapping.rows_key}


def _slow_table(path: Path, rows: list[Any], specs: list[ColumnSpec]) -> FloatArray:
    """The mapped columns value by value, naming the first value that is not a number."""
    try:
        return np.array([[_number(r[s.index or 0]) for s in specs] for r in rows], dtype=np.float64)
    except (TypeError, ValueError):
        for i, r in enumerate(rows):
            for s in specs:
                try:
                    _number(r[s.index or 0])
                except (TypeError, ValueError):
                    raise DataError(
                        f"{path}: row {i + 1}, {s.label}: not a number: {r[s.index or 0]!r}"
                    ) from None
        raise


def _number(value: Any) -> float:
    """A JSON number (not a bool, not a string); NaN passes and is caught as not finite."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(value)
    return float(value)


def _read_csv(path: Path, mapping: RigMapping) -> tuple[dict[str, FloatArray], dict[str, Any]]:
    table = read_table(path)
    cols = {}
    for quantity, spec in mapping.columns.items():
        if spec.name not in table.header:
            raise DataError(f"{path}: missing {spec.label}; the header has {list(table.header)}")
        j = table.header.index(spec.name or "")
        a = np.empty(len(table.rows))
        for i, row in enumerate(table.rows):
            text = row[j].replace(",", ".") if table.decimal_comma else row[j]
            try:
                a[i] = float(text)
            except ValueError:
                raise DataError(
                    f"{table.where(i, repr(spec.name))} ({quantity}): not a number: {row[j]!r}"
                ) from None
            if not math.isfinite(a[i]):
                raise DataError(
                    f"{table.where(i, repr(spec.name))} ({quantity}): not a finite number: {row[j]!r}"
                )
        cols[quantity] = a
    return cols, {}


def _design(path: Path, metadata: dict[str, Any], mapping: RigMapping) -> dict[str, float]:
    match = mapping.name_pattern.search(path.name) if mapping.name_pattern is not None else None
    out = {}
    for spec in mapping.design:
        if spec.group is not None:
            if match is None:
                pattern = mapping.name_pattern.pattern if mapping.name_pattern else ""
                raise DataError(
                    f"{path}: the file name does not match name.pattern {pattern!r} of "
                    f"{mapping.path} (design variable {spec.name})"
                )
            text: Any = match.group(spec.group)
            where = f"{path}: design variable {spec.name} (file-name group {spec.group!r})"
        else:
            text = metadata.get(spec.key or "")
            where = f"{path}: design variable {spec.name} (metadata key {spec.key!r})"
        try:
            value = float(text)
        except (TypeError, ValueError):
            raise DataError(f"{where}: not a number: {text!r}") from None
        if not math.isfinite(value):
            raise DataError(f"{where}: not a finite number: {text!r}")
        out[spec.name] = value * spec.factor
    return out
