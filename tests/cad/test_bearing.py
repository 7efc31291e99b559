import dataclasses
import math

import build123d as bd
import numpy as np
import pytest
from OCP.BRepAdaptor import BRepAdaptor_Surface

from cad.bearing import make_bearing_hinge
from cad.bearing_geometry import (
    Arrangement,
    BearingHingeParams,
    ball_center,
    contact_points,
    race_geometry,
)
from cad.errors import ParameterError
from cad.model import FaceRole, PairKind
from cad.surfaces import Sphere, Torus

P = BearingHingeParams()


@pytest.fixture(scope="module")
def model():
    return make_bearing_hinge(P)


def _segment(rho: float, h: float) -> tuple[float, float]:
    """Area of the circular segment cut at distance h from the centre, and its centroid distance."""
    area = rho * rho * math.acos(h / rho) - h * math.sqrt(rho * rho - h * h)
    return area, (2.0 / 3.0) * (rho * rho - h * h) ** 1.5 / area


def _ring_volumes(p: BearingHingeParams) -> dict[str, float]:
    """Pappus: revolved rectangle minus the revolved groove segment (2π · centroid r · area)."""
    g = race_geometry(p, 0)
    b, dw = p.width_mm, p.ball_diameter_mm
    rho_i, rho_o = p.inner_curvature_ratio * dw, p.outer_curvature_ratio * dw
    a_i, c_i = _segment(rho_i, g.inner_groove[0] - g.inner_land_mm)
    a_o, c_o = _segment(rho_o, g.outer_land_mm - g.outer_groove[0])
    inner = math.pi * (g.inner_land_mm**2 - (p.bore_mm / 2) ** 2) * b
    outer = math.pi * ((p.outer_diameter_mm / 2) ** 2 - g.outer_land_mm**2) * b
    return {
        "inner": inner - 2 * math.pi * (g.inner_groove[0] - c_i) * a_i,
        "outer": outer - 2 * math.pi * (g.outer_groove[0] + c_o) * a_o,
    }


def _torus_faces(solid: bd.Solid) -> list[tuple[float, float, float]]:
    """(major radius, minor radius, z of the centre) of every toroidal face, from the B-rep."""
    out = []
    for face in solid.faces():
        if face.geom_type == bd.GeomType.TORUS:
            t = BRepAdaptor_Surface(face.wrapped).Torus()
            assert abs(abs(t.Axis().Direction().Z()) - 1.0) < 1e-12
            out.append((t.MajorRadius(), t.MinorRadius(), t.Location().Z()))
    return out


def test_part_names_unique_and_solids_valid(model):
    names = [p.name for p in model.parts]
    assert len(names) == len(set(names)) == 4 + 4 + 2 * P.ball_count
    for part in model.parts:
        assert isinstance(part.solid, bd.Solid), part.name
        assert part.solid.is_valid, part.name
    assert model.kind == "bearing"
    assert model.params is P


def test_ball_count_per_bearing(model):
    for b in (0, 1):
        balls = [p for p in model.parts if p.name.startswith(f"ball_{b}_")]
        assert len(balls) == P.ball_count


def test_ball_volume_closed_form(model):
    r = P.ball_diameter_mm / 2
    for part in model.parts:
        if part.name.startswith("ball_"):
            assert part.solid.volume == pytest.approx(4 / 3 * math.pi * r**3, rel=1e-6)


def test_ring_volumes_pappus(model):
    expected = _ring_volumes(P)
    for b in (0, 1):
        for race in ("inner", "outer"):
            vol = model.part(f"{race}_ring_{b}").solid.volume
            assert vol == pytest.approx(expected[race], rel=1e-6)


def test_lug_bounding_boxes(model):
    tang = model.part("tang").solid.bounding_box()
    clevis = model.part("clevis").solid.bounding_box()
    tang_min_x, tang_max_y, clevis_max_x = tang.min.X, tang.max.Y, clevis.max.X
    assert tang_min_x == pytest.approx(-P.tang_length_mm, abs=1e-6)
    assert clevis_max_x == pytest.approx(P.clevis_length_mm + P.clevis_base_mm, abs=1e-6)
    assert tang_max_y == pytest.approx(P.outer_diameter_mm / 2 + P.tang_wall_mm, abs=1e-6)


@pytest.mark.parametrize("b", [0, 1], ids=["bearing_0", "bearing_1"])
def test_contact_angle_measured_from_solids(model, b):
    """Groove centres read from the rings' toroidal B-rep faces lie on a line through the
    ball centre (from the ball solid) at the requested angle to the radial direction."""
    ball = model.part(f"ball_{b}_0").solid
    c = ball.center()
    yz = (c.Y, c.Z)
    assert yz == pytest.approx((0.0, (b - 0.5) * P.width_mm), abs=1e-9)
    centres = {}
    for race in ("inner", "outer"):
        tori = _torus_faces(model.part(f"{race}_ring_{b}").solid)
        assert tori, f"{race}_ring_{b} has no toroidal face"
        assert len({(round(R, 9), round(r, 9), round(z, 9)) for R, r, z in tori}) == 1
        major, minor, z = tori[0]
        ratio = P.inner_curvature_ratio if race == "inner" else P.outer_curvature_ratio
        assert minor == pytest.approx(ratio * P.ball_diameter_mm, rel=1e-12)
        centres[race] = np.array([major, z])
    axis = centres["outer"] - centres["inner"]
    alpha = math.degrees(math.atan(abs(axis[1]) / abs(axis[0])))
    assert alpha == pytest.approx(P.contact_angle_deg, abs=1e-9)
    to_ball = np.array([c.X, c.Z]) - centres["inner"]
    assert abs(np.cross(axis, to_ball)) / np.linalg.norm(axis) < 1e-9  # ball centre on the line


@pytest.mark.parametrize("race", ["inner", "outer"])
def test_ball_touches_groove_at_nominal_point(model, race):
    ball = model.part("ball_1_3").solid
    ring = model.part(f"{race}_ring_1").solid
    dist, _, on_ring = ball.distance_to_with_closest_points(ring)
    assert dist < 1e-7
    # A tangency fixes the closest point only to ~sqrt(tolerance · radius): 1e-3 mm.
    nominal = np.array(contact_points(P, 1, 3)[race])
    assert np.linalg.norm(np.array(tuple(on_ring)) - nominal) < 1e-3


def test_face_to_face_outer_contacts_face_away_from_middle():
    for b in (0, 1):
        g = race_geometry(P, b)
        assert abs(g.outer_contact[1]) > abs(g.ball_center[1]) > abs(g.inner_contact[1])
    db = dataclasses.replace(P, arrangement=Arrangement.BACK_TO_BACK, preload_n=0.0)
    for b in (0, 1):
        g = race_geometry(db, b)
        assert abs(g.outer_contact[1]) < abs(g.ball_center[1]) < abs(g.inner_contact[1])


def test_balls_do_not_overlap(model):
    for b in (0, 1):
        centres = np.array(
            [tuple(model.part(f"ball_{b}_{k}").solid.center()) for k in range(P.ball_count)]
        )
        d = np.linalg.norm(centres[:, None] - centres[None], axis=2)
        d[np.diag_indices_from(d)] = np.inf
        assert d.min() > P.ball_diameter_mm
    # and the kernel agrees for one neighbouring pair
    assert model.part("ball_0_0").solid.distance_to(model.part("ball_0_1").solid) > 0.1


@pytest.mark.parametrize(
    ("a", "b"),
    [
        ("ball_0_0", "inner_ring_0"),
        ("ball_0_0", "outer_ring_0"),
        ("pin", "inner_ring_1"),
        ("tang", "outer_ring_0"),
        ("tang", "clevis"),
        ("preload_plate", "outer_ring_1"),
        ("preload_plate", "tang"),
        ("pin", "clevis"),
        ("inner_ring_0", "tang"),
    ],
    ids=lambda s: s,
)
def test_parts_do_not_interpenetrate(model, a, b):
    common = model.part(a).solid & model.part(b).solid
    volume = sum(s.volume for s in common.solids()) if common is not None else 0.0
    assert volume < 1e-6


def test_named_faces_and_pairs_consistent(model):
    names = {p.name for p in model.parts}
    for face in model.faces.values():
        assert face.part in names, face.name
    for pair in model.pairs:
        assert pair.slave in model.faces, pair.name
        assert pair.master in model.faces, pair.name
    contacts = [p for p in model.pairs if p.kind is PairKind.CONTACT]
    assert len(contacts) == 2 * 2 * P.ball_count
    for pair in contacts:
        slave, master = model.faces[pair.slave], model.faces[pair.master]
        assert isinstance(slave.surface, Sphere)
        assert slave.part.startswith("ball_")
        assert isinstance(master.surface, Torus)
        assert "ring" in master.part
        assert slave.box == master.box
    bonded = {p.name for p in model.pairs if p.kind is PairKind.BONDED}
    assert {"pin-clevis_1", "pin-clevis_2", "pin-inner_ring_0", "pin-inner_ring_1"} <= bonded
    assert {"outer_ring_0-tang", "outer_ring_1-tang"} <= bonded
    roles = {f.role for f in model.faces.values()}
    assert {FaceRole.FIXED, FaceRole.LOAD, FaceRole.PRELOAD} <= roles
    assert model.faces["plate_preload"].part == "preload_plate"


def test_contact_faces_match_the_solids(model):
    """Sphere and torus of each contact pair are those of the solids, and the box holds the
    nominal contact point, which lies on both exact surfaces."""
    tori = {
        f"{race}_ring_0": _torus_faces(model.part(f"{race}_ring_0").solid)[0]
        for race in ("inner", "outer")
    }
    for k in range(P.ball_count):
        for race in ("inner", "outer"):
            ball_face = model.faces[f"ball_0_{k}_{race}"]
            groove = model.faces[f"{race}_ring_0_groove_{k}"]
            centre = model.part(f"ball_0_{k}").solid.center()
            assert ball_face.surface.center == pytest.approx(tuple(centre), abs=1e-9)
            major, minor, z = tori[f"{race}_ring_0"]
            assert (groove.surface.major_mm, groove.surface.minor_mm, groove.surface.center[2]) == (
                pytest.approx((major, minor, z), abs=1e-9)
            )
            point = np.array([contact_points(P, 0, k)[race]])
            assert abs(ball_face.surface.distance_outside(point)[0]) < 1e-12
            assert abs(groove.surface.distance_outside(point)[0]) < 1e-12
            lo, hi = np.array(ball_face.box[0]), np.array(ball_face.box[1])
            assert (lo < point[0]).all()
            assert (point[0] < hi).all()
            assert hi[0] - lo[0] < P.ball_diameter_mm  # a cap, not the whole ball


def test_ball_centres_on_pitch_circle():
    for k in range(P.ball_count):
        x, y, _ = ball_center(P, 1, k)
        assert math.hypot(x, y) == pytest.approx(P.pitch_diameter_mm / 2, rel=1e-12)
        assert math.atan2(y, x) % (2 * math.pi) == pytest.approx(
            2 * math.pi * k / P.ball_count, abs=1e-12
        )


def test_params_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        P.preload_n = 50.0  # type: ignore[misc]


BAD = [
    ("ball_count", {"ball_count": 12}),
    ("ball_count", {"ball_count": 2}),
    ("ball_count", {"ball_count": 10.0}),
    ("ball_diameter_mm", {"ball_diameter_mm": 6.0}),
    ("ball_diameter_mm", {"width_mm": 3.5}),
    ("contact_angle_deg", {"contact_angle_deg": 0.0}),
    ("contact_angle_deg", {"contact_angle_deg": 50.0}),
    ("preload_n", {"preload_n": -1.0}),
    ("preload_n", {"preload_n": 520.0}),
    ("preload_n", {"arrangement": Arrangement.BACK_TO_BACK}),
    ("inner_curvature_ratio", {"inner_curvature_ratio": 0.5}),
    ("outer_curvature_ratio", {"outer_curvature_ratio": 0.49}),
    ("groove_depth_ratio", {"groove_depth_ratio": 0.05}),
    ("groove_depth_ratio", {"contact_angle_deg": 45.0, "groove_depth_ratio": 0.2}),
    ("outer_diameter_mm", {"outer_diameter_mm": 9.0}),
    ("clevis_length_mm", {"clevis_length_mm": 10.0}),
    ("plate_rim_mm", {"plate_rim_mm": 6.0}),
    ("contact_cap_mm", {"contact_cap_mm": 3.0}),
]


@pytest.mark.parametrize(
    ("name", "kwargs"),
    BAD,
    ids=[f"{n}:{','.join(f'{k}={v}' for k, v in kw.items())}" for n, kw in BAD],
)
def test_bad_parameters_raise_before_kernel(name, kwargs, monkeypatch):
    def no_kernel(*args, **kw):
        raise AssertionError("the kernel was called before validation")

    monkeypatch.setattr(bd, "Torus", no_kernel)
    with pytest.raises(ParameterError, match=name):
        BearingHingeParams(**kwargs)


def test_limits_are_reported_exactly():
    assert P.max_ball_count == 11
    with pytest.raises(ParameterError, match=r"\[3, 11\]"):
        BearingHingeParams(ball_count=12)
    BearingHingeParams(ball_count=11)  # the limit itself is accepted


def test_steep_contact_angle_keeps_groove_centres_on_contact_line():
    p = BearingHingeParams(contact_angle_deg=40.0, ball_count=8, preload_n=200.0)
    g = race_geometry(p, 1)
    u = np.array(g.direction)
    for centre in (g.inner_groove, g.outer_groove):
        d = np.array(centre) - np.array(g.ball_center)
        assert abs(np.cross(u, d)) < 1e-12
    assert math.degrees(math.atan2(u[1], u[0])) == pytest.approx(40.0)
    assert g.inner_land_mm < g.outer_land_mm
