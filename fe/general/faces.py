"""Contact points between the tang's faces and the clevis arms' inner faces, and their condensation.

The mesh has no facet sets for the axial faces (adding one would change the mesh hash of
every stored result), so the points are found from the mesh itself:

* **slave** — the tang's boundary facets on its two faces ``z = ±t/2`` (exact planes,
  read from the tang's z-extent) that lie inside an annular footprint around the hole,
  ``r ≤ FOOTPRINT_RADIUS_RATIO · R_hole`` (every facet node inside): the area a washer
  or a nut head clamps. The points are the facets' nodes, with their lumped areas.
* **master** — the clevis arm's inner face facing each tang face: the clevis boundary
  facets on the nearest plane ``z = ±(t/2 + g)`` whose outward normal points at the
  tang. Each slave is projected along z onto it (a plane: the closest-point projection
  of ``project_on_facets``), giving the facet and its bilinear weights.

Frames follow ``fe.surfaces.geometry``: ``n`` is the master's outward normal (toward the
slave, ``∓e_z``), ``t1 = e_x`` (the load direction), ``t2 = n × t1``; ``g0`` is the
geometric axial gap (the effect that uses them replaces it by a clamp overlap).

``extend_condensed`` adds such points, all on tang or clevis nodes, to a condensed
configuration: the pin's compliance does not see them, the lugs' compliance couples
them to the hole points, so ``W = C_P S_P C_Pᵀ + C_L S_L C_Lᵀ`` with ``S_L`` on the union
of the lug nodes involved.
"""

from __future__ import annotations

import dataclasses
import time
import weakref

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from cad.errors import MeshQualityError, ParameterError
from cad.surfaces import Cylinder, Plane
from fe.assembly import dofs_of
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState
from fe.general.system import GRIP, HingeSystem
from fe.structure.condensed import Condensed
from fe.surfaces.geometry import (
    ContactGeometry,
    bilinear_weights,
    contact_operator,
    project_on_facets,
)
from mesh.facets import boundary_facets, select_facets
from mesh.hexmesh import HexMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

FOOTPRINT_RADIUS_RATIO = 2.0
"""Outer radius of the clamped footprint over the hole radius: a washer's outer diameter
is about twice its bore (ISO 7089: 16 mm for an 8 mm bolt), and so is a nut's or bolt
head's bearing face."""

PLANE_TOL_MM = 1e-6
"""Largest distance of a facet node from the face plane [mm]."""

FACE_PAIR_CODE: dict[int, int] = {-1: -1, 1: -2}
"""``ContactGeometry.pair`` of the face points: tang face at z < 0 (facing clevis arm 1) → −1,
at z > 0 (facing arm 2) → −2. Negative, so they never index ``HexMesh.pairs``."""


def _lumped_areas(nodes: FloatArray, facets: IntArray) -> tuple[IntArray, FloatArray]:
    """Return (node ids (n,), lumped areas (n,) [mm²]) of a set of planar quads."""
    q = nodes[facets]  # (n_f, 4, 3)
    area = 0.5 * np.linalg.norm(np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1]), axis=1)
    ids, inv = np.unique(facets, return_inverse=True)
    node_area = np.zeros(len(ids))
    np.add.at(node_area, inv.reshape(facets.shape), (area / 4.0)[:, None])
    return ids.astype(np.int64), node_area


def _hole_axis(mesh: HexMesh) -> tuple[FloatArray, float]:
    """Return the tang hole's axis point (3,) [mm] and radius [mm]; the axis must be z."""
    hole = mesh.surfaces.get("tang_hole")
    if not isinstance(hole, Cylinder):
        raise MeshQualityError("face contact needs the tang hole's exact cylinder 'tang_hole'")
    axis = np.asarray(hole.axis, dtype=np.float64)
    if not np.allclose(axis / np.linalg.norm(axis), [0.0, 0.0, 1.0]):
        raise MeshQualityError(f"face contact needs the pin axis along z, got {hole.axis}")
    return np.asarray(hole.point, dtype=np.float64), hole.radius_mm


def _face_side(
    mesh: HexMesh, side: int, centre: FloatArray, r_out_mm: float
) -> tuple[IntArray, FloatArray, IntArray, float, float]:
    """Slave nodes, areas, master facets, z of the tang face and of the arm face, on one side."""
    X = np.asarray(mesh.nodes)
    everywhere = ((-1e9, -1e9, -1e9), (1e9, 1e9, 1e9))
    z_tang = side * float(np.abs(X[mesh.part_nodes("tang"), 2]).max())
    tang_f, _ = boundary_facets(mesh.hexes[mesh.part_elements("tang")])
    on_face = select_facets(
        X, tang_f, Plane((0.0, 0.0, z_tang), (0.0, 0.0, side)), everywhere, PLANE_TOL_MM
    )
    r = np.hypot(*(X[tang_f][..., :2] - centre[:2]).transpose(2, 0, 1))  # (n_f, 4)
    slave_f = tang_f[on_face & (r <= r_out_mm + PLANE_TOL_MM).all(axis=1)]
    clevis_f, _ = boundary_facets(mesh.hexes[mesh.part_elements("clevis")])
    q = X[clevis_f]  # (n_f, 4, 3)
    flat = np.ptp(q[..., 2], axis=1) <= PLANE_TOL_MM
    facing = np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1])[:, 2] * side < 0.0
    beyond = side * q[:, 0, 2] > side * z_tang
    if len(slave_f) == 0 or not np.any(flat & facing & beyond):
        raise MeshQualityError(
            f"no tang face footprint or clevis arm face found on the z {'+' if side > 0 else '−'} side"
        )
    z_arm = side * float(np.min(side * q[flat & facing & beyond, 0, 2]))
    master_f = clevis_f[
        select_facets(
            X, clevis_f, Plane((0.0, 0.0, z_arm), (0.0, 0.0, -side)), everywhere, PLANE_TOL_MM
        )
    ]
    ids, area = _lumped_areas(X, slave_f)
    return ids, area, master_f, z_tang, z_arm


def face_geometry(mesh: HexMesh, radius_ratio: float = FOOTPRINT_RADIUS_RATIO) -> ContactGeometry:
    """Build the tang-face → clevis-arm contact points of both faces (module docstring).

    Args:
        mesh: A general hinge mesh (parts ``tang`` and ``clevis``, surface ``tang_hole``).
        radius_ratio: Outer radius of the footprint over the hole radius, > 1.

    Returns:
        The points, the z < 0 face first; ``g0`` is the geometric axial gap [mm] and
        ``pair`` is ``FACE_PAIR_CODE[side]``.

    Raises:
        ParameterError: ``radius_ratio`` ≤ 1.
        MeshQualityError: The mesh has no such faces, or a point projects off the arm.
    """
    if not radius_ratio > 1.0:
        raise ParameterError(f"radius_ratio must be > 1, got {radius_ratio}")
    centre, r_hole = _hole_axis(mesh)
    X = np.asarray(mesh.nodes)
    parts = []
    for side in (-1, 1):
        ids, area, master_f, z_tang, z_arm = _face_side(mesh, side, centre, radius_ratio * r_hole)
        foot = X[ids].copy()
        foot[:, 2] = z_arm  # projected along z onto the arm's plane
        f, s, _ = project_on_facets(foot, X, master_f)
        n = np.array([0.0, 0.0, -float(side)])
        t1 = np.array([1.0, 0.0, 0.0])
        frame = np.tile(np.stack([n, t1, np.cross(n, t1)]), (len(ids), 1, 1))  # (m, 3, 3)
        parts.append(
            (
                ids,
                np.full(len(ids), FACE_PAIR_CODE[side], dtype=np.int64),
                frame,
                np.full(len(ids), side * (z_arm - z_tang)),
                master_f[f],
                bilinear_weights(s[:, 0], s[:, 1]),
                area,
            )
        )
    cols = list(zip(*parts, strict=True))
    return ContactGeometry(*(np.concatenate(c) for c in cols))


@dataclasses.dataclass(frozen=True)
class Extended:
    """A condensed configuration with extra lug–lug points appended.

    Attributes:
        cond: The configuration: the original points first, then the extra ones.
        extra: Slice of the extra points in ``cond``'s point order.
        wall_s: Time spent here (nodal compliance included) [s].
    """

    cond: Condensed
    extra: slice
    wall_s: float


def extend_condensed(
    system: HingeSystem, cond: Condensed, extra: ContactGeometry, w0_extra: FloatArray
) -> Extended:
    """Append contact points between tang and clevis nodes to a condensed configuration.

    The original points keep their block of ``W`` (and any change an effect made to it);
    the new blocks come from ``S_L``, the lugs' compliance on the union of the original
    points' master nodes and the new points' nodes (``HingeSystem.compliance``, cached by
    node set): ``W_eo = C_e,L S_L C_o,Lᵀ``, ``W_ee = C_e,L S_L C_e,Lᵀ`` (the pin takes no part,
    so ``C_e,P = 0``). ``G_e = [C_e R_pin, C_e u_grip]``.

    Args:
        system: The factorised hinge.
        cond: A configuration whose slaves are pin nodes and masters lug nodes.
        extra: Points whose slave and master nodes are all tang or clevis nodes.
        w0_extra: Their relative displacement at zero force, shape (m_e, 3) [mm].

    Returns:
        The extended configuration (a new object; ``cond`` is not modified).

    Raises:
        ParameterError: A point of ``extra`` uses a pin node, or ``w0_extra`` has the wrong shape.
    """
    t0 = time.perf_counter()
    m, m_e = len(cond.geo.slave), len(extra.slave)
    if np.shape(w0_extra) != (m_e, 3):
        raise ParameterError(f"w0_extra must have shape ({m_e}, 3), got {np.shape(w0_extra)}")
    pin = system.mesh.part_nodes("pin")
    extra_nodes = np.unique(np.concatenate([extra.slave, extra.master_nodes.ravel()]))
    if np.isin(extra_nodes, pin).any():
        raise ParameterError("extra contact points must join tang and clevis nodes, not the pin")
    lug = np.union1d(np.unique(cond.geo.master_nodes), extra_nodes)
    _, S_L = system.compliance(np.unique(cond.geo.slave), lug)
    C_e = contact_operator(extra, system.n_dof)
    lug_dofs = dofs_of(lug)
    Ce_L = C_e[:, lug_dofs]
    Co_L = cond.C[:, lug_dofs]
    X = np.asarray(Ce_L @ S_L)  # (3 m_e, 3 n_lug)
    W_eo = np.asarray(Co_L @ X.T).T  # (3 m_e, 3 m)
    W_ee = np.asarray(Ce_L @ X.T)  # (3 m_e, 3 m_e)
    W = np.block([[np.asarray(cond.W), W_eo.T], [W_eo, 0.5 * (W_ee + W_ee.T)]])
    G_e = np.column_stack([C_e @ system.pin_R, C_e @ system.u_grip])
    geo = ContactGeometry(
        *(
            np.concatenate([np.asarray(getattr(cond.geo, k)), np.asarray(getattr(extra, k))])
            for k in ContactGeometry.__dataclass_fields__
        )
    )
    out = dataclasses.replace(
        cond,
        geo=geo,
        C=sp.vstack([cond.C, C_e]).tocsr(),
        W=W,
        G=np.vstack([cond.G, G_e]),
        w0=np.vstack([cond.w0, np.asarray(w0_extra, dtype=np.float64)]),
    )
    return Extended(out, slice(m, m + m_e), time.perf_counter() - t0)


CALIBRATION_OVERLAP_MM = 1e-3
"""Face overlap of the clamp calibration solve [mm] (any value: the solve is homogeneous)."""


def faces_only(cond: Condensed) -> Condensed:
    """The face points of a configuration alone, with the grip as the only rigid amplitude.

    The faces while the pin is centred in its clearance and touches nothing: the pin's
    modes do not move face points (their columns of ``G`` are zero there), so they are
    dropped; ``α[0]`` of the result is the grip displacement.
    """
    keep = np.flatnonzero(np.asarray(cond.geo.pair) < 0)
    rows = (3 * keep[:, None] + np.arange(3)).ravel()
    geo = ContactGeometry(
        *(np.asarray(getattr(cond.geo, k))[keep] for k in ContactGeometry.__dataclass_fields__)
    )
    return Condensed(
        geo=geo,
        C=cond.C[rows],
        W=np.asarray(cond.W)[np.ix_(rows, rows)],
        w0=np.asarray(cond.w0)[keep],
        wall_s=0.0,
        G=np.asarray(cond.G)[rows][:, [GRIP]],
    )


def unloaded_state(cond: Condensed, contact: ContactSettings) -> ContactState:
    """Return the state of the unloaded hinge: one increment from the open state to F = 0.

    With an initial overlap somewhere (``w0_n < 0``) the contact forces are a prestress.
    The problem is positively homogeneous in ``w0``: scaling every overlap (and gap)
    by λ > 0 scales ``p``, ``α`` and ``w`` by λ, friction included (one increment from
    the open state, ``Δw_t = w_t − w0_t``).
    """
    m = len(cond.geo.slave)
    start = ContactState.initial(m, cond.G.shape[1], w=cond.w0)
    res = solve_increment(cond.W, cond.w0, start, contact, G=cond.G, e=np.zeros(cond.G.shape[1]))
    return res.state


def face_normal_forces(cond: Condensed, p: FloatArray) -> dict[int, float]:
    """Sum of the normal forces on each tang face, side (−1, +1) → force [N].

    Args:
        cond: A configuration with face points (``FACE_PAIR_CODE``).
        p: Contact forces, shape (m, 3) [N].
    """
    pair = np.asarray(cond.geo.pair)
    return {s: float(np.asarray(p)[pair == c, 0].sum()) for s, c in FACE_PAIR_CODE.items()}


@dataclasses.dataclass(frozen=True)
class ClampedFaces:
    """A configuration with the clamped tang/clevis faces added.

    Attributes:
        cond: The configuration: its own points, then the face points.
        faces: Slice of the face points.
        overlap_mm: Initial overlap of every face point, δ_c [mm].
        wall_s: Time spent (face points, condensation, calibration) [s].
    """

    cond: Condensed
    faces: slice
    overlap_mm: float
    wall_s: float


_CALIBRATIONS: dict[tuple[object, ...], tuple[Extended, float]] = {}
"""(system, configuration, μ, tol, max_iter, footprint) → (extension at the unit overlap, force
per face); dropped when the configuration is (``weakref.finalize``)."""


def _calibrated_extension(
    system: HingeSystem,
    cond: Condensed,
    contact: ContactSettings,
    radius_ratio: float,
    pin_centred: bool = False,
) -> tuple[Extended, float]:
    """Return the face points appended to ``cond`` and the force per face at the unit overlap.

    Neither depends on the clamp force, so a fit that tries many clamp values (or a run at
    many amplitudes) condenses and calibrates once per configuration and μ. With
    ``pin_centred`` the calibration solve has the faces alone (``faces_only``: the pin
    centred in a clearance touches nothing), so both touching configurations get the
    same overlap.
    """
    mu_key = tuple(np.ravel(contact.mu).tolist())  # a scalar or per-point μ, hashable
    key = (id(system), id(cond), mu_key, contact.tol, contact.max_iter, radius_ratio, pin_centred)
    if key not in _CALIBRATIONS:
        geo = face_geometry(system.mesh, radius_ratio)
        unit = np.zeros((len(geo.slave), 3))
        unit[:, 0] = -CALIBRATION_OVERLAP_MM
        ext = extend_condensed(system, cond, geo, unit)
        m = ext.extra.start
        w0 = np.array(ext.cond.w0, dtype=np.float64, copy=True)
        w0[:m, 0] = np.maximum(w0[:m, 0], 0.0)
        unloaded = dataclasses.replace(ext.cond, w0=w0)
        state = unloaded_state(faces_only(unloaded) if pin_centred else unloaded, contact)
        p = np.zeros((len(ext.cond.geo.slave), 3))
        p[ext.extra if pin_centred else slice(None)] = state.p
        forces = face_normal_forces(ext.cond, p).values()
        n_unit = float(np.mean(list(forces)))
        if not n_unit > 0.0:
            raise MeshQualityError(
                f"the face footprint carries no clamp: {n_unit:g} N per face at a "
                f"{CALIBRATION_OVERLAP_MM:g} mm overlap"
            )
        _CALIBRATIONS[key] = (ext, n_unit)
        weakref.finalize(cond, _CALIBRATIONS.pop, key, None)
    return _CALIBRATIONS[key]


def clamped_faces(
    system: HingeSystem,
    cond: Condensed,
    clamp_force_n: float,
    contact: ContactSettings,
    radius_ratio: float = FOOTPRINT_RADIUS_RATIO,
    pin_centred: bool = False,
) -> ClampedFaces:
    """Add the tang faces, pressed onto the clevis arms by an axial clamp, to a configuration.

    The footprint's face points get the initial normal relative displacement
    ``w0_n = −δ_c`` (an overlap: the running gap is ignored over the footprint, as if
    shimmed, and the clamp closes it). ``δ_c`` is set so that the normal forces on each
    face at F = 0 sum to ``clamp_force_n``: one unloaded solve (``unloaded_state``, with
    the cycle's μ, the same solve as the prestressed zero) at ``δ_c = 1 µm`` gives the
    force per face N₁ (mean of the two faces), and the problem being homogeneous,
    ``δ_c = 1 µm · clamp / N₁`` exactly. Other overlaps of ``cond`` (an interference) are
    left out of that solve, or it would not be homogeneous: ``clamp_force_n`` is the
    clamp without them. With clearance (``pin_centred``) the clamp is set with the pin
    centred, touching nothing: the solve has the faces alone.

    Args:
        system: The factorised hinge.
        cond: The configuration (its points are pin–hole points).
        clamp_force_n: Axial clamp per face [N], > 0.
        contact: Contact settings of the cycle (μ, tolerance).
        radius_ratio: Footprint outer radius over the hole radius.
        pin_centred: Calibrate on the faces alone (a touching configuration of a hinge
            with clearance, ``fe.general.freeplay``).

    Raises:
        ParameterError: ``clamp_force_n`` ≤ 0.
        ConvergenceError: The calibration solve failed.
        MeshQualityError: No face points, or the overlap gives them no force.
    """
    if not clamp_force_n > 0.0:
        raise ParameterError(f"clamp_force_n must be > 0, got {clamp_force_n}")
    t0 = time.perf_counter()
    ext, n_unit = _calibrated_extension(system, cond, contact, radius_ratio, pin_centred)
    m = ext.extra.start
    overlap = CALIBRATION_OVERLAP_MM * clamp_force_n / n_unit
    w0 = np.array(ext.cond.w0, dtype=np.float64, copy=True)
    w0[m:, 0] = -overlap
    g0 = np.array(ext.cond.geo.g0, dtype=np.float64, copy=True)
    g0[m:] = -overlap
    out = dataclasses.replace(ext.cond, w0=w0, geo=dataclasses.replace(ext.cond.geo, g0=g0))
    return ClampedFaces(out, ext.extra, overlap, time.perf_counter() - t0)
