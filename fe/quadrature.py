"""Gauss–Legendre quadrature on the reference hexahedron and quadrilateral.

The reference cell is [-1, 1]^3 (hexahedron, volume 8) or [-1, 1]^2 (quadrilateral,
area 4). A rule of ``order`` n uses n points per direction (n^3 or n^2 in all) and
integrates every monomial ξ^a η^b ζ^c with max(a, b, c) <= 2n - 1 exactly.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cad.errors import ParameterError

FloatArray = npt.NDArray[np.float64]

MAX_ORDER = 10
"""Largest number of points per direction that the rules accept."""


class QuadratureRule(NamedTuple):
    """Quadrature points and weights on a reference cell.

    Attributes:
        points: Reference coordinates, shape (n_qp, dim), float64 [-].
        weights: Weights, shape (n_qp,), float64; they sum to the cell's measure.
    """

    points: FloatArray
    weights: FloatArray


def exact_degree(order: int) -> int:
    """Return the highest per-variable polynomial degree a rule of ``order`` integrates exactly."""
    return 2 * order - 1


def gauss_legendre_1d(order: int) -> QuadratureRule:
    """Return the ``order``-point Gauss–Legendre rule on [-1, 1].

    Args:
        order: Number of points, 1 <= order <= MAX_ORDER.

    Returns:
        Points of shape (order, 1) and weights of shape (order,), summing to 2.

    Raises:
        ParameterError: If ``order`` is not an integer in [1, MAX_ORDER].
    """
    if (
        isinstance(order, bool)
        or not isinstance(order, int | np.integer)
        or not (1 <= order <= MAX_ORDER)
    ):
        raise ParameterError(
            f"quadrature order must be an integer in [1, {MAX_ORDER}], got {order!r}"
        )
    x, w = np.polynomial.legendre.leggauss(int(order))
    return QuadratureRule(x.astype(np.float64).reshape(-1, 1), w.astype(np.float64))


def _tensor_rule(order: int, dim: int) -> QuadratureRule:
    x1, w1 = gauss_legendre_1d(order)
    grids = np.meshgrid(*([x1[:, 0]] * dim), indexing="ij")
    wgrids = np.meshgrid(*([w1] * dim), indexing="ij")
    # Reverse the axis order so the first coordinate varies fastest, like the hex node order.
    points = np.stack([g.T.ravel() for g in grids], axis=1)  # (order**dim, dim)
    weights = np.prod(np.stack([g.T.ravel() for g in wgrids], axis=1), axis=1)  # (order**dim,)
    return QuadratureRule(points.astype(np.float64), weights.astype(np.float64))


def gauss_hex(order: int) -> QuadratureRule:
    """Return the tensor-product Gauss–Legendre rule on the hexahedron [-1, 1]^3.

    Args:
        order: Points per direction, 1 <= order <= MAX_ORDER (2 is full integration of hex8).

    Returns:
        Points of shape (order**3, 3) with ξ varying fastest, weights of shape (order**3,)
        summing to 8.

    Raises:
        ParameterError: If ``order`` is out of range.
    """
    return _tensor_rule(order, 3)


def gauss_quad(order: int) -> QuadratureRule:
    """Return the tensor-product Gauss–Legendre rule on the quadrilateral [-1, 1]^2.

    Args:
        order: Points per direction, 1 <= order <= MAX_ORDER.

    Returns:
        Points of shape (order**2, 2) with ξ varying fastest, weights of shape (order**2,)
        summing to 4.

    Raises:
        ParameterError: If ``order`` is out of range.
    """
    return _tensor_rule(order, 2)
