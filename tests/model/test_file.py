"""MODEL.toml: round trip, and refusal of unknown keys, wrong types and out-of-range values."""

from __future__ import annotations

import pytest

from cad.bearing_geometry import Arrangement, BearingHingeParams
from cad.errors import DataError, ParameterError
from cad.general_params import GeneralHingeParams
from cad.materials import Material
from fe.cycle.protocol import CycleSettings
from mesh.settings import MeshSettings
from model.file import read_model, write_model
from model.spec import DesignPoint, ModelSpec, hinge_at

REGISTRY = {
    "interference": {"delta_mm": (0.0, 0.05)},
    "tangential_stiffness": {"k_t_n_per_mm": (1.0, 1e9)},
}


def general_spec():
    return ModelSpec(
        "general",
        GeneralHingeParams(
            clearance_mm=0.05,
            pin_length_mm=22.0,
            lug_material=Material("7075-T6", 71_700.0, 0.33),
        ),
        MeshSettings.coarse(part_sizes_mm=(("pin", 1.5), ("tang", 3.0))),
        CycleSettings(
            amplitude_n=250.0, mu=0.15, increments_per_stage=6, clearance_increments=6, tol=1e-11
        ),
        {"interference": {"delta_mm": 0.01}},
    )


@pytest.mark.parametrize(
    "spec",
    [
        general_spec(),
        ModelSpec("general", GeneralHingeParams()),
        ModelSpec(
            "bearing",
            BearingHingeParams(arrangement=Arrangement.BACK_TO_BACK, preload_n=0.0, ball_count=9),
        ),
    ],
    ids=["general-full", "general-defaults", "bearing"],
)
def test_round_trip(tmp_path, spec):
    path = write_model(spec, tmp_path / "MODEL.toml")
    back = read_model(path, REGISTRY)
    assert back == spec
    write_model(back, tmp_path / "again.toml")
    assert (tmp_path / "again.toml").read_text() == path.read_text()


def test_written_file_is_readable_toml_with_sections(tmp_path):
    text = write_model(general_spec(), tmp_path / "m.toml").read_text()
    for section in (
        "[hinge]",
        "[materials.lug]",
        "[materials.pin]",
        "[mesh]",
        "[mesh.part_sizes_mm]",
        "[friction]",
        "[cycle]",
        '[effects."interference"]',
    ):
        assert section in text
    assert "mu = 0.15" in text


def write(tmp_path, text):
    path = tmp_path / "MODEL.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "error", "match"),
    [
        (
            '[hinge]\nkind = "general"\n[solver]\nx = 1\n',
            ParameterError,
            r"unknown key\(s\) \['solver'\]; allowed: hinge, materials",
        ),
        (
            '[hinge]\nkind = "general"\npin_radius = 4.0\n',
            ParameterError,
            r"\[hinge\]: unknown key\(s\) \['pin_radius'\]; allowed: pin_radius_mm, clearance_mm",
        ),
        (
            '[hinge]\nkind = "general"\nclearance_mm = 7.0\n',
            ParameterError,
            r"MODEL\.toml: \[hinge\]: clearance_mm must be in \[0, 5\], got 7\.0",
        ),
        (
            '[hinge]\nkind = "general"\nclearance_mm = "big"\n',
            ParameterError,
            r"\[hinge\]: clearance_mm must be a number, got 'big'",
        ),
        (
            '[hinge]\nkind = "general"\n[mesh]\nrefinement = 1.5\n',
            ParameterError,
            r"\[mesh\]: refinement must be an integer",
        ),
        (
            '[hinge]\nkind = "general"\n[mesh]\nsize_mm = 0.01\n',
            ParameterError,
            r"\[mesh\]: size_mm must be in",
        ),
        (
            '[hinge]\nkind = "general"\n[friction]\nmu = 3.0\n',
            ParameterError,
            r"mu must be in \[0, 2\], got 3\.0",
        ),
        (
            '[hinge]\nkind = "general"\n[friction]\nmu = 0.2\nmu_static = 0.3\n',
            ParameterError,
            r"\[friction\]: unknown key\(s\) \['mu_static'\]; allowed: mu",
        ),
        (
            '[hinge]\nkind = "general"\n[cycle]\nmu = 0.2\n',
            ParameterError,
            r"\[cycle\]: unknown key\(s\) \['mu'\]",
        ),
        (
            '[hinge]\nkind = "general"\n[materials.pin]\npoisson = 0.6\n',
            ParameterError,
            r"\[materials\.pin\]: 45 steel\.poisson must be in",
        ),
        (
            '[hinge]\nkind = "general"\n[materials.bearing]\npoisson = 0.3\n',
            ParameterError,
            r"\[materials\]: unknown key\(s\) \['bearing'\]; allowed: lug, pin",
        ),
        (
            '[hinge]\nkind = "general"\n[effects.creep]\nrate = 1.0\n',
            ParameterError,
            r"unknown effect 'creep'; known effects: interference, tangential_stiffness",
        ),
        (
            '[hinge]\nkind = "general"\n[effects.interference]\ndelta_mm = 0.5\n',
            ParameterError,
            r"effects\.interference\.delta_mm must be in \[0, 0\.05\], got 0\.5",
        ),
        (
            '[hinge]\nkind = "general"\n[effects.interference]\ndelta = 0.01\n',
            ParameterError,
            r"unknown key\(s\) \['delta'\]; allowed: delta_mm",
        ),
        (
            '[hinge]\nkind = "hinged"\n',
            ParameterError,
            r"kind must be one of \['bearing', 'general', 'joint'\], got 'hinged'",
        ),
        (
            '[hinge]\nkind = "bearing"\narrangement = "SIDEWAYS"\n',
            ParameterError,
            r"arrangement must be one of \['FACE_TO_FACE', 'BACK_TO_BACK'\]",
        ),
        ('[hinge\nkind = "general"\n', DataError, r"not valid TOML"),
    ],
    ids=[
        "unknown-section",
        "unknown-hinge-key",
        "clearance-range",
        "type",
        "int-type",
        "mesh-range",
        "mu-range",
        "friction-key",
        "mu-in-cycle",
        "material-range",
        "material-role",
        "unknown-effect",
        "effect-range",
        "effect-key",
        "kind",
        "enum",
        "toml-syntax",
    ],
)
def test_refusals_name_the_key(tmp_path, text, error, match):
    with pytest.raises(error, match=match):
        read_model(write(tmp_path, text), REGISTRY)


def test_default_registry_is_the_solvers(tmp_path):
    """Without a registry argument every effect the solver knows is accepted (what calibrate
    writes must read back in compare); NO_EFFECTS still refuses them all."""
    from model.file import NO_EFFECTS

    ok = write(
        tmp_path,
        '[hinge]\nkind = "general"\n[effects.frame_compliance]\ncompliance_mm_per_n = 2e-5\n',
    )
    assert dict(read_model(ok).effects) == {"frame_compliance": {"compliance_mm_per_n": 2e-5}}
    with pytest.raises(ParameterError, match=r"known effects: \(none yet\)"):
        read_model(ok, NO_EFFECTS)
    bad = write(tmp_path, '[hinge]\nkind = "general"\n[effects.interference]\ndelta_mm = 0.01\n')
    with pytest.raises(
        ParameterError, match=r"unknown key\(s\) \['delta_mm'\]; allowed: interference_mm"
    ):
        read_model(bad)


def test_missing_file_and_minimal_file(tmp_path):
    with pytest.raises(DataError, match="model file not found"):
        read_model(tmp_path / "nope.toml")
    spec = read_model(write(tmp_path, '[hinge]\nkind = "general"\n'))
    assert spec == ModelSpec("general", GeneralHingeParams())


def test_hinge_at_a_design_point_and_spec_checks():
    spec = general_spec()
    at = hinge_at(spec, DesignPoint(300.0, {"clearance_mm": 0.1}))
    assert at.clearance_mm == 0.1
    assert at.lug_material.name == "7075-T6"  # the rest of the model is kept
    with pytest.raises(ParameterError, match=r"clearance_mm must be in \[0, 5\], got 11"):
        hinge_at(spec, DesignPoint(300.0, {"clearance_mm": 11.0}))
    with pytest.raises(ParameterError, match="hinge kind must be one of"):
        ModelSpec("telescope", GeneralHingeParams())
    with pytest.raises(ParameterError, match="needs BearingHingeParams"):
        ModelSpec("bearing", GeneralHingeParams())
    with pytest.raises(TypeError):
        spec.effects["interference"]["delta_mm"] = 1.0  # read-only
