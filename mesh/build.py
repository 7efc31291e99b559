"""Mesh a whole hinge: every part into hexahedra, named sets picked, quality checked."""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import MeshQualityError
from cad.model import FaceRole, HingeModel, Part, Sweep
from cad.surfaces import Cylinder
from mesh.facets import boundary_facets, select_facets
from mesh.hexmesh import HexMesh
from mesh.quality import check_quality, hex_volumes
from mesh.settings import MeshSettings
from mesh.sweep import CircleSize, extrude, mesh_profile

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

VOLUME_RETRIES = 3
"""Attempts at a volume-meshed part, each with sizes 3 % smaller than the last."""

SET_TOL_MM = 1e-4
"""Largest distance of a node from a named face's exact surface to count as on it [mm]."""


@dataclass(frozen=True)
class MeshReport:
    """Quality figures of a hinge mesh.

    Attributes:
        n_nodes: Node count.
        n_hex: Hexahedron count.
        hex_fraction: Fraction of elements that are hexahedra (1.0: we make nothing else).
        min_scaled_jacobian: Smallest corner scaled Jacobian.
        parts: Part name → {"n_hex", "volume_mm3" (solid), "mesh_volume_mm3", "volume_rel_err"}.
        sets: Facet-set name → number of facets.
        wall_s: Meshing wall time [s].
    """

    n_nodes: int
    n_hex: int
    hex_fraction: float
    min_scaled_jacobian: float
    parts: dict[str, dict[str, float]]
    sets: dict[str, int]
    wall_s: float


def _contact_sizes(model: HingeModel, part: Part, s: MeshSettings) -> tuple[CircleSize, ...]:
    """Circles of a swept part that carry a contact surface, with the size wanted on them."""
    out = []
    for face in model.faces.values():
        if face.part != part.name or not isinstance(face.surface, Cylinder):
            continue
        if face.role is FaceRole.CONTACT_SLAVE:
            out.append(CircleSize(face.surface.radius_mm, s.slave_mm))
        elif face.role is FaceRole.CONTACT_MASTER:
            out.append(CircleSize(face.surface.radius_mm, s.master_mm))
    return tuple(dict.fromkeys(out))


def _slab_dz(
    model: HingeModel, part: Part, sweep: Sweep, s: MeshSettings, circles: tuple[CircleSize, ...]
) -> tuple[float, ...]:
    """Layer thickness per slab: the contact size where a contact face spans the slab, else global."""
    contact_z = [
        (f.box[0][2], f.box[1][2])
        for f in model.faces.values()
        if f.part == part.name and f.role in (FaceRole.CONTACT_SLAVE, FaceRole.CONTACT_MASTER)
    ]
    fine = min((c.size_mm for c in circles), default=s.size_for(part.name))
    out = []
    for slab in sweep.slabs:
        in_contact = any(
            lo <= slab.z0_mm + 1e-9 and slab.z1_mm <= hi + 1e-9 for lo, hi in contact_z
        )
        out.append(fine if in_contact else s.size_for(part.name))
    return tuple(out)


PIN_BAND_MAX_FRACTION = 0.5
"""Deepest pin band, as a fraction of the pin's radius, tried instead of the O-grid.

The band's inner circle keeps the surface's segment count, so its segments shrink
with its radius; at half the radius the core inside is as fine as the band, and the
O-grid of the cad profile (core square at half the radius) is cheaper."""


def _pin_band(model: HingeModel, part: Part, s: MeshSettings) -> tuple[CircleSize, float] | None:
    """Return (the pin's slave circle, band depth [mm]) if ``part`` may get a band, else None.

    A part may if it is swept, has a slave contact cylinder with its material inside
    (a pin), and the band asked for is shallower than ``PIN_BAND_MAX_FRACTION`` of
    that radius. ``mesh_part`` then keeps the banded profile only if it has fewer
    nodes than the O-grid: with few segments round the pin (32 at the default
    refinement 0) the band, its pillow ring and a core no coarser than the band's
    inner segments cost more nodes than the O-grid's core square.
    """
    if part.sweep is None or not math.isfinite(s.pin_band_mm):
        return None
    for face in model.faces.values():
        surface = face.surface
        if (
            face.part == part.name
            and face.role is FaceRole.CONTACT_SLAVE
            and isinstance(surface, Cylinder)
            and surface.material_inside
            and s.pin_band_mm < PIN_BAND_MAX_FRACTION * surface.radius_mm
        ):
            return CircleSize(surface.radius_mm, s.slave_mm), s.pin_band_mm
    return None


def mesh_part(model: HingeModel, part: Part, s: MeshSettings) -> tuple[FloatArray, IntArray]:
    """Mesh one part: swept if it is prismatic, volume-meshed by gmsh otherwise.

    Returns:
        (nodes (n, 3) [mm], hexes (n_elem, 8) int64).
    """
    if part.sweep is not None:
        circles = _contact_sizes(model, part, s)
        size = s.size_for(part.name)
        profile = mesh_profile(part.sweep, size, circles, arc_grading=s.arc_grading)
        band = _pin_band(model, part, s)
        if band is not None:  # the pin's circle first: the band lies under circles[0]
            first = (band[0], *(c for c in circles if c != band[0]))
            banded = mesh_profile(
                part.sweep, size, first, arc_grading=s.arc_grading, band_mm=band[1]
            )
            if len(banded.xy) < len(profile.xy):
                profile = banded
        return extrude(profile, part.sweep, _slab_dz(model, part, part.sweep, s, circles))
    from mesh.volume import mesh_solid_hex  # only volume-meshed parts need it

    error: MeshQualityError | None = None
    for attempt in range(VOLUME_RETRIES):
        # A tet sliver occasionally tangles when gmsh splits it into hexes; the same
        # solid at sizes 3 % smaller meshes differently, so retry before giving up.
        k = 0.97**attempt
        refine = [
            (
                f.surface,
                f.box,
                k * (s.slave_mm if f.role is FaceRole.CONTACT_SLAVE else s.master_mm),
            )
            for f in model.faces.values()
            if f.part == part.name and f.role in (FaceRole.CONTACT_SLAVE, FaceRole.CONTACT_MASTER)
        ]
        try:
            nodes, hexes = mesh_solid_hex(part.solid, k * s.size_for(part.name), refine)
        except MeshQualityError as err:
            error = err
            logger.warning(
                "%s: %s; retrying with sizes × %.2f", part.name, err, 0.97 ** (attempt + 1)
            )
            continue
        return nodes, hexes
    raise MeshQualityError(
        f"{part.name}: no valid hex mesh after {VOLUME_RETRIES} tries: {error}"
    ) from error


def mesh_hinge(
    model: HingeModel, settings: MeshSettings | None = None
) -> tuple[HexMesh, MeshReport]:
    """Mesh every part of a hinge and pick its named facet sets.

    Args:
        model: The hinge from ``cad``.
        settings: Element sizes; defaults to ``MeshSettings()``.

    Returns:
        The validated mesh and its quality report.

    Raises:
        MeshQualityError: On an inverted element or an empty named set.
    """
    s = settings or MeshSettings()
    t0 = time.perf_counter()
    all_nodes, all_hexes, part_of = [], [], []
    offset = 0
    for i, part in enumerate(model.parts):
        nodes, hexes = mesh_part(model, part, s)
        logger.info("meshed %s: %d hexes, %d nodes", part.name, len(hexes), len(nodes))
        all_nodes.append(nodes)
        all_hexes.append(hexes + offset)
        part_of.append(np.full(len(hexes), i, dtype=np.int64))
        offset += len(nodes)
    nodes = np.concatenate(all_nodes)
    hexes = np.concatenate(all_hexes)
    elem_part = np.concatenate(part_of)
    min_sj = check_quality(nodes, hexes)
    facets, owner = boundary_facets(hexes)
    names = [p.name for p in model.parts]
    facet_sets = {}
    for face in model.faces.values():
        mine = elem_part[owner] == names.index(face.part)
        chosen = facets[mine][
            select_facets(nodes, facets[mine], face.surface, face.box, SET_TOL_MM)
        ]
        if len(chosen) == 0:
            raise MeshQualityError(
                f"named face {face.name!r} of part {face.part!r} selected no facets"
            )
        facet_sets[face.name] = chosen
    surfaces = {
        f.name: f.surface
        for f in model.faces.values()
        if f.role
        in (
            FaceRole.CONTACT_SLAVE,
            FaceRole.CONTACT_MASTER,
            FaceRole.BONDED_SLAVE,
            FaceRole.BONDED_MASTER,
        )
    }
    mesh = HexMesh(
        nodes=nodes,
        hexes=hexes,
        elem_part=elem_part,
        part_names=tuple(names),
        materials=tuple(p.material for p in model.parts),
        facet_sets=facet_sets,
        surfaces=surfaces,
        pairs=model.pairs,
    )
    volumes = hex_volumes(nodes, hexes)
    solid_vol = model.volumes_mm3()
    parts = {}
    for i, name in enumerate(names):
        v = float(volumes[elem_part == i].sum())
        parts[name] = {
            "n_hex": int((elem_part == i).sum()),
            "volume_mm3": solid_vol[name],
            "mesh_volume_mm3": v,
            "volume_rel_err": (v - solid_vol[name]) / solid_vol[name],
        }
    report = MeshReport(
        n_nodes=len(nodes),
        n_hex=len(hexes),
        hex_fraction=1.0,
        min_scaled_jacobian=min_sj,
        parts=parts,
        sets={k: len(v) for k, v in facet_sets.items()},
        wall_s=time.perf_counter() - t0,
    )
    return mesh, report
