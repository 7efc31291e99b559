r"""Complete polynomial response surfaces with all cross terms (the paper's Eqs. 2-5).

A surface of degree ``d`` in ``n`` variables is

.. math::  \tilde y(x) = \sum_k \beta_k \prod_i x_i^{e_{ki}},
           \qquad \sum_i e_{ki} \le d,

with every monomial of total degree up to ``d`` present. Terms are ordered as
in the paper's Eq. 3: by total degree, and within a degree with the exponent of
``x1`` falling first, then that of ``x2``, and so on::

    1, x1, x2, x1^2, x1*x2, x2^2, x1^3, x1^2*x2, x1*x2^2, x2^3, x1^4, ...

so that the coefficients of two variables can be set beside Eq. 6 and Eq. 13.

Numerics: the paper solves the normal equations (Eq. 4). With ``x1`` in mm
(0-0.4) and ``x2`` in N (100-500) the quartic's columns span twenty orders of
magnitude, and forming ``ΦᵀΦ`` squares that condition number. Here each
variable is first mapped to ``s = (x - c) / h`` in [-1, 1] (``c`` the middle
and ``h`` the half-width of the sampled range), the least-squares problem is
solved by a QR factorisation of the scaled design matrix, and only then are the
coefficients expanded back to physical units for reporting. Predictions and
gradients are evaluated in the scaled variables.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import DataError, ParameterError

FloatArray = npt.NDArray[np.float64]
Exponents = tuple[tuple[int, ...], ...]

MAX_DEGREE = 4
"""Highest degree offered; the paper's quartic. Higher degrees need more points than
a finite-element study can usually afford and are poorly conditioned even when scaled."""


def monomial_exponents(n_vars: int, degree: int) -> Exponents:
    """List the exponent vectors of a complete polynomial in the paper's term order.

    Args:
        n_vars: Number of variables, at least 1.
        degree: Total degree, 1 to ``MAX_DEGREE``.

    Returns:
        One tuple of ``n_vars`` exponents per term; ``n_terms = C(n_vars + degree, degree)``.

    Raises:
        ParameterError: If ``n_vars`` or ``degree`` is out of range.

    Example:
        >>> monomial_exponents(2, 2)
        ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
    """
    if n_vars < 1:
        raise ParameterError(f"n_vars must be at least 1, got {n_vars}")
    if not 1 <= degree <= MAX_DEGREE:
        raise ParameterError(
            f"degree must be in [1, {MAX_DEGREE}], got {degree}", parameter="degree"
        )
    terms: list[tuple[int, ...]] = []
    for d in range(degree + 1):
        # combinations_with_replacement yields (0, 0, 1) before (0, 1, 1): x1^2*x2 before x1*x2^2.
        for combo in itertools.combinations_with_replacement(range(n_vars), d):
            e = [0] * n_vars
            for i in combo:
                e[i] += 1
            terms.append(tuple(e))
    return tuple(terms)


def term_names(exponents: Exponents, symbols: Sequence[str] | None = None) -> tuple[str, ...]:
    """Name each term, e.g. ``1``, ``x1``, ``x1^2*x2``.

    Args:
        exponents: As from :func:`monomial_exponents`.
        symbols: Variable names to use instead of ``x1``, ``x2``, ...

    Returns:
        One name per term.

    Raises:
        ParameterError: If the number of symbols does not match the number of variables.
    """
    n_vars = len(exponents[0])
    syms = tuple(symbols) if symbols is not None else tuple(f"x{i + 1}" for i in range(n_vars))
    if len(syms) != n_vars:
        raise ParameterError(f"symbols must have {n_vars} names, got {len(syms)}: {syms}")
    names = []
    for e in exponents:
        parts = [s if k == 1 else f"{s}^{k}" for s, k in zip(syms, e, strict=True) if k > 0]
        names.append("*".join(parts) if parts else "1")
    return tuple(names)


def design_matrix(x: npt.ArrayLike, exponents: Exponents) -> FloatArray:
    """Evaluate every monomial at every point (the paper's Φ, Eq. 5).

    Args:
        x: Points, shape (n_points, n_vars), any units.
        exponents: As from :func:`monomial_exponents`.

    Returns:
        Φ with shape (n_points, n_terms); ``Φ[m, k] = Π_i x[m, i] ** e_k[i]``.

    Raises:
        ParameterError: If ``x`` is not two-dimensional with one column per variable.
    """
    xa = _as_points(x, len(exponents[0]))
    e = np.asarray(exponents, dtype=np.int64)  # (n_terms, n_vars)
    phi: FloatArray = np.prod(xa[:, None, :] ** e[None, :, :], axis=2)  # (n_points, n_terms)
    return phi


def _as_points(x: npt.ArrayLike, n_vars: int) -> FloatArray:
    xa = np.asarray(x, dtype=np.float64)
    if xa.ndim == 1 and xa.shape[0] == n_vars:
        xa = xa[None, :]
    if xa.ndim != 2 or xa.shape[1] != n_vars:
        raise ParameterError(f"x must have shape (n_points, {n_vars}), got {xa.shape}")
    return xa


@dataclass(frozen=True)
class ResponseSurface:
    """A fitted polynomial response surface and the data it was fitted to.

    Attributes:
        exponents: Term exponents in paper order, see :func:`monomial_exponents`.
        x_names: Names of the variables x1, x2, ... (table columns, units in the name).
        y_name: Name of the response.
        coefficients: β in physical units, shape (n_terms,), paper order.
        coefficients_scaled: The same surface in the scaled variables
            ``s = (x - center) / half_range``, shape (n_terms,).
        center: Middle of the sampled range of each variable, shape (n_vars,).
        half_range: Half-width of the sampled range, shape (n_vars,).
        x: Sample inputs, shape (n_points, n_vars).
        y: Sample responses, shape (n_points,).
        leverage: Diagonal of the hat matrix, shape (n_points,), in [0, 1].
        condition_number: 2-norm condition number of the scaled design matrix
            (the one actually solved).
        condition_number_unscaled: Condition number the physical-unit design
            matrix would have had; shown for comparison only.
        labels: One label per sample point (a trace point id or a table row).
    """

    exponents: Exponents
    x_names: tuple[str, ...]
    y_name: str
    coefficients: FloatArray
    coefficients_scaled: FloatArray
    center: FloatArray
    half_range: FloatArray
    x: FloatArray
    y: FloatArray
    leverage: FloatArray
    condition_number: float
    condition_number_unscaled: float
    labels: tuple[str, ...]

    @property
    def degree(self) -> int:
        """Total degree of the polynomial."""
        return max(sum(e) for e in self.exponents)

    @property
    def n_vars(self) -> int:
        """Number of input variables."""
        return len(self.x_names)

    @property
    def n_terms(self) -> int:
        """Number of coefficients (the paper's N, Eq. 9-10)."""
        return len(self.exponents)

    @property
    def n_points(self) -> int:
        """Number of sample points (the paper's M)."""
        return int(self.y.shape[0])

    @property
    def lower(self) -> FloatArray:
        """Lower corner of the sampled box, shape (n_vars,)."""
        return np.asarray(self.center - self.half_range, dtype=np.float64)

    @property
    def upper(self) -> FloatArray:
        """Upper corner of the sampled box, shape (n_vars,)."""
        return np.asarray(self.center + self.half_range, dtype=np.float64)

    @property
    def term_names(self) -> tuple[str, ...]:
        """Term names with generic symbols ``x1``, ``x2``, ... in paper order."""
        return term_names(self.exponents)


def _readonly(a: npt.ArrayLike) -> FloatArray:
    arr = np.array(a, dtype=np.float64, copy=True)
    arr.setflags(write=False)
    return arr


def _rank_message(x: FloatArray, degree: int, rank: int, n_terms: int) -> str:
    few = [
        f"x{i + 1} has {len(np.unique(x[:, i]))} distinct values"
        for i in range(x.shape[1])
        if len(np.unique(x[:, i])) <= degree
    ]
    hint = ("; " + ", ".join(few) + f" (degree {degree} needs {degree + 1})") if few else ""
    return f"the design matrix has rank {rank} < {n_terms} coefficients{hint}"


def fit_response_surface(
    x: npt.ArrayLike,
    y: npt.ArrayLike,
    degree: int,
    *,
    x_names: Sequence[str] | None = None,
    y_name: str = "y",
    labels: Sequence[str] | None = None,
) -> ResponseSurface:
    """Fit a complete polynomial by least squares (Eq. 4, solved by QR on scaled variables).

    Args:
        x: Sample inputs, shape (n_points, n_vars), physical units.
        y: Sample responses, shape (n_points,).
        degree: Total degree, 1 to ``MAX_DEGREE``.
        x_names: Variable names; default ``x1``, ``x2``, ...
        y_name: Response name.
        labels: One label per point; default ``1``, ``2``, ...

    Returns:
        The fitted surface.

    Raises:
        DataError: If shapes disagree, a value is not finite, a variable is
            constant, there are fewer points than coefficients, or the points
            cannot determine every coefficient (rank-deficient design).
        ParameterError: If ``degree`` is out of range.

    Example:
        >>> xs = [[0.0], [1.0], [2.0]]
        >>> s = fit_response_surface(xs, [1.0, 3.0, 7.0], 2)
        >>> [round(float(b), 12) for b in s.coefficients]
        [1.0, 1.0, 1.0]
    """
    xa = np.asarray(x, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    if xa.ndim == 1:
        xa = xa[:, None]
    if xa.ndim != 2 or ya.ndim != 1 or xa.shape[0] != ya.shape[0]:
        raise DataError(
            f"x must have shape (n_points, n_vars) and y (n_points,), got {xa.shape} and {ya.shape}"
        )
    n_points, n_vars = xa.shape
    exps = monomial_exponents(n_vars, degree)
    names = tuple(x_names) if x_names is not None else tuple(f"x{i + 1}" for i in range(n_vars))
    if len(names) != n_vars:
        raise DataError(f"x_names must have {n_vars} names, got {names}")
    if not (np.all(np.isfinite(xa)) and np.all(np.isfinite(ya))):
        bad = int(np.flatnonzero(~(np.isfinite(xa).all(axis=1) & np.isfinite(ya)))[0])
        raise DataError(f"point {bad + 1} is not finite: x={xa[bad].tolist()}, y={ya[bad]}")
    if n_points < len(exps):
        raise DataError(
            f"a degree-{degree} surface in {n_vars} variables has {len(exps)} coefficients "
            f"but only {n_points} points were given"
        )
    lo, hi = xa.min(axis=0), xa.max(axis=0)
    for i in range(n_vars):
        if hi[i] == lo[i]:
            raise DataError(f"variable {names[i]!r} is constant ({lo[i]!r}); it cannot be fitted")
    center, half = (lo + hi) / 2.0, (hi - lo) / 2.0
    phi_s = design_matrix((xa - center) / half, exps)  # (n_points, n_terms)
    sv = np.linalg.svd(phi_s, compute_uv=False)
    rank = int(np.sum(sv > sv[0] * max(phi_s.shape) * np.finfo(np.float64).eps))
    if rank < len(exps):
        raise DataError(_rank_message(xa, degree, rank, len(exps)))
    q, r = np.linalg.qr(phi_s)  # reduced: q (n_points, n_terms), r (n_terms, n_terms)
    beta_s = np.linalg.solve(r, q.T @ ya)
    sv_u = np.linalg.svd(design_matrix(xa, exps), compute_uv=False)
    return ResponseSurface(
        exponents=exps,
        x_names=names,
        y_name=y_name,
        coefficients=_readonly(physical_from_scaled(beta_s, exps, center, half)),
        coefficients_scaled=_readonly(beta_s),
        center=_readonly(center),
        half_range=_readonly(half),
        x=_readonly(xa),
        y=_readonly(ya),
        leverage=_readonly(np.sum(q * q, axis=1)),
        condition_number=float(sv[0] / sv[-1]),
        condition_number_unscaled=float(sv_u[0] / sv_u[-1]) if sv_u[-1] > 0 else math.inf,
        labels=tuple(labels) if labels is not None else tuple(str(i + 1) for i in range(n_points)),
    )


def physical_from_scaled(
    beta_scaled: npt.ArrayLike,
    exponents: Exponents,
    center: npt.ArrayLike,
    half_range: npt.ArrayLike,
) -> FloatArray:
    """Expand coefficients in ``s = (x - c) / h`` into coefficients in ``x``.

    Each scaled monomial is expanded by the binomial theorem,
    ``((x - c) / h)^e = h^-e Σ_j C(e, j) x^j (-c)^(e-j)``, and the products are
    collected onto the physical monomials, which lie in the same complete set.

    Args:
        beta_scaled: Coefficients in scaled variables, shape (n_terms,).
        exponents: Term exponents, paper order.
        center: c, shape (n_vars,).
        half_range: h, shape (n_vars,), all non-zero.

    Returns:
        Coefficients in physical units, shape (n_terms,), paper order.
    """
    b = np.asarray(beta_scaled, dtype=np.float64)
    c = np.asarray(center, dtype=np.float64)
    h = np.asarray(half_range, dtype=np.float64)
    index = {e: k for k, e in enumerate(exponents)}
    out = np.zeros(len(exponents), dtype=np.float64)
    for coef, e in zip(b, exponents, strict=True):
        for js in itertools.product(*(range(ei + 1) for ei in e)):
            w = coef
            for ei, ji, ci, hi in zip(e, js, c, h, strict=True):
                w *= math.comb(ei, ji) * (-ci) ** (ei - ji) / hi**ei
            out[index[tuple(js)]] += w
    return out


def predict(surface: ResponseSurface, x: npt.ArrayLike) -> FloatArray:
    """Evaluate the surface.

    Args:
        surface: The fitted surface.
        x: Points, shape (n_points, n_vars) or a single point (n_vars,), physical units.

    Returns:
        ỹ with shape (n_points,).

    Raises:
        ParameterError: If ``x`` has the wrong number of variables.
    """
    xa = _as_points(x, surface.n_vars)
    s = (xa - surface.center) / surface.half_range
    return design_matrix(s, surface.exponents) @ surface.coefficients_scaled


def gradient(surface: ResponseSurface, x: npt.ArrayLike) -> FloatArray:
    """Evaluate the gradient of the surface with respect to the physical variables.

    ``∂ỹ/∂x_i = (1 / h_i) Σ_k β^s_k e_ki s_i^(e_ki - 1) Π_{j≠i} s_j^e_kj``.

    Args:
        surface: The fitted surface.
        x: Points, shape (n_points, n_vars) or a single point (n_vars,), physical units.

    Returns:
        ∇ỹ with shape (n_points, n_vars), in response units per variable unit.

    Raises:
        ParameterError: If ``x`` has the wrong number of variables.
    """
    xa = _as_points(x, surface.n_vars)
    s = (xa - surface.center) / surface.half_range
    e = np.asarray(surface.exponents, dtype=np.int64)  # (n_terms, n_vars)
    out = np.empty_like(s)
    for i in range(surface.n_vars):
        de = e.copy()
        de[:, i] = np.maximum(e[:, i] - 1, 0)
        dphi = (
            np.prod(s[:, None, :] ** de[None, :, :], axis=2) * e[None, :, i]
        )  # (n_points, n_terms)
        out[:, i] = dphi @ surface.coefficients_scaled / surface.half_range[i]
    return out


def format_polynomial(
    surface: ResponseSurface, *, digits: int = 6, symbols: Sequence[str] | None = None
) -> str:
    """Write the surface as one equation in physical units, paper term order.

    Args:
        surface: The fitted surface.
        digits: Significant digits per coefficient.
        symbols: Variable symbols; default the surface's ``x_names``.

    Returns:
        For example ``eta = 0.1 + 2*x1 - 3e-05*x1*x2``.
    """
    names = term_names(surface.exponents, symbols if symbols is not None else surface.x_names)
    parts = []
    for k, (b, name) in enumerate(zip(surface.coefficients, names, strict=True)):
        mag = f"{abs(float(b)):.{digits}g}"
        body = mag if name == "1" else f"{mag}*{name}"
        sign = ("-" if b < 0 else "") if k == 0 else (" - " if b < 0 else " + ")
        parts.append(sign + body)
    return f"{surface.y_name} = " + "".join(parts)
