"""What a deck is asked to be: the load history, the contact law, ccx's tolerances.

``fe.interop.inp`` writes a meshed hinge as a deck according to a ``DeckSettings``; the
settings live here so that the writer stays one concept (cards from a mesh) and the
choices (penalty or mortar contact, stick slope, increments, tolerances) another.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from cad.errors import ParameterError, check_range
from cad.general_params import MAX_CLEARANCE_MM

CYCLE = (1.0, -1.0, 1.0)
"""Load factors at the end of the three steps of the cycle: 0 → +Fg → −Fg → +Fg."""


EXACT_STICK_SLOPE_MPA_PER_MM = 1e12
"""Stick slope written for exact stick (``stick_slope_mpa_per_mm=None``, mortar only).

ccx's mortar contact solves Coulomb friction with Lagrange multipliers by a semismooth
Newton method in which 1/λ is a tangential compliance; at 10¹² MPa/mm it is 10⁻¹² mm/MPa,
so a sticking node slips by less than 10⁻¹¹ mm at 10 MPa: stick is exact to round-off.
(The penalty types read λ as the slope of a tangential spring instead.)
"""


TOUCH_INCREMENT_N = 0.005
"""``exact_mortar``'s ``touch_increment_n`` with clearance [N]: 0.1 µm of pin travel per
increment at the 50 N/mm grip spring, below the hinge's loop width (~0.16 µm)."""

SETTLE_INCREMENT_N = 0.3
"""``exact_mortar``'s ``settle_increment_n`` with clearance [N]: the first ``*CLOAD`` increment
after the touch. ccx's own cut-backs chose about this (7.8e-4 of a 390 N step) where its first
try, a twentieth of the step, did not converge (1 mm conforming mesh, Δr 0.1)."""


class ContactType(Enum):
    """CalculiX's contact discretisations (the deck's ``TYPE=``).

    The first two are penalty methods (a normal and a tangential spring per slave node or
    integration point). ``MORTAR`` is Sitzmann's dual-mortar method: Lagrange multipliers
    for the normal and the tangential tractions, eliminated per slave node, solved with a
    semismooth Newton method; with ``penalty_mpa_per_mm=None`` and
    ``stick_slope_mpa_per_mm=None`` it enforces hard contact and exact stick, as ours does.
    """

    NODE_TO_SURFACE = "NODE TO SURFACE"
    SURFACE_TO_SURFACE = "SURFACE TO SURFACE"
    MORTAR = "MORTAR"

    @property
    def is_penalty(self) -> bool:
        """Whether the contact is a penalty method (needs a normal slope and a stick slope)."""
        return self is not ContactType.MORTAR


@dataclass(frozen=True)
class DeckSettings:
    """What the deck needs beyond the mesh.

    Attributes:
        amplitude_n: Force amplitude Fg [N].
        mu: Coulomb friction coefficient of every contact pair (0: no ``*FRICTION``).
        clearance_mm: Radial clearance Δr of the model [mm] (sizes the grip spring's
            force offset; the geometry itself comes from the mesh).
        increments_per_stage: Largest increment = 1/this of a step (the initial 0 → +Fg
            step uses half as many, as our cycle does).
        contact: Node-to-surface (a spring per pin node, like our node-wise Lagrange
            multipliers), surface-to-surface (integration points on the slave faces) or
            mortar (Lagrange multipliers per slave node, weighted over the faces).
        penalty_mpa_per_mm: Slope of the linear pressure-overclosure law [MPa/mm]; None:
            hard contact (mortar only: no ``*SURFACE BEHAVIOR`` card).
        stick_slope_mpa_per_mm: Slope of shear stress versus elastic slip [MPa/mm]; None:
            exact stick (mortar only, see ``EXACT_STICK_SLOPE_MPA_PER_MM``).
        tension_mpa: Node-to-surface only: CalculiX's tension for open gaps σ∞ [MPa]
            (it smooths the law over ε = σ∞π/K; small, or it pulls on open nodes).
        adjust_mm: Slave nodes closer than this, or penetrating, are moved onto the master
            facets before the first step [mm]. At Δr = 0 every pin node sits on the
            exact cylinder, beyond the hole's chords, so all are moved; with clearance
            none are. 0: no ``ADJUST`` parameter.
        float_spring_n_per_mm: Total grounded spring per direction on every part held
            only by contact [N/mm] (spread over its nodes).
        grip_spring_n_per_mm: Grounded spring on the grip reference node [N/mm]; None:
            0 at Δr = 0, else 50 (then the force crosses the free play of 4Δr in 20 N).
        load_factors: Grip force at the end of each step as a multiple of Fg, starting
            from 0 (``CYCLE``; ``(1.0,)`` is the first loading alone).
        field_tolerance: None: ccx's default convergence criteria (largest residual
            0.5 % of the average force, 2 % after 9 iterations; largest correction 1 %
            of the increment's). Else all three criteria set to this value, and the
            looser one never used: the loop width of the hinge is about 1 % of its peak
            displacement, so the defaults leave errors of the size being compared.
        touch_increment_n: With clearance: the largest ``*CLOAD`` increment [N] within
            ``touch_band_n`` of the two forces of a reversal where the pin leaves one side of
            the free play and touches the other (∓ grip spring × 2Δr: the hinge carries
            nothing there). Each reversal step is then written as five steps (before, in,
            between and after the bands) whose step times still add up to 1. None: uniform
            increments. ccx detects a new contact once per increment and resolves an
            overlap over the next increments, so a pin that crosses the 4Δr free play in
            one increment runs up to 82 µm into the hole; and an increment that takes the
            hinge from ~30 N to free flight draws a chord across the free play whose
            triangle is 750 times our loop area (docs/calculix_crosscheck.md). With
            0.005 N increments at the 50 N/mm grip spring the pin moves 0.1 µm per
            increment in the bands.
        touch_band_n: Half width of each band [N] (0.1 N: ±2 µm of pin travel at 50 N/mm;
            the measured touch was within 0.01 µm of 2Δr).
        settle_increment_n: With ``touch_increment_n``: the *initial* ``*CLOAD`` increment
            [N] of the step after the touch band, which ccx then grows (by 1.5 after an
            increment that converges easily) up to the stage's increment. None: that step
            starts at the stage's increment. After the touch the contact widens over the
            next rows of nodes; ccx pairs its surfaces once per increment, and a large
            increment there leaves the path for 0.1-0.2 µm over the next 100-200 N
            (docs/calculix_crosscheck.md: its loop area was 4 times ours on a graded mesh,
            1.1 times where its own cut-backs had made those increments small).
    """

    amplitude_n: float = 400.0
    mu: float = 0.2
    clearance_mm: float = 0.0
    increments_per_stage: int = 20
    contact: ContactType = ContactType.NODE_TO_SURFACE
    penalty_mpa_per_mm: float | None = 1e6
    stick_slope_mpa_per_mm: float | None = 1e6
    tension_mpa: float = 1e-3
    adjust_mm: float = 1e-4
    float_spring_n_per_mm: float = 1.0
    grip_spring_n_per_mm: float | None = None
    load_factors: tuple[float, ...] = CYCLE
    field_tolerance: float | None = None
    touch_increment_n: float | None = None
    touch_band_n: float = 0.1
    settle_increment_n: float | None = None

    def __post_init__(self) -> None:
        if not self.load_factors:
            raise ParameterError("load_factors must hold at least one step, got ()")
        for k, f in enumerate(self.load_factors):
            check_range(f"load_factors[{k}]", f, -10.0, 10.0)
        check_range("amplitude_n", self.amplitude_n, 0.0, 1e6, lo_open=True)
        check_range("mu", self.mu, 0.0, 2.0)
        check_range("clearance_mm", self.clearance_mm, 0.0, MAX_CLEARANCE_MM)
        check_range("increments_per_stage", self.increments_per_stage, 2, 10_000)
        for name in ("penalty_mpa_per_mm", "stick_slope_mpa_per_mm"):
            value = getattr(self, name)
            if value is not None:
                check_range(name, value, 0.0, 1e12, lo_open=True)
            elif self.contact.is_penalty:
                raise ParameterError(
                    f"{name} must be a number for {self.contact.value} contact (None, hard"
                    " contact or exact stick, is mortar only)"
                )
        if self.field_tolerance is not None:
            check_range("field_tolerance", self.field_tolerance, 0.0, 0.1, lo_open=True)
        check_range("tension_mpa", self.tension_mpa, 0.0, 1e3, lo_open=True)
        check_range("adjust_mm", self.adjust_mm, 0.0, 10.0)
        check_range("float_spring_n_per_mm", self.float_spring_n_per_mm, 0.0, 1e9)
        if self.grip_spring_n_per_mm is not None:
            check_range("grip_spring_n_per_mm", self.grip_spring_n_per_mm, 0.0, 1e9)
        check_range("touch_band_n", self.touch_band_n, 0.0, 1e3, lo_open=True)
        if self.settle_increment_n is not None:
            check_range("settle_increment_n", self.settle_increment_n, 0.0, 1e3, lo_open=True)
            if self.touch_increment_n is None:
                raise ParameterError(
                    f"settle_increment_n = {self.settle_increment_n:g} N needs "
                    "touch_increment_n (it sets the step after the touch band)"
                )
        if self.touch_increment_n is not None:
            check_range("touch_increment_n", self.touch_increment_n, 0.0, 1e3, lo_open=True)
            if self.clearance_mm == 0.0 or self.grip_spring == 0.0:
                raise ParameterError(
                    f"touch_increment_n = {self.touch_increment_n:g} N needs free play and a "
                    f"grip spring (clearance_mm = {self.clearance_mm:g}, grip spring "
                    f"{self.grip_spring:g} N/mm): there is no touch to refine"
                )
            if self.touch_band_n >= self.grip_spring * 2.0 * self.clearance_mm:  # bands apart
                raise ParameterError(
                    f"touch_band_n = {self.touch_band_n:g} N must be below the grip spring's "
                    f"force at the touch, {self.grip_spring * 2.0 * self.clearance_mm:g} N"
                )

    @classmethod
    def exact_mortar(cls, **overrides: object) -> DeckSettings:
        """Return CalculiX's closest counterpart of our solver, with any field overridden.

        Mortar contact, hard normal contact, exact stick, no ``ADJUST`` (a mesh whose pin
        and hole nodes sit at the same angles starts without overclosure), tight
        convergence criteria (1e-4) and, with clearance, ``TOUCH_INCREMENT_N`` increments
        where the pin leaves one side of the free play and touches the other, and a first
        increment of ``SETTLE_INCREMENT_N`` after the touch.
        """
        base: dict[str, object] = {
            "contact": ContactType.MORTAR,
            "penalty_mpa_per_mm": None,
            "stick_slope_mpa_per_mm": None,
            "adjust_mm": 0.0,
            "field_tolerance": 1e-4,
        }
        clearance = overrides.get("clearance_mm", 0.0)
        if isinstance(clearance, (int, float)) and clearance > 0.0:
            base["touch_increment_n"] = TOUCH_INCREMENT_N
            base["settle_increment_n"] = SETTLE_INCREMENT_N
        return cls(**{**base, **overrides})  # type: ignore[arg-type]

    @property
    def grip_spring(self) -> float:
        """The grip spring actually written [N/mm]."""
        if self.grip_spring_n_per_mm is not None:
            return self.grip_spring_n_per_mm
        return 0.0 if self.clearance_mm == 0.0 else 50.0

    @property
    def peak_cload_n(self) -> float:
        """The ``*CLOAD`` at ±Fg: Fg plus the grip spring's force at δ = 2Δr [N]."""
        return self.amplitude_n + self.grip_spring * 2.0 * self.clearance_mm
