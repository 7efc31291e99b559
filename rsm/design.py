"""Designs of experiments in physical units, built on pyDOE3.

Every function returns sample points with shape (n_points, n_vars) in the units
of the bounds or levels it was given. The coded designs of pyDOE3 (levels in
[-1, 1], or indices) are mapped to physical values here and nowhere else.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import Enum

import numpy as np
import numpy.typing as npt
import pyDOE3

from cad.errors import ParameterError

FloatArray = npt.NDArray[np.float64]


class CompositeFace(Enum):
    """Where the axial ("star") points of a central composite design go.

    CIRCUMSCRIBED puts them outside the box (at ±α); the box corners are the
    factorial points. INSCRIBED shrinks the design so the star points lie on the
    box faces. FACED puts the star points at the centres of the box faces (α = 1).
    """

    CIRCUMSCRIBED = "ccc"
    INSCRIBED = "cci"
    FACED = "ccf"


def _check_bounds(bounds: Sequence[tuple[float, float]]) -> tuple[FloatArray, FloatArray]:
    if len(bounds) == 0:
        raise ParameterError("bounds must give (lower, upper) for at least one variable")
    lo = np.array([b[0] for b in bounds], dtype=np.float64)
    hi = np.array([b[1] for b in bounds], dtype=np.float64)
    for i, (a, b) in enumerate(zip(lo, hi, strict=True)):
        if not (np.isfinite(a) and np.isfinite(b) and a < b):
            raise ParameterError(f"bounds[{i}] must be finite with lower < upper, got ({a}, {b})")
    return lo, hi


def _from_coded(coded: FloatArray, lo: FloatArray, hi: FloatArray) -> FloatArray:
    """Map coded levels in [-1, 1] to the box [lo, hi], variable by variable."""
    return (lo + hi) / 2.0 + coded * (hi - lo) / 2.0


def full_factorial(levels: Sequence[Sequence[float]]) -> FloatArray:
    """Every combination of the given levels, first variable varying slowest.

    The paper's 5 × 5 designs (Tables 1 and 4) are
    ``full_factorial([[0, 0.1, 0.2, 0.3, 0.4], [100, 200, 300, 400, 500]])``,
    in the same row order as the tables.

    Args:
        levels: For each variable, its distinct levels in physical units.

    Returns:
        Points, shape (Π n_levels, n_vars), float64.

    Raises:
        ParameterError: If a variable has no level or repeats one.

    Example:
        >>> full_factorial([[0.0, 1.0], [10.0, 20.0, 30.0]]).tolist()[:3]
        [[0.0, 10.0], [0.0, 20.0], [0.0, 30.0]]
    """
    if len(levels) == 0:
        raise ParameterError("levels must list the levels of at least one variable")
    arrs = [np.asarray(lv, dtype=np.float64) for lv in levels]
    for i, a in enumerate(arrs):
        if a.ndim != 1 or a.size == 0 or len(np.unique(a)) != a.size:
            raise ParameterError(f"levels[{i}] must be distinct values, got {a.tolist()}")
    # pyDOE3 varies the first factor fastest; reversing makes it slowest, as in the paper.
    idx = pyDOE3.fullfact([a.size for a in reversed(arrs)])[:, ::-1].astype(np.int64)
    return np.column_stack([a[idx[:, i]] for i, a in enumerate(arrs)])


def latin_hypercube(
    bounds: Sequence[tuple[float, float]], n_samples: int, *, seed: int = 0, maximin: bool = True
) -> FloatArray:
    """Latin hypercube sample of a box.

    Args:
        bounds: (lower, upper) per variable, physical units.
        n_samples: Number of points.
        seed: Random seed, so that a study can be repeated exactly.
        maximin: Spread points by pyDOE3's "maximin" criterion (else plain random LHS).

    Returns:
        Points, shape (n_samples, n_vars), inside the box.

    Raises:
        ParameterError: If bounds are inverted or ``n_samples`` < 2.
    """
    lo, hi = _check_bounds(bounds)
    if n_samples < 2:
        raise ParameterError(f"n_samples must be at least 2, got {n_samples}")
    unit = pyDOE3.lhs(
        len(lo),
        samples=n_samples,
        criterion="maximin" if maximin else None,
        iterations=20 if maximin else None,
        seed=np.random.default_rng(seed),
    )
    return lo + np.asarray(unit, dtype=np.float64) * (hi - lo)


def central_composite(
    bounds: Sequence[tuple[float, float]],
    *,
    face: CompositeFace = CompositeFace.FACED,
    n_center: int = 1,
    rotatable: bool = False,
) -> FloatArray:
    """Central composite design (pyDOE3 ``ccdesign``) scaled to a box.

    Coded ±1 maps to the box bounds. With ``CIRCUMSCRIBED`` the axial points lie
    outside the box at ±α; choose ``FACED`` or ``INSCRIBED`` to stay inside.

    Args:
        bounds: (lower, upper) per variable, physical units; at least two variables.
        face: Where the axial points go.
        n_center: Centre points (split between factorial and axial blocks as pyDOE3 does).
        rotatable: Use the rotatable α instead of the orthogonal one (ignored for FACED).

    Returns:
        Points, shape (n_points, n_vars).

    Raises:
        ParameterError: If fewer than two variables or a negative centre count.
    """
    lo, hi = _check_bounds(bounds)
    if len(lo) < 2:
        raise ParameterError(
            f"a central composite design needs at least 2 variables, got {len(lo)}"
        )
    if n_center < 0:
        raise ParameterError(f"n_center must be >= 0, got {n_center}")
    center = (n_center - n_center // 2, n_center // 2)
    coded = pyDOE3.ccdesign(
        len(lo), center=center, alpha="rotatable" if rotatable else "orthogonal", face=face.value
    )
    return _from_coded(np.asarray(coded, dtype=np.float64), lo, hi)


def box_behnken(bounds: Sequence[tuple[float, float]], *, n_center: int = 1) -> FloatArray:
    """Box-Behnken design (pyDOE3 ``bbdesign``) scaled to a box.

    Args:
        bounds: (lower, upper) per variable, physical units; at least three variables.
        n_center: Number of centre points.

    Returns:
        Points, shape (n_points, n_vars), on edge midpoints and the centre of the box.

    Raises:
        ParameterError: If fewer than three variables or ``n_center`` < 1.
    """
    lo, hi = _check_bounds(bounds)
    if len(lo) < 3:
        raise ParameterError(f"a Box-Behnken design needs at least 3 variables, got {len(lo)}")
    if n_center < 1:
        raise ParameterError(f"n_center must be >= 1, got {n_center}")
    coded = pyDOE3.bbdesign(len(lo), center=n_center)
    return _from_coded(np.asarray(coded, dtype=np.float64), lo, hi)
