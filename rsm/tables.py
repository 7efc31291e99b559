"""Read and validate the CSV tables that response surfaces are fitted to.

A table is a CSV file with one header row and one sample point per row. Every
error names the file, and where it can, the line of the file (the header is
line 1, as in an editor or a spreadsheet) and the column, so that a user can go
straight to the bad cell.

Each sample point gets a label that follows it into fits, plots and reports:
``point 17`` when the table has a ``point_id`` column (a trace id, see
:mod:`rsm.trace`; ``hingelab trace DB 17`` then shows its files), otherwise
``row 3`` for the third data row.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from cad.errors import DataError

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Table:
    """A CSV table held as text cells, parsed to numbers column by column on demand.

    Attributes:
        path: The file it was read from.
        columns: Header names in file order.
        rows: The data cells, one tuple per data row, in file order.
        line_numbers: The file line of each data row (the header is line 1).
    """

    path: Path
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    line_numbers: tuple[int, ...]

    @property
    def n_rows(self) -> int:
        """Number of data rows (the header excluded)."""
        return len(self.rows)


@dataclass(frozen=True)
class XY:
    """Sample points taken from a table, ready for fitting.

    Attributes:
        x: Inputs, shape (n_points, n_vars), float64, in the table's units.
        y: Response, shape (n_points,), float64.
        x_names: Column names of ``x``, in column order of ``x``.
        y_name: Column name of ``y``.
        labels: One label per point: ``point <id>`` if the table has a
            ``point_id`` column, otherwise ``row <k>`` for the k-th data row.
    """

    x: FloatArray
    y: FloatArray
    x_names: tuple[str, ...]
    y_name: str
    labels: tuple[str, ...]


def read_table(path: str | Path) -> Table:
    """Read a CSV file with a header row.

    Args:
        path: The CSV file.

    Returns:
        The table with every cell stripped of surrounding blanks.

    Raises:
        FileNotFoundError: If the file does not exist.
        DataError: If the file is empty, a header is blank or repeated, or a row
            has a different number of cells than the header.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"table {p} does not exist")
    with p.open(newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        raw = [(reader.line_num, r) for r in reader if any(cell.strip() for cell in r)]
    if not raw:
        raise DataError(f"{p}: the file is empty (expected a header row)")
    line0, first = raw[0]
    header = tuple(c.strip() for c in first)
    for j, name in enumerate(header):
        if not name:
            raise DataError(f"{p}: line {line0}, column {j + 1}: blank column name")
        if name in header[:j]:
            raise DataError(f"{p}: line {line0}: column name {name!r} appears twice")
    for line, r in raw[1:]:
        if len(r) != len(header):
            raise DataError(f"{p}: line {line} has {len(r)} cells but the header has {len(header)}")
    return Table(
        path=p,
        columns=header,
        rows=tuple(tuple(c.strip() for c in r) for _, r in raw[1:]),
        line_numbers=tuple(line for line, _ in raw[1:]),
    )


def numeric_column(table: Table, name: str) -> FloatArray:
    """Return one column as finite float64 numbers.

    Args:
        table: The table.
        name: Column name.

    Returns:
        The values, shape (n_rows,), float64.

    Raises:
        DataError: If the column is missing (the message lists those present),
            or a cell is not a finite number (the message names row and column).
    """
    if name not in table.columns:
        raise DataError(f"{table.path}: no column {name!r}; columns are {', '.join(table.columns)}")
    j = table.columns.index(name)
    values = np.empty(table.n_rows, dtype=np.float64)
    for i, row in enumerate(table.rows):
        cell = row[j]
        try:
            v = float(cell)
        except ValueError:
            v = math.nan
        if not math.isfinite(v):
            raise DataError(
                f"{table.path}: line {table.line_numbers[i]}, column {name!r}: "
                "expected a finite number, "
                f"got {cell!r}"
            )
        values[i] = v
    return values


def xy_from_table(table: Table, x_names: Sequence[str], y_name: str) -> XY:
    """Extract inputs and response for a fit, checking they can support one.

    Args:
        table: The table.
        x_names: Input column names, in the order the variables x1, x2, ... take.
        y_name: Response column name.

    Returns:
        The sample points.

    Raises:
        DataError: If no input is given, a name repeats, a column is missing or
            holds a non-number, or a column is constant (nothing to fit against).
    """
    if not x_names:
        raise DataError(f"{table.path}: give at least one input column")
    names = (*x_names, y_name)
    for k, name in enumerate(names):
        if name in names[:k]:
            raise DataError(f"{table.path}: column {name!r} is used twice")
    if table.n_rows == 0:
        raise DataError(f"{table.path}: the table has a header but no data rows")
    x = np.column_stack([numeric_column(table, n) for n in x_names])  # (n_points, n_vars)
    y = numeric_column(table, y_name)
    for k, name in enumerate(names):
        col = x[:, k] if k < len(x_names) else y
        if table.n_rows > 1 and np.ptp(col) == 0.0:
            raise DataError(
                f"{table.path}: column {name!r} is constant ({col[0]!r} in every row); "
                "a constant column cannot be fitted"
            )
    if "point_id" in table.columns:
        j = table.columns.index("point_id")
        labels = tuple(f"point {row[j]}" for row in table.rows)
    else:
        labels = tuple(f"row {i + 1}" for i in range(table.n_rows))
    x.setflags(write=False)
    y.setflags(write=False)
    return XY(x=x, y=y, x_names=tuple(x_names), y_name=y_name, labels=labels)


def read_xy(path: str | Path, x_names: Sequence[str], y_name: str) -> XY:
    """Read a CSV table and extract inputs and response (see :func:`xy_from_table`).

    Args:
        path: The CSV file.
        x_names: Input column names.
        y_name: Response column name.

    Returns:
        The sample points.
    """
    return xy_from_table(read_table(path), x_names, y_name)
