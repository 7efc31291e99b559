"""The reduced-order joint element: parameters, state, and its increment-by-increment step.

The element, from the grips inwards (all in series)::

    u ──[ series spring k₊ (F > 0) / k₋ (F < 0) ]──[ free play, total width 2g ]──[ bank ]── 0
                                                                                   │
    bank:  k∞ (elastic path)  ∥  N Jenkins branches (kᵢ in series with a slider)   │
    and, across the whole element, an optional dashpot c (F_v = c·u̇).

Branch i slides when its spring's stretch |x − sᵢ| reaches its slip displacement

    rᵢ(x) = φᵢ + λᵢ·|x|,

x being the bank's deformation and sᵢ the slider's position: a fixed part φᵢ (Coulomb
friction under a fixed normal force, e.g. a bolt or band preload) and a part proportional
to the load the bank carries (Coulomb friction whose normal pressure is the load itself,
as in a pin bearing on its hole). The φᵢ and λᵢ are uniform over the branches (the
midpoints of N equal bins of [0, φ_max] and [0, λ_max], equal stiffnesses kᵢ = k_slip/N),
so the bank is Iwan's parallel-series model with a uniform slip distribution
(Σ kᵢφᵢ = F_s, the bank's fixed friction capacity). With λ = 0 the element obeys
Masing's rules; with φ = 0 it is positively homogeneous (the loop at amplitude 2Fg is the
loop at Fg scaled by 2), as a Coulomb contact without a gap is.

Why an Iwan bank and not Bouc–Wen or Valanis: each branch is a spring and a slider, so
every parameter is a stiffness, a slip force or a ratio a designer can read; the
dissipation is the sum of slider force × slip and the stored energy is a state function,
so the energy balance is exact (no thermodynamic inconsistency as Bouc–Wen's
drift under small reversals); the response is rate independent and piecewise linear in
the displacement, so a step is solved exactly (no ODE, no tolerance) and a history is
vectorised over monotone segments; and a load-proportional slip strength (λ), which a
Bouc–Wen or Valanis law cannot express without a new law, is what a contact with zero
clearance needs (its η does not depend on the amplitude).

The step (``fe.joint.step``) is exact: the response along a monotone increment is piecewise linear in u
(``fe.joint.segment``), so the force, the state and the consistent tangent dF/du (the
slope of the piece the increment ends on, plus c/Δt) carry no discretisation error.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cad.errors import ParameterError, check_range

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class JointParams:
    """The joint element's parameters (mm, N, s).

    Attributes:
        k_tension_n_per_mm: Series stiffness k₊ while the element is in tension (F > 0).
        k_compression_n_per_mm: Series stiffness k₋ while in compression (F < 0).
        k_elastic_n_per_mm: The bank's elastic path k∞ (≥ 0).
        k_slip_n_per_mm: The summed stiffness of the Jenkins branches, k_slip = Σ kᵢ.
        slip_force_n: The bank's fixed friction capacity F_s = Σ kᵢφᵢ [N].
        slip_ratio: λ_max, the largest load-proportional slip ratio, in [0, 1).
        free_play_mm: The total width 2g of the dead zone (backlash) [mm].
        slip_asymmetry: a in (−1, 1): the fixed slip force is F_s(1 + a) while the
            element is driven forwards (u increasing) and F_s(1 − a) backwards, as in a
            self-energising band brake (capstan e^{μθ} in one direction only). The
            branches' φᵢ scale the same way, so each slider sticks while
            −φᵢ(1 − a) < x − sᵢ < φᵢ(1 + a); a = 0 is the symmetric bank.
        damping_n_s_per_mm: The dashpot c across the element [N·s/mm].
        n_branches: N, the number of Jenkins branches.
    """

    k_tension_n_per_mm: float = 1.0e5
    k_compression_n_per_mm: float = 1.0e5
    k_elastic_n_per_mm: float = 1.0e5
    k_slip_n_per_mm: float = 1.0e5
    slip_force_n: float = 0.0
    slip_ratio: float = 0.0
    free_play_mm: float = 0.0
    damping_n_s_per_mm: float = 0.0
    n_branches: int = 20
    slip_asymmetry: float = 0.0

    def __post_init__(self) -> None:
        for name in ("k_tension_n_per_mm", "k_compression_n_per_mm"):
            check_range(name, getattr(self, name), 0.0, 1e12, lo_open=True)
        check_range("k_elastic_n_per_mm", self.k_elastic_n_per_mm, 0.0, 1e12)
        check_range("k_slip_n_per_mm", self.k_slip_n_per_mm, 0.0, 1e12)
        check_range("slip_force_n", self.slip_force_n, 0.0, 1e9)
        check_range("slip_ratio", self.slip_ratio, 0.0, 1.0, hi_open=True)
        check_range("free_play_mm", self.free_play_mm, 0.0, 1e3)
        check_range("damping_n_s_per_mm", self.damping_n_s_per_mm, 0.0, 1e9)
        check_range("n_branches", self.n_branches, 1, 10_000)
        check_range("slip_asymmetry", self.slip_asymmetry, -1.0, 1.0, lo_open=True, hi_open=True)
        if self.k_elastic_n_per_mm + self.k_slip_n_per_mm <= 0.0:
            raise ParameterError("k_elastic_n_per_mm + k_slip_n_per_mm must be > 0, got 0")
        if self.slip_force_n > 0.0 and self.k_slip_n_per_mm == 0.0:
            raise ParameterError(
                f"slip_force_n = {self.slip_force_n} needs k_slip_n_per_mm > 0 (got 0)"
            )
        # a branch sliding towards x = 0 sheds load at kᵢλᵢ: the elastic path must outweigh it
        shed = 0.5 * self.k_slip_n_per_mm * self.slip_ratio
        if self.slip_ratio > 0.0 and self.k_elastic_n_per_mm <= shed:
            raise ParameterError(
                f"k_elastic_n_per_mm must exceed k_slip_n_per_mm·slip_ratio/2 = {shed:.6g} "
                f"(a positive tangent), got {self.k_elastic_n_per_mm}"
            )

    @property
    def gap_mm(self) -> float:
        """Half the free play, g [mm]: the play position p lies in [−g, g]."""
        return 0.5 * self.free_play_mm

    @functools.cached_property
    def branches(self) -> Branches:
        """The branches' stiffnesses kᵢ, fixed slip displacements φᵢ and ratios λᵢ, shape (N,)."""
        n = self.n_branches
        mid = (np.arange(n, dtype=np.float64) + 0.5) / n
        k = np.full(n, self.k_slip_n_per_mm / n)
        phi_max = 2.0 * self.slip_force_n / self.k_slip_n_per_mm if self.k_slip_n_per_mm else 0.0
        lam = self.slip_ratio * mid
        return Branches(k, phi_max * mid, lam, 1.0 / (1.0 - lam), 1.0 / (1.0 + lam))

    def branches_towards(self, direction: float) -> Branches:
        """The branches as a segment moving in ``direction`` (+1 forwards, −1 backwards) sees them.

        Only φᵢ depends on the direction: φᵢ(1 + a·direction) (``slip_asymmetry``).
        """
        br = self.branches
        if self.slip_asymmetry == 0.0:
            return br
        return br._replace(phi=br.phi * (1.0 + self.slip_asymmetry * direction))

    def capacity_n(self) -> float:
        """The largest force the element can carry either way (inf with an elastic path or λ > 0)."""
        if self.k_elastic_n_per_mm > 0.0 or self.slip_ratio > 0.0:
            return math.inf
        return self.slip_force_n * (1.0 - abs(self.slip_asymmetry))


class Branches(NamedTuple):
    """The Jenkins branches: stiffness kᵢ [N/mm], φᵢ [mm], λᵢ, 1/(1 − λᵢ), 1/(1 + λᵢ), each (N,)."""

    k: FloatArray
    phi: FloatArray
    lam: FloatArray
    inv_minus: FloatArray
    inv_plus: FloatArray


@dataclass(frozen=True)
class JointState:
    """The element's state after an increment.

    Attributes:
        disp_mm: Total displacement u [mm].
        force_n: Force F [N] (the dashpot's part included).
        bank_mm: Bank deformation x [mm].
        play_mm: Position p in the free play, in [−g, g] [mm].
        sliders_mm: Slider positions sᵢ, shape (N,) [mm].
        dissipation_nmm: Friction work dissipated so far [N·mm].
        viscous_nmm: Dashpot work dissipated so far [N·mm].
    """

    disp_mm: float = 0.0
    force_n: float = 0.0
    bank_mm: float = 0.0
    play_mm: float = 0.0
    sliders_mm: FloatArray = field(default_factory=lambda: np.zeros(0))
    dissipation_nmm: float = 0.0
    viscous_nmm: float = 0.0

    def elastic_force_n(self, params: JointParams) -> float:
        """The force of the springs (the bank's force, which the series spring carries) [N]."""
        k = params.branches.k
        s = self.sliders_mm if self.sliders_mm.size else np.zeros_like(k)
        return float(params.k_elastic_n_per_mm * self.bank_mm + k @ (self.bank_mm - s))

    def elastic_energy_nmm(self, params: JointParams) -> float:
        """The energy stored in the springs [N·mm] (a function of the state alone)."""
        k = params.branches.k
        s = self.sliders_mm if self.sliders_mm.size else np.zeros_like(k)
        f = self.elastic_force_n(params)
        ks = params.k_tension_n_per_mm if f > 0 else params.k_compression_n_per_mm
        x = self.bank_mm
        return float(
            0.5 * params.k_elastic_n_per_mm * x * x + 0.5 * k @ (x - s) ** 2 + f * f / (2 * ks)
        )


def initial_state(params: JointParams) -> JointState:
    """The unloaded element: springs relaxed, sliders at rest, the play centred."""
    return JointState(sliders_mm=np.zeros(params.n_branches))
