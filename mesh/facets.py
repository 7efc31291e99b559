"""Boundary facets of hex meshes and their selection by exact surface.

Named facet sets are picked geometrically: the boundary facets of a part whose
nodes lie on a named face's exact surface (``cad.surfaces``) and whose centroid
lies in the face's box. That works the same for swept and volume meshes and
needs no bookkeeping of CAD face ids through the mesher.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from cad.model import Box
from cad.surfaces import Surface

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

HEX_FACES: IntArray = np.array(
    [
        [0, 3, 2, 1],  # zeta = -1
        [4, 5, 6, 7],  # zeta = +1
        [0, 1, 5, 4],  # eta = -1
        [1, 2, 6, 5],  # xi = +1
        [2, 3, 7, 6],  # eta = +1
        [3, 0, 4, 7],  # xi = -1
    ],
    dtype=np.int64,
)
"""Local node indices of the six faces of a VTK hexahedron, each counter-clockwise seen
from outside, so the right-hand normal points out of the element."""


def boundary_facets(hexes: IntArray) -> tuple[IntArray, IntArray]:
    """Return the faces that belong to exactly one hexahedron.

    Args:
        hexes: Connectivity, shape (n_elem, 8), int64.

    Returns:
        (facets (n_f, 4) int64 in outward node order, owning element (n_f,) int64).
    """
    faces = hexes[:, HEX_FACES].reshape(-1, 4)  # (n_elem*6, 4)
    owner = np.repeat(np.arange(len(hexes), dtype=np.int64), 6)
    key = np.sort(faces, axis=1)
    _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    once = first[counts == 1]
    once.sort()
    return faces[once].astype(np.int64), owner[once]


def select_facets(
    nodes: FloatArray,
    facets: IntArray,
    surface: Surface,
    box: Box,
    tol_mm: float,
) -> BoolArray:
    """Mark facets lying on ``surface`` inside ``box`` and facing out of the surface's body.

    Args:
        nodes: Coordinates, shape (n_nodes, 3) [mm].
        facets: Candidate facets, shape (n_f, 4), outward node order.
        surface: Exact surface of the named face.
        box: ((xmin, ymin, zmin), (xmax, ymax, zmax)) [mm] containing the facet centroids.
        tol_mm: Largest distance of a facet node from the surface [mm].

    Returns:
        Mask, shape (n_f,).
    """
    q = nodes[facets]  # (n_f, 4, 3)
    dist = np.abs(surface.distance_outside(q.reshape(-1, 3))).reshape(-1, 4)
    on_surface = (dist <= tol_mm).all(axis=1)
    c = q.mean(axis=1)
    lo, hi = np.asarray(box[0]), np.asarray(box[1])
    in_box = ((c >= lo) & (c <= hi)).all(axis=1)
    normal = np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1])
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
    facing = np.einsum("fi,fi->f", normal, surface.outward_normal(c)) > 0.5
    mask: BoolArray = on_surface & in_box & facing
    return mask
