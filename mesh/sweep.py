"""Hexahedral meshes of prismatic parts: gmsh quad-meshes the profile, we extrude it.

The general hinge's parts are prismatic along the pin axis (``cad.model.Sweep``):
gmsh meshes their build123d profile faces into all-quadrilateral 2-D meshes, graded
toward the contact circles, and each quad is extruded through the part's slabs into
hexahedra. Faces that touch share their edge mesh, so the result is conforming, and
every element is a right prism of a quad: no tetrahedra, no pyramids.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from cad.errors import GeometryError
from cad.model import Sweep
from mesh.band import banded_disk, check_band, pillow_core
from mesh.gmsh_session import gmsh_session

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

BAND_GROWTH = 0.4
"""Growth of the element size per mm of distance inward from a pin band's inner circle,
toward the part's global size [mm/mm]: about 1.4× from one element ring to the next."""

MAX_GROWTH = 2.5
"""Largest length ratio of neighbouring segments on a graded arc. Grading 9 over three
segments (ratio 3) inverted an element of the unstructured face next to the ring; every
tested size with ratios ≤ 2.5 stayed valid. The default grading 6 never reaches the cap."""

QUAD4 = 3
"""gmsh element type of the 4-node quadrangle."""


@dataclass(frozen=True)
class CircleSize:
    """A circle of the profile (a hole or pin edge) and the element size wanted on it.

    Attributes:
        radius_mm: Circle radius, centred on the pin axis (x = y = 0) [mm].
        size_mm: Element edge length on the circle [mm].
    """

    radius_mm: float
    size_mm: float


@dataclass(frozen=True)
class ProfileMesh:
    """An all-quad mesh of a part's profile.

    Attributes:
        xy: Node coordinates in the profile plane, shape (n, 2) [mm].
        quads: Counter-clockwise quads (normal +z), shape (n_q, 4), int64.
        quad_face: Index of the profile face each quad belongs to, shape (n_q,), int64.
    """

    xy: FloatArray
    quads: IntArray
    quad_face: IntArray


def mesh_profile(
    sweep: Sweep,
    size_mm: float,
    circles: tuple[CircleSize, ...],
    *,
    arc_grading: float = 1.0,
    band_mm: float | None = None,
) -> ProfileMesh:
    """Mesh the profile faces of a swept part into quadrilaterals with gmsh.

    With ``band_mm`` the profile must be the solid disk bounded by ``circles[0]`` (a
    pin), extruded whole in every slab; its faces are replaced by a structured band
    ``band_mm`` deep under the circle, four quarter annuli with the circle's segment
    counts and grading (so the circle's nodes are those of the faces it replaces), and
    an unstructured core graded from the band's inner segments to ``size_mm``
    (``BAND_GROWTH``) and pillowed against ears (``mesh.band.pillow_core``). Every
    quad then has ``quad_face`` 0.

    Args:
        sweep: The part's profile faces and slabs.
        size_mm: Element size away from the circles [mm].
        circles: Circles to refine (contact edges), each with its own size.
        arc_grading: Longest over shortest segment along structured arcs, shortest at
            the load line (θ = 0°, 180°); 1 is uniform.
        band_mm: Depth of the structured band under ``circles[0]`` [mm], in
            (0, radius); None meshes the profile faces as they are.

    Returns:
        The conforming quad mesh of all profile faces.

    Raises:
        GeometryError: If gmsh fails or leaves a non-quad element, or if a band is
            asked for a profile that is not one disk extruded whole.
    """
    if band_mm is not None:
        if not circles:
            raise GeometryError("a pin band needs the contact circle it lies under")
        check_band(sweep, circles[0].radius_mm, band_mm)
    with tempfile.TemporaryDirectory() as tmp, gmsh_session("profile") as gmsh:
        try:
            if band_mm is None:
                face_of_surface = _import_profile(gmsh, sweep, Path(tmp))
                core: set[int] = set()
            else:
                face_of_surface, core = banded_disk(gmsh, circles[0].radius_mm, band_mm)
            # Mesh at twice the size, recombine, then split every element into quads
            # (quad → 4, triangle → 3): all-quad whatever the parity of the boundary.
            _set_sizes(
                gmsh,
                2.0 * size_mm,
                tuple(CircleSize(c.radius_mm, 2.0 * c.size_mm) for c in circles),
                arc_grading,
                band_mm=band_mm,
                core=core,
            )
            gmsh.option.setNumber("Mesh.Algorithm", 8)  # frontal-Delaunay for quads
            gmsh.option.setNumber("Mesh.RecombineAll", 1)
            gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)  # blossom
            gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 1)  # all quadrangles
            gmsh.option.setNumber("Mesh.Smoothing", 5)
            gmsh.model.mesh.generate(2)
            profile = _collect_quads(gmsh, face_of_surface)
        except GeometryError:
            raise
        except Exception as err:
            raise GeometryError(f"gmsh could not mesh the profile: {err}") from err
    if band_mm is None:
        return profile
    inner_mm = circles[0].radius_mm - band_mm
    xy, quads = pillow_core(profile.xy, profile.quads, inner_mm)
    return ProfileMesh(xy, quads, np.zeros(len(quads), dtype=np.int64))


def _import_profile(gmsh: Any, sweep: Sweep, tmp: Path) -> dict[int, int]:
    """Load the profile faces into gmsh, fragmented so that touching faces share edges.

    Returns:
        gmsh surface tag → index of the profile face it came from.
    """
    from build123d import export_brep  # the faces are build123d's: it is loaded already

    inputs = []
    for i, face in enumerate(sweep.profile):
        path = tmp / f"face_{i}.brep"
        export_brep(face, str(path))
        inputs.append(gmsh.model.occ.importShapes(str(path)))
    flat = [dt for dts in inputs for dt in dts]
    if len(flat) > 1:  # make touching faces share their edges (a conforming mesh)
        _, children = gmsh.model.occ.fragment(flat, [])
    else:
        children = [flat]
    gmsh.model.occ.synchronize()
    return _map_surfaces(inputs, flat, children)


def _map_surfaces(
    inputs: list[list[tuple[int, int]]],
    flat: list[tuple[int, int]],
    children: list[list[tuple[int, int]]],
) -> dict[int, int]:
    """Return gmsh surface tag → index of the profile face it came from."""
    owner: dict[int, int] = {}
    k = 0
    for face_index, dts in enumerate(inputs):
        for _ in dts:
            for dim, tag in children[k]:
                if dim == 2:
                    owner[tag] = face_index
            k += 1
    if len(owner) < len(inputs):
        raise GeometryError(
            f"fragmenting {len(flat)} profile faces lost some: got {len(owner)} surfaces"
        )
    return owner


def _set_sizes(
    gmsh: Any,
    size_mm: float,
    circles: tuple[CircleSize, ...],
    arc_grading: float = 1.0,
    *,
    band_mm: float | None = None,
    core: set[int] | None = None,
) -> None:
    """Make four-sided faces transfinite and grade the other faces toward the circles.

    Counts on a transfinite face: an arc or a chord subtending angle θ at the pin axis
    gets ceil(θ·R_c / s_c) segments (R_c, s_c: the first circle's radius and size), so
    opposite sides of every quarter patch match; a radial line gets segments of 1.5 s_c.
    Arcs and chords are graded geometrically by ``arc_grading`` (longest/shortest),
    shortest at the end nearest the load line (the x axis); a band's inner arcs too, so
    that its elements stay on rays (a uniform inner arc shears them more at each level,
    and inverted one at level 3). With a band under the first circle the ``core``
    surfaces stay unstructured, the size growing from the inner arcs' mean segment
    s_c·(R_c − band)/R_c at depth ``band_mm`` to ``size_mm`` by ``BAND_GROWTH`` per mm.
    """
    g = gmsh
    g.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    g.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    g.option.setNumber("Mesh.MeshSizeMax", size_mm)
    if not circles:
        return
    r_c, s_c = circles[0].radius_mm, circles[0].size_mm
    for _, surface in g.model.getEntities(2):
        curves = [abs(tag) for _, tag in g.model.getBoundary([(2, surface)], oriented=False)]
        if len(curves) != 4 or surface in (core or set()):
            continue
        for tag in curves:
            n = _segments(g, tag, r_c, s_c)
            coef = _progression(g, tag, n, arc_grading, 2.0 * r_c)
            g.model.mesh.setTransfiniteCurve(tag, n + 1, "Progression", coef)
        g.model.mesh.setTransfiniteSurface(surface)
    fields = []
    for k, c in enumerate(circles):
        curves = [
            tag
            for _, tag in g.model.getEntities(1)
            if _radii(g, tag).std() < 1e-9 * c.radius_mm
            and abs(_radii(g, tag).mean() - c.radius_mm) < 1e-6 * c.radius_mm
        ]
        dist = g.model.mesh.field.add("Distance")
        g.model.mesh.field.setNumbers(dist, "CurvesList", curves)
        g.model.mesh.field.setNumber(dist, "Sampling", 200)
        thr = g.model.mesh.field.add("Threshold")
        g.model.mesh.field.setNumber(thr, "InField", dist)
        if k == 0 and band_mm is not None:
            s_in = c.size_mm * (c.radius_mm - band_mm) / c.radius_mm
            dist_min, dist_max = band_mm, band_mm + max(size_mm - s_in, 0.0) / BAND_GROWTH
        else:
            s_in, dist_min, dist_max = c.size_mm, 0.5 * c.radius_mm, c.radius_mm + 3 * size_mm
        g.model.mesh.field.setNumber(thr, "SizeMin", s_in)
        g.model.mesh.field.setNumber(thr, "SizeMax", size_mm)
        g.model.mesh.field.setNumber(thr, "DistMin", dist_min)
        g.model.mesh.field.setNumber(thr, "DistMax", dist_max)
        fields.append(thr)
    fmin = g.model.mesh.field.add("Min")
    g.model.mesh.field.setNumbers(fmin, "FieldsList", fields)
    g.model.mesh.field.setAsBackgroundMesh(fmin)


def _radii(gmsh: Any, tag: int) -> FloatArray:
    """Distances from the pin axis of 7 points along curve ``tag``, shape (7,) [mm]."""
    lo, hi = gmsh.model.getParametrizationBounds(1, tag)
    xyz = np.asarray(gmsh.model.getValue(1, tag, np.linspace(lo[0], hi[0], 7))).reshape(-1, 3)
    return np.asarray(np.hypot(xyz[:, 0], xyz[:, 1]), dtype=np.float64)


def _segments(gmsh: Any, tag: int, r_c: float, s_c: float) -> int:
    """Number of segments of a curve of a transfinite patch (see ``_set_sizes``)."""
    lo, hi = gmsh.model.getParametrizationBounds(1, tag)
    ends = np.asarray(gmsh.model.getValue(1, tag, [lo[0], hi[0]])).reshape(2, 3)
    r = np.hypot(ends[:, 0], ends[:, 1])
    if abs(r[0] - r[1]) > 1e-6 * max(r.max(), 1.0):  # radial line
        return max(1, math.ceil(float(np.linalg.norm(ends[1] - ends[0])) / (1.5 * s_c) - 1e-9))
    cos_theta = float(ends[0, :2] @ ends[1, :2]) / max(float(r[0] * r[1]), 1e-300)
    theta = math.acos(max(-1.0, min(1.0, cos_theta)))
    return max(2, math.ceil(theta * r_c / s_c - 1e-9))


def _progression(gmsh: Any, tag: int, n: int, grading: float, r_max: float) -> float:
    """Return the gmsh progression coefficient: segments grow by it from the curve's start.

    Radial lines, and arcs farther than ``r_max`` from the axis (a lug's rounded end,
    whose outline would turn visibly polygonal), stay uniform; arcs and chords near
    the contact get ``grading**(1/(n-1))``, inverted when the curve starts away from the
    load line so that the short segments sit on it.
    """
    lo, hi = gmsh.model.getParametrizationBounds(1, tag)
    ends = np.asarray(gmsh.model.getValue(1, tag, [lo[0], hi[0]])).reshape(2, 3)
    r = np.hypot(ends[:, 0], ends[:, 1])
    radial = abs(r[0] - r[1]) > 1e-6 * max(r.max(), 1.0)
    if grading == 1.0 or n < 2 or radial or r.max() > r_max:
        return 1.0
    q = min(float(grading ** (1.0 / (n - 1))), MAX_GROWTH)
    sin_start, sin_end = abs(ends[0, 1]) / max(r[0], 1e-300), abs(ends[1, 1]) / max(r[1], 1e-300)
    return q if sin_start <= sin_end else 1.0 / q


def _collect_quads(gmsh: Any, face_of_surface: dict[int, int]) -> ProfileMesh:
    g = gmsh
    tags, coords, _ = g.model.mesh.getNodes()
    xyz = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    index = np.full(int(np.max(tags)) + 1, -1, dtype=np.int64)
    index[np.asarray(tags, dtype=np.int64)] = np.arange(
        len(tags)
    )  # gmsh tags are 1-based: this is the one conversion
    quads, owners = [], []
    for surface, face_index in sorted(face_of_surface.items()):
        types, _, node_tags = g.model.mesh.getElements(2, surface)
        for etype, nt in zip(types, node_tags, strict=True):
            if etype != QUAD4:
                raise GeometryError(
                    f"gmsh left elements of type {etype} (not quads) on profile face {face_index}"
                )
            q = index[np.asarray(nt, dtype=np.int64).reshape(-1, 4)]
            quads.append(q)
            owners.append(np.full(len(q), face_index, dtype=np.int64))
    quad_arr = np.concatenate(quads)
    xy = xyz[:, :2]
    p = xy[quad_arr]  # (n_q, 4, 2)
    signed = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    quad_arr[signed < 0] = quad_arr[signed < 0][:, ::-1]  # counter-clockwise: normal +z
    used, compact = np.unique(quad_arr, return_inverse=True)
    return ProfileMesh(
        xy[used].copy(), compact.reshape(-1, 4).astype(np.int64), np.concatenate(owners)
    )


def layer_levels(z0_mm: float, z1_mm: float, dz_mm: float) -> FloatArray:
    """Return evenly spaced z levels from z0 to z1 with spacing at most ``dz_mm``, shape (n+1,)."""
    n = max(1, math.ceil((z1_mm - z0_mm) / dz_mm - 1e-9))
    return np.linspace(z0_mm, z1_mm, n + 1)


def extrude(
    profile: ProfileMesh, sweep: Sweep, slab_dz_mm: tuple[float, ...]
) -> tuple[FloatArray, IntArray]:
    """Extrude a profile mesh through a sweep's slabs into hexahedra.

    Args:
        profile: The quad mesh of the profile.
        sweep: Slabs: z-ranges and which profile faces each extrudes.
        slab_dz_mm: Largest layer thickness wanted in each slab [mm].

    Returns:
        (nodes (n, 3) [mm], hexes (n_elem, 8) int64), only nodes used by some hex.
    """
    levels: list[float] = []
    slab_layers: list[tuple[int, int]] = []  # (first level index, last level index) of each slab
    for slab, dz in zip(sweep.slabs, slab_dz_mm, strict=True):
        z = layer_levels(slab.z0_mm, slab.z1_mm, dz)
        if levels and abs(levels[-1] - z[0]) > 1e-9:
            raise GeometryError(
                f"slabs of the sweep are not contiguous at z = {levels[-1]} / {z[0]}"
            )
        start = len(levels) - 1 if levels else 0
        levels.extend(z[1:] if levels else z)
        slab_layers.append((start, len(levels) - 1))
    n2 = len(profile.xy)
    hexes = []
    for slab, (k0, k1) in zip(sweep.slabs, slab_layers, strict=True):
        q = profile.quads[np.isin(profile.quad_face, slab.faces)]  # (n_q, 4)
        for k in range(k0, k1):
            hexes.append(np.hstack([q + k * n2, q + (k + 1) * n2]))
    hex_arr = np.concatenate(hexes)
    z_all = np.asarray(levels)
    nodes = np.column_stack(
        [np.tile(profile.xy, (len(z_all), 1)), np.repeat(z_all, n2)]
    )  # node k*n2 + i is profile node i at level k
    used, compact = np.unique(hex_arr, return_inverse=True)
    return nodes[used], compact.reshape(-1, 8).astype(np.int64)
