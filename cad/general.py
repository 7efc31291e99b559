"""The general hinge: tang (single lug), clevis (double lug) and a steel pin.

Geometry (mm), in the frame of ``cad.model``: the pin axis is z through the origin;
the tang reaches from its fixed end at x = −tang_length_mm to its rounded end around
the hole; the clevis arms reach from their rounded ends to the clevis base, whose far
face at x = clevis_length_mm + clevis_base_mm is the load face. Seen along z::

      tang (z in [-t/2, t/2])           clevis arms (|z| in [t/2+g, t/2+g+a]) and base
   ┌─────────────────────╮            ╭─────────────────────────┬────────┐
   │ fixed            (  o  )  ==== (  o  )                     │  base  │ load
   └─────────────────────╯            ╰─────────────────────────┴────────┘
  x=-L_t                 0            0                        L_c     L_c+b

Default dimensions are those of a small precision deployable-boom hinge: an 8 mm
steel pin (the common M8-class size, and the 4 mm radius used as an example in the
project brief), lugs 20 mm wide (edge distance e/D = 1.25, above the e/D ≥ 1 usual
for pin-loaded lugs carrying well below their bearing strength: at 500 N the mean
bearing stress in the tang is 500/(8·8) ≈ 8 MPa), an 8 mm tang between two 5 mm
clevis arms so both shear planes carry half the load, and 0.2 mm axial running gaps.
The paper does not give its hinge's dimensions. The parameters and their bounds are in
``cad.general_params`` (no build123d there).
"""

from __future__ import annotations

import itertools
import math

import build123d as bd

from cad.general_params import GeneralHingeParams
from cad.kernel import checked_solid, extrude_faces, single_face
from cad.model import (
    FaceRole,
    HingeModel,
    NamedFace,
    PairKind,
    Part,
    Slab,
    SurfacePair,
    Sweep,
    grip_faces,
)
from cad.surfaces import Cylinder

SURFACE_TOL_MM = 1e-3
"""Half-width of the boxes that pick named faces along z [mm]."""


def _polar(r: float, angle_deg: float) -> bd.Vector:
    a = math.radians(angle_deg)
    return bd.Vector(r * math.cos(a), r * math.sin(a))


def _quarter_annulus(r_in: float, r_out: float, start_deg: float) -> bd.Face:
    """Return the face between radii r_in and r_out over 90° from ``start_deg``."""
    end = start_deg + 90.0
    edges = [
        bd.CenterArc((0, 0), r_in, start_deg, 90.0),
        bd.Line(_polar(r_in, end), _polar(r_out, end)),
        bd.CenterArc((0, 0), r_out, start_deg, 90.0),
        bd.Line(_polar(r_in, start_deg), _polar(r_out, start_deg)),
    ]
    return single_face(bd.make_face(edges), "quarter annulus")


def _ring_faces(r_in: float, r_out: float) -> tuple[bd.Face, ...]:
    """Four quarter annuli split at 0°, 90°, 180°, 270°.

    The splits must include 0°: the kernel's full circle bounding the lug outline has
    its seam vertex there, which would otherwise cut one quarter's arc in two and
    leave that patch five-sided (no longer structured).
    """
    return tuple(_quarter_annulus(r_in, r_out, a) for a in (0.0, 90.0, 180.0, 270.0))


def _disk_faces(radius: float) -> tuple[bd.Face, ...]:
    """An O-grid disk: a centre square and four patches reaching the circle.

    The patches span 0–90°, 90–180°, …, so every arc ends on the load line (±x), where
    the mesher can concentrate nodes toward the contact (``MeshSettings.arc_grading``).
    """
    rho = 0.5 * radius  # half-diagonal of the centre square
    starts = (0.0, 90.0, 180.0, 270.0)
    corners = [_polar(rho, a) for a in starts]
    square = bd.make_face([bd.Line(corners[i], corners[(i + 1) % 4]) for i in range(4)])
    faces = [single_face(square, "pin core")]
    for i, a in enumerate(starts):
        edges = [
            bd.CenterArc((0, 0), radius, a, 90.0),
            bd.Line(_polar(radius, a + 90.0), corners[(i + 1) % 4]),
            bd.Line(corners[(i + 1) % 4], corners[i]),
            bd.Line(corners[i], _polar(radius, a)),
        ]
        faces.append(single_face(bd.make_face(edges), "pin patch"))
    return tuple(faces)


def _lug_profile(p: GeneralHingeParams, toward: float, length: float) -> tuple[bd.Face, ...]:
    """Return the faces of a lug whose body extends from the hole toward ±x.

    Four ring quarters around the hole, two quarter annuli forming the rounded end
    (splitting there keeps the tangency points of the outline off any element's
    side), and the straight body.
    """
    half_w = p.lug_width_mm / 2
    align_x = bd.Align.MIN if toward > 0 else bd.Align.MAX
    body = bd.Rectangle(length, p.lug_width_mm, align=(align_x, bd.Align.CENTER)) - bd.Circle(
        p.ring_radius_mm
    )
    end_starts = (90.0, 180.0) if toward > 0 else (270.0, 0.0)
    end = tuple(_quarter_annulus(p.ring_radius_mm, half_w, a) for a in end_starts)
    return (*_ring_faces(p.hole_radius_mm, p.ring_radius_mm), *end, single_face(body, "lug body"))


def make_general_hinge(p: GeneralHingeParams) -> HingeModel:
    """Build the general hinge's solids, named faces and contact pairs.

    Args:
        p: Validated parameters.

    Returns:
        A HingeModel of kind ``"general"`` with parts tang, clevis, pin.

    Raises:
        GeometryError: If the kernel produces an invalid solid.
    """
    z = p.z_levels()
    tang_faces = _lug_profile(p, -1.0, p.tang_length_mm)
    arm_lug = _lug_profile(p, +1.0, p.clevis_length_mm)
    base = bd.Pos(p.clevis_length_mm, 0) * bd.Rectangle(
        p.clevis_base_mm, p.lug_width_mm, align=(bd.Align.MIN, bd.Align.CENTER)
    )
    base_face = single_face(base, "clevis base")
    pin_faces = _disk_faces(p.pin_radius_mm)

    tang = checked_solid(extrude_faces(tang_faces, *z["tang"]), "tang")
    arm_faces = (*arm_lug, base_face)
    base_index = len(arm_faces) - 1
    clevis_body = (
        extrude_faces(arm_faces, *z["clevis_1"])
        + extrude_faces((base_face,), z["clevis_1"][1], z["clevis_2"][0])
        + extrude_faces(arm_faces, *z["clevis_2"])
    )
    clevis = checked_solid(clevis_body, "clevis")
    pin = checked_solid(extrude_faces(pin_faces, *z["pin"]), "pin")
    everything = tuple(range(len(arm_faces)))

    pin_levels = sorted({*z["pin"], *z["clevis_1"], *z["clevis_2"], *z["tang"]})
    parts = (
        Part(
            "tang",
            tang,
            p.lug_material,
            Sweep(tang_faces, (Slab(*z["tang"], tuple(range(len(tang_faces)))),)),
        ),
        Part(
            "clevis",
            clevis,
            p.lug_material,
            Sweep(
                arm_faces,
                (
                    Slab(*z["clevis_1"], everything),
                    Slab(z["clevis_1"][1], z["clevis_2"][0], (base_index,)),
                    Slab(*z["clevis_2"], everything),
                ),
            ),
        ),
        Part(
            "pin",
            pin,
            p.pin_material,
            Sweep(
                pin_faces,
                tuple(Slab(a, b, tuple(range(5))) for a, b in itertools.pairwise(pin_levels)),
            ),
        ),
    )
    return HingeModel("general", p, parts, _named_faces(p), _pairs())


def _named_faces(p: GeneralHingeParams) -> dict[str, NamedFace]:
    z = p.z_levels()
    pin_surface = Cylinder((0, 0, 0), (0, 0, 1), p.pin_radius_mm, material_inside=True)
    hole = Cylinder((0, 0, 0), (0, 0, 1), p.hole_radius_mm, material_inside=False)
    tol = SURFACE_TOL_MM
    far = 1e6

    def zbox(
        rng: tuple[float, float],
    ) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        return ((-far, -far, rng[0] - tol), (far, far, rng[1] + tol))

    faces = [
        *grip_faces(p.tang_length_mm, p.clevis_length_mm + p.clevis_base_mm),
        NamedFace("tang_hole", "tang", FaceRole.CONTACT_MASTER, hole, zbox(z["tang"])),
        NamedFace("clevis_hole_1", "clevis", FaceRole.CONTACT_MASTER, hole, zbox(z["clevis_1"])),
        NamedFace("clevis_hole_2", "clevis", FaceRole.CONTACT_MASTER, hole, zbox(z["clevis_2"])),
        NamedFace("pin_tang", "pin", FaceRole.CONTACT_SLAVE, pin_surface, zbox(z["tang"])),
        NamedFace("pin_clevis_1", "pin", FaceRole.CONTACT_SLAVE, pin_surface, zbox(z["clevis_1"])),
        NamedFace("pin_clevis_2", "pin", FaceRole.CONTACT_SLAVE, pin_surface, zbox(z["clevis_2"])),
    ]
    return {f.name: f for f in faces}


def _pairs() -> tuple[SurfacePair, ...]:
    return (
        SurfacePair("pin-tang", "pin_tang", "tang_hole", PairKind.CONTACT),
        SurfacePair("pin-clevis_1", "pin_clevis_1", "clevis_hole_1", PairKind.CONTACT),
        SurfacePair("pin-clevis_2", "pin_clevis_2", "clevis_hole_2", PairKind.CONTACT),
    )
