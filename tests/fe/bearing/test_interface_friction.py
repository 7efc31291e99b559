"""``interface_friction``: the bearing hinge's bonded fits made Coulomb contacts (fe.effects.interfaces)."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from cad.bearing_geometry import BearingHingeParams, Interfaces
from cad.errors import ParameterError
from cad.general_params import GeneralHingeParams
from fe.cycle.protocol import CycleSettings
from fe.effects.interfaces import InterfaceFriction
from fe.effects.registry import REGISTRY
from fe.kinds import hinge_kind
from model.service import ModelService, check_spec
from model.spec import DesignPoint, ModelSpec, geometry_key, resolve_structural, result_key

COARSE = {"size_mm": 4.0, "contact_size_mm": 0.8, "part_sizes_mm": (("ring", 1.2),)}


def _bonded(**effects):  # type: ignore[no-untyped-def]
    mesh = hinge_kind("bearing").mesh_settings(**COARSE)
    cycle = CycleSettings(mu=0.2, increments_per_stage=10)
    return ModelSpec("bearing", BearingHingeParams(), mesh, cycle, effects=effects)


def test_only_the_bearing_hinge_takes_it_and_loop_effects_take_both():
    effect = REGISTRY["interface_friction"]
    assert isinstance(effect, InterfaceFriction)
    assert effect.applies_to("bearing")
    assert not effect.applies_to("general")
    assert REGISTRY["frame_compliance"].applies_to("bearing")  # acts on the loop only
    assert REGISTRY["frame_compliance"].applies_to("general")
    assert not REGISTRY["face_friction"].applies_to("bearing")


def test_it_is_keyed_and_run_as_the_contact_model_it_makes():
    spec = _bonded(interface_friction={"mu_interface": 0.35})
    contact = dataclasses.replace(
        _bonded(),
        hinge=BearingHingeParams(interfaces=Interfaces.CONTACT),
        cycle=dataclasses.replace(_bonded().cycle, mu=0.35),
    )
    resolved = resolve_structural(spec)
    assert resolved.hinge.interfaces is Interfaces.CONTACT
    assert resolved.cycle.mu == 0.35
    assert not resolved.effects
    point = DesignPoint(300.0, {"preload_n": 100.0})
    assert result_key(spec, point) == result_key(contact, point)
    assert geometry_key(spec, point) == geometry_key(contact, point)
    assert geometry_key(spec, point) != geometry_key(_bonded(), point)
    # μ_interface = 0 switches it off: the bonded model, another key than any contact model
    off = _bonded(interface_friction={"mu_interface": 0.0})
    assert result_key(off, point) == result_key(_bonded(), point)
    assert resolve_structural(_bonded()) == _bonded()


def test_it_is_refused_where_it_means_nothing():
    general = ModelSpec(
        "general", GeneralHingeParams(), effects={"interface_friction": {"mu_interface": 0.2}}
    )
    with pytest.raises(
        ParameterError, match=r"\['interface_friction'\] do not act on the general hinge"
    ):
        check_spec(general)
    contact = dataclasses.replace(
        _bonded(interface_friction={"mu_interface": 0.2}),
        hinge=BearingHingeParams(interfaces=Interfaces.CONTACT),
    )
    with pytest.raises(ParameterError, match=r"interfaces = 'contact' already"):
        check_spec(contact)
    with pytest.raises(
        ParameterError, match=r"\['face_friction'\] do not act on the bearing hinge"
    ):
        check_spec(_bonded(face_friction={"clamp_force_n": 100.0}))
    check_spec(_bonded(interface_friction={"mu_interface": 0.2}))  # accepted


def test_model_file_round_trip(tmp_path):
    from model.file import read_model, write_model

    spec = _bonded(interface_friction={"mu_interface": 0.25})
    back = read_model(write_model(spec, tmp_path / "MODEL.toml"), REGISTRY)
    assert dict(back.effects["interface_friction"]) == {"mu_interface": 0.25}
    bad = (tmp_path / "MODEL.toml").read_text().replace("mu_interface = 0.25", "mu_interface = 1.5")
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(ParameterError, match=r"effects.interface_friction.mu_interface"):
        read_model(tmp_path / "bad.toml", REGISTRY)


ROW = re.compile(r"^\s*(0|200)\s+(100|400)\s+(-?[\d.]+)\s+(-?[\d.]+)\s+([\d.]+)\s+([\d.]+)\s*$")


@pytest.mark.slow
def test_docstring_fingerprint_is_measured():
    """Every row of the effect's table, rerun through the service (bonded vs μ_interface 0.2)."""
    documented = {}
    for line in (InterfaceFriction.__doc__ or "").splitlines():
        hit = ROW.match(line)
        if hit:
            documented[(float(hit[1]), float(hit[2]))] = tuple(map(float, hit.groups()[2:]))
    assert len(documented) == 4
    service = ModelService()
    base, eff = _bonded(), _bonded(interface_friction={"mu_interface": 0.2})
    for (fp, fg), row in documented.items():
        point = DesignPoint(fg, {"preload_n": fp})
        b, e = service.run_point(base, point).metrics(), service.run_point(eff, point).metrics()
        got = (b["eta"], e["eta"], b["disp_at_peak_mm"] * 1e3, e["disp_at_peak_mm"] * 1e3)
        np.testing.assert_allclose(got, row, rtol=0.02, atol=1.5e-5, err_msg=str((fp, fg)))
        assert e["energy_balance_rel_err"] < 0.05
