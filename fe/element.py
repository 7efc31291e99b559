"""The eight-node hexahedron: shape functions, Jacobians, stiffness and stress recovery.

Two formulations share one isotropic kernel:

* ``ElementType.INCOMPATIBLE`` (default) – Wilson's incompatible-modes hexahedron with
  Taylor's correction (QM6 in 3D, similar to ABAQUS C3D8I). The displacement is enriched by
  three bubbles P_k = 1 - ξ_k² per component (9 internal modes α), whose gradients are taken
  with the centroid Jacobian J0 and scaled by det J0 / det J:

      ∇P_k(ξ) ≈ (det J0 / det J(ξ)) · J0^{-T} ∂P_k/∂ξ.

  Then ∫ ∇P_k dV = det J0 · J0^{-T} ∫ ∂P_k/∂ξ dξ = 0, so a constant stress does no work on
  the modes and the patch test passes on distorted meshes (this is the enhanced-assumed-strain
  reading of Simo & Rifai 1990). The modes are condensed per element,
  K = K_uu - K_uα K_αα^{-1} K_αu, and recovered as α = -K_αα^{-1} K_αu u_e. A rectangular
  element then bends without locking.
* ``ElementType.FULL`` – the standard trilinear hexahedron, 2×2×2 Gauss points. It shear-locks
  in bending; it is kept as a reference.

Everything is vectorised over elements. Element DOFs are ordered node-major,
``3 * local_node + component``, matching the global ``dof = 3 * node + component``.
Stresses are returned in Voigt order (xx, yy, zz, yz, xz, xy); internally the kernels work
with displacement-gradient tensors and never form B matrices.
"""

from __future__ import annotations

import functools
from enum import Enum
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cad.errors import MeshQualityError, ParameterError
from fe.quadrature import gauss_hex

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

HEX8_NODE_COORDS: FloatArray = np.array(
    [
        [-1.0, -1.0, -1.0],
        [1.0, -1.0, -1.0],
        [1.0, 1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
        [1.0, -1.0, 1.0],
        [1.0, 1.0, 1.0],
        [-1.0, 1.0, 1.0],
    ],
    dtype=np.float64,
)
"""Reference coordinates of the hex8 nodes, shape (8, 3), VTK order::

        7 -------- 6
       /|         /|        ζ
      4 -------- 5 |        |  η
      | |        | |        | /
      | 3 -------|-2        |/
      |/         |/         +---- ξ
      0 -------- 1
"""
HEX8_NODE_COORDS.setflags(write=False)

N_INTERNAL_MODES = 9
"""Internal incompatible-mode DOFs per element (3 bubbles × 3 components)."""

_STIFFNESS_ORDER = 2  # 2×2×2 Gauss points integrate both formulations fully.
_VOIGT = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))


class ElementType(Enum):
    """Hexahedral element formulation."""

    INCOMPATIBLE = "incompatible"
    """Wilson–Taylor incompatible modes (QM6-like, 9 condensed modes). Default."""
    FULL = "full"
    """Standard trilinear hex with 2×2×2 Gauss points (locks in bending)."""


def _as_points(xi: npt.ArrayLike, name: str = "xi") -> FloatArray:
    pts = np.asarray(xi, dtype=np.float64)
    if pts.ndim == 1 and pts.shape == (3,):
        pts = pts[None, :]
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ParameterError(f"{name} must have shape (n_points, 3), got {pts.shape}")
    return pts


def hex8_shape_functions(xi: npt.ArrayLike) -> FloatArray:
    """Evaluate the eight trilinear shape functions N_a = ⅛ Π_j (1 + ξ_j ξ_j^a).

    Args:
        xi: Reference coordinates in [-1, 1]^3, shape (n_points, 3) (or (3,)), float64.

    Returns:
        N with shape (n_points, 8), ordered as in HEX8_NODE_COORDS.

    Raises:
        ParameterError: If ``xi`` has the wrong shape.
    """
    pts = _as_points(xi)
    factors = 1.0 + pts[:, None, :] * HEX8_NODE_COORDS[None, :, :]  # (n_points, 8, 3)
    return np.asarray(0.125 * factors.prod(axis=2), dtype=np.float64)


def hex8_shape_gradients(xi: npt.ArrayLike) -> FloatArray:
    """Evaluate the reference gradients ∂N_a/∂ξ_j of the trilinear shape functions.

    Args:
        xi: Reference coordinates, shape (n_points, 3) (or (3,)), float64.

    Returns:
        dN_dxi with shape (n_points, 8, 3): [point, node, reference direction].

    Raises:
        ParameterError: If ``xi`` has the wrong shape.
    """
    pts = _as_points(xi)
    factors = 1.0 + pts[:, None, :] * HEX8_NODE_COORDS[None, :, :]  # (n_points, 8, 3)
    grads = np.empty_like(factors)
    for j in range(3):
        others = [k for k in range(3) if k != j]
        grads[:, :, j] = (
            0.125
            * HEX8_NODE_COORDS[None, :, j]
            * factors[:, :, others[0]]
            * factors[:, :, others[1]]
        )
    return grads


def bubble_gradients(xi: npt.ArrayLike) -> FloatArray:
    """Evaluate the reference gradients of the bubbles P_k = 1 - ξ_k².

    Args:
        xi: Reference coordinates, shape (n_points, 3) (or (3,)), float64.

    Returns:
        dP_dxi with shape (n_points, 3, 3): [point, mode k, direction j] = -2 ξ_k δ_kj.
    """
    pts = _as_points(xi)
    return np.asarray(-2.0 * pts[:, :, None] * np.eye(3)[None, :, :], dtype=np.float64)


def _check_coords(coords: npt.ArrayLike) -> FloatArray:
    x = np.asarray(coords, dtype=np.float64)
    if x.ndim != 3 or x.shape[1:] != (8, 3):
        raise ParameterError(f"coords must have shape (n_elem, 8, 3), got {x.shape}")
    if not np.isfinite(x).all():
        raise ParameterError("coords contain non-finite values")
    return x


def _jacobians(coords: FloatArray, points: FloatArray) -> FloatArray:
    dN = hex8_shape_gradients(points)  # (n_qp, 8, 3)
    # J_ij = Σ_a x_ai ∂N_a/∂ξ_j; matmul is much faster than a plain einsum here.
    J = np.matmul(coords.transpose(0, 2, 1)[:, None], dN[None])  # (n_elem, n_qp, 3, 3)
    return np.asarray(J, dtype=np.float64)


def _inv_det_3x3(J: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Return (J⁻¹, det J) of stacked 3×3 matrices by cofactors (shape (..., 3, 3), (...))."""
    a, b, c = J[..., 0, 0], J[..., 0, 1], J[..., 0, 2]
    d, e, f = J[..., 1, 0], J[..., 1, 1], J[..., 1, 2]
    g, h, i = J[..., 2, 0], J[..., 2, 1], J[..., 2, 2]
    c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * c00 + b * c01 + c * c02
    adj = np.stack(
        [c00, c * h - b * i, b * f - c * e, c01, a * i - c * g, c * d - a * f,
         c02, b * g - a * h, a * e - b * d],
        axis=-1,
    ).reshape(J.shape)  # fmt: skip
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = adj / det[..., None, None]
    return np.asarray(inv, dtype=np.float64), np.asarray(det, dtype=np.float64)


def elements_jacobian_det(coords: npt.ArrayLike, points: npt.ArrayLike) -> FloatArray:
    """Return det(∂x/∂ξ) of every element at the given reference points.

    Args:
        coords: Element node coordinates, shape (n_elem, 8, 3), float64 [mm].
        points: Reference points, shape (n_points, 3), float64 [-].

    Returns:
        Jacobian determinants, shape (n_elem, n_points), float64 [mm³ per unit reference
        volume]; the element volume is Σ_q w_q det J_q.

    Raises:
        ParameterError: If an argument has the wrong shape.
    """
    x = _check_coords(coords)
    return _inv_det_3x3(_jacobians(x, _as_points(points, "points")))[1]


def _check_det(det: FloatArray, what: str) -> None:
    bad = np.argwhere(~(det > 0.0))
    if len(bad):
        e, q = (int(v) for v in bad[0])
        raise MeshQualityError(
            f"element {e} has non-positive Jacobian determinant {det[e, q]:.6g} at {what} "
            f"point {q} ({len(bad)} bad points in total)"
        )


class _Kinematics(NamedTuple):
    """Generalised gradients of the interpolation functions.

    grads: (n_elem, n_qp, n_fun, 3) [1/mm]; n_fun = 8 nodes (+ 3 bubbles if incompatible).
    wdet: (n_elem, n_qp) quadrature weight × det J [mm³].
    """

    grads: FloatArray
    wdet: FloatArray


def _kinematics(
    coords: FloatArray, points: FloatArray, weights: FloatArray, kind: ElementType
) -> _Kinematics:
    J_inv, det = _inv_det_3x3(_jacobians(coords, points))  # (n_elem, n_qp, 3, 3): dξ_j/dx_k
    _check_det(det, "evaluation")
    dN = hex8_shape_gradients(points)  # (n_qp, 8, 3)
    grads = np.matmul(dN[None], J_inv)  # (n_elem, n_qp, 8, 3): Σ_j ∂N_a/∂ξ_j ∂ξ_j/∂x_k
    if kind is ElementType.INCOMPATIBLE:
        J0_inv, det0 = _inv_det_3x3(_jacobians(coords, np.zeros((1, 3))))  # (n_elem, 1, 3, 3)
        _check_det(det0, "centroid")
        dP = bubble_gradients(points)  # (n_qp, 3, 3)
        bub = np.matmul(dP[None], J0_inv)  # (n_elem, n_qp, 3, 3): J0⁻ᵀ ∂P_m/∂ξ, as rows
        bub *= (det0 / det)[:, :, None, None]  # Taylor's det J0 / det J scaling
        grads = np.concatenate([grads, bub], axis=2)  # (n_elem, n_qp, 11, 3)
    return _Kinematics(grads, weights[None, :] * det)


def _check_kind(kind: object) -> ElementType:
    if not isinstance(kind, ElementType):
        raise ParameterError(f"kind must be an ElementType, got {kind!r}")
    return kind


def _check_lame(
    lam: npt.ArrayLike, mu: npt.ArrayLike, n_elem: int
) -> tuple[FloatArray, FloatArray]:
    lam_a = np.broadcast_to(np.asarray(lam, dtype=np.float64), (n_elem,))
    mu_a = np.broadcast_to(np.asarray(mu, dtype=np.float64), (n_elem,))
    if not (np.isfinite(lam_a).all() and np.isfinite(mu_a).all()):
        raise ParameterError("lam and mu must be finite")
    if n_elem and mu_a.min() <= 0.0:
        raise ParameterError(f"mu must be > 0 MPa, got min {mu_a.min()!r}")
    bulk = lam_a + 2.0 * mu_a / 3.0
    if n_elem and bulk.min() <= 0.0:
        raise ParameterError(f"lam + 2 mu / 3 (bulk modulus) must be > 0 MPa, got {bulk.min()!r}")
    return lam_a, mu_a


@functools.cache
def _swap_index(n_fun: int) -> IntArray:
    """Flat index of (a, j, b, i) at flat position (a, i, b, j) of an (F, 3, F, 3) array."""
    idx = np.arange(9 * n_fun * n_fun, dtype=np.int64).reshape(n_fun, 3, n_fun, 3)
    return np.ascontiguousarray(idx.transpose(0, 3, 2, 1).ravel())


def _isotropic_matrix(kin: _Kinematics, lam: FloatArray, mu: FloatArray) -> FloatArray:
    """Return K_(ai)(bj) = ∫ λ g_ai g_bj + μ g_aj g_bi + μ δ_ij g_a·g_b dV, (n_elem, 3F, 3F)."""
    n_elem, n_qp, n_fun, _ = kin.grads.shape
    n = 3 * n_fun
    G = kin.grads.reshape(n_elem, n_qp, n)
    S = np.matmul(G.transpose(0, 2, 1) * kin.wdet[:, None, :], G).reshape(n_elem, n * n)
    # The permutation and the trace act on the flat (a, i, b, j) axis; gathering with
    # np.take is several times faster than broadcasting over the 5-D view.
    K = lam[:, None] * S
    K += mu[:, None] * np.take(S, _swap_index(n_fun), axis=1)
    S5 = S.reshape(n_elem, n_fun, 3, n_fun, 3)
    trace = mu[:, None, None] * (S5[:, :, 0, :, 0] + S5[:, :, 1, :, 1] + S5[:, :, 2, :, 2])
    K5 = K.reshape(n_elem, n_fun, 3, n_fun, 3)
    for k in range(3):
        K5[:, :, k, :, k] += trace
    return np.asarray(K.reshape(n_elem, n, n), dtype=np.float64)


def _full_matrix(
    coords: npt.ArrayLike, lam: npt.ArrayLike, mu: npt.ArrayLike, kind: ElementType
) -> tuple[FloatArray, FloatArray, FloatArray]:
    kind = _check_kind(kind)
    x = _check_coords(coords)
    lam_a, mu_a = _check_lame(lam, mu, len(x))
    points, weights = gauss_hex(_STIFFNESS_ORDER)
    return _isotropic_matrix(_kinematics(x, points, weights, kind), lam_a, mu_a), lam_a, mu_a


def element_stiffness(
    coords: npt.ArrayLike,
    lam: npt.ArrayLike,
    mu: npt.ArrayLike,
    kind: ElementType = ElementType.INCOMPATIBLE,
) -> FloatArray:
    """Return the element stiffness matrices of isotropic linear-elastic hexahedra.

    With u_e the element displacement vector (24,) [mm], the strain energy of element e is
    ½ u_eᵀ K_e u_e [N·mm]. For INCOMPATIBLE elements the 9 internal modes are condensed out.

    Args:
        coords: Node coordinates, shape (n_elem, 8, 3), float64 [mm], VTK node order.
        lam: Lamé λ per element, shape (n_elem,) or scalar, float64 [MPa].
        mu: Shear modulus μ per element, shape (n_elem,) or scalar, float64 [MPa].
        kind: Element formulation.

    Returns:
        K_e with shape (n_elem, 24, 24), float64 [N/mm], symmetric, DOF ``3 * node + comp``.

    Raises:
        ParameterError: On wrong shapes, non-finite input or a non-positive modulus.
        MeshQualityError: If det J <= 0 at a Gauss point (or the centroid).
    """
    K, _, _ = _full_matrix(coords, lam, mu, kind)
    if kind is ElementType.INCOMPATIBLE:
        K_uu, K_ua, K_aa = K[:, :24, :24], K[:, :24, 24:], K[:, 24:, 24:]
        # inv of the 9×9 block is faster than a batched solve with 24 right-hand sides.
        K = K_uu - np.matmul(np.matmul(K_ua, np.linalg.inv(K_aa)), K_ua.transpose(0, 2, 1))
    return np.asarray(0.5 * (K + K.transpose(0, 2, 1)), dtype=np.float64)


def _check_u_e(u_e: npt.ArrayLike, n_elem: int) -> FloatArray:
    u = np.asarray(u_e, dtype=np.float64)
    if u.shape != (n_elem, 24):
        raise ParameterError(f"u_e must have shape ({n_elem}, 24), got {u.shape}")
    return u


def element_stress_at_points(
    coords: npt.ArrayLike,
    u_e: npt.ArrayLike,
    lam: npt.ArrayLike,
    mu: npt.ArrayLike,
    kind: ElementType = ElementType.INCOMPATIBLE,
    points: npt.ArrayLike = ((0.0, 0.0, 0.0),),
) -> FloatArray:
    """Recover Cauchy stress σ = λ tr(ε) I + 2 μ ε at reference points of every element.

    For INCOMPATIBLE elements the internal-mode amplitudes are recovered from the static
    condensation, α = -K_αα⁻¹ K_αu u_e (no load acts on the modes), and their strain is
    added. Their gradient vanishes at the centroid (∂P_k/∂ξ = -2 ξ_k), so they matter only
    away from it, e.g. at the Gauss points.

    Args:
        coords: Node coordinates, shape (n_elem, 8, 3), float64 [mm].
        u_e: Element displacements, shape (n_elem, 24), float64 [mm], DOF ``3 * node + comp``.
        lam: Lamé λ, shape (n_elem,) or scalar [MPa].
        mu: Shear modulus μ, shape (n_elem,) or scalar [MPa].
        kind: Element formulation.
        points: Reference points, shape (n_points, 3) [-]; default the centroid.

    Returns:
        Stress with shape (n_elem, n_points, 6), float64 [MPa], Voigt order xx,yy,zz,yz,xz,xy.

    Raises:
        ParameterError: On wrong shapes or moduli.
        MeshQualityError: If det J <= 0 at a Gauss point or evaluation point.
    """
    kind = _check_kind(kind)
    x = _check_coords(coords)
    u = _check_u_e(u_e, len(x))
    pts = _as_points(points, "points")
    lam_a, mu_a = _check_lame(lam, mu, len(x))
    kin = _kinematics(x, pts, np.ones(len(pts)), kind)
    values = u.reshape(len(x), 8, 3)
    grads = kin.grads
    if kind is ElementType.INCOMPATIBLE and bubble_gradients(pts).any():
        values = np.concatenate([values, _mode_amplitudes(x, u, lam_a, mu_a)], axis=1)
    else:
        # At the centroid every bubble's gradient is zero (∂P_k/∂ξ = -2 ξ_k): the modes add
        # nothing to the strain there, so their recovery (a 33 × 33 matrix per element, 3.6 s
        # of a 47k-element mesh's frame) is skipped.
        grads = grads[:, :, :8]
    H = np.einsum("eai,eqak->eqik", values, grads)  # (n_elem, n_points, 3, 3): ∂u_i/∂x_k
    eps = 0.5 * (H + H.transpose(0, 1, 3, 2))
    tr = np.trace(eps, axis1=2, axis2=3)  # (n_elem, n_points)
    sigma = 2.0 * mu_a[:, None, None, None] * eps
    sigma += (lam_a[:, None] * tr)[:, :, None, None] * np.eye(3)
    rows = np.array([r for r, _ in _VOIGT], dtype=np.int64)
    cols = np.array([c for _, c in _VOIGT], dtype=np.int64)
    return np.asarray(sigma[:, :, rows, cols], dtype=np.float64)


def _mode_amplitudes(x: FloatArray, u: FloatArray, lam: FloatArray, mu: FloatArray) -> FloatArray:
    """Incompatible-mode amplitudes α = -K_αα⁻¹ K_αu u_e, shape (n_elem, 3, 3) [mm]."""
    K, _, _ = _full_matrix(x, lam, mu, ElementType.INCOMPATIBLE)
    K_au, K_aa = K[:, 24:, :24], K[:, 24:, 24:]
    alpha = -np.linalg.solve(K_aa, np.einsum("eij,ej->ei", K_au, u)[:, :, None])[:, :, 0]
    return np.asarray(alpha.reshape(len(x), 3, 3), dtype=np.float64)


def element_strain_stress(
    coords: npt.ArrayLike,
    u_e: npt.ArrayLike,
    lam: npt.ArrayLike,
    mu: npt.ArrayLike,
    kind: ElementType = ElementType.INCOMPATIBLE,
) -> FloatArray:
    """Return the Cauchy stress at the element centroids.

    See ``element_stress_at_points`` for the formulation (internal modes are recovered).

    Args:
        coords: Node coordinates, shape (n_elem, 8, 3), float64 [mm].
        u_e: Element displacements, shape (n_elem, 24), float64 [mm].
        lam: Lamé λ, shape (n_elem,) or scalar [MPa].
        mu: Shear modulus μ, shape (n_elem,) or scalar [MPa].
        kind: Element formulation.

    Returns:
        Stress with shape (n_elem, 6), float64 [MPa], Voigt order xx,yy,zz,yz,xz,xy.

    Raises:
        ParameterError: On wrong shapes or moduli.
        MeshQualityError: If det J <= 0 at a Gauss point or the centroid.
    """
    return element_stress_at_points(coords, u_e, lam, mu, kind)[:, 0, :]


def von_mises(stress: npt.ArrayLike) -> FloatArray:
    """Return the von Mises equivalent stress.

    σ_vm = sqrt(½[(σxx-σyy)² + (σyy-σzz)² + (σzz-σxx)²] + 3(σyz² + σxz² + σxy²)).

    Args:
        stress: Voigt stresses, shape (..., 6), float64 [MPa], order xx,yy,zz,yz,xz,xy.

    Returns:
        Equivalent stress, shape (...), float64 [MPa].

    Raises:
        ParameterError: If the last axis is not of length 6.
    """
    s = np.asarray(stress, dtype=np.float64)
    if s.ndim == 0 or s.shape[-1] != 6:
        raise ParameterError(f"stress must have shape (..., 6), got {s.shape}")
    normal = (
        (s[..., 0] - s[..., 1]) ** 2 + (s[..., 1] - s[..., 2]) ** 2 + (s[..., 2] - s[..., 0]) ** 2
    )
    shear = s[..., 3] ** 2 + s[..., 4] ** 2 + s[..., 5] ** 2
    return np.asarray(np.sqrt(0.5 * normal + 3.0 * shear), dtype=np.float64)
