"""Linear-elastic materials of the hinge parts (the paper's values), in MPa."""

from __future__ import annotations

from dataclasses import dataclass

from cad.errors import check_range


@dataclass(frozen=True)
class Material:
    """An isotropic linear-elastic material.

    Attributes:
        name: Human-readable name.
        young_mpa: Young's modulus [MPa].
        poisson: Poisson's ratio [-].
    """

    name: str
    young_mpa: float
    poisson: float

    def __post_init__(self) -> None:
        check_range(f"{self.name}.young_mpa", self.young_mpa, 0.0, float("inf"), lo_open=True)
        check_range(f"{self.name}.poisson", self.poisson, -1.0, 0.5, lo_open=True, hi_open=True)


ALUMINIUM = Material("aluminium alloy", 71_000.0, 0.33)
"""Tang and clevis (paper, Sec. II.A)."""

STEEL_45 = Material("45 steel", 210_000.0, 0.31)
"""Pin (paper, Sec. II.A)."""

GCR15 = Material("GCr15 bearing steel", 208_000.0, 0.30)
"""Bearing rings and balls (paper, Sec. IV.B)."""


def lame_from_young_poisson(young_mpa: float, poisson: float) -> tuple[float, float]:
    """Return (lambda, mu) in MPa."""
    mu = young_mpa / (2.0 * (1.0 + poisson))
    lam = young_mpa * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))
    return lam, mu
