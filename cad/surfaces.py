"""Analytic descriptions of the contact surfaces.

The contact solver measures gaps against these exact surfaces, not against the
faceted mesh: a 4 mm hole cut into 48 facets sags R(1 − cos(π/48)) ≈ 9 µm between
nodes, as large as the displacements we are after.

Every surface belongs to one body. ``outward_normal`` points out of that body's
material and ``distance_outside`` is positive on the side away from the material.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import check_range

FloatArray = npt.NDArray[np.float64]


def _unit(v: tuple[float, float, float]) -> FloatArray:
    a = np.asarray(v, dtype=np.float64)
    n = float(np.linalg.norm(a))
    if n == 0.0:
        raise ValueError("axis/normal must be non-zero, got (0, 0, 0)")
    return a / n


@dataclass(frozen=True)
class Cylinder:
    """A circular cylinder.

    Attributes:
        point: A point on the axis [mm].
        axis: Axis direction (need not be unit).
        radius_mm: Radius [mm].
        material_inside: True for a pin (material within the radius), False for a hole.
    """

    point: tuple[float, float, float]
    axis: tuple[float, float, float]
    radius_mm: float
    material_inside: bool

    def __post_init__(self) -> None:
        check_range("radius_mm", self.radius_mm, 0.0, float("inf"), lo_open=True)

    def _radial(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        a = _unit(self.axis)
        d = x - np.asarray(self.point, dtype=np.float64)
        d_perp = d - np.outer(d @ a, a)  # (n, 3)
        r = np.linalg.norm(d_perp, axis=1)
        return d_perp, r

    def outward_normal(self, x: FloatArray) -> FloatArray:
        """Unit normal out of the material at the closest surface point, shape (n, 3)."""
        d_perp, r = self._radial(x)
        radial = d_perp / np.maximum(r, 1e-300)[:, None]
        return radial if self.material_inside else -radial

    def distance_outside(self, x: FloatArray) -> FloatArray:
        """Signed distance [mm], positive away from the material, shape (n,)."""
        _, r = self._radial(x)
        return r - self.radius_mm if self.material_inside else self.radius_mm - r


@dataclass(frozen=True)
class Plane:
    """A plane through ``point`` whose ``normal`` points out of the material."""

    point: tuple[float, float, float]
    normal: tuple[float, float, float]

    def outward_normal(self, x: FloatArray) -> FloatArray:
        """Unit normal out of the material, shape (n, 3)."""
        return np.tile(_unit(self.normal), (len(x), 1))

    def distance_outside(self, x: FloatArray) -> FloatArray:
        """Signed distance [mm], positive away from the material, shape (n,)."""
        return (x - np.asarray(self.point, dtype=np.float64)) @ _unit(self.normal)


@dataclass(frozen=True)
class Sphere:
    """A sphere (a ball: material inside)."""

    center: tuple[float, float, float]
    radius_mm: float

    def outward_normal(self, x: FloatArray) -> FloatArray:
        """Unit normal out of the ball, shape (n, 3)."""
        d = x - np.asarray(self.center, dtype=np.float64)
        out: FloatArray = d / np.maximum(np.linalg.norm(d, axis=1), 1e-300)[:, None]
        return out

    def distance_outside(self, x: FloatArray) -> FloatArray:
        """Signed distance [mm], positive outside the ball, shape (n,)."""
        r: FloatArray = np.linalg.norm(x - np.asarray(self.center, dtype=np.float64), axis=1)
        return r - self.radius_mm


@dataclass(frozen=True)
class Torus:
    """A torus (a raceway groove): tube of radius ``minor_mm`` around a circle of radius ``major_mm``.

    Attributes:
        center: Centre of the generating circle [mm].
        axis: Axis of revolution.
        major_mm: Radius of the circle traced by the tube centre [mm].
        minor_mm: Tube (groove) radius [mm].
        material_inside: True if the material is inside the tube (never for a groove).
    """

    center: tuple[float, float, float]
    axis: tuple[float, float, float]
    major_mm: float
    minor_mm: float
    material_inside: bool = False

    def _to_tube(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        a = _unit(self.axis)
        d = x - np.asarray(self.center, dtype=np.float64)
        h = d @ a
        d_perp = d - np.outer(h, a)
        r = np.linalg.norm(d_perp, axis=1)
        ring = d_perp / np.maximum(r, 1e-300)[:, None] * self.major_mm  # nearest tube centre
        v = d - ring  # (n, 3) from tube centre to point
        return v, np.linalg.norm(v, axis=1)

    def outward_normal(self, x: FloatArray) -> FloatArray:
        """Unit normal out of the material, shape (n, 3)."""
        v, s = self._to_tube(x)
        radial = v / np.maximum(s, 1e-300)[:, None]
        return radial if self.material_inside else -radial

    def distance_outside(self, x: FloatArray) -> FloatArray:
        """Signed distance [mm], positive away from the material, shape (n,)."""
        _, s = self._to_tube(x)
        return s - self.minor_mm if self.material_inside else self.minor_mm - s


Surface = Cylinder | Plane | Sphere | Torus
