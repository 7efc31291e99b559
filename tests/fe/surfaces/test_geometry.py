"""Contact geometry on the general hinge's mesh: exact gaps and projections on the master."""

from __future__ import annotations

import numpy as np
import pytest

from cad.general import make_general_hinge
from cad.general_params import GeneralHingeParams
from cad.surfaces import Cylinder
from fe.surfaces.geometry import closest_point, contact_geometry
from mesh.build import mesh_hinge
from mesh.settings import MeshSettings


@pytest.mark.parametrize("inside", [True, False], ids=["pin-surface", "hole-surface"])
def test_closest_point_lies_on_the_surface(inside):
    # defect: the foot on a hole was taken at x + g n (2g off the surface, inside the hole)
    surface = Cylinder((0, 0, 0), (0, 0, 1), 4.2, material_inside=inside)
    rng = np.random.default_rng(1)
    x = np.column_stack(
        [
            rng.uniform(3.5, 4.0, 20) * np.cos(t := rng.uniform(0, 6.3, 20)),
            rng.uniform(3.5, 4.0, 20) * np.sin(t),
            rng.uniform(-1, 1, 20),
        ]
    )
    foot = closest_point(surface, x)
    assert np.allclose(surface.distance_outside(foot), 0.0, atol=1e-12)
    assert np.allclose(foot[:, 2], x[:, 2])


def test_gaps_are_exact_and_projections_land_on_the_master():
    c = 0.2
    mesh, _ = mesh_hinge(
        make_general_hinge(GeneralHingeParams(clearance_mm=c)),
        MeshSettings.coarse(),
    )
    geo = contact_geometry(mesh, {p.name: np.zeros(3) for p in mesh.pairs})
    assert np.allclose(geo.g0, c, atol=1e-12)  # from the exact cylinders, not the facets
    x = np.asarray(mesh.nodes)
    master_point = np.einsum("ma,mai->mi", geo.master_weights, x[geo.master_nodes])
    slave = x[geo.slave]
    # the interpolated master point is on the chord under the slave: same angle, radius
    # between the chord's sag and the hole radius
    r = np.hypot(master_point[:, 0], master_point[:, 1])
    assert np.all(r <= 4.2 + 1e-9)
    assert np.all(r >= 4.2 * np.cos(np.pi / 8) - 1e-9)
    angle = np.arctan2(master_point[:, 1], master_point[:, 0]) - np.arctan2(
        slave[:, 1], slave[:, 0]
    )
    assert np.abs(np.angle(np.exp(1j * angle))).max() < 0.05
    assert np.allclose(np.linalg.norm(geo.frame, axis=2), 1.0)
    assert np.allclose(np.einsum("mi,mi->m", geo.frame[:, 0], geo.frame[:, 1]), 0.0, atol=1e-12)
