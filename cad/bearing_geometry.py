"""Bearing hinge parameters and raceway geometry: rings, balls, grooves and contact points.

Raceway geometry in the meridional plane of a ball (centre c, diameter D_w): the
contact line through c makes the contact angle α with the radial direction, with unit
vector u = (cos α, ±sin α) pointing at the outer contact. The outer groove (radius
f_o·D_w) touches the ball at P_o = c + (D_w/2)·u, so its centre is
G_o = c − (f_o − ½)·D_w·u; the inner groove touches at P_i = c − (D_w/2)·u with centre
G_i = c + (f_i − ½)·D_w·u. Both groove centres lie on the contact line, and ball and
grooves touch without gap or overlap (the unloaded, zero-clearance state).

Arrangement: pinching the outer rings together loads the balls only if each outer
ring touches its balls on the side away from the pair's middle, i.e. contact lines
that converge toward the axis — a face-to-face (DF, "X") pair. In a back-to-back
(DB, "O") pair the same plate would unload the balls, so DB is accepted only with
``preload_n = 0`` (the clamping of a DB pair acts on the inner rings, which the paper
epoxies to the pin).

Default bearing: size 708C (ISO dimension series 18: bore 8 mm, outside diameter 22 mm,
width 7 mm; suffix C = 15° contact angle). Its 8 mm bore takes the 8 mm pin of the
general hinge (``cad.general``), so the two hinges of the paper differ only by the
bearings. The ball, 3.969 mm (5/32 in), is the one used in this size; the ball count,
10, follows the design rule Z = ⌊π·D_pw/D_w⌋ − 1 for a full angular-contact
complement. Ball size and count are representative, not copied from a maker's table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import NamedTuple

from cad.errors import ParameterError, check_range
from cad.materials import ALUMINIUM, GCR15, STEEL_45, Material

MIN_RING_WALL_FRACTION = 0.1
"""Smallest ring wall under a groove bottom, as a fraction of the radial section (D − d)/2."""

MIN_GROOVE_DEPTH_RATIO = 0.1
"""Shallowest groove accepted, as a fraction of D_w (ball bearings: ≈ 0.18–0.3)."""

MIN_LAND_FRACTION = 0.1
"""Smallest flat land either side of a groove, as a fraction of the ring width."""

MIN_BALL_GAP_RATIO = 0.05
"""Smallest gap between neighbouring balls (room for a cage bar), as a fraction of D_w."""

CONTACT_EDGE_MARGIN_DEG = 10.0
"""Smallest angle between the contact point and the groove edge, seen from the groove
centre: room for the contact ellipse (its half-width a/(f·D_w) is ≈ 6° at 200 N)."""

MAX_PRELOAD_N = 500.0
"""Largest axial preload F_p [N] (the paper: 0–200): the one range every check and message
of the preload states (``fe.kinds.bearing.PRELOAD``, the bearing cycles)."""

MIN_WALL_MM = 1.0
"""Smallest lug wall and plate rim accepted [mm]."""


class BallModel(Enum):
    """How the cycle models the balls (``docs/bearing_model.md``)."""

    HERTZ = "hertz"
    """Each ball a Hertz spring between its two raceway patches, free to roll; rings meshed."""
    FULL = "full"
    """Every ball a meshed, frictional contact body: one meshed ball with its raceway windows,
    condensed once and reused for all balls (``fe.bearing.full_cycle``; the structure is meshed
    without balls, as for ``HERTZ``)."""


class Interfaces(Enum):
    """How the rings, pin, clevis and plate are joined."""

    BONDED = "bonded"
    """Tied (the epoxy of the design)."""
    CONTACT = "contact"
    """Frictional contacts at zero clearance (the paper's ABAQUS model; ``fe.bearing.fits``)."""


class Arrangement(Enum):
    """How the two bearings of the pair face each other."""

    FACE_TO_FACE = "DF"
    BACK_TO_BACK = "DB"


@dataclass(frozen=True)
class BearingHingeParams:
    """Parameters of the bearing hinge (mm, N, degrees).

    Attributes:
        bore_mm: Bearing bore d, also the pin diameter.
        outer_diameter_mm: Bearing outside diameter D, also the tang bore.
        width_mm: Width B of one bearing.
        ball_diameter_mm: Ball diameter D_w.
        ball_count: Balls per bearing Z.
        contact_angle_deg: Nominal contact angle α, in (0, 45].
        inner_curvature_ratio: Inner groove radius / D_w (f_i > 0.5).
        outer_curvature_ratio: Outer groove radius / D_w (f_o > 0.5).
        groove_depth_ratio: Depth of each groove below its land / D_w.
        arrangement: Face-to-face (preloadable by the plate) or back-to-back.
        preload_n: Axial preload F_p on the plate [N], in [0, 500] (the paper: 0–200).
        tang_wall_mm: Tang wall around the bearing bore (the tang is D + 2·wall wide).
        tang_length_mm: Distance from the pin axis to the tang's fixed end.
        lip_thickness_mm: Tang lip under outer ring 0 (the abutment the preload reacts on).
        plate_thickness_mm: Preload plate thickness above its boss.
        plate_boss_mm: Height of the plate's boss on outer ring 1 (its gap to the tang).
        plate_rim_mm: Radial overhang of the plate beyond the tang bore (where its screws go).
        clevis_width_mm: Width of the clevis arms (y), also the diameter of their round ends.
        clevis_arm_thickness_mm: Thickness of each clevis arm along the pin axis.
        clevis_gap_mm: Axial gap between each clevis arm and the tang/plate stack.
        clevis_length_mm: Distance from the pin axis to the clevis base.
        clevis_base_mm: Length of the clevis base along x (it ends at the load face).
        pin_overhang_mm: Pin length beyond each clevis arm.
        contact_cap_mm: Half-size of the box around each nominal contact point that bounds
            the ball–raceway facet sets (the Hertz semi-major axis at 200 N is ≈ 0.45 mm).
        lug_material: Tang, clevis and plate.
        pin_material: Pin.
        bearing_material: Rings and balls.
        ball_model: How the cycle models the balls.
        interfaces: How the cycle joins rings, pin, clevis and plate.
    """

    bore_mm: float = 8.0
    outer_diameter_mm: float = 22.0
    width_mm: float = 7.0
    ball_diameter_mm: float = 3.969
    ball_count: int = 10
    contact_angle_deg: float = 15.0
    inner_curvature_ratio: float = 0.52
    outer_curvature_ratio: float = 0.53
    groove_depth_ratio: float = 0.25
    arrangement: Arrangement = Arrangement.FACE_TO_FACE
    preload_n: float = 100.0
    tang_wall_mm: float = 4.0
    tang_length_mm: float = 25.0
    lip_thickness_mm: float = 2.0
    plate_thickness_mm: float = 2.0
    plate_boss_mm: float = 0.3
    plate_rim_mm: float = 2.5
    clevis_width_mm: float = 20.0
    clevis_arm_thickness_mm: float = 5.0
    clevis_gap_mm: float = 0.2
    clevis_length_mm: float = 25.0
    clevis_base_mm: float = 8.0
    pin_overhang_mm: float = 1.0
    contact_cap_mm: float = 0.8
    lug_material: Material = field(default=ALUMINIUM)
    pin_material: Material = field(default=STEEL_45)
    bearing_material: Material = field(default=GCR15)
    ball_model: BallModel = BallModel.HERTZ
    interfaces: Interfaces = Interfaces.BONDED

    def __post_init__(self) -> None:
        self._check_bearing()
        self._check_grooves()
        self._check_surroundings()

    def _check_bearing(self) -> None:
        check_range("bore_mm", self.bore_mm, 1.0, 200.0)
        check_range(
            "outer_diameter_mm", self.outer_diameter_mm, self.bore_mm + 2.0, 400.0, lo_open=True
        )
        check_range("width_mm", self.width_mm, 1.0, 200.0)
        check_range("contact_angle_deg", self.contact_angle_deg, 0.0, 45.0, lo_open=True)
        check_range("inner_curvature_ratio", self.inner_curvature_ratio, 0.5, 0.6, lo_open=True)
        check_range("outer_curvature_ratio", self.outer_curvature_ratio, 0.5, 0.6, lo_open=True)
        check_range("preload_n", self.preload_n, 0.0, MAX_PRELOAD_N)
        for name, kind in (("ball_model", BallModel), ("interfaces", Interfaces)):
            if not isinstance(getattr(self, name), kind):
                allowed = [m.value for m in kind]
                raise ParameterError(
                    f"{name} must be one of {allowed}, got {getattr(self, name)!r}",
                    parameter=name,
                )
        if self.arrangement is Arrangement.BACK_TO_BACK and self.preload_n > 0.0:
            raise ParameterError(
                f"preload_n must be 0 for arrangement={self.arrangement.name} (a plate "
                f"pinching the outer rings unloads a back-to-back pair; use FACE_TO_FACE), "
                f"got {self.preload_n!r}",
                parameter="preload_n",
            )
        check_range(
            "ball_diameter_mm", self.ball_diameter_mm, 0.0, self.max_ball_diameter_mm, lo_open=True
        )
        if isinstance(self.ball_count, bool) or not isinstance(self.ball_count, int):
            raise ParameterError(f"ball_count must be an integer, got {self.ball_count!r}")
        if not 3 <= self.ball_count <= self.max_ball_count:
            raise ParameterError(
                f"ball_count must be in [3, {self.max_ball_count}] for ball_diameter_mm="
                f"{self.ball_diameter_mm:g} on a {self.pitch_diameter_mm:g} mm pitch circle "
                f"(more balls overlap), got {self.ball_count!r}"
            )

    def _check_grooves(self) -> None:
        alpha = math.radians(self.contact_angle_deg + CONTACT_EDGE_MARGIN_DEG)
        f_max = max(self.inner_curvature_ratio, self.outer_curvature_ratio)
        depth_min = max(MIN_GROOVE_DEPTH_RATIO, f_max * (1.0 - math.cos(alpha)))
        check_range("groove_depth_ratio", self.groove_depth_ratio, depth_min, 0.45)
        g = race_geometry(self, 0)
        if g.outer_land_mm - g.inner_land_mm < 0.1 * self.ball_diameter_mm:
            gap = g.outer_land_mm - g.inner_land_mm
            raise ParameterError(
                f"groove_depth_ratio leaves the ring lands {gap:.3g} mm "
                f"apart (must be ≥ 0.1·ball_diameter_mm), got {self.groove_depth_ratio!r}"
            )
        half_span = max(
            _groove_half_span(
                self.ball_diameter_mm, f, self.groove_depth_ratio, self.contact_angle_deg
            )
            for f in (self.inner_curvature_ratio, self.outer_curvature_ratio)
        )
        max_half_span = (0.5 - MIN_LAND_FRACTION) * self.width_mm
        if half_span > max_half_span:
            raise ParameterError(
                f"ball_diameter_mm makes each groove {2 * half_span:.3g} mm wide, more than "
                f"{2 * max_half_span:.3g} mm allowed by width_mm={self.width_mm:g}, "
                f"got {self.ball_diameter_mm!r}"
            )

    def _check_surroundings(self) -> None:
        check_range("tang_wall_mm", self.tang_wall_mm, MIN_WALL_MM, 100.0)
        check_range("tang_length_mm", self.tang_length_mm, self.tang_radius_mm + 1.0, 1000.0)
        check_range("lip_thickness_mm", self.lip_thickness_mm, 0.5, 50.0)
        check_range("plate_thickness_mm", self.plate_thickness_mm, 0.5, 50.0)
        check_range("plate_boss_mm", self.plate_boss_mm, 0.05, 5.0)
        check_range("plate_rim_mm", self.plate_rim_mm, MIN_WALL_MM, self.tang_wall_mm)
        check_range("clevis_width_mm", self.clevis_width_mm, self.bore_mm + 2 * MIN_WALL_MM, 500.0)
        check_range("clevis_arm_thickness_mm", self.clevis_arm_thickness_mm, 0.5, 200.0)
        check_range("clevis_gap_mm", self.clevis_gap_mm, 0.01, 20.0)
        reach = max(self.tang_radius_mm, self.clevis_width_mm / 2)
        check_range("clevis_length_mm", self.clevis_length_mm, reach + 1.0, 1000.0)
        check_range("clevis_base_mm", self.clevis_base_mm, 1.0, 200.0)
        check_range("pin_overhang_mm", self.pin_overhang_mm, 0.0, 10.0)
        check_range("contact_cap_mm", self.contact_cap_mm, 0.01, 0.5 * self.ball_diameter_mm)

    @property
    def pitch_diameter_mm(self) -> float:
        """Pitch (ball-centre) diameter D_pw = (d + D)/2 [mm].

        >>> BearingHingeParams().pitch_diameter_mm
        15.0
        """
        return 0.5 * (self.bore_mm + self.outer_diameter_mm)

    @property
    def max_ball_count(self) -> int:
        """Most balls that fit on the pitch circle with a gap of MIN_BALL_GAP_RATIO·D_w."""
        chord = (1.0 + MIN_BALL_GAP_RATIO) * self.ball_diameter_mm / self.pitch_diameter_mm
        return int(math.pi / math.asin(chord)) if chord < 1.0 else 0

    @property
    def max_ball_diameter_mm(self) -> float:
        """Largest ball whose grooves leave both ring walls MIN_RING_WALL_FRACTION thick [mm].

        The groove bottoms lie at r = r_p ± D_w·(f − (f − ½)·cos α), linear in D_w.
        """
        cos_a = math.cos(math.radians(self.contact_angle_deg))
        r_p = 0.5 * self.pitch_diameter_mm
        wall = MIN_RING_WALL_FRACTION * 0.5 * (self.outer_diameter_mm - self.bore_mm)
        f_i, f_o = self.inner_curvature_ratio, self.outer_curvature_ratio
        inner = (r_p - 0.5 * self.bore_mm - wall) / (f_i - (f_i - 0.5) * cos_a)
        outer = (0.5 * self.outer_diameter_mm - wall - r_p) / (f_o - (f_o - 0.5) * cos_a)
        return min(inner, outer)

    @property
    def tang_radius_mm(self) -> float:
        """Half the tang width, also the radius of its round end [mm]."""
        return 0.5 * self.outer_diameter_mm + self.tang_wall_mm

    def z_levels(self) -> dict[str, tuple[float, float]]:
        """Return the z-range of every axial layer [mm]."""
        b = self.width_mm
        top = b + self.plate_boss_mm + self.plate_thickness_mm
        bottom = -b - self.lip_thickness_mm
        arm_1 = (
            bottom - self.clevis_gap_mm - self.clevis_arm_thickness_mm,
            bottom - self.clevis_gap_mm,
        )
        arm_2 = (top + self.clevis_gap_mm, top + self.clevis_gap_mm + self.clevis_arm_thickness_mm)
        return {
            "bearing_0": (-b, 0.0),
            "bearing_1": (0.0, b),
            "lip": (bottom, -b),
            "tang": (bottom, b),
            "boss": (b, b + self.plate_boss_mm),
            "plate": (b, top),
            "clevis_1": arm_1,
            "clevis_2": arm_2,
            "pin": (arm_1[0] - self.pin_overhang_mm, arm_2[1] + self.pin_overhang_mm),
        }


class RaceGeometry(NamedTuple):
    """Meridional (r, z) geometry of one bearing [mm]; angles measured in the r–z plane.

    Attributes:
        ball_center: Ball centre (r, z).
        direction: Unit vector (cos α, ±sin α) from the ball centre toward the outer contact.
        inner_groove: Centre of the inner groove circle (r, z).
        outer_groove: Centre of the outer groove circle (r, z).
        inner_contact: Nominal inner contact point (r, z).
        outer_contact: Nominal outer contact point (r, z).
        inner_land_mm: Outer radius of the inner ring (its land).
        outer_land_mm: Inner radius of the outer ring (its land).
    """

    ball_center: tuple[float, float]
    direction: tuple[float, float]
    inner_groove: tuple[float, float]
    outer_groove: tuple[float, float]
    inner_contact: tuple[float, float]
    outer_contact: tuple[float, float]
    inner_land_mm: float
    outer_land_mm: float


def race_geometry(p: BearingHingeParams, bearing: int) -> RaceGeometry:
    """Return ball, groove and contact positions of bearing 0 (z < 0) or 1 (z > 0).

    Args:
        p: Parameters.
        bearing: 0 or 1.

    Returns:
        The bearing's meridional geometry (see the module docstring for the construction).
    """
    side = -1.0 if bearing == 0 else 1.0
    away = (
        1.0 if p.arrangement is Arrangement.FACE_TO_FACE else -1.0
    )  # outer contact away from z = 0?
    a = math.radians(p.contact_angle_deg)
    u = (math.cos(a), away * side * math.sin(a))
    dw = p.ball_diameter_mm
    c = (0.5 * p.pitch_diameter_mm, side * 0.5 * p.width_mm)

    def along(s: float) -> tuple[float, float]:
        return (c[0] + s * u[0], c[1] + s * u[1])

    f_i, f_o = p.inner_curvature_ratio, p.outer_curvature_ratio
    inner_groove = along((f_i - 0.5) * dw)
    outer_groove = along(-(f_o - 0.5) * dw)
    return RaceGeometry(
        ball_center=c,
        direction=u,
        inner_groove=inner_groove,
        outer_groove=outer_groove,
        inner_contact=along(-0.5 * dw),
        outer_contact=along(0.5 * dw),
        inner_land_mm=inner_groove[0] - f_i * dw + p.groove_depth_ratio * dw,
        outer_land_mm=outer_groove[0] + f_o * dw - p.groove_depth_ratio * dw,
    )


def _groove_half_span(dw: float, f: float, depth: float, alpha_deg: float) -> float:
    """Half the axial width of a groove at its land, including its axial offset [mm]."""
    offset = (f - 0.5) * dw * math.sin(math.radians(alpha_deg))
    return dw * math.sqrt(f * f - (f - depth) ** 2) + offset


def _to_xyz(rz: tuple[float, float], theta: float) -> tuple[float, float, float]:
    return (rz[0] * math.cos(theta), rz[0] * math.sin(theta), rz[1])


def ball_center(p: BearingHingeParams, bearing: int, k: int) -> tuple[float, float, float]:
    """Return the centre of ball ``k`` of ``bearing`` [mm]; balls sit at angles 2πk/Z."""
    return _to_xyz(race_geometry(p, bearing).ball_center, 2.0 * math.pi * k / p.ball_count)


def contact_points(
    p: BearingHingeParams, bearing: int, k: int
) -> dict[str, tuple[float, float, float]]:
    """Return the nominal inner and outer contact points of one ball [mm]."""
    g = race_geometry(p, bearing)
    theta = 2.0 * math.pi * k / p.ball_count
    return {"inner": _to_xyz(g.inner_contact, theta), "outer": _to_xyz(g.outer_contact, theta)}
