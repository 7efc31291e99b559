"""One meshed ball pressed between an inner and an outer raceway block: FE against Hertz.

Verification item of issue #11 and groundwork for a meshed-ball bearing model. The
default 708C geometry (:class:`cad.bearing_geometry.BearingHingeParams`) gives the ball,
the two groove tori and the contact line; :mod:`mesh.ball_block` meshes a column of the
ball through both contacts and one block of each ring (half model, y ≥ 0), every contact
node on the exact sphere or torus. The ball nodes near each contact are the slaves,
measured against the exact tori (node-to-surface, as
:func:`fe.structure.twobody.two_body_geometry`); the system is condensed on their normal
directions only (:func:`condense_normal`, exact for μ = 0).

Loading (frictionless): the inner block's far face is clamped; the outer block's far
face is a rigid grip pushed along the contact line by Q (force control through
``solve_increment``'s rigid amplitudes); the ball floats, its translations along x and z
being two more amplitudes with zero load (one node on its axis holds its rotation about
y, which frictionless forces through the centre leave undetermined). Half model: the grip
carries Q/2 and y = 0 is a symmetry plane.

Measurements per contact (inner and outer), compared with the exact Hertz solution at
the resultant contact force Q:

* Semi-axes a (x, across the groove) and b (y, rolling direction) three ways: (1) the
  force moments: for the Hertz pressure ``<x²> = a²/5``, so ``a² = 5 (Σ F x²/Σ F − h_x²/6)``
  (the consistent nodal forces integrate the bilinear interpolant of x², which exceeds
  x² by h²/6 on average over a uniform grid); (2) the least-squares fit of
  ``p² = p0² (1 − x²/a² − y²/b²)`` to the nodal pressures ``p = F/A`` of the closed nodes
  whose four grid neighbours are closed (the edge nodes integrate the square-root edge);
  (3) the discrete edge: midway between the last closed and first open node on the
  axes.
* Local approach: the mutual approach of the two points on the contact axis at depth
  ``d`` (a grid node near ``approach_depth_mm``) in ball and ring. Hertz (half-spaces)
  predicts ``δ_H − w(d_ball) − w(d_ring)`` with ``w(d)`` the Boussinesq displacement at
  depth d under the Hertz pressure
  (:func:`fe.bearing.one_ball_post.halfspace_axis_displacement`). Measured close to the
  contact, it is free of the bodies' far-field (bulk) compliance, which differs between
  a finite ball column and ring blocks and the half-spaces of Hertz theory.
* Total approach: ball centre to each block's far face, ``δ_FE = δ_H + c Q`` with a bulk
  compliance c (linear in Q); over several loads, fitting ``δ = K Q^{2/3} + c Q`` gives
  the contact constant K to compare with Hertz's.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.bearing_geometry import BearingHingeParams, race_geometry
from cad.errors import ParameterError
from cad.surfaces import Torus
from fe.assembly import dofs_of
from fe.bearing.hertz import (
    ContactEllipse,
    Race,
    contact_ellipse,
    effective_modulus,
    race_curvatures,
)
from fe.bearing.one_ball_post import footprint_semi_axes, halfspace_axis_displacement
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState
from fe.structure.condensed import Condensed
from fe.structure.twobody import TwoBodySystem, build_two_body, zero_energy_map
from fe.surfaces.geometry import (
    ContactGeometry,
    bilinear_weights,
    contact_operator,
    project_on_facets,
)
from mesh.ball_block import BallBlockBodies, BallBlockGrid, ball_block_mesh
from mesh.hexmesh import HexMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

RACES = (Race.INNER, Race.OUTER)

MESH_LEVELS: dict[int, BallBlockGrid] = {
    0: BallBlockGrid(h_x=0.1, h_y=0.025, h_z=0.03, growth=1.6),
    1: BallBlockGrid(h_x=0.05, h_y=0.0125, h_z=0.015),
    2: BallBlockGrid(h_x=0.035, h_y=0.009, h_z=0.011),
}
"""Mesh levels: fine cell sizes [mm] across the groove (x), along the rolling direction
(y) and in depth; the contact window is the fine window of :class:`BallBlockGrid`."""


def local_frame(p: BearingHingeParams) -> FloatArray:
    """Return the rows (e_x, e_y, e_z) of the local frame in bearing coordinates, (3, 3).

    Bearing coordinates: X radial through the ball, Y circumferential, Z the axis; e_z is
    the contact line toward the outer contact, e_y = Y, e_x = e_y × e_z.
    """
    u = race_geometry(p, 1).direction
    e_z = np.array([u[0], 0.0, u[1]])
    e_y = np.array([0.0, 1.0, 0.0])
    return np.stack([np.cross(e_y, e_z), e_y, e_z])


def model_bodies(p: BearingHingeParams) -> BallBlockBodies:
    """Return the ball radius and both groove tori in the local frame (ball centre at 0)."""
    g = race_geometry(p, 1)
    rot = local_frame(p)
    c = np.array([g.ball_center[0], 0.0, g.ball_center[1]])

    def torus(groove: tuple[float, float], f: float) -> Torus:
        centre = rot @ (np.array([0.0, 0.0, groove[1]]) - c)
        axis = rot @ np.array([0.0, 0.0, 1.0])
        minor = f * p.ball_diameter_mm
        return Torus(tuple(centre.tolist()), tuple(axis.tolist()), groove[0], minor)

    m = p.bearing_material
    return BallBlockBodies(
        radius_mm=0.5 * p.ball_diameter_mm,
        inner_race=torus(g.inner_groove, p.inner_curvature_ratio),
        outer_race=torus(g.outer_groove, p.outer_curvature_ratio),
        ball=m,
        rings=m,
    )


def hertz_reference(p: BearingHingeParams, race: Race, load_n: float) -> ContactEllipse:
    """Return the exact (elliptic-integral) Hertz contact of one raceway at load Q [N]."""
    f = p.inner_curvature_ratio if race is Race.INNER else p.outer_curvature_ratio
    curv = race_curvatures(p.ball_diameter_mm, p.pitch_diameter_mm, p.contact_angle_deg, f, race)
    e_star = effective_modulus(p.bearing_material, p.bearing_material)
    return contact_ellipse(curv, e_star, load_n)


@dataclass
class OneBallRig:
    """The one-ball model, factorised and condensed.

    Attributes:
        params: Bearing parameters.
        grid: Mesh grid.
        mesh: Mesh (with the slave windows ``ball_inner_window``, ``ball_outer_window``).
        system: Assembled, factorised system.
        cond: Condensed operators (points of the inner contact first).
        G: Rigid map, shape (3m, 3): outer grip z, ball x, ball z.
        race_of: Raceway index per contact point (0 inner, 1 outer), shape (m,).
        timings_s: Wall time of mesh, assembly, factorisation and condensation [s].
    """

    params: BearingHingeParams
    grid: BallBlockGrid
    mesh: HexMesh
    system: TwoBodySystem
    cond: Condensed
    G: FloatArray
    race_of: IntArray
    timings_s: dict[str, float]

    @property
    def n_points(self) -> int:
        """Number of contact points m."""
        return len(self.race_of)


def _window(mesh: HexMesh, name: str, grid: BallBlockGrid) -> IntArray:
    """Facets of a ball cap whose centroid lies in the fine window."""
    f = mesh.facet_sets[name]
    c = mesh.nodes[f].mean(axis=1)
    keep = (np.abs(c[:, 0]) <= grid.fine_x) & (c[:, 1] <= grid.fine_y)
    out: IntArray = f[keep]
    return out


def _geometry(mesh: HexMesh, slave: str, master: str) -> ContactGeometry:
    """Contact points of one slave window against an exact torus (as ``two_body_geometry``).

    The slave nodes on the symmetry edge y = 0 project a hair outside the faceted
    master's edge (the facets are chords of the torus), hence ``max_overshoot = 1e-3``.
    """
    surface = mesh.surfaces[master]
    ids, area, _ = mesh.nodal_areas(slave)
    x = mesh.nodes[ids]
    g0 = surface.distance_outside(x)
    n = surface.outward_normal(x)
    t1 = np.array([1.0, 0.0, 0.0]) - n[:, :1] * n
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    facets = mesh.facet_sets[master]
    f, s, _ = project_on_facets(
        x - g0[:, None] * n, mesh.nodes, facets, n_candidates=32, max_overshoot=1e-3
    )
    return ContactGeometry(
        slave=ids,
        pair=np.zeros(len(ids), dtype=np.int64),
        frame=np.stack([n, t1, np.cross(n, t1)], axis=1),
        g0=g0,
        master_nodes=facets[f],
        master_weights=bilinear_weights(s[:, 0], s[:, 1]),
        area_mm2=area,
    )


def _concat(geos: list[ContactGeometry]) -> ContactGeometry:
    fields = ContactGeometry.__dataclass_fields__
    return ContactGeometry(*(np.concatenate([getattr(g, k) for g in geos]) for k in fields))


def condense_normal(system: TwoBodySystem, geo: ContactGeometry, block: int = 256) -> Condensed:
    """Condense on the normal directions only: ``W_nn = C_n K_ff⁻¹ C_nᵀ`` (frictionless).

    With μ = 0 the tangential forces vanish, so the tangential rows and columns of W
    never act: they get the mean normal compliance on the diagonal and zeros elsewhere.
    This needs m solves instead of 3m, and ``K_ff⁻¹ C_nᵀ`` is never stored whole (blocks
    of ``block`` columns), so memory stays ``n_free × block`` beyond W.

    Args:
        system: The factorised system.
        geo: Contact points (m of them).
        block: Right-hand sides per solve.

    Returns:
        The condensed operators, W of shape (3m, 3m) [mm/N]; valid for μ = 0 only.
    """
    t0 = time.perf_counter()
    C = contact_operator(geo, system.n_dof)
    Cn = C[0::3][:, system.free].tocsr()
    m = Cn.shape[0]
    Wnn = np.zeros((m, m))
    for j in range(0, m, block):
        X = system.factor.solve(Cn[j : j + block].T.toarray())
        Wnn[:, j : j + block] = Cn @ X
    W = np.zeros((3 * m, 3 * m))
    W[0::3, 0::3] = 0.5 * (Wnn + Wnn.T)
    compliance = float(np.mean(np.diag(Wnn)))
    W[np.arange(1, 3 * m, 3), np.arange(1, 3 * m, 3)] = compliance
    W[np.arange(2, 3 * m, 3), np.arange(2, 3 * m, 3)] = compliance
    w0 = np.column_stack([geo.g0, np.zeros((m, 2))])
    return Condensed(geo=geo, C=C, W=W, w0=w0, wall_s=time.perf_counter() - t0)


def _rigid_fields(mesh: HexMesh) -> FloatArray:
    """Unit rigid fields, shape (n_dof, 3): outer block along z, ball along x, ball along z."""
    fields = np.zeros((3 * mesh.n_nodes, 3))
    fields[3 * mesh.part_nodes("outer") + 2, 0] = 1.0
    ball = mesh.part_nodes("ball")
    fields[3 * ball, 1] = 1.0
    fields[3 * ball + 2, 2] = 1.0
    return fields


def contact_points_of(
    mesh: HexMesh, grid: BallBlockGrid
) -> tuple[ContactGeometry, IntArray, HexMesh]:
    """Contact points of both ball caps' fine windows against the exact tori.

    Returns:
        (the points, inner ones first; their raceway index (m,), 0 inner 1 outer; the
        mesh with the slave windows ``ball_inner_window`` and ``ball_outer_window``).
    """
    sets = dict(mesh.facet_sets)
    sets["ball_inner_window"] = _window(mesh, "ball_inner", grid)
    sets["ball_outer_window"] = _window(mesh, "ball_outer", grid)
    mesh = dataclasses.replace(mesh, facet_sets=sets)
    geos = [
        _geometry(mesh, "ball_inner_window", "inner_race"),
        _geometry(mesh, "ball_outer_window", "outer_race"),
    ]
    race_of = np.repeat(np.arange(2), [len(g.slave) for g in geos]).astype(np.int64)
    return _concat(geos), race_of, mesh


def build_rig(grid: BallBlockGrid, params: BearingHingeParams | None = None) -> OneBallRig:
    """Mesh, assemble, factorise and condense the one-ball model.

    Args:
        grid: Mesh grid (e.g. ``MESH_LEVELS[1]``).
        params: Bearing parameters; the default 708C when None.
    """
    p = BearingHingeParams() if params is None else params
    t0 = time.perf_counter()
    mesh = ball_block_mesh(model_bodies(p), grid)
    geo, race_of, mesh = contact_points_of(mesh, grid)
    t_mesh = time.perf_counter() - t0

    axis = mesh.set_nodes("ball_axis")
    r = 0.5 * p.ball_diameter_mm
    holder = axis[np.argmin(np.abs(mesh.nodes[axis, 2] - 0.5 * r))]  # stops rotation about y
    fixed = np.concatenate(
        [
            dofs_of(mesh.set_nodes("symmetry"), [1]),
            dofs_of(mesh.set_nodes("inner_base"), [0, 1, 2]),
            dofs_of(mesh.set_nodes("outer_grip"), [0, 1, 2]),
            dofs_of(mesh.set_nodes("ball_centre"), [0, 2]),
            dofs_of(np.array([holder]), [0]),
        ]
    )
    system = build_two_body(mesh, "ball_inner_window", "inner_race", fixed)
    t1 = time.perf_counter()
    cond = condense_normal(system, geo)
    G = zero_energy_map(system, cond, _rigid_fields(mesh))
    timings = {"mesh": t_mesh, **system.timings_s, "condensation": time.perf_counter() - t1}
    return OneBallRig(p, grid, mesh, system, cond, G, race_of, timings)


@dataclass(frozen=True)
class ContactResult:
    """FE measurements of one ball–raceway contact against Hertz.

    Attributes:
        race: Inner or outer.
        hertz: Hertz reference at the load.
        load_n: Resultant contact force of the full ball along the contact line [N]
            (twice the half model's; the normal forces summed as scalars are larger
            by the normals' tilt across the conformal groove).
        n_closed: Closed contact points (half model).
        a_moment_mm: a from the force moments [mm].
        b_moment_mm: b from the force moments [mm].
        a_fit_mm: a from the pressure ellipsoid fit [mm].
        b_fit_mm: b from the fit [mm].
        a_edge_mm: a from the discrete edge on y = 0 [mm].
        b_edge_mm: b from the discrete edge on x = 0 [mm].
        p0_mpa: Largest nodal pressure [MPa].
        depth_mm: (ball, ring) depths of the local approach points [mm].
        approach_local_mm: FE mutual approach of those points [mm].
        approach_local_hertz_mm: Its half-space Hertz value [mm].
        approach_total_mm: Ball centre to the block's far face [mm].
    """

    race: Race
    hertz: ContactEllipse
    load_n: float
    n_closed: int
    a_moment_mm: float
    b_moment_mm: float
    a_fit_mm: float
    b_fit_mm: float
    a_edge_mm: float
    b_edge_mm: float
    p0_mpa: float
    depth_mm: tuple[float, float]
    approach_local_mm: float
    approach_local_hertz_mm: float
    approach_total_mm: float


def _axis_point(mesh: HexMesh, name: str, z: float) -> tuple[int, float]:
    """Node of a set nearest to height z, and its z [mm]."""
    ids = mesh.set_nodes(name)
    k = ids[int(np.argmin(np.abs(mesh.nodes[ids, 2] - z)))]
    return int(k), float(mesh.nodes[k, 2])


def solve_load(
    rig: OneBallRig, load_n: float, approach_depth_mm: float = 0.2
) -> tuple[ContactResult, ContactResult]:
    """Press the ball with Q along the contact line and measure both contacts.

    Args:
        rig: The condensed model.
        load_n: Ball load Q [N] (the half model carries Q/2).
        approach_depth_mm: Target depth of the local approach points [mm].

    Returns:
        (inner, outer) results.

    Raises:
        ParameterError: If a contact reaches the edge of the slave window.
        ConvergenceError: If the contact solve does not converge.
    """
    m = rig.n_points
    res = solve_increment(
        rig.cond.W,
        rig.cond.w0,
        ContactState.initial(m, 3),
        ContactSettings(mu=0.0),
        G=rig.G,
        e=np.array([0.5 * load_n, 0.0, 0.0]),
    )
    st = res.state
    u = rig.system.factor.solve((rig.cond.C.T @ np.ravel(st.p))[rig.system.free])
    disp = np.zeros(rig.system.n_dof)
    disp[rig.system.free] = u
    mesh = rig.mesh
    uz = (disp + _rigid_fields(mesh) @ st.alpha).reshape(-1, 3)[:, 2]
    r = 0.5 * rig.params.ball_diameter_mm
    mat = rig.params.bearing_material
    out = []
    for k, race in enumerate(RACES):
        sel = rig.race_of == k
        xyz = mesh.nodes[rig.cond.geo.slave[sel]]
        force = st.p[sel, 0]
        rim = np.abs(xyz[:, 0]) >= np.abs(xyz[:, 0]).max() - 1e-9
        rim |= xyz[:, 1] >= xyz[:, 1].max() - 1e-9
        if np.any(force[rim] > 0.0):
            raise ParameterError(
                f"{race.value} contact reaches the edge of the contact window at Q = "
                f"{load_n:g} N: widen fine_x/fine_y of the grid"
            )
        area = rig.cond.geo.area_mm2[sel]
        axes = footprint_semi_axes(xyz[:, 0], xyz[:, 1], force, area, rig.grid.h_x, rig.grid.h_y)
        side = -1.0 if race is Race.INNER else 1.0
        nb, zb = _axis_point(mesh, "ball_axis", side * (r - approach_depth_mm))
        ring = "inner_axis" if race is Race.INNER else "outer_axis"
        nr, zr = _axis_point(mesh, ring, side * (r + approach_depth_mm))
        hz = hertz_reference(rig.params, race, load_n)
        d_ball, d_ring = r - abs(zb), abs(zr) - r
        w = [
            halfspace_axis_displacement(hz, d, mat.young_mpa, mat.poisson) for d in (d_ball, d_ring)
        ]
        total = -st.alpha[2] if race is Race.INNER else st.alpha[2] - st.alpha[0]
        out.append(
            ContactResult(
                race=race,
                hertz=hz,
                load_n=2.0 * abs(float(force @ rig.cond.geo.frame[sel, 0, 2])),
                n_closed=int(np.count_nonzero(force > 0.0)),
                a_moment_mm=axes.a_moment,
                b_moment_mm=axes.b_moment,
                a_fit_mm=axes.a_fit,
                b_fit_mm=axes.b_fit,
                a_edge_mm=axes.a_edge,
                b_edge_mm=axes.b_edge,
                p0_mpa=axes.p_max,
                depth_mm=(d_ball, d_ring),
                approach_local_mm=side * float(uz[nb] - uz[nr]),
                approach_local_hertz_mm=hz.approach_mm - w[0] - w[1],
                approach_total_mm=float(total),
            )
        )
    return out[0], out[1]
