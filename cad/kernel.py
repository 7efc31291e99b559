"""Small checked wrappers around the CAD kernel that every hinge builder uses."""

from __future__ import annotations

from typing import Any

import build123d as bd

from cad.errors import GeometryError


def single_face(sketch: bd.Sketch, what: str) -> bd.Face:
    """Return the one face of a sketch, or raise naming what it should have been."""
    faces = sketch.faces()
    if len(faces) != 1:
        raise GeometryError(f"{what} should be one face, the kernel made {len(faces)}")
    return faces[0]


def extrude_faces(faces: tuple[bd.Face, ...], z0: float, z1: float) -> bd.Part:
    """Extrude planar faces (normal z) from z = z0 to z = z1 [mm]."""
    return bd.Pos(0, 0, z0) * bd.extrude(bd.Sketch() + list(faces), amount=z1 - z0)


def checked_solid(shape: bd.Shape[Any], name: str) -> bd.Solid:
    """Return the one valid solid of a boolean's result, or raise naming the part."""
    solids = shape.solids()
    if len(solids) != 1 or not solids[0].is_valid:
        raise GeometryError(
            f"{name}: the kernel made {len(solids)} solid(s), valid={shape.is_valid}"
        )
    return solids[0]
