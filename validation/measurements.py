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

A **displacement-controlled** case (a rig that drives ±δ, as ``hingelab import-records``
writes) says so in the optional columns ``control`` (``force``, the default, or
``displacement``) and ``amplitude_mm`` (the controlled amplitude δ_a); its loop file is
one cycle +δ → −δ → +δ, measured by ``validation.rig_cycles.process_displacement_cycle``,
and its ``amplitude_N`` is the force amplitude the rig measured (a result, not a set
point). Columns ``cond_<name>_<unit>`` (``cond_band_tension_N``) carry test conditions
that are no hinge kind's design variable (``Case.conditions``). Files without these
columns read as before.

A force-controlled loop must reach the stated amplitude: after removing the force offset (see
``validation.loops.loading_start``: a record cut mid-cycle is measured from the midpoint
of its peaks, not from its first force), ``max F ≥ (1 − AMPLITUDE_TOL)·Fg`` and ``min F ≤ −(1 − AMPLITUDE_TOL)·Fg``,
and it must not overshoot by more than ``OVERSHOOT_TOL`` (which would mean the stated
amplitude is wrong).
"""

from __future__ import annotations

import types
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cad.errors import DataError, ParameterError
from fe.kinds import DEFAULT_KIND, hinge_kind, kind_names
from validation.loop_files import (
    Loop,
    Table,
    read_loop_file,
    read_table,
    table_number,
    table_optional,
)
from validation.loops import ProcessedLoop, loading_start, process_loop
from validation.rig_cycles import check_displacement_amplitude, process_displacement_cycle
from validation.rig_mapping import CONDITION_PREFIX, Control

__all__ = [
    "AMPLITUDE_TOL",
    "CASE_COLUMNS",
    "OPTIONAL_CASE_COLUMNS",
    "OVERSHOOT_TOL",
    "Case",
    "MeasurementSet",
    "check_amplitude",
    "design_columns",
    "process_case_loop",
    "read_eta_table",
    "read_measurement_set",
]

AMPLITUDE_TOL = 0.02
"""A loop must reach ±Fg within this fraction (load frames under force control reach the
set point to well under 1 %; 2 % leaves room for noise and slow sampling at the peaks)."""

OVERSHOOT_TOL = 0.10
"""A loop whose peaks exceed ±Fg by more than this fraction is refused."""


def design_columns() -> dict[str, tuple[str, str]]:
    """Column (``clearance_mm``, ``preload_N``) → (kind, design variable name), over every kind.

    A cases.csv or η table names a point's design values by these columns; which of them
    a case uses depends on its hinge kind (``fe.kinds``).
    """
    out: dict[str, tuple[str, str]] = {}
    for name in kind_names():
        for v in hinge_kind(name).design_variables:
            out.setdefault(v.column, (name, v.name))
    return out


@dataclass(frozen=True)
class Case:
    """One test: a design point, its protocol and its loop (or its η only).

    Attributes:
        case_id: Unique name of the test.
        hinge: Hinge kind (a registered kind name: ``general``, ``bearing``, ...).
        values: The kind's design variables (``fe.kinds.DesignVariable.name`` → value,
            e.g. ``{"clearance_mm": 0.1}``).
        amplitude_n: Stated force amplitude Fg [N].
        loop: The recorded loop, or None for an η-only row.
        replicate: Replicate number, or None.
        rate_mm_per_min: Crosshead rate [mm/min], or None.
        temperature_c: Test temperature [°C], or None.
        eta: Loss factor stated by an η-only table, or None.
        control: What the rig controlled (force, or displacement: then ``amplitude_n`` is
            the measured force amplitude and ``amplitude_mm`` the controlled one).
        amplitude_mm: Controlled displacement amplitude δ_a [mm], or None.
        conditions: Test conditions that are no kind's design variable (column without
            the ``cond_`` prefix → value, e.g. ``{"band_tension_N": 133.4}``).
    """

    case_id: str
    hinge: str
    values: Mapping[str, float]
    amplitude_n: float
    loop: Loop | None = None
    replicate: int | None = None
    rate_mm_per_min: float | None = None
    temperature_c: float | None = None
    eta: float | None = None
    control: Control = Control.FORCE
    amplitude_mm: float | None = None
    conditions: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("values", "conditions"):
            mapping = getattr(self, name)
            object.__setattr__(self, name, types.MappingProxyType(dict(sorted(mapping.items()))))

    def __reduce__(self) -> tuple[Any, ...]:  # mappingproxy does not pickle
        return (
            _case,
            (
                self.case_id, self.hinge, dict(self.values), self.amplitude_n, self.loop,
                self.replicate, self.rate_mm_per_min, self.temperature_c, self.eta,
                self.control, self.amplitude_mm, dict(self.conditions),
            ),
        )  # fmt: skip

    @property
    def design_point(self) -> tuple[Any, ...]:
        """(hinge, (name, value) pairs, controlled amplitude): replicates share it.

        The amplitude is Fg [N] under force control, δ_a [mm] under displacement control;
        test conditions, when there are any, follow the design values.
        """
        pairs = tuple(self.values.items()) + tuple(self.conditions.items())
        if self.control is Control.DISPLACEMENT:
            return (self.hinge, pairs, ("amplitude_mm", self.amplitude_mm))
        return (self.hinge, pairs, self.amplitude_n)

    def describe(self) -> str:
        """The design values in words, e.g. ``Δr = 0.1 mm`` (the kind's symbols and units)."""
        variables = {v.name: v for v in hinge_kind(self.hinge).design_variables}
        return ", ".join(variables[k].text(v) for k, v in self.values.items())


def _case(*args: Any) -> Case:
    return Case(*args)


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

    def replicate_groups(self) -> dict[tuple[Any, ...], tuple[str, ...]]:
        """Return design point (``Case.design_point``) → case ids of the cases measured there."""
        groups: dict[tuple[Any, ...], list[str]] = {}
        for c in self.cases:
            groups.setdefault(c.design_point, []).append(c.case_id)
        return {k: tuple(v) for k, v in groups.items()}


def process_case_loop(case: Case) -> ProcessedLoop:
    """Process a case's loop as its control mode asks.

    Force control: ``validation.loops.process_loop``; displacement control:
    ``validation.rig_cycles.process_displacement_cycle``.

    Raises:
        DataError: If the case has no loop (an η-only row), or as the processing does.
    """
    if case.loop is None:
        raise DataError(f"case {case.case_id!r}: no loop (an η-only row)")
    loop = case.loop
    if case.control is Control.DISPLACEMENT:
        return process_displacement_cycle(loop.force_n, loop.displacement_mm, loop.source)
    return process_loop(loop.force_n, loop.displacement_mm, loop.source)


# --------------------------------------------------------------------------- amplitude


def check_amplitude(loop: Loop, amplitude_n: float, where: str) -> None:
    """Check that a loop reaches ±Fg within AMPLITUDE_TOL and does not overshoot by OVERSHOOT_TOL.

    Args:
        loop: The loop.
        amplitude_n: Stated amplitude Fg [N].
        where: What to name in the error (file, case).

    Raises:
        DataError: Naming the case, the stated and the reached force.
    """
    start = loading_start(loop.force_n, loop.displacement_mm)
    F = loop.force_n - start.force_offset_n
    lo, hi = float(F.min()), float(F.max())
    reach = (1 - AMPLITUDE_TOL) * amplitude_n
    if hi < reach or lo > -reach:
        raise DataError(
            f"{where}: the loop never reaches the stated amplitude ±{amplitude_n:g} N within "
            f"{AMPLITUDE_TOL:.0%}: its force spans [{lo:.4g}, {hi:.4g}] N "
            f"({start.describe()})"
        )
    over = (1 + OVERSHOOT_TOL) * amplitude_n
    if hi > over or lo < -over:
        raise DataError(
            f"{where}: the loop overshoots the stated amplitude ±{amplitude_n:g} N by more than "
            f"{OVERSHOOT_TOL:.0%}: its force spans [{lo:.4g}, {hi:.4g}] N"
        )


# --------------------------------------------------------------------------- sets

CASE_COLUMNS = ("case_id", "hinge", "amplitude_N", "loop_file")
"""Columns every cases.csv has; besides them, the design columns of its cases' kinds
(``clearance_mm`` for the general hinge, ``preload_N`` for the bearing hinge)."""
OPTIONAL_CASE_COLUMNS = (
    "replicate", "rate_mm_per_min", "temperature_C", "control", "amplitude_mm",
)  # fmt: skip
"""Optional columns; besides them, test conditions ``cond_<name>_<unit>`` (``Case.conditions``)."""


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
    table = read_table(root / "cases.csv")
    allowed = CASE_COLUMNS + tuple(design_columns()) + OPTIONAL_CASE_COLUMNS
    missing = [c for c in CASE_COLUMNS if c not in table.header]
    if missing:
        raise DataError(
            f"{table.path}: missing column(s) {missing}; columns are {list(table.header)}"
        )
    unknown = [h for h in table.header if h not in allowed and not _is_condition(h)]
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


def _is_condition(column: str) -> bool:
    return column.startswith(CONDITION_PREFIX) and len(column) > len(CONDITION_PREFIX)


def _control(table: Table, i: int, cell: dict[str, str]) -> tuple[Control, float | None]:
    """The row's control mode and, under displacement control, its amplitude_mm."""
    text = cell.get("control", "") or Control.FORCE.value
    try:
        control = Control(text)
    except ValueError:
        raise DataError(
            f"{table.where(i, 'control')}: must be one of {[c.value for c in Control]}, got {text!r}"
        ) from None
    if control is Control.FORCE:
        return control, None
    if "amplitude_mm" not in table.header:
        raise DataError(
            f"{table.path}: missing column amplitude_mm (row {i + 1} is displacement-controlled)"
        )
    amp = table_number(table, i, "amplitude_mm")
    if amp <= 0:
        raise DataError(f"{table.where(i, 'amplitude_mm')}: must be > 0, got {amp:g}")
    return control, amp


def _design_values(table: Table, i: int, hinge: str) -> dict[str, float]:
    """The kind's design values of row ``i``; another kind's column must be empty or 0."""
    kind = hinge_kind(hinge)
    own = {v.column: v.name for v in kind.design_variables}
    values = {}
    for column, (other, _name) in design_columns().items():
        if column not in table.header and column in own:
            raise DataError(
                f"{table.path}: missing column {column!r}, a design variable of the "
                f"{kind.title} (row {i + 1})"
            )
        if column not in table.header:
            continue
        present = table.rows[i][table.header.index(column)].strip() != ""
        value = table_number(table, i, column) if present or column in own else 0.0
        if value < 0:
            raise DataError(f"{table.where(i, column)}: must be ≥ 0, got {value:g}")
        if column in own:
            values[own[column]] = value
        elif value != 0.0:
            raise DataError(
                f"{table.where(i, column)}: {column} = {value:g}, but the {kind.title} has "
                f"no {column} (it belongs to the {other} hinge)"
            )
    return values


def _hinge_of(table: Table, i: int, hinge: str) -> str:
    try:
        return hinge_kind(hinge).name
    except ParameterError as err:
        raise DataError(f"{table.where(i, 'hinge')}: {err}") from err


def _case_from_row(table: Table, i: int, cell: dict[str, str], root: Path) -> Case:
    hinge = _hinge_of(table, i, cell["hinge"])
    design = _design_values(table, i, hinge)
    values = {"amplitude_N": table_number(table, i, "amplitude_N")}
    if values["amplitude_N"] <= 0:
        raise DataError(
            f"{table.where(i, 'amplitude_N')}: must be > 0, got {values['amplitude_N']:g}"
        )
    loop_file = cell["loop_file"]
    if not loop_file:
        raise DataError(f"{table.where(i, 'loop_file')}: empty loop_file")
    loop_path = root / loop_file
    if not loop_path.is_file():
        raise DataError(f"{table.where(i, 'loop_file')}: loop file {loop_path} not found")
    loop = read_loop_file(loop_path)
    where = f"{loop_path} (case {cell['case_id']!r}, {table.path.name} row {i + 1})"
    control, amplitude_mm = _control(table, i, cell)
    if control is Control.DISPLACEMENT:
        check_displacement_amplitude(loop, amplitude_mm or 0.0, where)
        process_displacement_cycle(loop.force_n, loop.displacement_mm, where)
    else:
        check_amplitude(loop, values["amplitude_N"], where)
        # refuses a record without the stages
        process_loop(loop.force_n, loop.displacement_mm, where)
    replicate = None
    if cell.get("replicate", ""):
        r = table_number(table, i, "replicate")
        if r != int(r) or r < 0:
            raise DataError(f"{table.where(i, 'replicate')}: must be a whole number ≥ 0, got {r:g}")
        replicate = int(r)
    rate = table_optional(table, i, ("rate_mm_per_min", 1.0) if "rate_mm_per_min" in cell else None)
    temp = table_optional(table, i, ("temperature_C", 1.0) if "temperature_C" in cell else None)
    return Case(
        case_id=cell["case_id"],
        hinge=hinge,
        values=design,
        amplitude_n=values["amplitude_N"],
        loop=loop,
        replicate=replicate,
        rate_mm_per_min=rate,
        temperature_c=temp,
        control=control,
        amplitude_mm=amplitude_mm,
        conditions={
            h[len(CONDITION_PREFIX) :]: table_number(table, i, h)
            for h in table.header
            if _is_condition(h)
        },
    )


def read_eta_table(
    path: Path | str, *, hinge: str | None = None, eta_column: str = "eta"
) -> MeasurementSet:
    """Read an η-only table (``clearance_mm, preload_N, amplitude_N, eta``), like the paper's Table 1.

    The design columns are those of the rows' kind; a kind's column may be absent (the
    paper's general-hinge table has no preload column, its bearing-hinge table no
    clearance column): then it is the model's own value (0 by default). Other columns
    (``num``, a reference value) are kept out of the cases but allowed. Case ids are
    ``row<N>`` with N the 1-based data row.

    Args:
        path: The table.
        hinge: Hinge kind of every row; None: the kind whose design columns the table has
            (the general hinge when none or several fit).
        eta_column: The column that holds η (``eta_fe`` in the paper's Table 1).

    Raises:
        DataError: Missing ``amplitude_N``/``eta`` or every design column, a non-numeric
            or non-finite value, η outside (0, 1], a negative design value.
    """
    table = read_table(Path(path))
    columns = design_columns()
    present = [c for c in columns if c in table.header]
    if hinge is None:
        owners = {columns[c][0] for c in present}
        hinge = owners.pop() if len(owners) == 1 else DEFAULT_KIND
    try:
        kind = hinge_kind(hinge)
    except ParameterError as err:
        raise DataError(f"{table.path}: {err}") from err
    own = {v.column: v.name for v in kind.design_variables}
    missing = [c for c in ("amplitude_N", eta_column) if c not in table.header]
    if own and not any(c in table.header for c in own):
        missing.append(" or ".join(own))
    if missing:
        raise DataError(
            f"{table.path}: missing column(s) {missing}; columns are {list(table.header)}"
        )
    cases = []
    for i in range(len(table.rows)):
        v = {c: table_number(table, i, c) for c in ("amplitude_N", eta_column)}
        if not 0 < v[eta_column] <= 1:
            raise DataError(
                f"{table.where(i, eta_column)}: η must be in (0, 1], got {v[eta_column]:g}"
            )
        if v["amplitude_N"] <= 0:
            raise DataError(
                f"{table.where(i, 'amplitude_N')}: must be > 0, got {v['amplitude_N']:g}"
            )
        design = {}
        for column in present:
            x = table_number(table, i, column)
            if x < 0:
                raise DataError(f"{table.where(i, column)}: must be ≥ 0, got {x:g}")
            if column in own:
                design[own[column]] = x
            elif x != 0.0:
                raise DataError(
                    f"{table.where(i, column)}: {column} = {x:g}, but the {kind.title} has no {column}"
                )
        cases.append(
            Case(
                case_id=f"row{i + 1}",
                hinge=kind.name,
                values=design,
                amplitude_n=v["amplitude_N"],
                eta=v[eta_column],
            )
        )
    if not cases:
        raise DataError(f"{table.path}: no rows")
    return MeasurementSet(tuple(cases), Path(path))
