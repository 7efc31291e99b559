"""The paper's published values as the validation workflow reads them (no FE here)."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from studies.paper.validation import SUBSET, _subset, measured_point, table1_set

SHARED = Path(__file__).resolve().parents[4] / "shared" / "reference"


def test_table1_eta_is_the_papers_table_as_printed():
    data = table1_set()
    assert len(data.cases) == 25
    assert {c.values["clearance_mm"] for c in data.cases} == {0.0, 0.1, 0.2, 0.3, 0.4}
    assert {c.amplitude_n for c in data.cases} == {100.0, 200.0, 300.0, 400.0, 500.0}
    assert data.cases[1].eta == 0.109  # row 2 as printed: Δr 0, 200 N
    if not SHARED.is_dir():
        pytest.skip(f"{SHARED} is absent (a fresh clone): the copy is checked where it exists")
    with (SHARED / "paper_table1_general_hinge.csv").open() as f:
        printed = {
            (float(r["clearance_mm"]), float(r["amplitude_N"])): float(r["eta_fe"])
            for r in csv.DictReader(f)
        }
    for c in data.cases:  # the project's copy is the reference's
        assert c.eta == printed[(c.values["clearance_mm"], c.amplitude_n)]


def test_test_point_and_subset():
    (point,) = measured_point().cases
    assert (point.values["clearance_mm"], point.amplitude_n, point.eta) == (0.0, 400.0, 0.0933)
    sub = _subset(table1_set(), SUBSET)
    assert sorted((c.values["clearance_mm"], c.amplitude_n) for c in sub.cases) == sorted(SUBSET)
