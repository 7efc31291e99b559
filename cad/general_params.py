"""Parameters of the general hinge: a frozen dataclass and its bounds, without build123d.

``cad.general`` builds the solid from them (``make_general_hinge``); this module is what
reading a model file, a study or a command's options needs, so none of those imports the
CAD kernel (build123d loads only when a solid is built).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cad.errors import check_range
from cad.materials import ALUMINIUM, STEEL_45, Material

MIN_WALL_MM = 1.0
"""Smallest lug wall (outer radius minus hole radius) accepted [mm]."""

MAX_OVERHANG_MM = 10.0
"""Longest pin overhang beyond a clevis arm that something still holds [mm]."""

MAX_CLEARANCE_MM = 10.0
"""Largest radial clearance on any geometry [mm] (``GeneralHingeParams.max_clearance_mm``
is the bound on a given one)."""


@dataclass(frozen=True)
class GeneralHingeParams:
    """Parameters of the general hinge (mm).

    Attributes:
        pin_radius_mm: Pin radius.
        clearance_mm: Radial clearance Δr between pin and holes (0 = line-to-line fit).
        lug_width_mm: Width of tang and clevis arms (y), also the diameter of their rounded ends.
        tang_thickness_mm: Tang thickness along the pin axis.
        clevis_arm_thickness_mm: Thickness of each clevis arm along the pin axis.
        clevis_gap_mm: Axial gap between the tang and each clevis arm.
        tang_length_mm: Distance from the hole centre to the tang's fixed end.
        clevis_length_mm: Distance from the hole centre to the clevis base.
        clevis_base_mm: Length of the clevis base along x (it ends at the load face).
        pin_length_mm: Pin length; None means the span of the clevis plus 1 mm each side.
        lug_material: Material of tang and clevis.
        pin_material: Material of the pin.
    """

    pin_radius_mm: float = 4.0
    clearance_mm: float = 0.0
    lug_width_mm: float = 20.0
    tang_thickness_mm: float = 8.0
    clevis_arm_thickness_mm: float = 5.0
    clevis_gap_mm: float = 0.2
    tang_length_mm: float = 25.0
    clevis_length_mm: float = 25.0
    clevis_base_mm: float = 8.0
    pin_length_mm: float | None = None
    lug_material: Material = field(default=ALUMINIUM)
    pin_material: Material = field(default=STEEL_45)

    def __post_init__(self) -> None:
        check_range("pin_radius_mm", self.pin_radius_mm, 0.5, 50.0)
        check_range(
            "lug_width_mm", self.lug_width_mm, 2 * (self.pin_radius_mm + MIN_WALL_MM), 500.0
        )
        check_range("clearance_mm", self.clearance_mm, 0.0, self.max_clearance_mm)
        check_range("tang_thickness_mm", self.tang_thickness_mm, 0.5, 200.0)
        check_range("clevis_arm_thickness_mm", self.clevis_arm_thickness_mm, 0.5, 200.0)
        check_range("clevis_gap_mm", self.clevis_gap_mm, 0.01, 20.0)
        check_range("tang_length_mm", self.tang_length_mm, self.lug_width_mm / 2 + 1.0, 1000.0)
        check_range("clevis_length_mm", self.clevis_length_mm, self.lug_width_mm / 2 + 1.0, 1000.0)
        check_range("clevis_base_mm", self.clevis_base_mm, 1.0, 200.0)
        if self.pin_length_mm is not None:
            check_range(
                "pin_length_mm",
                self.pin_length_mm,
                self.span_mm,
                self.span_mm + 2 * MAX_OVERHANG_MM,
            )

    @property
    def max_clearance_mm(self) -> float:
        """The largest clearance Δr on this geometry [mm].

        The hole leaves ``MIN_WALL_MM`` of lug wall, and Δr is never more than
        ``MAX_CLEARANCE_MM``: the one range every check and message of the clearance
        states (``fe.kinds.general.CLEARANCE`` reads it).
        """
        return min(MAX_CLEARANCE_MM, self.lug_width_mm / 2 - self.pin_radius_mm - MIN_WALL_MM)

    @property
    def hole_radius_mm(self) -> float:
        """Radius of the holes in tang and clevis [mm]."""
        return self.pin_radius_mm + self.clearance_mm

    @property
    def span_mm(self) -> float:
        """Overall thickness of the clevis along the pin axis [mm]."""
        return self.tang_thickness_mm + 2 * (self.clevis_gap_mm + self.clevis_arm_thickness_mm)

    @property
    def pin_length(self) -> float:
        """Pin length actually used [mm]."""
        return self.span_mm + 2.0 if self.pin_length_mm is None else self.pin_length_mm

    @property
    def ring_radius_mm(self) -> float:
        """Outer radius of the ring around each hole that the mesher grades toward the hole [mm]."""
        return self.hole_radius_mm + 0.5 * (self.lug_width_mm / 2 - self.hole_radius_mm)

    def z_levels(self) -> dict[str, tuple[float, float]]:
        """Return the z-range of tang, each clevis arm and the pin [mm]."""
        t2 = self.tang_thickness_mm / 2
        inner = t2 + self.clevis_gap_mm
        outer = inner + self.clevis_arm_thickness_mm
        half_pin = self.pin_length / 2
        return {
            "tang": (-t2, t2),
            "clevis_1": (-outer, -inner),
            "clevis_2": (inner, outer),
            "pin": (-half_pin, half_pin),
        }
