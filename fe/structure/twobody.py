"""Two bodies in frictional contact, condensed on the slave nodes: for verification and reuse.

A :class:`~mesh.hexmesh.HexMesh` holds two bodies (any number of parts); one facet set is
the *slave* (its nodes become the contact points) and one is the *master*, whose exact
surface ``mesh.surfaces[master]`` (a Plane, Cylinder, Sphere or Torus) measures the gaps.
Dirichlet DOFs are held at prescribed values; every other DOF is free.

Workflow (conventions of :mod:`fe.contact`)::

    system = build_two_body(mesh, "slave", "master", fixed_dofs)  # assemble, factorise once
    geo = two_body_geometry(mesh, "slave", "master")              # points, frames, g0
    cond = condense(system, geo)                                  # C and W = C K⁻¹ Cᵀ
    u_ext = external_response(system, f_ext=f, u_fixed=u_d)       # p = 0 response
    w_free = free_gap(cond, u_ext)                                # (m, 3) per load step
    G = zero_energy_map(system, cond, fields)                     # force-controlled grips

then ``solve_increment(cond.W, w_free, state, settings, G=G, e=e)`` per load step and
``displacement(system, cond, p, u_ext, fields, alpha)`` for the full field.

Frames: ``n`` is the master's outward normal at the slave point's closest point on the
exact master surface (it points from the master toward the slave), ``t1`` is the
projection of ``tangent_hint`` on the tangent plane (or an automatic orthonormal
completion), ``t2 = n × t1``; ``g0 = master.distance_outside(x_slave)``. The exact slave
surface is used for nothing: the slave nodes are assumed to lie on it already.

Locked directions: a row of ``C`` that vanishes on the free DOFs (e.g. ``t2 = ∓z`` when
every node has ``u_z = 0`` in a plane-strain slice) gives a zero row and column of ``W``,
which makes the contact Newton matrix singular for sticking points. Such a direction gets
the mean diagonal compliance instead. Nothing drives it (``W`` is zero off its diagonal
there and ``w_free`` comes from the same zero row when ``u_fixed`` does not move it), so
its force stays exactly zero whether the point sticks or slips; :class:`Condensed`
records which directions were locked.

Force control through ``G``: a unit field ``φ_j`` whose amplitude ``α_j`` is a load
parameter (a rigid grip on a body that touches nothing else) enters as ``G = C φ``
with ``Gᵀ p = e``. It is exact only if ``φ_j`` costs no strain energy, which
:func:`zero_energy_map` checks.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from cad.errors import MeshQualityError, ParameterError
from fe.assembly import assemble_stiffness
from fe.element import ElementType
from fe.linalg.sparse import Factorization
from fe.structure.condensed import BLOCK_RHS, Condensed
from fe.surfaces.geometry import (
    ContactGeometry,
    bilinear_weights,
    contact_operator,
    project_on_facets,
)
from mesh.hexmesh import HexMesh

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

ZERO_ENERGY_RTOL = 1e-8
"""Largest ``|K φ|_free / |K|·|φ|`` for a field to count as zero-energy."""

__all__ = [
    "TwoBodySystem",
    "build_two_body",
    "condense",
    "displacement",
    "external_response",
    "free_gap",
    "two_body_geometry",
    "zero_energy_map",
]


@dataclass
class TwoBodySystem:
    """The assembled and factorised two-body mesh.

    Attributes:
        mesh: The mesh.
        slave: Name of the slave facet set.
        master: Name of the master facet set (with an exact surface).
        K: Global stiffness, shape (n_dof, n_dof), CSR, float64 [N/mm].
        fixed: Dirichlet DOFs, sorted, shape (n_fixed,), int64.
        free: All other DOFs, sorted, shape (n_free,), int64.
        factor: Factorisation of ``K[free, free]``.
        timings_s: Wall time of assembly and factorisation [s].
    """

    mesh: HexMesh
    slave: str
    master: str
    K: sp.csr_matrix
    fixed: IntArray
    free: IntArray
    factor: Factorization
    timings_s: dict[str, float] = field(default_factory=dict)

    @property
    def n_dof(self) -> int:
        """Number of DOFs of the whole mesh."""
        return 3 * self.mesh.n_nodes


def build_two_body(
    mesh: HexMesh,
    slave: str,
    master: str,
    fixed_dofs: npt.ArrayLike,
    kind: ElementType = ElementType.INCOMPATIBLE,
) -> TwoBodySystem:
    """Assemble the stiffness and factorise it on the free DOFs.

    Args:
        mesh: Mesh holding both bodies, the two facet sets and ``mesh.surfaces[master]``.
        slave: Slave facet set name.
        master: Master facet set name.
        fixed_dofs: Dirichlet DOFs ``3 node + component``, shape (n_fixed,), integer
            (repeats allowed). They must suppress every rigid mode of every body except
            those later driven through :func:`zero_energy_map` as grips.
        kind: Element formulation.

    Returns:
        The factorised system.

    Raises:
        MeshQualityError: If a facet set or the master surface is missing.
        ParameterError: If a fixed DOF is out of range or ``K[free, free]`` is singular.
    """
    for name in (slave, master):
        if name not in mesh.facet_sets:
            raise MeshQualityError(f"the mesh has no facet set {name!r}")
    if master not in mesh.surfaces:
        raise MeshQualityError(f"master facet set {master!r} has no exact surface in mesh.surfaces")
    n_dof = 3 * mesh.n_nodes
    fixed = np.unique(np.asarray(fixed_dofs, dtype=np.int64).ravel())
    if fixed.size and (fixed[0] < 0 or fixed[-1] >= n_dof):
        raise ParameterError(f"fixed_dofs must lie in [0, {n_dof}), got {fixed[0]}..{fixed[-1]}")
    free = np.setdiff1d(np.arange(n_dof, dtype=np.int64), fixed)
    t0 = time.perf_counter()
    K = assemble_stiffness(mesh, kind)
    t1 = time.perf_counter()
    factor = Factorization(K[free][:, free])
    t2 = time.perf_counter()
    logger.info("two-body system: %d free DOF, factorised in %.2f s", len(free), t2 - t1)
    timings = {"assembly": t1 - t0, "factorisation": t2 - t1}
    return TwoBodySystem(mesh, slave, master, K, fixed, free, factor, timings)


def _tangents(n: FloatArray, hint: FloatArray | None) -> tuple[FloatArray, FloatArray]:
    """Return (t1, t2), each (m, 3): ``t1`` ⟂ n from ``hint`` (or the least-aligned axis)."""
    if hint is None:
        axis = np.argmin(np.abs(n), axis=1)
        ref = np.eye(3)[axis]  # (m, 3)
    else:
        ref = np.broadcast_to(hint, n.shape)
    t1 = ref - np.sum(ref * n, axis=1)[:, None] * n
    length = np.linalg.norm(t1, axis=1)
    if np.any(length < 1e-6):
        i = int(np.argmin(length))
        raise ParameterError(
            f"tangent_hint {np.round(ref[i], 6).tolist()} is parallel to the normal at point {i}"
        )
    t1 = t1 / length[:, None]
    return t1, np.cross(n, t1)


def two_body_geometry(
    mesh: HexMesh,
    slave: str,
    master: str,
    *,
    slave_shift_mm: npt.ArrayLike = (0.0, 0.0, 0.0),
    tangent_hint: npt.ArrayLike | None = None,
) -> ContactGeometry:
    """Build the contact points (slave nodes) against the exact master surface.

    Args:
        mesh: The mesh.
        slave: Slave facet set; its nodes are the contact points.
        master: Master facet set with an exact surface in ``mesh.surfaces``.
        slave_shift_mm: Rigid offset of the slave relative to the mesh position in the
            configuration to linearise about, shape (3,) [mm].
        tangent_hint: Direction projected on the tangent plane to give ``t1``, shape (3,);
            None picks, per point, the coordinate axis least aligned with ``n``.

    Returns:
        The geometry: ``pair`` is 0 for every point, ``g0`` the signed distance [mm]
        of the slave node from the exact master surface, ``master_nodes`` and
        ``master_weights`` the bilinear master facet under the closest surface point.

    Raises:
        MeshQualityError: If a set or the surface is missing, or a point's closest
            surface point lies outside every master facet.
    """
    if master not in mesh.surfaces:
        raise MeshQualityError(f"master facet set {master!r} has no exact surface in mesh.surfaces")
    surface = mesh.surfaces[master]
    ids, area, _ = mesh.nodal_areas(slave)
    x = np.asarray(mesh.nodes)[ids] + np.asarray(slave_shift_mm, dtype=np.float64)  # (m, 3)
    g0 = surface.distance_outside(x)
    n = surface.outward_normal(x)  # (m, 3), master → slave
    hint = None if tangent_hint is None else np.asarray(tangent_hint, dtype=np.float64)
    t1, t2 = _tangents(n, hint)
    foot = x - g0[:, None] * n  # closest point on the exact master surface
    facets = mesh.facet_sets[master]
    f, s, _ = project_on_facets(foot, np.asarray(mesh.nodes), facets)
    return ContactGeometry(
        slave=ids,
        pair=np.zeros(len(ids), dtype=np.int64),
        frame=np.stack([n, t1, t2], axis=1),
        g0=g0,
        master_nodes=facets[f],
        master_weights=bilinear_weights(s[:, 0], s[:, 1]),
        area_mm2=area,
    )


def condense(system: TwoBodySystem, geo: ContactGeometry) -> Condensed:
    """Condense the system on the contact points: ``W = C_f K_ff⁻¹ C_fᵀ``.

    ``K_ff⁻¹ C_fᵀ`` is solved by blocks of ``BLOCK_RHS`` right-hand sides with the one
    factorisation of :func:`build_two_body`.

    Args:
        system: The factorised system.
        geo: Contact points, e.g. from :func:`two_body_geometry`.

    Returns:
        The condensed operators.

    Raises:
        MeshQualityError: If a normal direction is locked (a point that cannot move
            normally relative to the master cannot be a contact point).
    """
    t0 = time.perf_counter()
    C = contact_operator(geo, system.n_dof)
    C_f = sp.csr_matrix(C[:, system.free])
    row_norm = np.sqrt(np.asarray(C_f.multiply(C_f).sum(axis=1)).ravel())
    locked = row_norm <= 1e-12 * max(float(row_norm.max()), 1e-300)
    if np.any(locked[0::3]):
        i = int(np.flatnonzero(locked[0::3])[0])
        raise MeshQualityError(
            f"contact point {i} (node {geo.slave[i]}) has its normal direction fully constrained"
        )
    live = np.flatnonzero(~locked)  # locked rows are zero: no solve needed
    C_live = C_f[live]
    X = np.zeros((len(system.free), len(live)))
    for j in range(0, len(live), BLOCK_RHS):
        X[:, j : j + BLOCK_RHS] = system.factor.solve(C_live[j : j + BLOCK_RHS].T.toarray())
    W_live = np.asarray(C_live @ X)
    W = np.zeros((C.shape[0], C.shape[0]))
    W[np.ix_(live, live)] = 0.5 * (W_live + W_live.T)
    compliance = float(np.mean(np.diag(W_live)))
    W[locked, locked] = compliance
    w0 = np.column_stack([geo.g0, np.zeros((len(geo.g0), 2))])
    return Condensed(
        geo=geo,
        C=C,
        W=W,
        w0=w0,
        wall_s=time.perf_counter() - t0,
        locked=locked,
        locked_compliance=compliance,
    )


def external_response(
    system: TwoBodySystem,
    *,
    f_ext: npt.ArrayLike | None = None,
    u_fixed: npt.ArrayLike | None = None,
) -> FloatArray:
    """Return the displacement with zero contact force: ``K_ff u_f = f_f − K_fd u_d``.

    Args:
        system: The factorised system.
        f_ext: External nodal forces, shape (n_dof,) [N] (entries on fixed DOFs ignored);
            None for none.
        u_fixed: Values of the fixed DOFs in ``system.fixed`` order, shape (n_fixed,)
            [mm]; None for zero.

    Returns:
        u, shape (n_dof,), float64 [mm].

    Raises:
        ParameterError: On wrong shapes.
    """
    n_dof = system.n_dof
    f = np.zeros(n_dof) if f_ext is None else np.asarray(f_ext, dtype=np.float64)
    ud = np.zeros(len(system.fixed)) if u_fixed is None else np.asarray(u_fixed, dtype=np.float64)
    if f.shape != (n_dof,) or ud.shape != system.fixed.shape:
        raise ParameterError(
            f"f_ext must have shape ({n_dof},) and u_fixed {system.fixed.shape}, "
            f"got {f.shape} and {ud.shape}"
        )
    u = np.zeros(n_dof)
    u[system.fixed] = ud
    rhs = f[system.free] - system.K[system.free][:, system.fixed] @ ud
    u[system.free] = system.factor.solve(rhs)
    return u


def free_gap(cond: Condensed, u_ext: FloatArray) -> FloatArray:
    """Return ``w_free = w0 + C u_ext``, shape (m, 3) [mm], for :func:`solve_increment`.

    Args:
        cond: The condensed system.
        u_ext: Displacement with zero contact force, shape (n_dof,) [mm].
    """
    w: FloatArray = cond.w0 + np.asarray(cond.C @ np.ravel(u_ext), dtype=np.float64).reshape(-1, 3)
    return w


def zero_energy_map(system: TwoBodySystem, cond: Condensed, fields: FloatArray) -> FloatArray:
    """Return ``G = C φ`` for force-controlled grip amplitudes, shape (3m, k).

    Args:
        system: The factorised system.
        cond: The condensed system.
        fields: Unit displacement fields φ, shape (n_dof, k) [mm per unit amplitude],
            e.g. a rigid translation of a body whose fixed DOFs are its grip.

    Returns:
        G, shape (3m, k); the loads are then ``e = Gᵀ p`` [N], i.e. minus the grip
        force on the body in the field's direction.

    Raises:
        ParameterError: If a field costs strain energy (``|K φ|`` on the free DOFs above
            ``ZERO_ENERGY_RTOL · max|K| · max|φ|``): its amplitude would then need a
            stiffness that ``solve_increment`` does not have.
    """
    phi = np.asarray(fields, dtype=np.float64).reshape(system.n_dof, -1)
    residual = np.abs(system.K @ phi)[system.free].max(axis=0)  # (k,)
    scale = ZERO_ENERGY_RTOL * abs(system.K).max() * np.abs(phi).max(axis=0)
    if np.any(residual > scale):
        j = int(np.argmax(residual / np.maximum(scale, 1e-300)))
        raise ParameterError(
            f"field {j} is not zero-energy: max|K φ| on free DOFs = {residual[j]:.3e} N"
        )
    return np.asarray(cond.C @ phi)


def displacement(
    system: TwoBodySystem,
    cond: Condensed,
    p: FloatArray,
    u_ext: FloatArray | None = None,
    fields: FloatArray | None = None,
    alpha: FloatArray | None = None,
) -> FloatArray:
    """Recover the displacement ``u = u_ext + K_ff⁻¹ Cᵀ p + φ α``, shape (n_nodes, 3) [mm].

    Args:
        system: The factorised system.
        cond: The condensed system.
        p: Contact forces on the slave, shape (m, 3) [N], local frames.
        u_ext: Displacement with zero contact force, shape (n_dof,) [mm]; None for zero.
        fields: Grip fields φ, shape (n_dof, k); None for none.
        alpha: Grip amplitudes, shape (k,); required with ``fields``.
    """
    f = cond.C.T @ np.ravel(p)  # nodal contact forces, shape (n_dof,)
    u = np.zeros(system.n_dof) if u_ext is None else np.array(u_ext, dtype=np.float64)
    u[system.free] += system.factor.solve(f[system.free])
    if fields is not None and alpha is not None:
        u += np.asarray(fields).reshape(system.n_dof, -1) @ np.asarray(alpha)
    return u.reshape(-1, 3)
