"""The general hinge's solids against closed-form geometry."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from cad.errors import ParameterError
from cad.general import make_general_hinge
from cad.general_params import GeneralHingeParams
from cad.step import read_step_parts, write_step


@pytest.fixture(scope="module")
def params() -> GeneralHingeParams:
    return GeneralHingeParams(clearance_mm=0.2)


@pytest.fixture(scope="module")
def model(params):
    return make_general_hinge(params)


def lug_area(p: GeneralHingeParams, length: float) -> float:
    """Rectangle from the hole centre plus the half-disk end, minus the hole."""
    w = p.lug_width_mm
    return length * w + math.pi * w**2 / 8 - math.pi * p.hole_radius_mm**2


def test_volumes_match_closed_form(model, params):
    p = params
    v = model.volumes_mm3()
    assert v["tang"] == pytest.approx(lug_area(p, p.tang_length_mm) * p.tang_thickness_mm, rel=1e-6)
    arms = 2 * lug_area(p, p.clevis_length_mm) * p.clevis_arm_thickness_mm
    base = p.lug_width_mm * p.clevis_base_mm * p.span_mm
    assert v["clevis"] == pytest.approx(arms + base, rel=1e-6)
    assert v["pin"] == pytest.approx(math.pi * p.pin_radius_mm**2 * p.pin_length, rel=1e-6)


def test_bounding_boxes(model, params):
    bb = model.part("clevis").solid.bounding_box()
    assert pytest.approx(params.clevis_length_mm + params.clevis_base_mm, abs=1e-6) == bb.max.X
    assert pytest.approx(params.span_mm, abs=1e-6) == bb.max.Z - bb.min.Z
    bb = model.part("tang").solid.bounding_box()
    assert pytest.approx(-params.tang_length_mm, abs=1e-6) == bb.min.X


@pytest.mark.parametrize("clearance", [0.05, 0.2, 0.4], ids=lambda c: f"clearance={c}")
def test_measured_clearance_equals_requested(clearance):
    m = make_general_hinge(GeneralHingeParams(clearance_mm=clearance))
    pin = m.part("pin").solid
    for lug in ("tang", "clevis"):
        assert m.part(lug).solid.distance_to(pin) == pytest.approx(clearance, abs=1e-7)


def test_zero_clearance_solids_touch():
    m = make_general_hinge(GeneralHingeParams(clearance_mm=0.0))
    assert m.part("tang").solid.distance_to(m.part("pin").solid) == pytest.approx(0.0, abs=1e-9)


def test_step_round_trip_keeps_parts_and_volumes(model, tmp_path):
    path = write_step(model, tmp_path / "hinge.step")
    back = read_step_parts(path)
    assert set(back) == {"tang", "clevis", "pin"}
    for name, volume in model.volumes_mm3().items():
        assert back[name] == pytest.approx(volume, rel=1e-6)


def test_named_faces_and_pairs(model):
    assert {p.name for p in model.pairs} == {"pin-tang", "pin-clevis_1", "pin-clevis_2"}
    for pair in model.pairs:
        assert model.faces[pair.slave].part == "pin"  # slave = pin side, as in the paper
        assert model.faces[pair.master].part in ("tang", "clevis")


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("clearance_mm", -0.1),
        ("clearance_mm", 5.5),  # leaves less than the minimum wall
        ("pin_radius_mm", 0.0),
        ("tang_thickness_mm", -1.0),
        ("pin_length_mm", 10.0),  # shorter than the clevis: nothing holds the outer arm
        ("pin_length_mm", 60.0),  # overhangs more than anything holds
        ("clearance_mm", float("nan")),
    ],
    ids=[
        "negative-clearance",
        "no-wall",
        "zero-pin",
        "negative-thickness",
        "short-pin",
        "long-pin",
        "nan",
    ],
)
def test_bad_parameters_name_themselves(field, value):
    with pytest.raises(ParameterError, match=field) as info:
        replace(GeneralHingeParams(), **{field: value})
    assert "must be in" in str(info.value)
