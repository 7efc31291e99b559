"""Graded plane-strain meshes of a cylinder pressed on a flat, for the Hertz/Mindlin tests.

Geometry (x across the contact, y the load direction, z the cylinder axis)::

          +----------- cyl_top (rigid grip) -----------+   y = H
          |                                            |
          |   cylinder body: bottom face on the circle |
          |   x² + (y − R)² = R² (nodes exactly on it)  |
          +-..                                     ..-+
               ''--..___  cyl_contact  ___..--''           y = R − √(R² − x²)
    +---------------------- flat_top -----------------------+   y = 0 (Plane, normal +y)
    |                     flat body                         |
    +--------------------- flat_bottom ---------------------+   y = −H

Both bodies are one element thick in z (thickness ``h``); with ``u_z = 0`` on every node
(all nodes lie on the two end faces) the discrete solution is exactly plane strain.
The x grid is uniform with size ``h`` over ``|x| <= fine_half_width`` and grows
geometrically outside; the y grid is uniform over ``fine_depth`` and grows away from
the contact. Both bodies share the x grid, so slave nodes sit over master nodes.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from cad.materials import Material
from cad.surfaces import Cylinder, Plane
from fe.assembly import dofs_of
from fe.structure.condensed import Condensed
from fe.structure.twobody import (
    TwoBodySystem,
    build_two_body,
    condense,
    two_body_geometry,
    zero_energy_map,
)
from mesh.hexmesh import HexMesh
from tests.helpers import box_mesh, merge_meshes


@dataclass(frozen=True)
class CylinderOnFlat:
    """Parameters of the graded cylinder-on-flat mesh [mm]."""

    radius_mm: float
    h_mm: float  # fine element size (also the z thickness)
    fine_half_width_mm: float  # uniform x grid over |x| <= this
    fine_depth_mm: float  # uniform y grid over this depth from the contact
    half_width_mm: float  # bodies span |x| <= this
    height_mm: float  # each body is this tall
    contact_half_width_mm: float  # slave facets with |x_centroid| <= this
    growth: float
    cylinder: Material
    flat: Material


def graded_axis(h: float, fine: float, length: float, growth: float) -> np.ndarray:
    """Coordinates 0 … length: cells of size h up to ``fine``, then growing by ``growth``.

    The graded cells are scaled so the last node lands on ``length`` exactly.
    """
    n_fine = round(fine / h)
    cells = [h] * n_fine
    rest = length - n_fine * h
    graded = []
    size = h * growth
    while sum(graded) + size < rest:
        graded.append(size)
        size *= growth
    graded_arr = np.asarray(graded) * (rest / sum(graded)) if graded else np.asarray([rest])
    return np.concatenate([[0.0], np.cumsum(np.concatenate([cells, graded_arr]))])


def _mapped_box(xs: np.ndarray, ys: np.ndarray, h: float, prefix: str, mat: Material) -> HexMesh:
    """A box_mesh whose grid lines are moved to xs × ys × [0, h]."""
    box = box_mesh(
        len(xs) - 1,
        len(ys) - 1,
        1.0,
        len(xs) - 1,
        len(ys) - 1,
        1,
        part=prefix,
        material=mat,
        set_prefix=prefix,
    )
    ij = np.rint(box.nodes).astype(np.int64)
    nodes = np.column_stack([xs[ij[:, 0]], ys[ij[:, 1]], h * ij[:, 2]]).astype(np.float64)
    return dataclasses.replace(box, nodes=nodes)


def cylinder_on_flat(p: CylinderOnFlat) -> HexMesh:
    """Return the mesh: sets cyl_contact (slave), flat_top (master), cyl_top, flat_bottom."""
    half = graded_axis(p.h_mm, p.fine_half_width_mm, p.half_width_mm, p.growth)
    xs = np.concatenate([-half[:0:-1], half])
    ys = graded_axis(p.h_mm, p.fine_depth_mm, p.height_mm, p.growth)
    R, H = p.radius_mm, p.height_mm
    if p.half_width_mm >= R:
        raise ValueError(f"half_width_mm must be < radius_mm, got {p.half_width_mm} >= {R}")

    cyl = _mapped_box(xs, ys, p.h_mm, "cyl_", p.cylinder)
    x, y = cyl.nodes[:, 0], cyl.nodes[:, 1]
    sag = R - np.sqrt(R**2 - x**2)  # bottom face on the circle, blended to a flat top
    cyl_nodes = np.column_stack([x, y + (1.0 - y / H) * sag, cyl.nodes[:, 2]])
    bottom = cyl.facet_sets["cyl_ymin"]
    centroid_x = cyl_nodes[bottom][:, :, 0].mean(axis=1)
    cyl = dataclasses.replace(
        cyl,
        nodes=cyl_nodes,
        part_names=("cylinder",),
        facet_sets={
            "cyl_contact": bottom[np.abs(centroid_x) <= p.contact_half_width_mm],
            "cyl_top": cyl.facet_sets["cyl_ymax"],
        },
        surfaces={"cyl_contact": Cylinder((0.0, R, 0.0), (0.0, 0.0, 1.0), R, True)},
    )

    flat = _mapped_box(xs, -ys[::-1], p.h_mm, "flat_", p.flat)
    flat = dataclasses.replace(
        flat,
        part_names=("flat",),
        facet_sets={
            "flat_top": flat.facet_sets["flat_ymax"],
            "flat_bottom": flat.facet_sets["flat_ymin"],
        },
        surfaces={"flat_top": Plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))},
    )
    return merge_meshes(cyl, flat)


@dataclass
class PressRig:
    """The cylinder-on-flat mesh condensed on its contact points, with a rigid grip.

    The cylinder's top face is a rigid grip: it is a Dirichlet face for the
    factorisation, and its translation (δx, δy) is driven through ``G`` by the force
    ``e = (−Q, P)`` (``Gᵀp = e``: the contact force on the cylinder balances the grip).
    The flat's bottom is clamped; every node has ``u_z = 0`` (plane strain).
    """

    mesh: HexMesh
    system: TwoBodySystem
    cond: Condensed
    grip: np.ndarray  # (n_dof, 2): unit translations x, y of the whole cylinder
    G: np.ndarray  # (3m, 2): C @ grip
    x: np.ndarray  # (m,) x of the contact points [mm]
    z: np.ndarray  # (m,) z of the contact points [mm]


def press_rig(p: CylinderOnFlat) -> PressRig:
    """Build, factorise and condense the cylinder-on-flat model."""
    mesh = cylinder_on_flat(p)
    fixed = np.concatenate(
        [
            dofs_of(np.arange(mesh.n_nodes), [2]),
            dofs_of(mesh.set_nodes("cyl_top"), [0, 1]),
            dofs_of(mesh.set_nodes("flat_bottom"), [0, 1]),
        ]
    )
    system = build_two_body(mesh, "cyl_contact", "flat_top", fixed)
    geo = two_body_geometry(mesh, "cyl_contact", "flat_top", tangent_hint=(1.0, 0.0, 0.0))
    cond = condense(system, geo)
    grip = np.zeros((system.n_dof, 2))
    cyl_nodes = mesh.part_nodes("cylinder")
    grip[3 * cyl_nodes, 0] = 1.0
    grip[3 * cyl_nodes + 1, 1] = 1.0
    G = zero_energy_map(system, cond, grip)
    xz = mesh.nodes[geo.slave]
    return PressRig(mesh, system, cond, grip, G, xz[:, 0], xz[:, 2])


def plane_strain_modulus(a: Material, b: Material) -> float:
    """Return E* [MPa]: 1/E* = (1 − ν1²)/E1 + (1 − ν2²)/E2."""
    return 1.0 / ((1 - a.poisson**2) / a.young_mpa + (1 - b.poisson**2) / b.young_mpa)
