"""Bonded (tied) interfaces between non-matching meshes, eliminated as multi-point constraints.

Each bonded pair ties every node of its slave face to the master face under it: the slave
node's displacement is the bilinear interpolation of the master facet's four nodes
(``u_s = Σ w_i u_m,i``), the classical node-to-surface tie (ABAQUS ``*TIE``). Slave DOFs are
eliminated, ``u = T u_ind``, so the tied stiffness ``Tᵀ K T`` stays symmetric positive
definite and needs no penalty or multiplier. A node on two slave faces (an edge shared by
two bonded faces) is tied once, by the first pair; a master node that is itself a slave
(the preload plate on outer ring 1, whose outer edge is tied to the tang) is resolved by
substitution, so chains of ties are exact.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from cad.errors import MeshQualityError
from cad.model import PairKind
from fe.surfaces.geometry import bilinear_weights, project_on_facets
from mesh.hexmesh import HexMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

TIE_DISTANCE_MM = 0.15
"""Largest distance of a slave node from the master facets it is tied to [mm].

Non-matching meshes of one cylinder leave a node up to the two chord sagittas off the
other side's facets (h²/8R each: 0.045 mm for 1.2 mm elements on the 4 mm pin, 0.068 mm
measured on the default mesh); more means the faces do not touch."""

MAX_OVERSHOOT = 0.5
"""Largest local-coordinate overshoot of a slave node beyond its master facet (clipped).

A node on the edge of a tied face can fall just outside the other side's faceted edge
(0.025 measured at the OD edge of outer ring 1); half a facet beyond is a wrong face."""

MAX_CHAIN = 8
"""Longest chain of ties resolved by substitution (the bearing hinge has two)."""


@dataclass(frozen=True)
class Ties:
    """The tie constraints of a mesh.

    Attributes:
        T: Map from independent DOFs to all DOFs, shape (n_dof, n_ind), CSR: ``u = T u_ind``.
        independent: The independent (not eliminated) DOFs, sorted, shape (n_ind,).
        slave_nodes: The tied (eliminated) nodes, sorted, shape (n_tied,).
        max_distance_mm: Largest slave-to-master distance found [mm].
    """

    T: sp.csr_matrix
    independent: IntArray
    slave_nodes: IntArray
    max_distance_mm: float

    def position(self) -> IntArray:
        """Index of every DOF among ``independent``, −1 for a tied one, shape (n_dof,)."""
        pos = np.full(self.T.shape[0], -1, dtype=np.int64)
        pos[self.independent] = np.arange(len(self.independent))
        return pos

    def held(self, dofs: IntArray, what: str) -> IntArray:
        """Independent indices of DOFs that are to be held (fixed, gripped, supported).

        Raises:
            MeshQualityError: If one of them is tied (a tied DOF follows its master).
        """
        idx = self.position()[dofs]
        if np.any(idx < 0):
            raise MeshQualityError(f"a {what} DOF is tied: it cannot be held")
        return idx


def unit_field(
    ties: Ties, K_ind: sp.csr_matrix, factor: Any, free: IntArray, moved: IntArray
) -> FloatArray:
    """Displacement with the independent DOFs ``moved`` at 1 and the free ones in equilibrium.

    Args:
        ties: The ties (``u = T u_ind``).
        K_ind: Stiffness on the independent DOFs, ``Tᵀ K T``.
        factor: Factorisation of ``K_ind`` on ``free``.
        free: Free independent DOFs.
        moved: Independent DOFs given a unit displacement (held DOFs stay at 0).

    Returns:
        The field on all DOFs, shape (n_dof,) [mm per unit].
    """
    u_ind = np.zeros(len(ties.independent))
    u_ind[moved] = 1.0
    u_ind[free] = factor.solve(-(K_ind[free] @ u_ind))
    return np.asarray(ties.T @ u_ind)


def assemble_tied(
    mesh: HexMesh, kind: Any, required: tuple[str, ...]
) -> tuple[sp.csr_matrix, Ties, dict[str, float]]:
    """Check the facet sets a system needs, assemble K and tie the bonded pairs.

    Args:
        mesh: The mesh.
        kind: Element formulation (``fe.element.ElementType``).
        required: Facet sets the system holds or loads.

    Returns:
        (K on all DOFs [N/mm], the ties, wall times of "assembly" and "ties" [s]).

    Raises:
        MeshQualityError: Naming a missing facet set, or a tie without its master face.
    """
    from fe.assembly import assemble_stiffness

    for name in required:
        if name not in mesh.facet_sets:
            raise MeshQualityError(f"the mesh has no facet set {name!r}: not this hinge's mesh")
    t0 = time.perf_counter()
    K = assemble_stiffness(mesh, kind)
    t1 = time.perf_counter()
    ties = tie_bonded_pairs(mesh)
    return K, ties, {"assembly": t1 - t0, "ties": time.perf_counter() - t1}


def tie_bonded_pairs(mesh: HexMesh, tol_mm: float = TIE_DISTANCE_MM) -> Ties:
    """Tie every bonded pair of the mesh.

    Raises:
        MeshQualityError: If a slave node lies farther than ``tol_mm`` from its master face,
            or ties form a cycle.
    """
    n_nodes = mesh.n_nodes
    owner = np.full(n_nodes, -1, dtype=np.int64)  # slave node → row in the lists below
    masters: list[IntArray] = []
    weights: list[FloatArray] = []
    worst = 0.0
    nodes = np.asarray(mesh.nodes)
    for pair in mesh.pairs:
        if pair.kind is not PairKind.BONDED:
            continue
        slaves = mesh.set_nodes(pair.slave)
        slaves = slaves[owner[slaves] < 0]
        if len(slaves) == 0:
            continue
        facets = np.asarray(mesh.facet_sets[pair.master])
        f, xi, dist = project_on_facets(nodes[slaves], nodes, facets, max_overshoot=MAX_OVERSHOOT)
        if dist.max() > tol_mm:
            bad = int(np.argmax(dist))
            raise MeshQualityError(
                f"bonded pair {pair.name!r}: slave node {int(slaves[bad])} is "
                f"{dist[bad]:.3g} mm from face {pair.master!r} (allowed {tol_mm:g} mm)"
            )
        worst = max(worst, float(dist.max()))
        owner[slaves] = len(masters) + np.arange(len(slaves))
        masters.extend(facets[f])
        weights.extend(bilinear_weights(xi[:, 0], xi[:, 1]))
    tied = np.flatnonzero(owner >= 0)
    # Node-level substitution matrix: row i (a node) → its masters, identity elsewhere.
    rows, cols, vals = [], [], []
    free = np.flatnonzero(owner < 0)
    rows.append(free)
    cols.append(free)
    vals.append(np.ones(len(free)))
    for node in tied:
        rows.append(np.full(4, node))
        cols.append(masters[owner[node]])
        vals.append(weights[owner[node]])
    S = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(n_nodes, n_nodes),
    )
    N = S
    for _ in range(MAX_CHAIN):
        if N[:, tied].nnz == 0:
            break
        N = (S @ N).tocsr()
    else:
        raise MeshQualityError(f"bonded ties form a chain longer than {MAX_CHAIN} (or a cycle)")
    N = N[:, free].tocsr()
    T = sp.kron(N, sp.identity(3), format="csr")  # node → 3 DOFs, same weights per component
    independent = (3 * free[:, None] + np.arange(3)).ravel()
    return Ties(T, independent.astype(np.int64), tied.astype(np.int64), worst)
