"""The pin's structured band under its contact surface (MeshSettings.pin_band_sizes)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cad.errors import ParameterError
from cad.general import make_general_hinge
from cad.general_params import GeneralHingeParams
from fe.kinds import hinge_kind
from mesh.band import corner_sines
from mesh.build import mesh_hinge, mesh_part
from mesh.settings import MeshSettings

O_GRID = float("inf")


@pytest.fixture(scope="module")
def model():
    return make_general_hinge(GeneralHingeParams(clearance_mm=0.1))


@pytest.fixture(scope="module")
def pin(model):
    return next(p for p in model.parts if p.name == "pin")


@pytest.fixture(scope="module")
def level1(model):
    """The hinge at refinement 1 with the default band and with the O-grid."""
    return {
        band: mesh_hinge(model, MeshSettings(refinement=1, pin_band_sizes=band))
        for band in (MeshSettings().pin_band_sizes, O_GRID)
    }


def section(nodes, hexes):
    """Bottom quads of swept hexes: corner coordinates (n_elem, 4, 2) [mm]."""
    return nodes[hexes[:, :4], :2]


def pin_share(mesh) -> float:
    pin = mesh.part_names.index("pin")
    return len(np.unique(mesh.hexes[mesh.elem_part == pin])) / len(mesh.nodes)


@pytest.mark.parametrize("level", [1, 2], ids=["level-1", "level-2"])
def test_no_fine_pin_elements_below_the_band(model, pin, level):
    # Deeper than the band and two slave sizes of transition, no element edge is shorter
    # than 0.4 slave sizes; the O-grid has them everywhere (its core square is finer
    # than the surface), so the same check refuses it.
    radius = model.params.pin_radius_mm
    for band, ok in ((3.0, True), (O_GRID, False)):
        s = MeshSettings(refinement=level, pin_band_sizes=band)
        p = section(*mesh_part(model, pin, s))
        depth = radius - np.hypot(*p.mean(axis=1).T)
        shortest = np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2).min(axis=1)
        deep = depth > 3.0 * s.slave_mm + 2.0 * s.slave_mm
        assert deep.any()
        assert bool(shortest[deep].min() >= 0.4 * s.slave_mm) is ok


def test_default_band_cuts_the_pin_share(level1):
    banded, o_grid = (mesh for mesh, _ in level1.values())
    assert len(banded.nodes) < 0.9 * len(o_grid.nodes)
    assert pin_share(banded) < pin_share(o_grid) - 0.05


def test_contact_surface_nodes_do_not_move(level1):
    from scipy.spatial import cKDTree

    (banded, r_band), (o_grid, r_grid) = level1.values()
    assert r_band.sets == r_grid.sets
    for name in ("pin_tang", "pin_clevis_1", "pin_clevis_2"):
        a, b = banded.nodes[banded.set_nodes(name)], o_grid.nodes[o_grid.set_nodes(name)]
        assert len(a) == len(b)
        assert cKDTree(b).query(a)[0].max() < 1e-6


def test_pin_volume_is_still_the_inscribed_polygon_prism(model, level1):
    mesh, report = level1[MeshSettings().pin_band_sizes]
    p = model.params
    xyz = mesh.nodes[mesh.set_nodes("pin_tang")]
    ring = xyz[np.isclose(xyz[:, 2], xyz[:, 2].min())]
    theta = np.sort(np.arctan2(ring[:, 1], ring[:, 0]))
    dtheta = np.diff(np.append(theta, theta[0] + 2 * math.pi))
    polygon = 0.5 * p.pin_radius_mm**2 * np.sin(dtheta).sum()
    assert report.parts["pin"]["mesh_volume_mm3"] == pytest.approx(polygon * p.pin_length, rel=1e-9)


def test_level_0_keeps_the_o_grid(model):
    # 32 segments round the pin: the band, its pillow ring and its core would cost more
    # nodes than the O-grid, so the default mesh of refinement 0 is the one before the band.
    a, _ = mesh_hinge(model, MeshSettings())
    b, _ = mesh_hinge(model, MeshSettings(pin_band_sizes=O_GRID))
    np.testing.assert_array_equal(a.nodes, b.nodes)
    np.testing.assert_array_equal(a.hexes, b.hexes)


@pytest.mark.parametrize("level", [1, 2, 3], ids=["level-1", "level-2", "level-3"])
def test_band_quads_are_well_shaped(model, pin, level):
    # The core's ears (three nodes on the band's circle, a corner of 180° − 360°/N) are
    # pillowed away; a uniform inner arc had sheared the band until level 3 inverted.
    p = section(*mesh_part(model, pin, MeshSettings(refinement=level)))
    xy = p.reshape(-1, 2)
    quads = np.arange(len(xy), dtype=np.int64).reshape(-1, 4)
    assert corner_sines(xy, quads).min() > 0.3


@pytest.mark.parametrize("value", [0.5, -1.0, math.nan], ids=["shallow", "negative", "nan"])
def test_bad_band_depth_is_refused(value):
    with pytest.raises(ParameterError, match="pin_band_sizes"):
        MeshSettings(pin_band_sizes=value)


def test_bearing_pin_is_not_banded():
    # The bearing hinge's pin is bonded into its rings and the clevis, not in contact:
    # it has no contact circle to lie under, so no band.
    from cad.bearing import make_bearing_hinge
    from cad.bearing_geometry import BearingHingeParams
    from mesh.build import _pin_band

    bearing = make_bearing_hinge(BearingHingeParams())
    pin = next(p for p in bearing.parts if p.name == "pin")
    settings = hinge_kind("bearing").mesh_settings()
    assert math.isfinite(settings.pin_band_mm)
    assert _pin_band(bearing, pin, settings) is None
