"""The rig mapping file (validation.rig_mapping): parsing, units, design variables."""

from __future__ import annotations

import copy
import math
import re
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cad.errors import DataError
from validation.rig_mapping import Control, parse_mapping, read_mapping, unit_factor

EXAMPLE = Path(__file__).resolve().parents[2] / "studies" / "examples" / "rig_arts_brfd.toml"

BASE: dict[str, Any] = {
    "source": {"format": "json", "rows": "data", "control": "displacement", "hinge": "general"},
    "columns": {
        "time": {"index": 0, "unit": "ms"},
        "displacement": {"index": 1, "unit": "in", "flip": True},
        "force": {"index": 2, "unit_key": "force units"},
    },
    "name": {"pattern": r"T(?P<tension>[\d.]+)lb_A(?P<amp>[\d.]+)in"},
    "design": {
        "tension": {"unit": "lbf", "to": "N"},
        "amplitude": {"group": "amp", "unit": "in", "to": "mm"},
        "rate": {"key": "sampling", "unit": "kHz", "to": "Hz"},
    },
    "constants": {"clearance_mm": 0.0},
    "cycles": {"steady_tolerance": 0.03},
}


def _with(path: str, value: Any) -> dict[str, Any]:
    """BASE with one key set (``a.b.c``); value None deletes it."""
    data = copy.deepcopy(BASE)
    *head, last = path.split(".")
    node = data
    for k in head:
        node = node[k]
    if value is None:
        del node[last]
    else:
        node[last] = value
    return data


def test_a_full_mapping_parses_into_its_parts() -> None:
    m = parse_mapping(copy.deepcopy(BASE), "rig.toml")
    assert m.control is Control.DISPLACEMENT
    assert (m.format, m.rows_key, m.hinge, m.glob) == ("json", "data", "general", "*.json")
    assert m.columns["displacement"].flip
    assert not m.columns["force"].flip
    assert m.columns["force"].unit_key == "force units"
    by_name = {d.name: d for d in m.design}
    assert by_name["tension"].factor == pytest.approx(4.4482216152605, rel=1e-12)
    assert by_name["amplitude"].group == "amp"
    assert by_name["amplitude"].factor == pytest.approx(25.4, rel=1e-12)
    assert by_name["rate"].key == "sampling"
    assert by_name["rate"].factor == pytest.approx(1000.0, rel=1e-12)
    assert by_name["tension"].column == "tension_N"
    assert m.steady_tolerance == 0.03
    assert m.constants == {"clearance_mm": 0.0}


def test_the_arts_example_mapping_reads() -> None:
    m = read_mapping(EXAMPLE)
    assert m.control is Control.DISPLACEMENT
    assert {d.column for d in m.design} == {
        "frequency_Hz", "band_tension_N", "nominal_amplitude_mm", "sampling_rate_Hz",
    }  # fmt: skip
    match = m.name_pattern.search("1Hz30lbtension1.5amplitude.json")
    assert match is not None
    assert match.group("band_tension") == "30"


@pytest.mark.parametrize(
    ("unit", "target", "factor"),
    [
        ("kip", "newton", 4448.2216152605),  # 1000 lbf, lbf = 0.45359237 kg × 9.80665 m/s²
        ("lbf", "newton", 0.45359237 * 9.80665),
        ("kN", "newton", 1e3),
        ("in", "millimeter", 25.4),
        ("um", "millimeter", 1e-3),
        ("ms", "second", 1e-3),
        ("min", "second", 60.0),
    ],
    ids=["kip", "lbf", "kN", "in", "um", "ms", "min"],
)
def test_unit_factors_match_their_definitions(unit: str, target: str, factor: float) -> None:
    assert unit_factor(unit, target, "x") == pytest.approx(factor, rel=1e-12)


@pytest.mark.parametrize(
    ("unit", "target", "message"),
    [
        ("lb", "newton", "write 'lbf' for pound-force"),
        ("furlongz", "millimeter", "unknown unit 'furlongz'"),
        ("kip", "millimeter", "expected a unit of [length]"),
        ("degF", "degC", "has an offset"),
    ],
    ids=["lb-is-a-mass", "unknown", "wrong-dimension", "offset"],
)
def test_bad_units_are_refused_by_name(unit: str, target: str, message: str) -> None:
    with pytest.raises(DataError, match=re.escape(message)) as err:
        unit_factor(unit, target, "rig.toml: columns.force.unit")
    assert str(err.value).startswith("rig.toml: columns.force.unit: ")


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        ("source.format", "xlsx", "source.format must be 'json' or 'csv', got 'xlsx'"),
        ("source.rows", None, "source.rows (the JSON key holding the rows) is required"),
        ("source.control", "velocity", "source.control must be one of"),
        ("source.colour", "red", "unknown key(s) ['colour']"),
        ("columns.force", None, "columns.force: missing"),
        (
            "columns.time.index",
            -1,
            "columns.time.index: a JSON row position must be an integer ≥ 0, got -1",
        ),
        ("columns.time.unit_key", "t", "columns.time: give exactly one of unit and unit_key"),
        ("columns.time.unit", "kg", "columns.time.unit: unit 'kg' is [mass]"),
        ("columns.displacement.flip", "yes", "columns.displacement.flip: must be true or false"),
        ("name.pattern", "(?P<x", "name.pattern: not a valid regular expression"),
        (
            "design.amplitude.group",
            "amplitude",
            "design.amplitude.group: 'amplitude' is not a named group",
        ),
        ("design.tension.to", "lbf", "design.tension.to: must be one of"),
        ("design.tension.unit", "lb", "design.tension.unit: unit 'lb' is [mass]"),
        (
            "design.rate.group",
            "amp",
            "design.rate: give group (file name) or key (metadata), not both",
        ),
        ("constants.clearance_mm", "zero", "constants.clearance_mm: must be a number, got 'zero'"),
        ("cycles.steady_tolerance", 0.7, "cycles.steady_tolerance must be in (0, 0.5), got 0.7"),
    ],
    ids=lambda v: str(v)[:24],
)
def test_each_bad_mapping_entry_gets_one_line_naming_it(
    path: str, value: Any, message: str
) -> None:
    with pytest.raises(DataError, match=re.escape(message)) as err:
        parse_mapping(_with(path, value), "rig.toml")
    assert str(err.value).startswith("rig.toml: ")
    assert "\n" not in str(err.value)


def test_a_csv_column_needs_a_name_and_no_metadata_unit() -> None:
    data = _with("source.format", "csv")
    with pytest.raises(
        DataError, match=re.escape("columns.time.name: a CSV column is named by its header")
    ):
        parse_mapping(data, "rig.toml")
    for q, name in (("time", "t"), ("displacement", "x"), ("force", "F")):
        data["columns"][q]["name"] = name
    with pytest.raises(
        DataError, match=re.escape("columns.force.unit_key: only JSON files carry metadata")
    ):
        parse_mapping(data, "rig.toml")


def test_a_mapping_file_that_is_not_toml_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "rig.toml"
    bad.write_text("[source\nformat = json\n", encoding="utf-8")
    with pytest.raises(DataError, match=r"rig\.toml: not valid TOML"):
        read_mapping(bad)
    with pytest.raises(DataError, match="mapping file not found"):
        read_mapping(tmp_path / "none.toml")


PREFIXES = {"": 1.0, "k": 1e3, "m": 1e-3, "u": 1e-6, "M": 1e6}


@settings(max_examples=60, deadline=None)
@given(
    prefix=st.sampled_from(sorted(PREFIXES)),
    base=st.sampled_from([("N", "newton", 1.0), ("m", "millimeter", 1e3), ("s", "second", 1.0)]),
)
def test_si_prefixes_scale_by_their_power_of_ten(prefix: str, base: tuple[str, str, float]) -> None:
    symbol, target, to_project = base
    assert unit_factor(prefix + symbol, target, "x") == pytest.approx(
        PREFIXES[prefix] * to_project, rel=1e-12
    )


@settings(max_examples=60, deadline=None)
@given(
    tension=st.floats(0, 1e4, allow_nan=False).map(lambda v: round(v, 3)),
    amp=st.floats(1e-3, 1e3, allow_nan=False).map(lambda v: round(v, 4)),
)
def test_design_values_in_the_file_name_convert_to_project_units(
    tension: float, amp: float
) -> None:
    from validation.rig_records import _design

    m = parse_mapping(_with("design.rate", None), "rig.toml")
    name = Path(f"T{tension!r}lb_A{amp!r}in.json")
    values = _design(name, {}, m)
    assert values["tension"] == pytest.approx(tension * 4.4482216152605, rel=1e-12)
    assert values["amplitude"] == pytest.approx(amp * 25.4, rel=1e-12)
    assert math.isfinite(values["tension"])
