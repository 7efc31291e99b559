"""Global assembly, post-processing and the linear solve with Dirichlet elimination.

Global DOF numbering is ``dof = 3 * node + component`` (component 0, 1, 2 = x, y, z), so a
displacement field of shape (n_nodes, 3) flattens row-major into the (n_dof,) vector.
"""

from __future__ import annotations

import ctypes
import weakref
from collections.abc import Callable
from enum import Enum

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from cad.errors import ParameterError
from cad.materials import lame_from_young_poisson
from fe.element import (
    ElementType,
    element_stiffness,
    element_strain_stress,
    elements_jacobian_det,
    hex8_shape_functions,
)
from fe.quadrature import gauss_hex
from mesh.hexmesh import HexMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

__all__ = [
    "Factorization",
    "LinearSolverBackend",
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


class LinearSolverBackend(Enum):
    """Sparse direct solver behind ``Factorization``."""

    AUTO = "auto"
    """MKL PARDISO if pypardiso is importable, else SciPy SuperLU."""
    PARDISO = "pardiso"
    """MKL PARDISO, real symmetric positive definite (mtype = 2), upper triangle only."""
    SCIPY = "scipy"
    """SciPy SuperLU in symmetric mode (fallback; slower, more memory)."""


_PARDISO_SPD = 2


def _load_mkl() -> ctypes.CDLL | None:
    try:
        import pypardiso  # optional dependency, hence imported lazily
    except ImportError:
        return None
    # Reuse pypardiso's search for mkl_rt; call PARDISO ourselves so a solve does not
    # re-convert the index arrays or compare the matrix on every call.
    lib: ctypes.CDLL = pypardiso.PyPardisoSolver().libmkl
    fn = lib.pardiso
    i32p = ctypes.POINTER(ctypes.c_int32)
    fn.argtypes = [ctypes.POINTER(ctypes.c_int64), i32p, i32p, i32p, i32p, i32p,
                   ctypes.c_void_p, i32p, i32p, i32p, i32p, i32p, i32p,
                   ctypes.c_void_p, ctypes.c_void_p, i32p]  # fmt: skip
    fn.restype = None
    return lib


_MKL: list[ctypes.CDLL | None] = []


def _mkl() -> ctypes.CDLL | None:
    if not _MKL:
        _MKL.append(_load_mkl())
    return _MKL[0]


class _Pardiso:
    """One MKL PARDISO handle holding the factor of an SPD matrix (upper triangle)."""

    def __init__(self, lib: ctypes.CDLL, upper: sp.csr_matrix) -> None:
        self._fn = lib.pardiso
        self.n = upper.shape[0]
        self._a = np.ascontiguousarray(upper.data, dtype=np.float64)
        self._ia = np.ascontiguousarray(upper.indptr, dtype=np.int32)
        self._ja = np.ascontiguousarray(upper.indices, dtype=np.int32)
        self._pt = np.zeros(64, dtype=np.int64)
        self._iparm = np.zeros(64, dtype=np.int32)
        self._iparm[0] = 1  # we set iparm ourselves
        self._iparm[1] = 2  # nested-dissection (METIS) ordering
        self._iparm[34] = 1  # zero-based ia/ja
        self._call(12, np.zeros((self.n, 1), order="F"))
        weakref.finalize(self, _Pardiso._release, self._fn, self._pt, self._iparm, self.n)

    def _call(self, phase: int, b: FloatArray) -> FloatArray:
        x = np.zeros_like(b, order="F")
        err = ctypes.c_int32(0)
        i32 = ctypes.c_int32
        i32p = ctypes.POINTER(i32)
        self._fn(
            self._pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
            ctypes.byref(i32(1)), ctypes.byref(i32(1)), ctypes.byref(i32(_PARDISO_SPD)),
            ctypes.byref(i32(phase)), ctypes.byref(i32(self.n)), self._a.ctypes.data,
            self._ia.ctypes.data_as(i32p), self._ja.ctypes.data_as(i32p), None,
            ctypes.byref(i32(b.shape[1])), self._iparm.ctypes.data_as(i32p),
            ctypes.byref(i32(0)), b.ctypes.data, x.ctypes.data, ctypes.byref(err),
        )  # fmt: skip
        if err.value != 0:
            raise ParameterError(
                f"PARDISO phase {phase} failed with error {err.value} (-4: matrix not positive "
                "definite, e.g. too few fixed DOFs)"
            )
        return x

    @staticmethod
    def _release(
        fn: Callable[..., None], pt: IntArray, iparm: npt.NDArray[np.int32], n: int
    ) -> None:
        i32 = ctypes.c_int32
        dummy = np.zeros(1, dtype=np.float64)
        err = i32(0)
        fn(pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(i32(1)),
           ctypes.byref(i32(1)), ctypes.byref(i32(_PARDISO_SPD)), ctypes.byref(i32(-1)),
           ctypes.byref(i32(n)), dummy.ctypes.data, None, None, None, ctypes.byref(i32(1)),
           iparm.ctypes.data_as(ctypes.POINTER(i32)), ctypes.byref(i32(0)), dummy.ctypes.data,
           dummy.ctypes.data, ctypes.byref(err))  # fmt: skip

    def solve(self, B: FloatArray) -> FloatArray:
        return self._call(33, np.asfortranarray(B))


class Factorization:
    """A sparse Cholesky-type factorisation of a symmetric positive definite matrix.

    The matrix is factorised once, in the constructor; ``solve`` then costs only the two
    triangular sweeps, so factorise once and call ``solve`` many times, preferably with
    blocks of right-hand sides (see benchmarks/bench_assembly.py for timings). A PARDISO
    handle is not thread-safe: use one ``Factorization`` per thread.

    Attributes:
        n: Size of the system.
        backend: The backend actually used (never AUTO).
    """

    def __init__(
        self,
        K_ff: sp.spmatrix | sp.sparray,
        *,
        backend: LinearSolverBackend = LinearSolverBackend.AUTO,
        symmetry_rtol: float = 1e-10,
    ) -> None:
        """Factorise ``K_ff``.

        Args:
            K_ff: Symmetric positive definite matrix, shape (n, n), float64 (the full
                matrix, not a triangle). It is copied, never modified.
            backend: Which solver to use.
            symmetry_rtol: Allowed max|K - Kᵀ| relative to max|K|.

        Raises:
            ParameterError: If K_ff is not square, not symmetric, or (PARDISO) not positive
                definite; or if PARDISO was requested but pypardiso is not installed.
        """
        if not isinstance(backend, LinearSolverBackend):
            raise ParameterError(f"backend must be a LinearSolverBackend, got {backend!r}")
        A = sp.csr_matrix(K_ff, dtype=np.float64)
        if A.shape[0] != A.shape[1] or A.shape[0] == 0:
            raise ParameterError(f"K_ff must be square and non-empty, got shape {A.shape}")
        scale = abs(A).max()
        asym = abs(A - A.T).max() if A.nnz else 0.0
        if asym > symmetry_rtol * scale:
            raise ParameterError(
                f"K_ff is not symmetric: max|K - Kᵀ| = {asym:.3e}, max|K| = {scale:.3e}"
            )
        self.n: int = A.shape[0]
        lib = _mkl() if backend is not LinearSolverBackend.SCIPY else None
        if backend is LinearSolverBackend.PARDISO and lib is None:
            raise ParameterError("backend PARDISO requested but pypardiso is not installed")
        self._impl: _Pardiso | spla.SuperLU
        if lib is not None:
            upper = sp.triu(A, format="csr")
            upper.sort_indices()
            self._impl = _Pardiso(lib, upper)
            self.backend = LinearSolverBackend.PARDISO
        else:
            self._impl = spla.splu(
                A.tocsc(),
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
            self.backend = LinearSolverBackend.SCIPY

    def solve(self, B: npt.ArrayLike) -> FloatArray:
        """Solve K_ff X = B.

        Args:
            B: One right-hand side, shape (n,), or a block of k, shape (n, k), float64.

        Returns:
            X with the shape of B, float64.

        Raises:
            ParameterError: If B has the wrong shape.
        """
        rhs = np.asarray(B, dtype=np.float64)
        if rhs.ndim not in (1, 2) or rhs.shape[0] != self.n:
            raise ParameterError(f"B must have shape ({self.n},) or ({self.n}, k), got {rhs.shape}")
        block = rhs.reshape(self.n, -1)
        if block.shape[1] == 0:
            return np.zeros(rhs.shape, dtype=np.float64)
        X = self._impl.solve(block)
        return np.ascontiguousarray(X, dtype=np.float64).reshape(rhs.shape)


def inverse_block(
    K_ff: sp.spmatrix | sp.sparray,
    idx: npt.ArrayLike,
    *,
    factor: Factorization | Callable[[], Factorization] | None = None,
    block_rhs: int = 128,
    backend: LinearSolverBackend = LinearSolverBackend.AUTO,
) -> FloatArray:
    """Return ``(K_ff⁻¹)[idx, idx]``, the compliance of a few DOFs of a sparse SPD matrix.

    With MKL PARDISO the block comes from the Schur complement
    ``S = K_bb − K_bi K_ii⁻¹ K_ib`` (b = idx), which PARDISO forms during a partial
    factorisation with the b DOFs ordered last, and ``(K⁻¹)_bb = S⁻¹`` (a dense Cholesky
    inverse). That costs about one factorisation plus O(b³), instead of b sparse
    triangular solves: 3 600 DOFs of a 159k-DOF hinge in 2.4 s + 5 s instead of ~150 s
    (benchmarks/bench_assembly.py). Without PARDISO, unit right-hand sides are solved in
    blocks of ``block_rhs`` with ``factor`` (built here if None).

    Args:
        K_ff: Symmetric positive definite matrix, shape (n, n), float64.
        idx: Distinct DOF indices, shape (b,), in any order; the result follows it.
        factor: A factorisation of K_ff to reuse on the fallback path, or a callable
            returning one (called only on that path, so it can be made lazily).
        block_rhs: Right-hand sides per block solve on the fallback path.
        backend: AUTO or PARDISO: the Schur complement (PARDISO required); SCIPY: block
            solves (with ``factor``, whatever its backend).

    Returns:
        The symmetric block, shape (b, b) [inverse units of K_ff].

    Raises:
        ParameterError: Repeated or out-of-range indices, or K_ff not positive definite.
    """
    A = sp.csr_matrix(K_ff, dtype=np.float64)
    n = A.shape[0]
    b = np.asarray(idx, dtype=np.int64).ravel()
    if b.size and (b.min() < 0 or b.max() >= n):
        raise ParameterError(f"idx must lie in [0, {n}), got {b.min()}..{b.max()}")
    if np.unique(b).size != b.size:
        raise ParameterError(f"idx contains {b.size - np.unique(b).size} repeated DOFs")
    if b.size == 0:
        return np.zeros((0, 0))
    lib = None if backend is LinearSolverBackend.SCIPY else _mkl()
    if backend is LinearSolverBackend.PARDISO and lib is None:
        raise ParameterError("backend PARDISO requested but pypardiso is not installed")
    if lib is None or b.size == n:
        f = factor() if callable(factor) else factor
        f = Factorization(A) if f is None else f
        out = np.empty((b.size, b.size))
        for j in range(0, b.size, block_rhs):
            cols = b[j : j + block_rhs]
            E = np.zeros((n, cols.size))
            E[cols, np.arange(cols.size)] = 1.0
            out[:, j : j + cols.size] = f.solve(E)[b]
        return 0.5 * (out + out.T)
    order = np.argsort(b)
    S = _pardiso_schur(lib, A, b[order])
    c, info = sla.lapack.dpotrf(S, lower=0, overwrite_a=1)
    if info != 0:
        raise ParameterError(f"Schur complement not positive definite (dpotrf info {info})")
    inv, info = sla.lapack.dpotri(c, lower=0, overwrite_c=1)
    if info != 0:
        raise ParameterError(f"Schur complement inversion failed (dpotri info {info})")
    inv = np.triu(inv) + np.triu(inv, 1).T
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    return np.ascontiguousarray(inv[np.ix_(back, back)])


def _pardiso_schur(lib: ctypes.CDLL, A: sp.csr_matrix, b: IntArray) -> FloatArray:
    """Schur complement of A onto the sorted DOFs b by a PARDISO partial factorisation, (nb, nb)."""
    upper = sp.triu(A, format="csr")
    upper.sort_indices()
    n = A.shape[0]
    a = np.ascontiguousarray(upper.data, dtype=np.float64)
    ia = np.ascontiguousarray(upper.indptr, dtype=np.int32)
    ja = np.ascontiguousarray(upper.indices, dtype=np.int32)
    pt = np.zeros(64, dtype=np.int64)
    iparm = np.zeros(64, dtype=np.int32)
    iparm[0] = 1  # we set iparm ourselves
    iparm[1] = 2  # nested-dissection (METIS) ordering
    iparm[34] = 1  # zero-based ia/ja
    iparm[35] = 1  # return the Schur complement of the DOFs marked in perm, dense, in x
    perm = np.zeros(n, dtype=np.int32)
    perm[b] = 1
    S = np.zeros((b.size, b.size), order="F")
    rhs = np.zeros(n)
    err = ctypes.c_int32(0)
    i32 = ctypes.c_int32
    i32p = ctypes.POINTER(i32)
    fn = lib.pardiso
    try:
        fn(pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(i32(1)),
           ctypes.byref(i32(1)), ctypes.byref(i32(_PARDISO_SPD)), ctypes.byref(i32(12)),
           ctypes.byref(i32(n)), a.ctypes.data, ia.ctypes.data_as(i32p), ja.ctypes.data_as(i32p),
           perm.ctypes.data_as(i32p), ctypes.byref(i32(1)), iparm.ctypes.data_as(i32p),
           ctypes.byref(i32(0)), rhs.ctypes.data, S.ctypes.data, ctypes.byref(err))  # fmt: skip
    finally:
        _Pardiso._release(fn, pt, iparm, n)
    if err.value != 0:
        raise ParameterError(
            f"PARDISO Schur complement failed with error {err.value} (-4: matrix not positive "
            "definite, e.g. too few fixed DOFs)"
        )
    return S  # upper triangle used by the Cholesky that follows


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
