"""The object ``cad`` hands to ``mesh``: solids, materials and named faces.

Coordinates of every hinge model: ``x`` is the load line (tang's fixed end at −x,
clevis load end at +x), ``z`` is the pin axis, ``y`` completes a right-handed frame.
The pin axis passes through the origin.

A named face carries its exact geometry (``cad.surfaces``) where the solver needs it
(contact surfaces), so gaps are measured against the true surface, not the facets.
The mesher selects the boundary facets of ``part`` that lie on ``surface`` and whose
centroid lies inside ``box``.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any

from cad.materials import Material
from cad.surfaces import Plane, Surface

Box = tuple[tuple[float, float, float], tuple[float, float, float]]
"""Axis-aligned box ((xmin, ymin, zmin), (xmax, ymax, zmax)) [mm]."""

EVERYWHERE: Box = ((-1e9, -1e9, -1e9), (1e9, 1e9, 1e9))


class FaceRole(Enum):
    """What a named face is for."""

    FIXED = "fixed"
    LOAD = "load"
    CONTACT_SLAVE = "contact_slave"
    CONTACT_MASTER = "contact_master"
    BONDED_SLAVE = "bonded_slave"
    BONDED_MASTER = "bonded_master"
    PRELOAD = "preload"


class PairKind(Enum):
    """How two named faces interact."""

    CONTACT = "contact"
    BONDED = "bonded"


@dataclass(frozen=True)
class SurfacePair:
    """A named pair of faces (and, after meshing, of facet sets with the same names).

    Attributes:
        name: Pair name, e.g. ``"pin-tang"``.
        slave: Slave face name (pin or ball side, as in the paper).
        master: Master face name (hole or raceway side).
        kind: Contact (unilateral, frictional) or bonded (tied).
    """

    name: str
    slave: str
    master: str
    kind: PairKind = PairKind.CONTACT


@dataclass(frozen=True)
class NamedFace:
    """A face of a part that loads, supports or contacts are attached to.

    Attributes:
        name: Unique name; survives unchanged into the mesh's facet sets.
        part: Name of the part it bounds.
        role: What it is for.
        surface: Its exact geometry.
        box: Region of ``surface`` that belongs to this face [mm].
    """

    name: str
    part: str
    role: FaceRole
    surface: Surface
    box: Box = EVERYWHERE


@dataclass(frozen=True)
class Slab:
    """A z-range of a swept part and which profile faces it extrudes.

    Attributes:
        z0_mm: Bottom of the slab [mm].
        z1_mm: Top of the slab [mm].
        faces: Indices into ``Sweep.profile`` of the faces extruded over this slab.
    """

    z0_mm: float
    z1_mm: float
    faces: tuple[int, ...]


@dataclass(frozen=True)
class Sweep:
    """How a prismatic part is generated: planar faces (normal z) extruded slab by slab.

    The profile faces share edges where they touch, so a mesh of the profile is
    conforming across faces and, extruded, across slabs.

    Attributes:
        profile: build123d Faces in a plane z = const (their z is ignored).
        slabs: The z-ranges, bottom to top, adjacent slabs sharing their z level.
    """

    profile: tuple[Any, ...]
    slabs: tuple[Slab, ...]


@dataclass(frozen=True)
class Part:
    """One solid body of the hinge.

    Attributes:
        name: Part name (``"tang"``, ``"clevis"``, ``"pin"``, ``"ball_3"``, …).
        solid: The build123d solid, in mm.
        material: Its material.
        sweep: How it is generated, if it is prismatic along z (lets ``mesh`` sweep hexes); None
            for parts that must be volume-meshed.
    """

    name: str
    solid: Any
    material: Material
    sweep: Sweep | None = None


@dataclass(frozen=True)
class HingeModel:
    """A complete hinge: parts, named faces and the pairs between them.

    Attributes:
        kind: ``"general"`` or ``"bearing"``.
        params: The frozen parameter dataclass it was built from.
        parts: The solids.
        faces: Named faces by name.
        pairs: Contact and bonded pairs.
    """

    kind: str
    params: Any
    parts: tuple[Part, ...]
    faces: dict[str, NamedFace]
    pairs: tuple[SurfacePair, ...]

    def part(self, name: str) -> Part:
        """Return the part called ``name``."""
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(f"no part {name!r}; parts are {[p.name for p in self.parts]}")

    def volumes_mm3(self) -> dict[str, float]:
        """Return each part's solid volume [mm³]."""
        return {p.name: float(p.solid.volume) for p in self.parts}


def grip_faces(tang_length_mm: float, clevis_end_mm: float) -> list[NamedFace]:
    """Return the two faces a test machine holds, the same for every hinge kind.

    Args:
        tang_length_mm: The tang's fixed end lies at x = −tang_length_mm.
        clevis_end_mm: The clevis load face lies at x = clevis_end_mm.

    Returns:
        ``tang_fixed`` (FIXED, normal −x) and ``clevis_load`` (LOAD, normal +x).
    """
    return [
        NamedFace("tang_fixed", "tang", FaceRole.FIXED, Plane((-tang_length_mm, 0, 0), (-1, 0, 0))),
        NamedFace("clevis_load", "clevis", FaceRole.LOAD, Plane((clevis_end_mm, 0, 0), (1, 0, 0))),
    ]
