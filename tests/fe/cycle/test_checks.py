"""A cycle's own convergence checks (fe.cycle.checks) and their words (studies.convergence).

The cycles are the driver's slider (tests/fe/cycle/test_driver.py), whose energy balance
closes to round-off; a balance error or cut-backs are put in by hand, so the expected
finding is known exactly.
"""

from __future__ import annotations

import dataclasses

import pytest

from fe.cycle.checks import ENERGY_BALANCE_TOL, convergence_findings
from fe.cycle.driver import drive
from model.store import ResultStore
from studies.convergence import DOUBLED_TOL, IncrementCheck, check_point, warning_lines
from tests.fe.cycle.test_driver import SliderStep, settings


@pytest.fixture(scope="module")
def clean():
    s = settings()
    return drive(SliderStep(s), s)


def _lossy(result, factor: float):
    """The cycle with every friction work scaled: the balance is off by |1 − factor|."""
    incs = tuple(dataclasses.replace(i, friction_work=factor * i.friction_work)
                 for i in result.increments)  # fmt: skip
    return dataclasses.replace(result, increments=incs)


def test_a_balanced_cycle_without_cutbacks_has_no_finding(clean):
    assert clean.metrics()["energy_balance_rel_err"] < 1e-13
    assert convergence_findings(clean) == []
    assert warning_lines(clean) == []


@pytest.mark.parametrize(
    ("clearance", "setting", "current"),
    [(0.0, "increments_per_stage", 10), (0.1, "clearance_increments", 60)],
    ids=["no-clearance", "clearance"],
)
def test_a_balance_worse_than_the_tolerance_names_the_measured_value_and_the_option(
    clean, clearance, setting, current
):
    bad = dataclasses.replace(_lossy(clean, 1.03), clearance_mm=clearance)
    (f,) = convergence_findings(bad)
    assert (f.kind, f.setting, f.current) == ("energy_balance", setting, current)
    assert f.value == pytest.approx(0.03, rel=1e-9)
    (line,) = warning_lines(bad)
    assert "closes only to 3 %" in line
    assert f"raise --increments (MODEL.toml [cycle] {setting}" in line
    assert line.endswith(f"above {current}")
    # just inside the tolerance: nothing
    assert convergence_findings(_lossy(clean, 1 + 0.9 * ENERGY_BALANCE_TOL)) == []


def test_many_recovered_cutbacks_say_to_raise_the_increments_few_do_not(clean):
    n = len(clean.increments)
    few = dataclasses.replace(clean, cutbacks=((3, 2),))
    assert convergence_findings(few) == []
    many = dataclasses.replace(clean, cutbacks=tuple((k, 1) for k in range(n // 10 + 1)))
    (f,) = convergence_findings(many)
    assert (f.kind, f.value) == ("cutbacks", n // 10 + 1)
    assert f"{n // 10 + 1} of {n} increments" in warning_lines(many)[0]


def test_the_store_keeps_the_cutbacks(clean, tmp_path):
    store = ResultStore(tmp_path)
    store.put("k", dataclasses.replace(clean, cutbacks=((4, 1), (9, 3))))
    back = store.get("k")
    assert back is not None
    assert back.cutbacks == ((4, 1), (9, 3))
    assert back.n_cutbacks == 4


def test_doubled_check_verdict_and_message():
    ok = IncrementCheck("c0.100_F300", "clearance_increments", 60, 0.001132, 0.001122, 0.8)
    assert ok.change_rel == pytest.approx(0.010 / 1.122, rel=1e-9)
    assert ok.converged
    assert "raise" not in ok.message()
    bad = IncrementCheck("c0.100_F300", "clearance_increments", 12, 0.00157, 0.001242, 0.3)
    assert bad.change_rel > DOUBLED_TOL
    assert not bad.converged
    assert "with 24 (26 % change" in bad.message()
    assert bad.message().endswith("clearance_increments) above 12")


def test_the_checked_point_is_the_clearance_point_of_the_largest_amplitude(clean):
    from model.spec import DesignPoint

    play = dataclasses.replace(clean, clearance_mm=0.1)
    pts = [(DesignPoint(a, {"clearance_mm": c}), play if c else clean)
           for c in (0.0, 0.1, 0.2) for a in (200.0, 400.0)]  # fmt: skip
    assert check_point(pts) == 5  # Δr 0.2, 400 N (the last geometry of the sweep)
    assert check_point(pts[:2]) is None  # no clearance: nothing to check
