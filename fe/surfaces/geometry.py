"""Node-to-surface contact geometry: points, local frames, exact gaps, and the operator C.

A contact point is a slave node. Its local frame ``[n, t1, t2]`` takes ``n`` from the
master's *exact* surface (``cad.surfaces``) at the slave's closest point, its initial gap
``g0`` is the exact signed distance, and the master displacement is interpolated
bilinearly on the master facet under it. ``C`` maps nodal displacements to relative
displacements (slave − master) in those frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.spatial import cKDTree

from cad.errors import MeshQualityError, ParameterError
from cad.surfaces import Cylinder
from mesh.hexmesh import HexMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True)
class ContactGeometry:
    """Contact points in one configuration.

    Attributes:
        slave: Slave node per point, shape (m,), int64.
        pair: Pair index per point (into ``HexMesh.pairs``), shape (m,), int64.
        frame: Local frames, shape (m, 3, 3): rows n, t1, t2 (unit, global components).
        g0: Initial normal gap from the exact surfaces, shape (m,) [mm].
        master_nodes: Nodes of the master facet each point projects on, shape (m, 4), int64.
        master_weights: Bilinear weights at the projection, shape (m, 4).
        area_mm2: Slave nodal area, shape (m,) [mm²].
    """

    slave: IntArray
    pair: IntArray
    frame: FloatArray
    g0: FloatArray
    master_nodes: IntArray
    master_weights: FloatArray
    area_mm2: FloatArray


def bilinear_weights(xi: FloatArray, eta: FloatArray) -> FloatArray:
    """Quad shape functions at (xi, eta), shape (n, 4), counter-clockwise node order."""
    return 0.25 * np.stack(
        [(1 - xi) * (1 - eta), (1 + xi) * (1 - eta), (1 + xi) * (1 + eta), (1 - xi) * (1 + eta)],
        axis=1,
    )


def project_on_facets(
    points: FloatArray,
    nodes: FloatArray,
    facets: IntArray,
    *,
    n_candidates: int = 8,
    max_overshoot: float = 1e-6,
) -> tuple[IntArray, FloatArray, FloatArray]:
    """Closest-point projection of points on a set of bilinear quad facets.

    Args:
        points: Points to project, shape (m, 3) [mm].
        nodes: Mesh coordinates, shape (n_nodes, 3) [mm].
        facets: Quads, shape (n_f, 4), int64.
        n_candidates: Nearest facet centroids tried per point.
        max_overshoot: Largest local coordinate beyond ±1 accepted (clipped to the facet):
            a tie accepts a node on the edge of its face that falls just outside the
            other side's faceted edge. When it is larger than the default, the closest
            facet within that overshoot wins (a badly shaped quad's projection can stall
            inside it far from the point); otherwise the least overshoot wins.

    Returns:
        (facet index (m,), local coordinates (m, 2) in [-1, 1]², distance (m,) [mm]).
    """
    q = nodes[facets]  # (n_f, 4, 3)
    tree = cKDTree(q.mean(axis=1))
    k = min(n_candidates, len(facets))
    _, cand = tree.query(points, k=k)
    cand = cand.reshape(len(points), k)
    best_f = np.zeros(len(points), dtype=np.int64)
    best_x = np.zeros((len(points), 2))
    best_d = np.full(len(points), np.inf)
    best_out = np.full(len(points), np.inf)
    for j in range(k):
        f = cand[:, j]
        x = q[f]  # (m, 4, 3)
        s = np.zeros((len(points), 2))
        for _ in range(8):  # Newton on the tangent-plane equations
            N = bilinear_weights(s[:, 0], s[:, 1])
            dxi = 0.25 * np.stack(
                [-(1 - s[:, 1]), (1 - s[:, 1]), (1 + s[:, 1]), -(1 + s[:, 1])], axis=1
            )
            deta = 0.25 * np.stack(
                [-(1 - s[:, 0]), -(1 + s[:, 0]), (1 + s[:, 0]), (1 - s[:, 0])], axis=1
            )
            r = np.einsum("mn,mni->mi", N, x) - points
            a1 = np.einsum("mn,mni->mi", dxi, x)
            a2 = np.einsum("mn,mni->mi", deta, x)
            A = np.stack(
                [
                    np.stack([(a1 * a1).sum(1), (a1 * a2).sum(1)], 1),
                    np.stack([(a1 * a2).sum(1), (a2 * a2).sum(1)], 1),
                ],
                1,
            )  # (m, 2, 2)
            b = -np.stack([(r * a1).sum(1), (r * a2).sum(1)], 1)
            s = s + np.linalg.solve(A, b[..., None])[..., 0]
        N = bilinear_weights(s[:, 0], s[:, 1])
        d = np.linalg.norm(np.einsum("mn,mni->mi", N, x) - points, axis=1)
        out = np.maximum(np.abs(s).max(axis=1) - 1.0, 0.0)
        if max_overshoot > 1e-6:
            ok = out <= max_overshoot
            better = (ok & ((best_out > max_overshoot) | (d < best_d))) | (
                ~ok & (best_out > max_overshoot) & (out < best_out)
            )
        else:
            better = (out < best_out - 1e-12) | ((np.abs(out - best_out) <= 1e-12) & (d < best_d))
        best_f[better], best_x[better], best_d[better], best_out[better] = (
            f[better],
            s[better],
            d[better],
            out[better],
        )
    if np.any(best_out > max_overshoot):
        i = int(np.argmax(best_out))
        raise MeshQualityError(
            f"contact point {i} at {points[i].round(4).tolist()} mm projects outside every master facet "
            f"(local coordinate overshoot {best_out[i]:.3g})"
        )
    return best_f, np.clip(best_x, -1.0, 1.0), best_d


def closest_point(surface: Cylinder, x: FloatArray) -> FloatArray:
    """Closest points on an exact surface, shape (m, 3) [mm].

    ``x − g n`` with g the signed distance and n the outward normal: a point at distance
    g on the non-material side moves back along −n onto the surface.
    """
    return x - surface.distance_outside(x)[:, None] * surface.outward_normal(x)


def split_window(geo: ContactGeometry, window_mm: float) -> tuple[ContactGeometry, ContactGeometry]:
    """Split contact points into those with an initial gap ≤ ``window_mm`` and the rest.

    Returns:
        (inside the window, outside it), each a ContactGeometry.
    """
    inside = geo.g0 <= window_mm

    def pick(mask: npt.NDArray[np.bool_]) -> ContactGeometry:
        return ContactGeometry(
            *(np.asarray(getattr(geo, f))[mask] for f in geo.__dataclass_fields__)
        )

    return pick(inside), pick(~inside)


def contact_geometry(
    mesh: HexMesh, shift_mm: dict[str, FloatArray], *, max_overshoot: float = 1e-6
) -> ContactGeometry:
    """Build the contact points of every contact pair in a configuration.

    Args:
        mesh: The hinge mesh (pairs, facet sets and exact surfaces).
        shift_mm: Pair name → rigid offset of the slave relative to the master in this
            configuration, shape (3,) [mm].
        max_overshoot: As ``project_on_facets`` (a slave node on the edge of a face that
            ends where the master face ends falls a hair outside its faceted edge).

    Returns:
        The contact geometry, points ordered pair by pair.
    """
    parts = []
    for ip, pair in enumerate(mesh.pairs):
        if pair.kind.value != "contact":
            continue
        master = mesh.surfaces[pair.master]
        if not isinstance(master, Cylinder):
            raise ParameterError(
                f"pair {pair.name!r}: master surface must be a Cylinder, got {type(master).__name__}"
            )
        ids, area, _ = mesh.nodal_areas(pair.slave)
        x = np.asarray(mesh.nodes)[ids] + shift_mm[pair.name]  # (m, 3) slave in this configuration
        g0 = master.distance_outside(x)
        n = master.outward_normal(x)  # into the hole, toward the slave
        axis = np.asarray(master.axis, dtype=np.float64) / np.linalg.norm(master.axis)
        t1 = np.cross(axis, n)
        t1 /= np.linalg.norm(t1, axis=1)[:, None]
        t2 = np.cross(n, t1)
        foot = closest_point(master, x)
        facets = mesh.facet_sets[pair.master]
        f, s, _ = project_on_facets(
            foot, np.asarray(mesh.nodes), facets, max_overshoot=max_overshoot
        )
        parts.append(
            (
                ids,
                np.full(len(ids), ip),
                np.stack([n, t1, t2], axis=1),
                g0,
                facets[f],
                bilinear_weights(s[:, 0], s[:, 1]),
                area,
            )
        )
    cols = list(zip(*parts, strict=True))
    return ContactGeometry(*(np.concatenate(c) for c in cols))


def contact_operator(geo: ContactGeometry, n_dof: int) -> sp.csr_matrix:
    """Return C, shape (3m, n_dof): relative displacement (slave − master) in local frames."""
    m = len(geo.slave)
    rows = np.repeat(np.arange(3 * m), 3).reshape(m, 3, 3)  # (m, k, j)
    vals_s = geo.frame  # (m, k, j)
    cols_s = 3 * geo.slave[:, None, None] + np.arange(3)[None, None, :]
    cols_s = np.broadcast_to(cols_s, (m, 3, 3))
    # master: −N_a n_k·e_j at node a
    vals_m = -geo.master_weights[:, None, :, None] * geo.frame[:, :, None, :]  # (m, k, a, j)
    cols_m = 3 * geo.master_nodes[:, None, :, None] + np.arange(3)[None, None, None, :]
    cols_m = np.broadcast_to(cols_m, (m, 3, 4, 3))
    rows_m = np.broadcast_to(np.arange(3 * m).reshape(m, 3)[:, :, None, None], (m, 3, 4, 3))
    C = sp.coo_matrix(
        (
            np.concatenate([vals_s.ravel(), vals_m.ravel()]),
            (
                np.concatenate([rows.ravel(), rows_m.ravel()]),
                np.concatenate([cols_s.ravel(), cols_m.ravel()]),
            ),
        ),
        shape=(3 * m, n_dof),
    )
    return C.tocsr()
