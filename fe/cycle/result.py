"""A computed hysteresis cycle: its increments, loop, loss factor and energy balance.

Results are measured on the last closed loop +Fg → −Fg → +Fg:

* ``W_cycle`` — the loop area ∮F dδ [N·mm] (trapezoidal);
* ``U_max = ½ F_max δ_max`` — the paper's triangle, with δ_max the half peak-to-peak
  displacement ``(δ(+Fg) − δ(−Fg))/2`` of the loop with the free play removed; where
  clamped faces slide the clevis across the free play (``CycleResult.slides``) the free
  play is part of the loop (its rectangle is dissipation): W, δ(±Fg), δ_max and η are
  then those of the loop the grips follow, free play included;
* ``η = W_cycle / (2π U_max)`` (the paper's Eq. 1);
* the energy balance: friction (and open/close) work summed over every contact point,
  plus the work time-dependent effects dissipate (``effect_work_Nmm``), against
  ``W_cycle − ΔE_elastic``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from fe.contact.state import ContactState
from fe.cycle.protocol import CycleSettings

if TYPE_CHECKING:  # the general hinge's condensed operators, which the result keeps
    from fe.structure.condensed import Condensed

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Increment:
    """One converged increment.

    Attributes:
        stage: Stage index (0: initial loading, then 1, 2, … alternating −/+).
        force_n: Applied force F [N].
        disp_mm: Grip displacement δ relative to the touching configuration [mm].
        side: +1 tension configuration, −1 compression configuration.
        iterations: Contact Newton iterations.
        n_open: Open points. n_stick: Sticking points. n_slip: Slipping points.
        friction_work: Friction work of the increment summed over points [N·mm].
        normal_work: Open/close work of the increment summed over points [N·mm].
        elastic_energy: Strain energy at the end of the increment [N·mm].
        stiffness_n_per_mm: Tangent dF/dδ at the end of the increment [N/mm], where the
            response is smooth (the bearing hinge's elastic balls); NaN where it is not
            known. Where both ends of an increment have it, the loop area uses the cubic
            Hermite rule in δ instead of the trapezoid (exact for a cubic F(δ)), so an
            elastic but curved path (Hertz: F ∝ δ^{3/2}) encloses no spurious area.
        effect_work: Work dissipated in the increment by time-dependent effects on the
            loop (a viscous element, ``fe.effects.registry.post_increments``) [N·mm].
    """

    stage: int
    force_n: float
    disp_mm: float
    side: int
    iterations: int
    n_open: int
    n_stick: int
    n_slip: int
    friction_work: float
    normal_work: float
    elastic_energy: float
    stiffness_n_per_mm: float = math.nan
    effect_work: float = 0.0


@dataclass(frozen=True)
class CycleResult:
    """A computed hysteresis cycle.

    Attributes:
        settings: The protocol.
        clearance_mm: Radial clearance of the hinge [mm].
        increments: Every converged increment in order.
        free_play_mm: Total rigid travel between the tension and compression touching
            configurations, 4·Δr [mm] (removed from ``disp_mm``).
        states: Final contact state of each increment (for fields and files).
        configs: The condensed configuration of each side (+1, −1).
        timings_s: Wall time per phase [s].
        preload_state: The bearing hinge's state after its preload step, one point per
            ball (``fe.bearing.cycle``); None for the general hinge.
        ball_coordinates: The frictional-fit bearing hinge's balls (``fe.bearing.fit_cycle``):
            per ball (radial, axial) groove-centre coordinates, then the preload shift σ,
            after the preload (row 0) and after every increment, shape
            (n_increments + 1, 2 n_b + 1) [mm]; None otherwise.
        slides: Increments that slide the clevis across the free play at the faces'
            slip force (clamped faces with clearance, ``fe.general.freeplay``); empty when
            the free play is crossed at zero force. When not empty the loop area is taken
            on the displacement with the free play (the slides are real dissipation).
        start_disp_mm: δ of the unloaded start in the tension configuration's
            coordinates [mm]: 0 (the pin pushed there at zero force) or −2Δr (the pin
            centred, ``fe.general.freeplay``).
        cutbacks: The increments that converged only after cut-backs, as (increment
            index, halvings) in order (``fe.cycle.driver.drive`` counts them); empty when
            every increment converged at its full size.
    """

    settings: CycleSettings
    clearance_mm: float
    increments: tuple[Increment, ...]
    free_play_mm: float
    states: tuple[ContactState, ...] = field(repr=False)
    configs: dict[int, Condensed] = field(repr=False)
    timings_s: dict[str, float] = field(default_factory=dict)
    preload_state: ContactState | None = field(default=None, repr=False)
    ball_coordinates: FloatArray | None = field(default=None, repr=False)
    slides: tuple[int, ...] = ()
    start_disp_mm: float = 0.0
    cutbacks: tuple[tuple[int, int], ...] = ()

    @property
    def n_cutbacks(self) -> int:
        """Cut-backs (halvings of a failed increment) that recovered, over the whole cycle."""
        return sum(level for _, level in self.cutbacks)

    @property
    def faces_slide(self) -> bool:
        """True for a cycle whose free play is crossed by sliding clamped faces (``slides``)."""
        return bool(self.slides) or self.start_disp_mm != 0.0

    def loop_arrays(
        self, *, with_free_play: bool = False
    ) -> tuple[FloatArray, FloatArray, npt.NDArray[np.int64]]:
        """Return (force (n+1,) [N], displacement (n+1,) [mm], stage (n+1,)) starting at the origin.

        Args:
            with_free_play: Add back the ±2Δr rigid offsets of the touching configurations.
        """
        F = np.array([0.0] + [i.force_n for i in self.increments])
        d = np.array([self.start_disp_mm] + [i.disp_mm for i in self.increments])
        if with_free_play:
            side = np.array([1] + [i.side for i in self.increments])
            d = d + side * self.free_play_mm / 2
        stage = np.array([0] + [i.stage for i in self.increments], dtype=np.int64)
        return F, d, stage

    def machine_path(self) -> tuple[FloatArray, FloatArray]:
        """Return the loop the grips follow, free play included: (force (n,) [N], δ (n,) [mm]).

        The path starts where the grips start, with the pin centred in its holes (δ = 0),
        and crosses the first 2Δr to the tension touching configuration at zero force. Where
        the pin changes sides at F = 0 the free play is crossed at zero force, so a point
        at F = 0 in the new touching configuration is inserted; without it a loop area
        would count a spurious F·4Δr trapezoid. Where clamped faces hold the clevis
        (``slides``) the pin changes sides at the faces' slip force instead: the slide
        increment is the crossing, and the path starts with the pin centred.
        """
        F, d, _ = self.loop_arrays(with_free_play=True)
        side = np.array([1] + [i.side for i in self.increments])
        F_out, d_out = ([0.0], [0.0]) if d[0] != 0.0 else ([], [])
        F_out, d_out = [*F_out, F[0]], [*d_out, d[0]]
        for k in range(1, len(F)):
            if side[k] != side[k - 1] and k - 1 not in self.slides:
                F_out.append(0.0)
                d_out.append(side[k] * self.free_play_mm / 2)
            F_out.append(F[k])
            d_out.append(d[k])
        return np.array(F_out), np.array(d_out)

    def last_loop(self) -> slice:
        """Slice of increments (into ``loop_arrays``) spanning the last +Fg → −Fg → +Fg loop."""
        n_stage = len(self.settings.stages())
        _, _, stage = self.loop_arrays()
        first = int(np.flatnonzero(stage == n_stage - 2)[0]) - 1  # the +Fg point before it
        return slice(first, len(stage))

    def loop_work(self, loop: slice | None = None) -> float:
        """Loop area ∮F dδ of the last (or a given) loop [N·mm].

        Trapezoidal, with the cubic Hermite correction on increments whose ends both carry
        a tangent stiffness (``Increment.stiffness_n_per_mm``).
        """
        F, d, _ = self.loop_arrays(with_free_play=self.faces_slide)
        k = np.array([math.nan] + [i.stiffness_n_per_mm for i in self.increments])
        sl = loop or self.last_loop()
        f, x, k = F[sl], d[sl], k[sl]
        h = np.diff(x)
        seg = 0.5 * (f[1:] + f[:-1]) * h + np.nan_to_num(h**2 * (k[:-1] - k[1:]) / 12.0)
        return float(np.sum(seg))

    def metrics(self) -> dict[str, float]:
        """Return η, W_cycle, U_max, peak displacements, stiffness and the energy balance."""
        F, d, _ = self.loop_arrays(with_free_play=self.faces_slide)
        sl = self.last_loop()
        f, x = F[sl], d[sl]
        i_min = int(np.argmin(f))
        d_plus, d_minus = float(x[-1]), float(x[i_min])
        W = self.loop_work(sl)
        Fg = self.settings.amplitude_n
        delta_max = 0.5 * (d_plus - d_minus)
        U = 0.5 * Fg * delta_max
        incs = self.increments[sl.start :]  # increments after the loop's start point
        fric = sum(i.friction_work + i.normal_work for i in incs)
        lost = sum(i.effect_work for i in incs)
        dE = incs[-1].elastic_energy - self.increments[sl.start - 1].elastic_energy
        per_cycle = self.work_per_cycle()
        return {
            "eta": W / (2 * math.pi * U) if U > 0 else float("nan"),
            "W_cycle_Nmm": W,
            "U_max_Nmm": U,
            "delta_max_mm": delta_max,
            "disp_at_peak_mm": d_plus,
            "disp_at_minus_peak_mm": d_minus,
            "secant_stiffness_N_per_mm": 2 * Fg / (d_plus - d_minus)
            if d_plus > d_minus
            else float("nan"),
            "free_play_mm": self.free_play_mm,
            "friction_work_Nmm": fric,
            "effect_work_Nmm": lost,
            "elastic_energy_change_Nmm": dE,
            "energy_balance_rel_err": abs(W - dE - fric - lost) / max(abs(W), 1e-300),
            "loop_closure_mm": float(x[-1] - x[0]),
            "W_change_last_two_cycles_rel": (
                abs(per_cycle[-1] - per_cycle[-2]) / max(abs(per_cycle[-1]), 1e-300)
                if len(per_cycle) > 1
                else float("nan")
            ),
            "reported_cycle": float(self.settings.n_cycles),
        }

    def work_per_cycle(self) -> list[float]:
        """Loop area of every closed cycle [N·mm]."""
        _, _, stage = self.loop_arrays()
        out = []
        for c in range(self.settings.n_cycles):
            first = int(np.flatnonzero(stage == 1 + 2 * c)[0]) - 1
            last = int(np.flatnonzero(stage == 2 + 2 * c)[-1]) + 1
            out.append(self.loop_work(slice(first, last)))
        return out
