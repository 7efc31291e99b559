"""Swept hex meshes of the general hinge: volumes, exact surfaces, sets, quality."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cad.errors import MeshQualityError
from cad.general import make_general_hinge
from cad.general_params import GeneralHingeParams
from fe.kinds import hinge_kind
from mesh.build import mesh_hinge
from mesh.hexmesh import HexMesh
from mesh.quality import check_quality, hex_volumes
from mesh.settings import MeshSettings


@pytest.fixture(scope="module")
def params():
    return GeneralHingeParams(clearance_mm=0.15)


@pytest.fixture(scope="module")
def meshed(params):
    return mesh_hinge(make_general_hinge(params))


def ring_count(mesh: HexMesh, name: str, radius: float) -> int:
    """Nodes of a set on one z level: the number of divisions around the circle."""
    xyz = mesh.nodes[mesh.set_nodes(name)]
    assert np.allclose(np.hypot(xyz[:, 0], xyz[:, 1]), radius, atol=1e-9)
    z0 = xyz[:, 2].min()
    return int(np.sum(np.isclose(xyz[:, 2], z0)))


def test_pin_mesh_volume_is_the_inscribed_polygon_prism(meshed, params):
    # The pin's section is the polygon inscribed in its circle through the surface nodes
    # (graded, so irregular): area ½ R² Σ sin Δθ_i, exactly.
    mesh, report = meshed
    xyz = mesh.nodes[mesh.set_nodes("pin_tang")]
    ring = xyz[np.isclose(xyz[:, 2], xyz[:, 2].min())]
    theta = np.sort(np.arctan2(ring[:, 1], ring[:, 0]))
    dtheta = np.diff(np.append(theta, theta[0] + 2 * math.pi))
    polygon = 0.5 * params.pin_radius_mm**2 * np.sin(dtheta).sum()
    assert report.parts["pin"]["mesh_volume_mm3"] == pytest.approx(
        polygon * params.pin_length, rel=1e-9
    )


def test_lug_mesh_volumes_close_to_solids(meshed):
    # Curved boundaries are replaced by chords: the error is O(h²); at these sizes < 0.5 %.
    _, report = meshed
    for part in ("tang", "clevis"):
        assert abs(report.parts[part]["volume_rel_err"]) < 5e-3


def test_all_hex_and_no_inverted_element(meshed):
    mesh, report = meshed
    assert report.hex_fraction == 1.0
    assert np.all(hex_volumes(mesh.nodes, mesh.hexes) > 0)
    assert report.min_scaled_jacobian > 0.2


def test_inverted_element_is_refused(meshed):
    mesh, _ = meshed
    flipped = mesh.hexes.copy()
    flipped[0] = flipped[0][[4, 5, 6, 7, 0, 1, 2, 3]]
    with pytest.raises(MeshQualityError, match="element 0"):
        check_quality(mesh.nodes, flipped)


def test_contact_nodes_on_exact_surfaces(meshed, params):
    mesh, _ = meshed
    for name in ("tang_hole", "clevis_hole_1", "clevis_hole_2"):
        r = np.hypot(*mesh.nodes[mesh.set_nodes(name)][:, :2].T)
        assert np.allclose(r, params.hole_radius_mm, atol=1e-9)


def test_named_sets_non_empty_with_outward_normals(meshed):
    mesh, _ = meshed
    for name, facets in mesh.facet_sets.items():
        assert len(facets) > 0, name
        normals, areas = mesh.facet_normals_areas(name)
        assert np.all(areas > 0)
        if name in mesh.surfaces:
            centres = mesh.nodes[facets].mean(axis=1)
            dots = np.einsum("fi,fi->f", normals, mesh.surfaces[name].outward_normal(centres))
            assert dots.min() > 0.95, name
    assert np.allclose(mesh.facet_normals_areas("tang_fixed")[0], [-1, 0, 0])
    assert np.allclose(mesh.facet_normals_areas("clevis_load")[0], [1, 0, 0])


def test_fixed_and_load_face_areas(meshed, params):
    mesh, _ = meshed
    p = params
    assert mesh.facet_normals_areas("tang_fixed")[1].sum() == pytest.approx(
        p.lug_width_mm * p.tang_thickness_mm
    )
    assert mesh.facet_normals_areas("clevis_load")[1].sum() == pytest.approx(
        p.lug_width_mm * p.span_mm
    )


def test_slave_surface_finer_than_master(meshed, params):
    mesh, _ = meshed
    s = MeshSettings()
    slave = ring_count(mesh, "pin_tang", params.pin_radius_mm)
    master = ring_count(mesh, "tang_hole", params.hole_radius_mm)
    assert slave / master >= s.slave_ratio * params.pin_radius_mm / params.hole_radius_mm * 0.9
    assert slave > master


def test_refinement_halves_sizes(params):
    model = make_general_hinge(params)
    m0, _ = mesh_hinge(model, MeshSettings(refinement=0))
    m1, r1 = mesh_hinge(model, MeshSettings(refinement=1))
    n0 = ring_count(m0, "pin_tang", params.pin_radius_mm)
    n1 = ring_count(m1, "pin_tang", params.pin_radius_mm)
    assert 2 * n0 - 8 <= n1 <= 2 * n0 + 8  # per quarter: ceil of a doubled count
    z0 = np.unique(m0.nodes[m0.set_nodes("pin_tang")][:, 2]).size
    z1 = np.unique(m1.nodes[m1.set_nodes("pin_tang")][:, 2]).size
    assert z1 - 1 == 2 * (z0 - 1)
    assert r1.min_scaled_jacobian > 0.2


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"refinement": 5}, "refinement"),
        ({"size_mm": -1.0}, "size_mm"),
        ({"slave_ratio": 0.5}, "slave_ratio"),
        ({"contact_size_mm": 5.0, "size_mm": 2.0}, "contact_size_mm"),
    ],
    ids=["refinement", "size", "ratio", "contact-larger-than-global"],
)
def test_bad_mesh_settings(kwargs, name):
    from cad.errors import ParameterError

    with pytest.raises(ParameterError, match=name):
        MeshSettings(**kwargs)


def test_per_part_sizes_and_hinge_defaults():
    s = hinge_kind("bearing").mesh_settings(cycle=False)
    assert s.size_for("ball_0_3") == pytest.approx(0.6)
    assert s.size_for("inner_ring_1") == pytest.approx(0.8)
    assert s.size_for("tang") == pytest.approx(s.size_mm)
    assert hinge_kind("bearing").mesh_settings(cycle=False, refinement=1).size_for(
        "ball_0_3"
    ) == pytest.approx(0.3)
    assert hinge_kind("general").mesh_settings() == MeshSettings()


def test_unknown_hinge_kind_is_refused():
    from cad.errors import ParameterError

    with pytest.raises(ParameterError, match="hinge kind"):
        hinge_kind("telescope")


def test_strong_grading_on_coarse_arcs_does_not_invert():
    # defect: arc_grading 9 over three segments per quarter (growth ratio 3) inverted an
    # element next to the ring (synth's finer mesh at Δr 0.2 mm); the growth is now capped
    settings = MeshSettings(size_mm=3.6, contact_size_mm=1.5, arc_grading=9.0)
    _, report = mesh_hinge(make_general_hinge(GeneralHingeParams(clearance_mm=0.2)), settings)
    assert report.min_scaled_jacobian > 0.05
