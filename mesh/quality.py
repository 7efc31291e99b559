"""Element quality: Jacobian sign and scaled Jacobian at the corners."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from cad.errors import MeshQualityError

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

CORNER_EDGES: IntArray = np.array(
    [
        [1, 3, 4],
        [2, 0, 5],
        [3, 1, 6],
        [0, 2, 7],
        [7, 5, 0],
        [4, 6, 1],
        [5, 7, 2],
        [6, 4, 3],
    ],
    dtype=np.int64,
)
"""For corner i of a VTK hexahedron, the three neighbours (along xi, eta, zeta, in a
right-handed order) whose edge vectors span the corner's Jacobian."""


def corner_jacobians(nodes: FloatArray, hexes: IntArray) -> tuple[FloatArray, FloatArray]:
    """Return the corner Jacobian determinants and scaled Jacobians.

    Args:
        nodes: Coordinates, shape (n_nodes, 3) [mm].
        hexes: Connectivity, shape (n_elem, 8).

    Returns:
        (det (n_elem, 8) [mm³], scaled (n_elem, 8) in [-1, 1]; 1 for a perfect cube corner).
    """
    x = nodes[hexes]  # (n_elem, 8, 3)
    e = x[:, CORNER_EDGES, :] - x[:, :, None, :]  # (n_elem, 8, 3, 3): three edges per corner
    det = np.linalg.det(e)
    lengths = np.linalg.norm(e, axis=3).prod(axis=2)
    return det, det / np.maximum(lengths, 1e-300)


def check_quality(nodes: FloatArray, hexes: IntArray, *, min_scaled: float = 0.05) -> float:
    """Refuse a mesh with an inverted or degenerate element; return the minimum scaled Jacobian.

    Raises:
        MeshQualityError: Naming the worst element and its scaled Jacobian.
    """
    if len(hexes) == 0:
        raise MeshQualityError("mesh has no hexahedra")
    _, scaled = corner_jacobians(nodes, hexes)
    worst = scaled.min(axis=1)
    i = int(np.argmin(worst))
    if worst[i] <= min_scaled:
        raise MeshQualityError(
            f"element {i} has scaled Jacobian {worst[i]:.3g} (must be > {min_scaled:g}; "
            f"≤ 0 means inverted) at centroid {nodes[hexes[i]].mean(axis=0).round(3).tolist()} mm"
        )
    return float(worst[i])


def hex_volumes(nodes: FloatArray, hexes: IntArray) -> FloatArray:
    """Return each hexahedron's volume by 2×2×2 Gauss integration of det J, shape (n_elem,) [mm³].

    Exact for trilinear hexahedra (det J is a polynomial of degree ≤ 2 per direction).
    """
    g = 1.0 / np.sqrt(3.0)
    ref = np.array(
        [
            [-1, -1, -1],
            [1, -1, -1],
            [1, 1, -1],
            [-1, 1, -1],
            [-1, -1, 1],
            [1, -1, 1],
            [1, 1, 1],
            [-1, 1, 1],
        ],
        dtype=np.float64,
    )
    x = nodes[hexes]  # (n_elem, 8, 3)
    vol = np.zeros(len(hexes))
    for p in ref * g:
        dN = (
            ref
            * np.array(
                [
                    (1 + ref[:, 1] * p[1]) * (1 + ref[:, 2] * p[2]),
                    (1 + ref[:, 0] * p[0]) * (1 + ref[:, 2] * p[2]),
                    (1 + ref[:, 0] * p[0]) * (1 + ref[:, 1] * p[1]),
                ]
            ).T
            / 8.0
        )  # (8, 3) dN/dxi at this point
        J = np.einsum("eni,nj->eij", x, dN)  # (n_elem, 3, 3)
        vol += np.linalg.det(J)
    return vol
