"""Global assembly, post-processing and the linear solve with Dirichlet elimination.

Global DOF numbering is ``dof = 3 * node + component`` (component 0, 1, 2 = x, y, z), so a
displacement field of shape (n_nodes, 3) flattens row-major into the (n_dof,) vector.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from cad.errors import ParameterError
from cad.materials import lame_from_young_poisson
from fe.element import (
    ElementType,
    element_stiffness,
    element_strain_stress,
    elements_jacobian_det,
    hex8_shape_functions,
)
from fe.linalg.sparse import Factorization, LinearSolverBackend
from fe.quadrature import gauss_hex
from mesh.hexmesh import HexMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

__all__ = [
    "assemble_body_force",
    "assemble_stiffness",
    "dofs_of",
    "element_coords",
    "element_dofs",
    "lame_per_element",
    "nodal_average",
    "solve_dirichlet",
    "strain_energy",
    "stress_field",
]

DEFAULT_CHUNK = 256
"""Elements per vectorised batch: small enough that the temporaries stay in cache."""


def element_coords(mesh: HexMesh) -> FloatArray:
    """Return the node coordinates of every element, shape (n_elem, 8, 3), float64 [mm]."""
    return np.asarray(mesh.nodes[mesh.hexes], dtype=np.float64)


def element_dofs(hexes: npt.ArrayLike) -> IntArray:
    """Return the global DOFs of every element, shape (n_elem, 24), int64, node-major."""
    h = np.asarray(hexes, dtype=np.int64)
    return (3 * h[:, :, None] + np.arange(3, dtype=np.int64)).reshape(len(h), 24)


def lame_per_element(mesh: HexMesh) -> tuple[FloatArray, FloatArray]:
    """Return (λ, μ) of every element from its part's material, each (n_elem,) float64 [MPa]."""
    lame = np.array(
        [lame_from_young_poisson(m.young_mpa, m.poisson) for m in mesh.materials],
        dtype=np.float64,
    ).reshape(-1, 2)
    return lame[mesh.elem_part, 0], lame[mesh.elem_part, 1]


def assemble_stiffness(
    mesh: HexMesh,
    kind: ElementType = ElementType.INCOMPATIBLE,
    *,
    chunk_size: int = DEFAULT_CHUNK,
) -> sp.csr_matrix:
    """Assemble the global linear-elastic stiffness matrix.

    Element matrices are computed in vectorised batches of ``chunk_size`` elements, written
    into one COO triplet list and converted to CSR once (duplicates summed).

    Args:
        mesh: The mesh; each part uses its own material.
        kind: Element formulation.
        chunk_size: Elements per batch (memory/speed trade-off only).

    Returns:
        K, shape (n_dof, n_dof) with n_dof = 3 n_nodes, symmetric, float64 [N/mm].

    Raises:
        ParameterError: If ``chunk_size`` < 1 or ``kind`` is not an ElementType.
        MeshQualityError: If an element has det J <= 0 at a Gauss point.
    """
    if chunk_size < 1:
        raise ParameterError(f"chunk_size must be >= 1, got {chunk_size}")
    n_dof = 3 * mesh.n_nodes
    lam, mu = lame_per_element(mesh)
    data = np.empty((mesh.n_elem, 24, 24), dtype=np.float64)
    for start in range(0, mesh.n_elem, chunk_size):  # batches, not elements
        sl = slice(start, start + chunk_size)
        coords = mesh.nodes[mesh.hexes[sl]]  # (n_chunk, 8, 3)
        data[sl] = element_stiffness(coords, lam[sl], mu[sl], kind)
    # int32 triplets when they fit: SciPy would downcast int64 ones with an extra copy.
    index_dtype = np.int32 if n_dof < np.iinfo(np.int32).max else np.int64
    edofs = element_dofs(mesh.hexes).astype(index_dtype)  # (n_elem, 24)
    rows = np.broadcast_to(edofs[:, :, None], data.shape).ravel()
    cols = np.broadcast_to(edofs[:, None, :], data.shape).ravel()
    K = sp.coo_matrix((data.ravel(), (rows, cols)), shape=(n_dof, n_dof)).tocsr()
    K.sort_indices()
    return K


def _as_field(u: npt.ArrayLike, n_nodes: int, name: str = "u") -> FloatArray:
    arr = np.asarray(u, dtype=np.float64)
    if arr.shape == (3 * n_nodes,):
        arr = arr.reshape(n_nodes, 3)
    if arr.shape != (n_nodes, 3):
        raise ParameterError(
            f"{name} must have shape ({n_nodes}, 3) or ({3 * n_nodes},), got {arr.shape}"
        )
    return arr


def stress_field(
    mesh: HexMesh, u: npt.ArrayLike, kind: ElementType = ElementType.INCOMPATIBLE
) -> FloatArray:
    """Return the centroid stress of every element.

    Args:
        mesh: The mesh.
        u: Nodal displacements, shape (n_nodes, 3) or (n_dof,), float64 [mm].
        kind: Element formulation used for the solve (selects the mode recovery).

    Returns:
        Stress, shape (n_elem, 6), float64 [MPa], Voigt order xx,yy,zz,yz,xz,xy.

    Raises:
        ParameterError: If ``u`` has the wrong shape.
    """
    field = _as_field(u, mesh.n_nodes)
    lam, mu = lame_per_element(mesh)
    u_e = field[mesh.hexes].reshape(mesh.n_elem, 24)
    return element_strain_stress(element_coords(mesh), u_e, lam, mu, kind)


def nodal_average(mesh: HexMesh, elem_values: npt.ArrayLike) -> FloatArray:
    """Average element values onto the nodes (unweighted mean over the attached elements).

    Args:
        mesh: The mesh.
        elem_values: One value (or row) per element, shape (n_elem,) or (n_elem, k).

    Returns:
        Nodal values, shape (n_nodes,) or (n_nodes, k), float64 (same unit as the input);
        NaN at nodes that belong to no element.

    Raises:
        ParameterError: If the first axis is not n_elem.
    """
    vals = np.asarray(elem_values, dtype=np.float64)
    if vals.ndim not in (1, 2) or vals.shape[0] != mesh.n_elem:
        raise ParameterError(
            f"elem_values must have shape ({mesh.n_elem},) or ({mesh.n_elem}, k), got {vals.shape}"
        )
    flat = vals.reshape(mesh.n_elem, -1)
    idx = mesh.hexes.ravel()
    count = np.bincount(idx, minlength=mesh.n_nodes).astype(np.float64)
    sums = np.stack(
        [np.bincount(idx, np.repeat(col, 8), minlength=mesh.n_nodes) for col in flat.T], axis=1
    )  # (n_nodes, k)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = sums / count[:, None]
    return np.asarray(mean.reshape((mesh.n_nodes, *vals.shape[1:])), dtype=np.float64)


def strain_energy(K: sp.spmatrix | sp.sparray, u: npt.ArrayLike) -> float:
    """Return the strain energy ½ uᵀ K u [N·mm].

    Args:
        K: Stiffness, shape (n_dof, n_dof) [N/mm].
        u: Displacements, shape (n_dof,) or (n_dof/3, 3), float64 [mm].

    Raises:
        ParameterError: If the sizes do not match.
    """
    vec = np.asarray(u, dtype=np.float64).ravel()
    if K.shape != (vec.size, vec.size):
        raise ParameterError(f"K has shape {K.shape} but u has {vec.size} entries")
    return float(0.5 * vec @ (K @ vec))


def dofs_of(nodes: npt.ArrayLike, comps: npt.ArrayLike = (0, 1, 2)) -> IntArray:
    """Return the global DOFs ``3 * node + comp`` of nodes × components.

    Args:
        nodes: Node indices, shape (n,), integer.
        comps: Components in {0, 1, 2}, shape (m,).

    Returns:
        DOFs, shape (n * m,), int64, node-major (all comps of the first node first).

    Raises:
        ParameterError: If a component is outside {0, 1, 2} or a node index is negative.
    """
    n = np.asarray(nodes, dtype=np.int64).ravel()
    c = np.asarray(comps, dtype=np.int64).ravel()
    if c.size and (c.min() < 0 or c.max() > 2):
        raise ParameterError(f"comps must be in {{0, 1, 2}}, got {c.tolist()}")
    if n.size and n.min() < 0:
        raise ParameterError(f"node indices must be >= 0, got min {n.min()}")
    return (3 * n[:, None] + c[None, :]).ravel()


def assemble_body_force(
    mesh: HexMesh,
    body_force: Callable[[FloatArray], FloatArray],
    order: int = 2,
) -> FloatArray:
    """Return the consistent load vector f_(a,i) = ∫ N_a b_i dV of a body force.

    Args:
        mesh: The mesh.
        body_force: Maps points (n, 3) [mm] to force densities (n, 3) [N/mm³].
        order: Gauss points per direction.

    Returns:
        f, shape (n_dof,), float64 [N].

    Raises:
        ParameterError: If ``body_force`` returns the wrong shape.
    """
    points, weights = gauss_hex(order)
    coords = element_coords(mesh)
    N = hex8_shape_functions(points)  # (n_qp, 8)
    wdet = weights * elements_jacobian_det(coords, points)  # (n_elem, n_qp)
    x_q = np.einsum("qa,eai->eqi", N, coords)  # (n_elem, n_qp, 3)
    b = np.asarray(body_force(x_q.reshape(-1, 3)), dtype=np.float64)
    if b.shape != (x_q.shape[0] * x_q.shape[1], 3):
        raise ParameterError(f"body_force must return shape ({x_q.size // 3}, 3), got {b.shape}")
    f_e = np.einsum("eq,qa,eqi->eai", wdet, N, b.reshape(x_q.shape))  # (n_elem, 8, 3)
    f = np.bincount(element_dofs(mesh.hexes).ravel(), f_e.ravel(), minlength=3 * mesh.n_nodes)
    return np.asarray(f, dtype=np.float64)


def solve_dirichlet(
    K: sp.spmatrix | sp.sparray,
    f: npt.ArrayLike,
    fixed_dofs: npt.ArrayLike,
    fixed_values: npt.ArrayLike = 0.0,
    *,
    backend: LinearSolverBackend = LinearSolverBackend.AUTO,
) -> FloatArray:
    """Solve K u = f with u prescribed on some DOFs, by eliminating them.

    With F the free and D the fixed DOFs: K_FF u_F = f_F - K_FD u_D, u_D = fixed_values.

    Args:
        K: Symmetric positive semi-definite stiffness, shape (n_dof, n_dof) [N/mm].
        f: External nodal forces, shape (n_dof,) [N] (entries on fixed DOFs are ignored).
        fixed_dofs: Unique prescribed DOFs, shape (n_fixed,), integer.
        fixed_values: Prescribed displacements, shape (n_fixed,) or scalar [mm].
        backend: Sparse direct solver (see ``Factorization``).

    Returns:
        u, shape (n_dof,), float64 [mm].

    Raises:
        ParameterError: On wrong shapes, repeated or out-of-range DOFs, or if K_FF is singular.
    """
    n_dof = K.shape[0]
    rhs = np.asarray(f, dtype=np.float64)
    if K.shape != (n_dof, n_dof) or rhs.shape != (n_dof,):
        raise ParameterError(
            f"K must be square and f of shape (n_dof,); got {K.shape}, {rhs.shape}"
        )
    fixed = np.asarray(fixed_dofs, dtype=np.int64).ravel()
    if fixed.size and (fixed.min() < 0 or fixed.max() >= n_dof):
        raise ParameterError(
            f"fixed_dofs must lie in [0, {n_dof}), got {fixed.min()}..{fixed.max()}"
        )
    if np.unique(fixed).size != fixed.size:
        raise ParameterError(f"fixed_dofs contains {fixed.size - np.unique(fixed).size} repeats")
    values = np.broadcast_to(np.asarray(fixed_values, dtype=np.float64), fixed.shape)
    free_mask = np.ones(n_dof, dtype=bool)
    free_mask[fixed] = False
    free = np.flatnonzero(free_mask)
    u = np.zeros(n_dof, dtype=np.float64)
    u[fixed] = values
    if free.size:
        Kc = sp.csr_matrix(K)
        K_ff = Kc[free][:, free]
        rhs_f = rhs[free] - Kc[free][:, fixed] @ values
        u[free] = Factorization(K_ff, backend=backend).solve(rhs_f)
    return u
