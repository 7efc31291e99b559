"""The modified ("bearing") hinge: the pin runs in a preloaded pair of angular-contact bearings.

Paper, Sec. IV.A: the outer rings of two angular-contact ball bearings are epoxied
into the tang, the inner rings and the clevis are epoxied to the pin, and a plate
held by four screws pinches the outer rings together to preload the pair (axial
preload Fp = 0–200 N). Only the ball–raceway contacts remain; every other interface
is bonded.

Frame as in ``cad.model`` (pin axis z through the origin, load line x). Meridional
section (r = distance from the pin axis), with the default face-to-face pair::

    z ↑      plate  ┌──┐ boss                 clevis arm 2 (z > 0)
         B + b + t  │  └─────┐
                  B ┼────────┼── outer ring 1 ─┐ tang
                    │ ◯ ball 1 ╲ contact line   │ bore
                  0 ┼─────────────────────────┤
                    │ ◯ ball 0 ╱               │
                 −B ┼────────┬── outer ring 0 ─┘
             −B − t  tang lip┘                    clevis arm 1 (z < 0)
                    └ inner rings on the pin (r = bore/2 … inner land)

Bearing 0 occupies z ∈ [−B, 0], bearing 1 z ∈ [0, B] (B = ``width_mm``). Ball k of
bearing b is the part ``ball_{b}_{k}``, centred at angle 2πk/Z on the pitch circle.

The parameters and the raceway geometry (ball, groove and contact positions, the
arrangement and the default bearing) are in ``cad.bearing_geometry``; this module builds
the solids, the named faces and the surface pairs.
"""

from __future__ import annotations

import itertools

import build123d as bd

from cad.bearing_geometry import (
    BearingHingeParams,
    ball_center,
    contact_points,
    race_geometry,
)
from cad.kernel import checked_solid, extrude_faces, single_face
from cad.model import (
    Box,
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
from cad.surfaces import Cylinder, Plane, Sphere, Torus

__all__ = [
    "SURFACE_TOL_MM",
    "make_bearing_hinge",
    "without_balls",
]

SURFACE_TOL_MM = 1e-3
"""Slack of the boxes that pick named faces [mm]."""


def _annulus(r_in: float, r_out: float, what: str) -> bd.Face:
    return single_face(bd.Circle(r_out) - bd.Circle(r_in), what)


def _swept(
    faces: tuple[bd.Face, ...], slabs: tuple[Slab, ...], name: str
) -> tuple[bd.Solid, Sweep]:
    """Return the solid made by extruding ``faces`` slab by slab, and its Sweep."""
    layers = [extrude_faces(tuple(faces[i] for i in s.faces), s.z0_mm, s.z1_mm) for s in slabs]
    body = layers[0]
    for layer in layers[1:]:
        body = body + layer
    return checked_solid(body, name), Sweep(faces, slabs)


def _lug(
    width: float, toward: float, length: float, ring_r: float, hole_r: float, what: str
) -> tuple[bd.Face, bd.Face]:
    """Return the (ring around the hole, rest of the outline) faces of a lug reaching toward ±x."""
    align_x = bd.Align.MIN if toward > 0 else bd.Align.MAX
    body = bd.Rectangle(length, width, align=(align_x, bd.Align.CENTER)) + bd.Circle(width / 2)
    return (
        _annulus(hole_r, ring_r, f"{what} ring"),
        single_face(body - bd.Circle(ring_r), f"{what} outline"),
    )


def make_bearing_hinge(p: BearingHingeParams) -> HingeModel:
    """Build the bearing hinge's solids, named faces and surface pairs.

    Args:
        p: Validated parameters.

    Returns:
        A HingeModel of kind ``"bearing"`` with parts tang, clevis, pin, preload_plate,
        inner_ring_{0,1}, outer_ring_{0,1} and ball_{b}_{k}.

    Raises:
        GeometryError: If the kernel produces an invalid solid.
    """
    parts = [*_lug_parts(p)]
    for b in (0, 1):
        parts.extend(_bearing_parts(p, b))
    faces = _named_faces(p)
    return HingeModel("bearing", p, tuple(parts), faces, _pairs(p))


def _lug_parts(p: BearingHingeParams) -> tuple[Part, ...]:
    z = p.z_levels()
    r_d, r_o = 0.5 * p.bore_mm, 0.5 * p.outer_diameter_mm
    seat = race_geometry(p, 1).outer_land_mm  # lip and plate bear on the outer-ring face only
    tang_ring, tang_outer = _lug(
        2 * p.tang_radius_mm, -1.0, p.tang_length_mm, r_o + 0.5 * p.tang_wall_mm, r_o, "tang"
    )
    lip = _annulus(seat, r_o, "tang lip")
    tang, tang_sweep = _swept(
        (lip, tang_ring, tang_outer),
        (Slab(*z["lip"], (0, 1, 2)), Slab(z["lip"][1], z["tang"][1], (1, 2))),
        "tang",
    )
    arm_ring_r = r_d + 0.5 * (0.5 * p.clevis_width_mm - r_d)
    arm_ring, arm_outer = _lug(
        p.clevis_width_mm, 1.0, p.clevis_length_mm, arm_ring_r, r_d, "clevis"
    )
    base = single_face(
        bd.Pos(p.clevis_length_mm, 0)
        * bd.Rectangle(p.clevis_base_mm, p.clevis_width_mm, align=(bd.Align.MIN, bd.Align.CENTER)),
        "clevis base",
    )
    clevis, clevis_sweep = _swept(
        (arm_ring, arm_outer, base),
        (
            Slab(*z["clevis_1"], (0, 1, 2)),
            Slab(z["clevis_1"][1], z["clevis_2"][0], (2,)),
            Slab(*z["clevis_2"], (0, 1, 2)),
        ),
        "clevis",
    )
    levels = sorted(
        {v for key in ("pin", "clevis_1", "clevis_2", "tang", "plate") for v in z[key]} | {0.0}
    )
    pin_face = single_face(bd.Circle(r_d), "pin section")
    pin, pin_sweep = _swept(
        (pin_face,), tuple(Slab(a, b, (0,)) for a, b in itertools.pairwise(levels)), "pin"
    )
    boss, rim = _annulus(seat, r_o, "plate boss"), _annulus(r_o, r_o + p.plate_rim_mm, "plate rim")
    plate, plate_sweep = _swept(
        (boss, rim),
        (Slab(*z["boss"], (0,)), Slab(z["boss"][1], z["plate"][1], (0, 1))),
        "preload_plate",
    )
    return (
        Part("tang", tang, p.lug_material, tang_sweep),
        Part("clevis", clevis, p.lug_material, clevis_sweep),
        Part("pin", pin, p.pin_material, pin_sweep),
        Part("preload_plate", plate, p.lug_material, plate_sweep),
    )


def _bearing_parts(p: BearingHingeParams, b: int) -> tuple[Part, ...]:
    g = race_geometry(p, b)
    z0, z1 = p.z_levels()[f"bearing_{b}"]
    zc, height = 0.5 * (z0 + z1), z1 - z0
    dw = p.ball_diameter_mm

    def cylinder(radius: float, extra: float = 0.0) -> bd.Part:
        return bd.Pos(0, 0, zc) * bd.Cylinder(radius, height + extra)

    def groove(centre: tuple[float, float], f: float) -> bd.Part:
        return bd.Pos(0, 0, centre[1]) * bd.Torus(centre[0], f * dw)

    # The cutting cylinders are taller than the rings: no coplanar end faces in the booleans.
    inner = (
        cylinder(g.inner_land_mm)
        - cylinder(0.5 * p.bore_mm, 2.0)
        - groove(g.inner_groove, p.inner_curvature_ratio)
    )
    outer = (
        cylinder(0.5 * p.outer_diameter_mm)
        - cylinder(g.outer_land_mm, 2.0)
        - groove(g.outer_groove, p.outer_curvature_ratio)
    )
    parts = [
        Part(f"inner_ring_{b}", checked_solid(inner, f"inner_ring_{b}"), p.bearing_material),
        Part(f"outer_ring_{b}", checked_solid(outer, f"outer_ring_{b}"), p.bearing_material),
    ]
    for k in range(p.ball_count):
        x, y, z = ball_center(p, b, k)
        ball = bd.Pos(x, y, z) * bd.Sphere(0.5 * dw)
        parts.append(
            Part(f"ball_{b}_{k}", checked_solid(ball, f"ball_{b}_{k}"), p.bearing_material)
        )
    return tuple(parts)


def _around(point: tuple[float, float, float], half: float) -> Box:
    x, y, z = point
    return ((x - half, y - half, z - half), (x + half, y + half, z + half))


def _zbox(rng: tuple[float, float], half_xy: float = 1e6) -> Box:
    tol = SURFACE_TOL_MM
    return ((-half_xy, -half_xy, rng[0] - tol), (half_xy, half_xy, rng[1] + tol))


def _named_faces(p: BearingHingeParams) -> dict[str, NamedFace]:
    z = p.z_levels()
    r_d, r_o = 0.5 * p.bore_mm, 0.5 * p.outer_diameter_mm
    axis = ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    pin_surface = Cylinder(*axis, r_d, material_inside=True)
    pin_hole = Cylinder(*axis, r_d, material_inside=False)
    ring_od = Cylinder(*axis, r_o, material_inside=True)
    tang_bore = Cylinder(*axis, r_o, material_inside=False)
    seat_box = _zbox(z["bearing_1"], r_o + SURFACE_TOL_MM)
    faces = [
        *grip_faces(p.tang_length_mm, p.clevis_length_mm + p.clevis_base_mm),
        NamedFace(
            "plate_preload",
            "preload_plate",
            FaceRole.PRELOAD,
            Plane((0, 0, z["plate"][1]), (0, 0, 1)),
        ),
        NamedFace(
            "plate_seat",
            "preload_plate",
            FaceRole.BONDED_SLAVE,
            Plane((0, 0, p.width_mm), (0, 0, -1)),
            seat_box,
        ),
        NamedFace(
            "outer_ring_1_top",
            "outer_ring_1",
            FaceRole.BONDED_MASTER,
            Plane((0, 0, p.width_mm), (0, 0, 1)),
        ),
        NamedFace(
            "outer_ring_0_bottom",
            "outer_ring_0",
            FaceRole.BONDED_SLAVE,
            Plane((0, 0, -p.width_mm), (0, 0, -1)),
        ),
        NamedFace(
            "tang_lip",
            "tang",
            FaceRole.BONDED_MASTER,
            Plane((0, 0, -p.width_mm), (0, 0, 1)),
            _zbox((-p.width_mm, -p.width_mm), r_o + SURFACE_TOL_MM),
        ),
    ]
    land = race_geometry(p, 0).inner_land_mm + SURFACE_TOL_MM  # the inner rings abut at z = 0
    faces += [
        NamedFace(
            "inner_ring_0_top",
            "inner_ring_0",
            FaceRole.BONDED_SLAVE,
            Plane((0, 0, 0), (0, 0, 1)),
            _zbox((0.0, 0.0), land),
        ),
        NamedFace(
            "inner_ring_1_bottom",
            "inner_ring_1",
            FaceRole.BONDED_MASTER,
            Plane((0, 0, 0), (0, 0, -1)),
            _zbox((0.0, 0.0), land),
        ),
    ]
    for k, arm in ((1, "clevis_1"), (2, "clevis_2")):
        faces.append(
            NamedFace(f"pin_clevis_{k}", "pin", FaceRole.BONDED_SLAVE, pin_surface, _zbox(z[arm]))
        )
        faces.append(
            NamedFace(f"clevis_hole_{k}", "clevis", FaceRole.BONDED_MASTER, pin_hole, _zbox(z[arm]))
        )
    for b in (0, 1):
        zb = _zbox(z[f"bearing_{b}"])
        faces += [
            NamedFace(f"pin_inner_ring_{b}", "pin", FaceRole.BONDED_SLAVE, pin_surface, zb),
            NamedFace(
                f"inner_ring_{b}_bore", f"inner_ring_{b}", FaceRole.BONDED_MASTER, pin_hole, zb
            ),
            NamedFace(f"outer_ring_{b}_od", f"outer_ring_{b}", FaceRole.BONDED_SLAVE, ring_od, zb),
            NamedFace(f"tang_bore_{b}", "tang", FaceRole.BONDED_MASTER, tang_bore, zb),
        ]
        faces += _ball_faces(p, b)
    return {f.name: f for f in faces}


def _ball_faces(p: BearingHingeParams, b: int) -> list[NamedFace]:
    g = race_geometry(p, b)
    dw = p.ball_diameter_mm
    grooves = {
        "inner": Torus(
            (0, 0, g.inner_groove[1]), (0, 0, 1), g.inner_groove[0], p.inner_curvature_ratio * dw
        ),
        "outer": Torus(
            (0, 0, g.outer_groove[1]), (0, 0, 1), g.outer_groove[0], p.outer_curvature_ratio * dw
        ),
    }
    faces = []
    for k in range(p.ball_count):
        ball = Sphere(ball_center(p, b, k), 0.5 * dw)
        for race, point in contact_points(p, b, k).items():
            box = _around(point, p.contact_cap_mm)
            faces.append(
                NamedFace(
                    f"ball_{b}_{k}_{race}", f"ball_{b}_{k}", FaceRole.CONTACT_SLAVE, ball, box
                )
            )
            faces.append(
                NamedFace(
                    f"{race}_ring_{b}_groove_{k}",
                    f"{race}_ring_{b}",
                    FaceRole.CONTACT_MASTER,
                    grooves[race],
                    box,
                )
            )
    return faces


def _pairs(p: BearingHingeParams) -> tuple[SurfacePair, ...]:
    bonded = [
        SurfacePair("pin-clevis_1", "pin_clevis_1", "clevis_hole_1", PairKind.BONDED),
        SurfacePair("pin-clevis_2", "pin_clevis_2", "clevis_hole_2", PairKind.BONDED),
        SurfacePair("plate-outer_ring_1", "plate_seat", "outer_ring_1_top", PairKind.BONDED),
        SurfacePair("outer_ring_0-tang_lip", "outer_ring_0_bottom", "tang_lip", PairKind.BONDED),
        SurfacePair(
            "inner_ring_0-inner_ring_1", "inner_ring_0_top", "inner_ring_1_bottom", PairKind.BONDED
        ),
    ]
    contact = []
    for b in (0, 1):
        bonded.append(
            SurfacePair(
                f"pin-inner_ring_{b}",
                f"pin_inner_ring_{b}",
                f"inner_ring_{b}_bore",
                PairKind.BONDED,
            )
        )
        bonded.append(
            SurfacePair(
                f"outer_ring_{b}-tang", f"outer_ring_{b}_od", f"tang_bore_{b}", PairKind.BONDED
            )
        )
        for k in range(p.ball_count):
            for race in ("inner", "outer"):
                contact.append(
                    SurfacePair(
                        f"ball_{b}_{k}-{race}_ring_{b}",
                        f"ball_{b}_{k}_{race}",
                        f"{race}_ring_{b}_groove_{k}",
                        PairKind.CONTACT,
                    )
                )
    return (*bonded, *contact)


def without_balls(model: HingeModel) -> HingeModel:
    """Return the bearing hinge without its balls: the structure a ``hertz`` ball model needs.

    The balls, their faces and the ball–raceway pairs go; the raceway faces
    (``{inner,outer}_ring_{b}_groove_{k}``) stay, since they carry the patches each ball
    loads and make the mesh finer there.
    """
    parts = tuple(p for p in model.parts if not p.name.startswith("ball_"))
    faces = {k: f for k, f in model.faces.items() if not f.part.startswith("ball_")}
    pairs = tuple(p for p in model.pairs if p.kind is PairKind.BONDED)
    return HingeModel(model.kind, model.params, parts, faces, pairs)
