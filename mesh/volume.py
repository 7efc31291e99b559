"""All-hexahedral volume meshes of arbitrary solids (balls, bearing rings).

Parts that are not prismatic (``Part.sweep is None``) cannot be swept. gmsh meshes
them with tetrahedra, graded toward refinement patches, and then splits every
tetrahedron into four hexahedra (``Mesh.SubdivisionAlgorithm = 2``: one node at each
edge midpoint, face centroid and the tetrahedron's centroid). The result is
all-hexahedral and conforming, with every edge half as long as the tetrahedra's, so
the tetrahedra are generated at twice the requested size. New nodes on the boundary
are placed on the CAD surface, so boundary nodes lie on the exact geometry (a sphere's
surface nodes are at its radius to round-off).

Refinement patches are given as exact surfaces (``cad.surfaces``) with a box: the
element size is ``size`` on the surface inside the box and grows by GRADING per mm of
distance from the surface and from the box.
"""

from __future__ import annotations

import logging
import math
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from cad.errors import GeometryError, MeshQualityError, check_range
from cad.model import Box
from cad.surfaces import Cylinder, Plane, Sphere, Surface, Torus
from mesh.gmsh_session import gmsh_session
from mesh.quality import check_quality, corner_jacobians

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

logger = logging.getLogger(__name__)

HEX8 = 5
"""gmsh element type of the 8-node hexahedron."""

GMSH_HEX8_TO_VTK: IntArray = np.arange(8, dtype=np.int64)
"""``p`` such that ``ours[i] = gmsh[p[i]]`` for an 8-node hexahedron: the identity.

gmsh numbers the linear hexahedron as VTK_HEXAHEDRON does (``mesh.hexmesh``): nodes
0–3 counter-clockwise round the ζ = −1 face seen from +ζ, nodes 4–7 above them.
``tests/mesh/test_volume.py`` checks it on a one-element gmsh box."""

FLIP_ZETA: IntArray = np.array([4, 5, 6, 7, 0, 1, 2, 3], dtype=np.int64)
"""Node permutation that mirrors a hexahedron in ζ, reversing its orientation."""

GRADING = 0.3
"""Growth of the element size per mm of distance from a refinement patch [mm/mm]."""

CURVATURE_POINTS = 12
"""Tetrahedron edges per 2π of surface curvature (24 hexahedron edges after the split)."""


class VolumeMesh(NamedTuple):
    """An all-hexahedral mesh of one solid.

    Attributes:
        nodes: Coordinates, shape (n_nodes, 3), float64 [mm]; only nodes used by ``hexes``.
        hexes: Connectivity, shape (n_elem, 8), int64, VTK node order, positive Jacobian.
    """

    nodes: FloatArray
    hexes: IntArray


Refinement = tuple[Surface, Box, float]
"""(exact surface, box bounding the patch [mm], hexahedron size on the patch [mm])."""


def mesh_solid_hex(solid: Any, size_mm: float, refine: Sequence[Refinement] = ()) -> VolumeMesh:
    """Mesh a build123d solid into hexahedra only, refined on the given patches.

    Args:
        solid: A build123d Solid (mm).
        size_mm: Hexahedron edge length away from the patches [mm].
        refine: Patches where the hexahedron size is smaller: (surface, box, size [mm]).

    Returns:
        VolumeMesh with nodes (n_nodes, 3) float64 [mm] and hexes (n_elem, 8) int64.

    Raises:
        ParameterError: If a size is not positive and finite.
        GeometryError: If the BREP export or gmsh fails.
        MeshQualityError: If an element is inverted or degenerate.
    """
    check_range("size_mm", size_mm, 0.0, float("inf"), lo_open=True)
    for i, (_, _, size) in enumerate(refine):
        check_range(f"refine[{i}] size", size, 0.0, size_mm, lo_open=True)
    from build123d import export_brep  # imported here, as gmsh: the core library runs without

    with tempfile.TemporaryDirectory() as tmp, gmsh_session("volume") as gmsh:
        path = Path(tmp) / "solid.brep"
        try:
            if not export_brep(solid, str(path)):
                raise GeometryError(f"BREP export of the solid to {path} failed")
            gmsh.model.occ.importShapes(str(path))
            gmsh.model.occ.synchronize()
            _set_sizes(gmsh, size_mm, refine)
            gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 2)  # every tet → 4 hexes
            gmsh.model.mesh.generate(3)
            node_tags, xyz, _ = gmsh.model.mesh.getNodes()
            _, elem_nodes = gmsh.model.mesh.getElementsByType(HEX8)
            others = [t for t in gmsh.model.mesh.getElementTypes(dim=3) if t != HEX8]
        except GeometryError:
            raise
        except Exception as err:  # gmsh raises bare Exception; OCP raises Standard_Failure
            raise GeometryError(f"gmsh could not volume-mesh the solid: {err}") from err
    if others:
        raise MeshQualityError(f"gmsh left non-hexahedral 3-D elements of types {others}")
    return _to_volume_mesh(np.asarray(node_tags), np.asarray(xyz), np.asarray(elem_nodes))


def _set_sizes(gmsh: Any, size_mm: float, refine: Sequence[Refinement]) -> None:
    """Size field: twice the hexahedron sizes, since the split halves every edge."""
    gmsh.option.setNumber("Mesh.MeshSizeMax", 2.0 * size_mm)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", CURVATURE_POINTS)
    gmsh.option.setNumber("Mesh.Algorithm", 6)  # frontal-Delaunay triangles: well-shaped
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay
    gmsh.option.setNumber(
        "Mesh.OptimizeNetgen", 1
    )  # fewer flat tets: min scaled Jacobian 0.12→0.16
    if not refine:
        return
    fields = []
    for surface, box, size in refine:
        f = gmsh.model.mesh.field.add("MathEval")
        expr = f"{2.0 * size:.17g} + {GRADING:g}*({_distance_expr(surface)} + {_box_expr(box)})"
        gmsh.model.mesh.field.setString(f, "F", expr)
        fields.append(f)
    smallest = gmsh.model.mesh.field.add("Min")
    gmsh.model.mesh.field.setNumbers(smallest, "FieldsList", fields)
    gmsh.model.mesh.field.setAsBackgroundMesh(smallest)


def _num(v: float) -> str:
    return f"({float(v):.17g})"


def _offset(point: tuple[float, float, float]) -> tuple[str, str, str]:
    """Return the expressions of x − point, component by component."""
    return tuple(f"({c}-{_num(p)})" for c, p in zip("xyz", point, strict=True))  # type: ignore[return-value]


def _dot(d: tuple[str, str, str], a: tuple[float, float, float]) -> str:
    return "(" + "+".join(f"{di}*{_num(ai)}" for di, ai in zip(d, a, strict=True)) + ")"


def _unit(a: tuple[float, float, float]) -> tuple[float, float, float]:
    n = math.sqrt(sum(c * c for c in a))
    return (a[0] / n, a[1] / n, a[2] / n)


def _distance_expr(surface: Surface) -> str:
    """Return a gmsh MathEval expression of the unsigned distance to ``surface`` [mm]."""
    if isinstance(surface, Plane):
        return f"abs({_dot(_offset(surface.point), _unit(surface.normal))})"
    if isinstance(surface, Sphere):
        d = _offset(surface.center)
        return f"abs(sqrt({d[0]}^2+{d[1]}^2+{d[2]}^2)-{_num(surface.radius_mm)})"
    point = surface.point if isinstance(surface, Cylinder) else surface.center
    d = _offset(point)
    h = _dot(d, _unit(surface.axis))
    rho = f"sqrt(max({d[0]}^2+{d[1]}^2+{d[2]}^2-{h}^2,0))"
    if isinstance(surface, Cylinder):
        return f"abs({rho}-{_num(surface.radius_mm)})"
    if isinstance(surface, Torus):
        return f"abs(sqrt(({rho}-{_num(surface.major_mm)})^2+{h}^2)-{_num(surface.minor_mm)})"
    raise GeometryError(f"no distance expression for surface type {type(surface).__name__}")


def _box_expr(box: Box) -> str:
    """Return a MathEval expression of the (L1) distance outside ``box``, 0 inside [mm]."""
    terms = []
    for c, lo, hi in zip("xyz", box[0], box[1], strict=True):
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        terms.append(f"max(abs({c}-{_num(mid)})-{_num(half)},0)")
    return "(" + "+".join(terms) + ")"


def _to_volume_mesh(node_tags: IntArray, xyz: FloatArray, elem_nodes: IntArray) -> VolumeMesh:
    """Turn gmsh's tagged nodes and hexahedra into a compact, positively oriented mesh."""
    if elem_nodes.size == 0:
        raise MeshQualityError("gmsh produced no hexahedra")
    coords = xyz.reshape(-1, 3).astype(np.float64)
    # The one place where gmsh's node tags (1-based, possibly with gaps) become 0-based rows.
    row_of_tag = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    row_of_tag[node_tags.astype(np.int64)] = np.arange(len(node_tags), dtype=np.int64)
    hexes = row_of_tag[elem_nodes.astype(np.int64).reshape(-1, 8)][:, GMSH_HEX8_TO_VTK]
    used, compact = np.unique(hexes, return_inverse=True)
    nodes, hexes = coords[used], compact.reshape(-1, 8).astype(np.int64)
    hexes = _orient_positive(nodes, hexes)
    try:
        check_quality(nodes, hexes)
    except MeshQualityError as err:
        raise MeshQualityError(
            f"{err}; features thinner or more curved than the element size distort the split "
            "tetrahedra: try a smaller size_mm"
        ) from err
    logger.debug("volume mesh: %d hexahedra, %d nodes", len(hexes), len(nodes))
    return VolumeMesh(nodes, hexes)


def _orient_positive(nodes: FloatArray, hexes: IntArray) -> IntArray:
    """Mirror the node order of hexahedra whose corner Jacobians are all negative.

    Raises:
        MeshQualityError: If a hexahedron has corners of both signs (tangled).
    """
    det, _ = corner_jacobians(nodes, hexes)
    negative = (det < 0.0).all(axis=1)
    tangled = ~negative & (det <= 0.0).any(axis=1)
    if tangled.any():
        i = int(np.flatnonzero(tangled)[0])
        raise MeshQualityError(
            f"{int(tangled.sum())} hexahedra are tangled (corner Jacobians of both signs), first "
            f"element {i} at {nodes[hexes[i]].mean(axis=0).round(3).tolist()} mm"
        )
    out = hexes.copy()
    out[negative] = hexes[negative][:, FLIP_ZETA]
    return out
