"""The energy yardstick of a displacement-controlled grid (issue 34): what a straight line predicts.

For a friction device the simplest model of the energy per cycle is a Coulomb rectangle
with a fixed lost travel b: ``W = 4 F_s (δ_a − b)``, a straight line in the amplitude δ_a
for each slip force (here: each band tension). ``energy_yardstick`` measures

* per record (the steady cycles of one file, replicates of one design point): the
  energy per cycle ``W_k = ∮ F dδ`` of each steady cycle, their mean and their scatter
  ``max_k |W_k / W̄ − 1|``;
* leave-one-amplitude-out: in each group of records that share a condition (the band
  tension), a straight line ``W̄(δ_a)`` through the other records predicts the left-out
  one; the relative error ``W_pred / W̄ − 1`` per record and its RMS over the grid.

A model that is to beat this line must predict the left-out record better than its RMS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import DataError
from validation.measurements import MeasurementSet, process_case_loop
from validation.rig_mapping import Control

FloatArray = npt.NDArray[np.float64]

__all__ = ["LooRow", "RecordEnergy", "Yardstick", "energy_yardstick", "format_yardstick"]


@dataclass(frozen=True)
class RecordEnergy:
    """The steady cycles of one record (one design point).

    Attributes:
        case_ids: Its cases (one per steady cycle).
        group: The value of the grouping condition (e.g. band tension [N]).
        x: The amplitude the line uses [mm] (measured ``amplitude_mm`` or a condition).
        energies_nmm: Energy per steady cycle, shape (n_cycles,) [N·mm].
    """

    case_ids: tuple[str, ...]
    group: float
    x: float
    energies_nmm: FloatArray

    @property
    def mean_nmm(self) -> float:
        """Mean energy per cycle W̄ [N·mm]."""
        return float(np.mean(self.energies_nmm))

    @property
    def scatter(self) -> float:
        """Largest relative deviation of a cycle's energy from the mean, ``max |W_k/W̄ − 1|``."""
        return float(np.max(np.abs(self.energies_nmm / self.mean_nmm - 1.0)))


@dataclass(frozen=True)
class LooRow:
    """One left-out record: measured and predicted mean energy per cycle.

    Attributes:
        record: The record left out.
        predicted_nmm: The line through the group's other records at its x [N·mm].
    """

    record: RecordEnergy
    predicted_nmm: float

    @property
    def error(self) -> float:
        """Relative error ``W_pred / W̄ − 1``."""
        return self.predicted_nmm / self.record.mean_nmm - 1.0


@dataclass(frozen=True)
class Yardstick:
    """The yardstick of a grid.

    Attributes:
        by: The grouping condition (``band_tension_N``).
        x: The amplitude column of the line (``amplitude_mm`` or a condition).
        records: Every record, in the set's order.
        rows: One leave-one-out row per record of a group with ≥ 3 records.
    """

    by: str
    x: str
    records: tuple[RecordEnergy, ...]
    rows: tuple[LooRow, ...]

    @property
    def rms_error(self) -> float:
        """RMS of the leave-one-out relative errors (NaN without rows)."""
        if not self.rows:
            return math.nan
        return float(np.sqrt(np.mean([r.error**2 for r in self.rows])))

    @property
    def max_scatter(self) -> float:
        """Largest cycle-to-cycle scatter of any record."""
        return max(r.scatter for r in self.records)


def _value(
    case_conditions: dict[str, float], amplitude_mm: float | None, name: str, cid: str
) -> float:
    if name == "amplitude_mm" and amplitude_mm is not None:
        return amplitude_mm
    if name not in case_conditions:
        raise DataError(
            f"case {cid!r}: no condition {name!r} (its conditions: {sorted(case_conditions)})"
        )
    return case_conditions[name]


def record_energies(
    mset: MeasurementSet, by: str, x: str = "amplitude_mm"
) -> tuple[RecordEnergy, ...]:
    """Group the displacement-controlled cases by design point and measure their cycles.

    Args:
        mset: A measurement set with displacement-controlled cases (``import-records``).
        by: The condition that groups records into lines (``band_tension_N``).
        x: ``amplitude_mm`` (the measured amplitude) or a condition (``nominal_amplitude_mm``).

    Raises:
        DataError: No displacement-controlled case, or a missing condition.
    """
    cases = mset.by_id()
    out = []
    for ids in mset.replicate_groups().values():
        first = cases[ids[0]]
        if first.control is not Control.DISPLACEMENT:
            continue
        cond = dict(first.conditions)
        energies = np.array([process_case_loop(cases[c]).metrics.W_cycle_Nmm for c in ids])
        out.append(
            RecordEnergy(
                ids,
                _value(cond, first.amplitude_mm, by, first.case_id),
                _value(cond, first.amplitude_mm, x, first.case_id),
                energies,
            )
        )
    if not out:
        raise DataError(f"{mset.root}: no displacement-controlled case (control = displacement)")
    return tuple(out)


def energy_yardstick(mset: MeasurementSet, by: str, x: str = "amplitude_mm") -> Yardstick:
    """Energy per cycle per record and the straight line's leave-one-amplitude-out error.

    Args:
        mset: The measurement set.
        by: The condition whose levels each get their own line (``band_tension_N``).
        x: The amplitude of the line (see ``record_energies``).

    Returns:
        The yardstick; a group with fewer than 3 records gets no leave-one-out rows (a
        line through one point predicts nothing).
    """
    records = record_energies(mset, by, x)
    rows = []
    for level in sorted({r.group for r in records}):
        group = [r for r in records if r.group == level]
        if len(group) < 3:
            continue
        for left in group:
            others = [r for r in group if r is not left]
            slope, intercept = np.polyfit([r.x for r in others], [r.mean_nmm for r in others], 1)
            rows.append(LooRow(left, float(slope * left.x + intercept)))
    return Yardstick(by, x, records, tuple(rows))


def format_yardstick(y: Yardstick) -> str:
    """The yardstick as a text table (one row per record; energies in J)."""
    lines = [
        f"{y.by:>16} {y.x:>22} {'cycles':>6} {'W_mean J':>9} {'scatter':>8} "
        f"{'W_line J':>9} {'error':>7}"
    ]
    loo = {id(r.record): r for r in y.rows}
    for r in sorted(y.records, key=lambda r: (r.group, r.x)):
        row = loo.get(id(r))
        pred = f"{row.predicted_nmm / 1e3:9.1f} {row.error:+7.1%}" if row else f"{'':>9} {'':>7}"
        lines.append(
            f"{r.group:16.4g} {r.x:22.4g} {r.energies_nmm.size:6d} {r.mean_nmm / 1e3:9.1f} "
            f"{r.scatter:8.1%} {pred}"
        )
    lines.append(
        f"leave-one-amplitude-out RMS error {y.rms_error:.1%} over {len(y.rows)} records; "
        f"largest cycle scatter {y.max_scatter:.1%}"
    )
    return "\n".join(lines)
