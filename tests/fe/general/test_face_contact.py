"""Tang-face / clevis-arm contact points: geometry from the mesh, condensation, clamp calibration.

Coarse mesh (as the effect tests), zero clearance.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cad.errors import ParameterError
from cad.general import make_general_hinge
from cad.general_params import GeneralHingeParams
from fe.assembly import dofs_of
from fe.contact.state import ContactSettings
from fe.cycle.protocol import CycleSettings
from fe.general.cycle import configurations, run_cycle
from fe.general.faces import (
    FACE_PAIR_CODE,
    FOOTPRINT_RADIUS_RATIO,
    clamped_faces,
    extend_condensed,
    face_geometry,
    face_normal_forces,
    unloaded_state,
)
from fe.general.system import build_system
from mesh.build import mesh_hinge
from mesh.settings import MeshSettings

COARSE = MeshSettings.coarse()
P = GeneralHingeParams()


@pytest.fixture(scope="module")
def tight():
    mesh, _ = mesh_hinge(make_general_hinge(P), COARSE)
    system = build_system(mesh)
    return system, configurations(system, 0.0)[1]


@pytest.fixture(scope="module")
def faces(tight):
    return face_geometry(tight[0].mesh)


def test_face_points_lie_on_the_tang_faces_inside_the_footprint(tight, faces):
    mesh = tight[0].mesh
    X = np.asarray(mesh.nodes)
    t2, r_hole = P.tang_thickness_mm / 2, P.hole_radius_mm
    assert np.isin(faces.slave, mesh.part_nodes("tang")).all()
    assert np.isin(faces.master_nodes, mesh.part_nodes("clevis")).all()
    for side, code in FACE_PAIR_CODE.items():
        on = faces.pair == code
        x = X[faces.slave[on]]
        np.testing.assert_allclose(x[:, 2], side * t2, atol=1e-12)
        r = np.hypot(x[:, 0], x[:, 1])
        assert r.min() == pytest.approx(r_hole, abs=1e-9)  # the hole's edge is in the footprint
        assert r.max() <= FOOTPRINT_RADIUS_RATIO * r_hole + 1e-9
        # the interpolated master point is the slave projected along z onto the arm's face
        xm = np.einsum("ma,mai->mi", faces.master_weights[on], X[faces.master_nodes[on]])
        np.testing.assert_allclose(xm[:, :2], x[:, :2], atol=1e-9)
        np.testing.assert_allclose(xm[:, 2], side * (t2 + P.clevis_gap_mm), atol=1e-12)
        np.testing.assert_allclose(faces.g0[on], P.clevis_gap_mm, rtol=1e-12)
        np.testing.assert_allclose(faces.frame[on, 0], [[0, 0, -side]] * on.sum())
        # lumped areas: at most the annulus, at least the part the coarse facets cover (measured 72 %)
        area = faces.area_mm2[on].sum()
        annulus = np.pi * r_hole**2 * (FOOTPRINT_RADIUS_RATIO**2 - 1)
        assert 0.5 * annulus < area <= annulus
    assert np.allclose(np.linalg.det(faces.frame), 1.0)  # right-handed [n, t1, t2]


def test_face_footprint_ratio_must_exceed_one(tight):
    with pytest.raises(ParameterError, match=r"radius_ratio must be > 1, got 1.0"):
        face_geometry(tight[0].mesh, 1.0)


def test_extension_keeps_the_pin_block_and_adds_the_lug_couplings(tight, faces):
    system, cond = tight
    w0 = np.column_stack([faces.g0, np.zeros((len(faces.g0), 2))])
    ext = extend_condensed(system, cond, faces, w0)
    out, m = ext.cond, len(cond.geo.slave)
    assert ext.extra == slice(m, m + len(faces.slave))
    np.testing.assert_array_equal(out.W[: 3 * m, : 3 * m], cond.W)  # unchanged (effects kept)
    np.testing.assert_array_equal(out.W, out.W.T)
    # the full W = C_P S_P C_Pᵀ + C_L S_L C_Lᵀ, computed independently, agrees
    pin = np.unique(cond.geo.slave)
    lug = np.union1d(
        np.unique(cond.geo.master_nodes), np.concatenate([faces.slave, faces.master_nodes.ravel()])
    )
    S_P, S_L = system.compliance(pin, lug)
    CP, CL = out.C[:, dofs_of(pin)], out.C[:, dofs_of(lug)]
    W = np.asarray(CP @ (CP @ S_P).T) + np.asarray(CL @ (CL @ S_L).T)
    np.testing.assert_allclose(out.W, W, rtol=0, atol=1e-12 * np.abs(W).max())
    # rigid map: the pin's modes do not move the lug points; the grip moves the arm (master) +x
    G_e = out.G[3 * m :].reshape(-1, 3, 7)
    assert not G_e[:, :, :6].any()
    np.testing.assert_allclose(G_e[:, :, 6], [[0.0, -1.0, 0.0]] * len(faces.slave), atol=1e-15)
    assert not np.may_share_memory(out.W, cond.W)


def test_open_faces_leave_the_cycle_unchanged(tight, faces):
    """Faces at their 0.2 mm running gap never touch: the loop is the baseline's to round-off."""
    system, cond = tight
    settings = CycleSettings(amplitude_n=400.0, mu=0.2, increments_per_stage=6)
    w0 = np.column_stack([faces.g0, np.zeros((len(faces.g0), 2))])
    ext = extend_condensed(system, cond, faces, w0).cond
    base = run_cycle(system, 0.0, settings, configs={1: cond, -1: cond})
    with_faces = run_cycle(system, 0.0, settings, configs={1: ext, -1: ext})
    _, d0, _ = base.loop_arrays()
    _, d1, _ = with_faces.loop_arrays()
    np.testing.assert_allclose(d1, d0, rtol=0, atol=1e-9 * np.abs(d0).max())
    assert all(s.p[len(cond.geo.slave) :].max() == 0.0 for s in with_faces.states)


def test_extra_points_on_the_pin_are_refused(tight, faces):
    system, cond = tight
    pin_node = int(system.mesh.part_nodes("pin")[0])
    bad = dataclasses.replace(faces, slave=np.full_like(faces.slave, pin_node))
    with pytest.raises(ParameterError, match="tang and clevis nodes, not the pin"):
        extend_condensed(system, cond, bad, np.zeros((len(faces.slave), 3)))


@pytest.mark.parametrize("mu", [0.0, 0.2], ids=["frictionless", "mu0.2"])
def test_clamp_calibration_is_exact_and_homogeneous(tight, mu):
    """Each face carries the clamp at F = 0 (homogeneity: exact to the solver tolerance)."""
    system, cond = tight
    contact = ContactSettings(mu=mu)
    one = clamped_faces(system, cond, 300.0, contact)
    two = clamped_faces(system, cond, 600.0, contact)
    assert two.overlap_mm == pytest.approx(2 * one.overlap_mm, rel=1e-12)
    state = unloaded_state(one.cond, contact)
    for side, force in face_normal_forces(one.cond, np.asarray(state.p)).items():
        assert force == pytest.approx(300.0, rel=1e-6), side
    np.testing.assert_array_equal(one.cond.w0[one.faces, 0], -one.overlap_mm)
    np.testing.assert_array_equal(one.cond.geo.g0[one.faces], -one.overlap_mm)


def test_friction_changes_the_overlap_a_clamp_needs(tight):
    """The faces' friction resists the tang's Poisson expansion: stiffer, less overlap per newton."""
    system, cond = tight
    dry = clamped_faces(system, cond, 300.0, ContactSettings(mu=0.2)).overlap_mm
    wet = clamped_faces(system, cond, 300.0, ContactSettings(mu=0.0)).overlap_mm
    assert dry < wet


def test_calibration_is_made_once_per_configuration_and_mu(tight, monkeypatch):
    """The unit-overlap solve does not depend on the clamp force: a fit over clamp values
    (or a run over amplitudes) must not repeat it; another μ or configuration must."""
    import fe.general.faces as fc

    system, cond = tight
    calls = []
    real = fc.unloaded_state

    def counting(c, contact):
        calls.append(contact.mu)
        return real(c, contact)

    monkeypatch.setattr(fc, "unloaded_state", counting)
    own = dataclasses.replace(cond)  # a configuration no other test has calibrated
    a = clamped_faces(system, own, 100.0, ContactSettings(mu=0.2))
    b = clamped_faces(system, own, 400.0, ContactSettings(mu=0.2))
    assert calls == [0.2]
    assert b.overlap_mm == pytest.approx(4 * a.overlap_mm, rel=1e-12)
    clamped_faces(system, own, 400.0, ContactSettings(mu=0.3))
    clamped_faces(system, dataclasses.replace(cond), 400.0, ContactSettings(mu=0.2))
    assert calls == [0.2, 0.3, 0.2]
