"""Mesh settings shared by the swept and the volume mesher."""

from __future__ import annotations

from dataclasses import dataclass

from cad.errors import ParameterError, check_range


@dataclass(frozen=True)
class MeshSettings:
    """Element sizes of a hinge mesh.

    Attributes:
        size_mm: Global element size at refinement 0 [mm].
        contact_size_mm: Element size on master contact surfaces at refinement 0 [mm].
        slave_ratio: Slave contact surfaces get ``contact_size_mm / slave_ratio`` (≥ 1:
            the slave side is the finer one, as in the paper).
        refinement: Refinement level; each level halves every size.
        part_sizes_mm: Per-part global sizes at level 0 as (name fragment, size) pairs;
            the first fragment found in a part's name wins, other parts use ``size_mm``.
        arc_grading: Ratio of the longest to the shortest element along the structured
            arcs around pin and holes, shortest at the load line (θ = 0°, 180°), where a
            pin with clearance touches over a few degrees only (1 = uniform). With a
            uniform mesh the contact at Δr = 0.1 mm is one node row wide and η loses its
            amplitude dependence; graded 6×, η at 400 N agrees within 1.5 % with a mesh
            of twice the contact points.
        pin_band_sizes: Depth of the structured band under the slave contact surface of
            a pin (a swept solid disk bounded by a slave contact circle), in slave
            contact sizes (``slave_mm``, so the band halves with each level as every
            size does). Below the band the pin's core is unstructured, graded from the
            band's inner segments to the pin's global size; the contact surface's nodes
            are the same at any depth. A band that would reach half the pin's radius
            keeps the O-grid of the cad profile instead (contact-size segment counts
            across the whole section, its core square finer than the surface): at
            that depth the core inside the band is no coarser. ``inf`` keeps the
            O-grid at every level (meshes before this setting, node for node).
    """

    size_mm: float = 3.0
    contact_size_mm: float = 1.2
    slave_ratio: float = 1.5
    refinement: int = 0
    part_sizes_mm: tuple[tuple[str, float], ...] = ()
    arc_grading: float = 6.0
    pin_band_sizes: float = 3.0

    def __post_init__(self) -> None:
        check_range("size_mm", self.size_mm, 0.05, 50.0)
        check_range("contact_size_mm", self.contact_size_mm, 0.01, 20.0)
        check_range("slave_ratio", self.slave_ratio, 1.0, 8.0)
        if not isinstance(self.refinement, int) or not 0 <= self.refinement <= 4:
            raise ParameterError(
                f"refinement must be an integer in [0, 4], got {self.refinement!r}",
                parameter="refinement",
            )
        check_range("arc_grading", self.arc_grading, 1.0, 100.0)
        check_range("pin_band_sizes", self.pin_band_sizes, 1.0, float("inf"))
        for fragment, size in self.part_sizes_mm:
            check_range(f"part_sizes_mm[{fragment!r}]", size, 0.01, 50.0)
        if self.contact_size_mm > self.size_mm:
            raise ParameterError(
                f"contact_size_mm must be ≤ size_mm ({self.size_mm:g}), got {self.contact_size_mm:g}",
                parameter="contact_size_mm",
            )

    @property
    def scale(self) -> float:
        """Factor applied to every size at this refinement level."""
        return 0.5**self.refinement

    @property
    def global_mm(self) -> float:
        """Global size at this level [mm]."""
        return self.size_mm * self.scale

    @property
    def master_mm(self) -> float:
        """Master contact-surface size at this level [mm]."""
        return self.contact_size_mm * self.scale

    @property
    def slave_mm(self) -> float:
        """Slave contact-surface size at this level [mm]."""
        return self.master_mm / self.slave_ratio

    @property
    def pin_band_mm(self) -> float:
        """Depth of a pin's structured band at this level [mm] (``inf``: no band)."""
        return self.pin_band_sizes * self.slave_mm

    def size_for(self, part: str) -> float:
        """Global size of one part at this level [mm]."""
        for fragment, size in self.part_sizes_mm:
            if fragment in part:
                return size * self.scale
        return self.global_mm

    @classmethod
    def coarse(cls, **overrides: object) -> MeshSettings:
        """Return the coarse general-hinge mesh of the fast tests and quick runs.

        Global size 4 mm, contact size 2 mm: about 13k DOF (3 080 hexahedra, 4 249
        nodes), meshed in ~1 s, a cycle in ~10 s. Fine enough for the exact invariances
        and the workflow; too coarse for converged η (see benchmarks/bench_cycle.py for
        the levels).
        """
        return cls(**{"size_mm": 4.0, "contact_size_mm": 2.0, **overrides})  # type: ignore[arg-type]
