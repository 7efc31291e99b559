"""The paper's published values as the validation workflow reads them (no FE here)."""

from __future__ import annotations

import csv
from importlib import resources
from pathlib import Path

import pytest

from studies.paper.validation import SUBSET, TABLE1, TEST_POINT, _subset, data_file
from validation.measurements import read_eta_table


def test_table1_eta_is_the_papers_table_as_printed():
    data = read_eta_table(data_file(TABLE1))
    assert len(data.cases) == 25
    assert {c.values["clearance_mm"] for c in data.cases} == {0.0, 0.1, 0.2, 0.3, 0.4}
    assert {c.amplitude_n for c in data.cases} == {100.0, 200.0, 300.0, 400.0, 500.0}
    rsm_copy = Path(str(resources.files("rsm") / "data" / "paper_table1_general_hinge.csv"))
    with rsm_copy.open() as f:
        printed = {
            (float(r["clearance_mm"]), float(r["amplitude_N"])): float(r["eta_fe"])
            for r in csv.DictReader(f)
        }
    for c in data.cases:  # the two copies in the project must agree
        assert c.eta == printed[(c.values["clearance_mm"], c.amplitude_n)]


def test_test_point_and_subset():
    (point,) = read_eta_table(data_file(TEST_POINT)).cases
    assert (point.values["clearance_mm"], point.amplitude_n, point.eta) == (
        0.0,
        400.0,
        pytest.approx(0.0933),
    )
    sub = _subset(read_eta_table(data_file(TABLE1)), SUBSET)
    assert sorted((c.values["clearance_mm"], c.amplitude_n) for c in sub.cases) == sorted(SUBSET)
