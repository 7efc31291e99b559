"""Import a test rig's records into a measurement set (``hingelab import-records``).

``import_records(mapping, sources, out)`` reads every record through the mapping
(``validation.rig_records``), and writes the measurement format of
``validation.measurements`` into ``out``:

* **displacement control**: the force offset of the record's initial rest
  (``validation.loops.remove_offsets``) is removed, the record is cut into cycles
  (``validation.rig_cycles.split_cycles``), ramp-in and ramp-out cycles are dropped and
  each steady cycle becomes one loop file ``loops/<record>_c<k>.csv`` (``time_s, force_N,
  displacement_mm``, the displacement centred on the steady cycles' mid-range) and one
  row of ``cases.csv`` with ``control = displacement``, ``amplitude_mm`` (the record's
  steady half peak-to-peak, shared by its cycles, which are replicates), ``amplitude_N``
  (the record's measured force amplitude, mean over its steady cycles), the kind's design
  columns and the test conditions ``cond_<name>_<unit>``;
* **force control**: the record is one loop file and one case, its ``amplitude_N`` a
  design variable or constant of the mapping.

``import.json`` beside them keeps the provenance: the mapping, each record's cycles
(peak-to-peak, steady or not, energy per cycle) and the offsets removed. The folder is
written in a temporary sibling and renamed when complete, then read back through
``read_measurement_set`` (so what was written is what the measurement reader accepts).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cad.errors import DataError
from fe.kinds import hinge_kind
from validation.loop_files import Loop
from validation.loops import remove_offsets
from validation.measurements import MeasurementSet, design_columns, read_measurement_set
from validation.rig_cycles import (
    CycleSplit,
    cycle_energies,
    process_displacement_cycle,
    split_cycles,
)
from validation.rig_mapping import CONDITION_PREFIX, Control, RigMapping
from validation.rig_records import RigRecord, read_record

__all__ = ["ImportedRecord", "expand_sources", "import_records", "record_cycles"]


@dataclass(frozen=True)
class ImportedRecord:
    """What the import did with one record.

    Attributes:
        record: The record in project units.
        split: Its cycles, or None under force control.
        energies_nmm: Energy per cycle ∮F dδ, shape (n_cycles,) [N·mm], or None.
        force_offset_n: The force offset removed [N].
        case_ids: The cases written for it.
        columns: Its cases.csv values besides case_id, loop_file and replicate.
    """

    record: RigRecord
    split: CycleSplit | None
    energies_nmm: np.ndarray | None
    force_offset_n: float
    case_ids: tuple[str, ...]
    columns: dict[str, float | str]


def expand_sources(sources: Sequence[Path | str], mapping: RigMapping) -> list[Path]:
    """Files to import: each file given, and each folder's files matching ``source.glob``.

    Raises:
        DataError: A source that does not exist, a folder with no matching file, or a
            file given twice.
    """
    out: list[Path] = []
    for s in map(Path, sources):
        if s.is_dir():
            found = sorted(p for p in s.glob(mapping.glob) if p.is_file())
            if not found:
                raise DataError(
                    f"{s}: no file matches source.glob {mapping.glob!r} of {mapping.path}"
                )
            out.extend(found)
        elif s.is_file():
            out.append(s)
        else:
            raise DataError(f"{s}: no such record file or folder")
    seen: set[Path] = set()
    for p in out:
        if p.resolve() in seen:
            raise DataError(f"{p}: given twice")
        seen.add(p.resolve())
    if not out:
        raise DataError("no record file given")
    return out


def record_cycles(
    record: RigRecord, mapping: RigMapping
) -> tuple[CycleSplit, np.ndarray, float, float]:
    """Split a displacement-controlled record: (cycles, energy per cycle [N·mm], force offset [N], centre [mm]).

    The displacement centre is the mean mid-range of the steady cycles.
    """
    where = f"{record.path}: {mapping.columns['displacement'].label}"
    _, _, f0, _ = remove_offsets(record.force_n, record.displacement_mm)
    split = split_cycles(record.displacement_mm, mapping.steady_tolerance, where)
    d = record.displacement_mm
    mids = [0.5 * (d[i : j + 1].max() + d[i : j + 1].min()) for i, j in split.bounds[split.steady]]
    centre = float(np.mean(mids))
    energies = cycle_energies(record.force_n - f0, d - centre, split)
    return split, energies, f0, centre


def _case_columns(record: RigRecord, mapping: RigMapping) -> dict[str, float | str]:
    """The kind's design columns and the conditions of a record (cases.csv column → value)."""
    kind = hinge_kind(mapping.hinge)
    own = {v.column for v in kind.design_variables}
    values: dict[str, float | str] = {"hinge": kind.name}
    given = {s.column: record.design[s.name] for s in mapping.design} | mapping.constants
    all_design = design_columns()
    for column in sorted(own):
        if column not in given:
            raise DataError(
                f"{mapping.path}: the {kind.title} needs design column {column!r}: give it in "
                "[constants] or as a [design] variable"
            )
    for column, value in given.items():
        if column in own or column in ("amplitude_N", "amplitude_mm"):
            values[column] = value
        elif column in all_design:
            raise DataError(
                f"{mapping.path}: {column} is a design variable of the {all_design[column][0]} "
                f"hinge, not of source.hinge = {kind.name!r}"
            )
        else:
            values[CONDITION_PREFIX + column] = value
    return values


def _write_loop(path: Path, t: np.ndarray, F: np.ndarray, d: np.ndarray) -> None:
    rows = np.column_stack([t, F, d])
    with open(path, "w", encoding="utf-8", newline="") as fh:
        fh.write("time_s,force_N,displacement_mm\n")
        np.savetxt(fh, rows, delimiter=",", fmt="%.10g")


def _import_one(
    record: RigRecord, mapping: RigMapping, loops: Path
) -> tuple[ImportedRecord, list[dict[str, Any]]]:
    columns = _case_columns(record, mapping)
    stem = record.path.stem
    rows: list[dict[str, Any]] = []
    if mapping.control is Control.FORCE:
        if "amplitude_N" not in columns:
            raise DataError(
                f"{mapping.path}: a force-controlled record needs amplitude_N ([design] or [constants])"
            )
        _write_loop(loops / f"{stem}.csv", record.time_s, record.force_n, record.displacement_mm)
        rows.append({"case_id": stem, "loop_file": f"loops/{stem}.csv", "replicate": "", **columns})
        return ImportedRecord(record, None, None, 0.0, (stem,), columns), rows
    split, energies, f0, centre = record_cycles(record, mapping)
    F, d = record.force_n - f0, record.displacement_mm - centre
    steady = split.bounds[split.steady]
    columns["control"] = Control.DISPLACEMENT.value
    columns["amplitude_mm"] = 0.5 * float(split.peak_to_peak_mm[split.steady].mean())
    columns["amplitude_N"] = float(np.mean([0.5 * np.ptp(F[i : j + 1]) for i, j in steady]))
    ids = []
    for k in np.flatnonzero(split.steady):
        i, j = split.bounds[k]
        cid = f"{stem}_c{k + 1}"
        where = f"{record.path}: cycle {k + 1} (rows {i + 1}–{j + 1})"
        process_displacement_cycle(F[i : j + 1], d[i : j + 1], where)  # refused here, not on read
        _write_loop(loops / f"{cid}.csv", record.time_s[i : j + 1], F[i : j + 1], d[i : j + 1])
        rows.append(
            {"case_id": cid, "loop_file": f"loops/{cid}.csv", "replicate": int(k + 1), **columns}
        )
        ids.append(cid)
    return ImportedRecord(record, split, energies, f0, tuple(ids), columns), rows


def _cases_csv(rows: list[dict[str, Any]]) -> str:
    first = ["case_id", "hinge"]
    last = ["amplitude_N", "loop_file", "replicate", "control", "amplitude_mm"]
    middle = sorted({k for r in rows for k in r} - set(first) - set(last))
    header = first + sorted(c for c in middle if not c.startswith(CONDITION_PREFIX))
    header += [c for c in last if any(c in r for r in rows)]
    header += sorted(c for c in middle if c.startswith(CONDITION_PREFIX))

    def cell(v: Any) -> str:
        return f"{v:.10g}" if isinstance(v, float) else str(v)

    lines = [",".join(header)] + [",".join(cell(r.get(h, "")) for h in header) for r in rows]
    return "\n".join(lines) + "\n"


def _provenance(mapping: RigMapping, done: list[ImportedRecord]) -> dict[str, Any]:
    records = []
    for r in done:
        entry: dict[str, Any] = {
            "file": str(r.record.path),
            "design": r.record.design,
            "cases": list(r.case_ids),
            "force_offset_N": r.force_offset_n,
        }
        if r.split is not None and r.energies_nmm is not None:
            entry["cycles"] = [
                {"peak_to_peak_mm": float(p), "steady": bool(s), "energy_Nmm": float(e)}
                for p, s, e in zip(
                    r.split.peak_to_peak_mm, r.split.steady, r.energies_nmm, strict=True
                )
            ]
            entry["steady_peak_to_peak_mm"] = r.split.steady_peak_to_peak_mm
        records.append(entry)
    return {
        "generator": "hingelab import-records (validation.rig_import)",
        "mapping": mapping.path,
        "control": mapping.control.value,
        "steady_tolerance": mapping.steady_tolerance,
        "records": records,
    }


def import_records(
    mapping: RigMapping, sources: Sequence[Path | str], out: Path | str
) -> tuple[MeasurementSet, list[ImportedRecord]]:
    """Read the records through the mapping and write them as a measurement set.

    Args:
        mapping: The rig's mapping.
        sources: Record files, or folders (their files matching ``source.glob``).
        out: The measurement folder to write; it must not exist or be empty.

    Returns:
        The measurement set as read back from ``out``, and what was done per record.

    Raises:
        DataError: The first bad record (one line: file, column, problem), or an ``out``
            that already holds files. Nothing is written then.
    """
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise DataError(f"{out}: --out exists and is not an empty folder; choose a new one")
    files = expand_sources(sources, mapping)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=out.parent))
    try:
        (tmp / "loops").mkdir()
        done, rows = [], []
        for f in files:
            imported, case_rows = _import_one(read_record(f, mapping), mapping, tmp / "loops")
            done.append(imported)
            rows.extend(case_rows)
        (tmp / "cases.csv").write_text(_cases_csv(rows), encoding="utf-8")
        text = json.dumps(_provenance(mapping, done), indent=1, default=_json_default)
        (tmp / "import.json").write_text(text + "\n", encoding="utf-8")
        written = read_measurement_set(tmp)  # what was written must read back
        if out.exists():
            out.rmdir()
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return _moved(written, tmp, out), done


def _moved(mset: MeasurementSet, tmp: Path, out: Path) -> MeasurementSet:
    """The set read from the temporary folder, its loops' sources named in ``out``."""
    cases = []
    for c in mset.cases:
        loop = c.loop
        if loop is not None:
            source = str(out / Path(loop.source).relative_to(tmp))
            loop = Loop(loop.force_n, loop.displacement_mm, loop.time_s, source)
        cases.append(dataclasses.replace(c, loop=loop))
    return MeasurementSet(tuple(cases), out)


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    raise TypeError(f"not JSON-serialisable: {value!r}")
