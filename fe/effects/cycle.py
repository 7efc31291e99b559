"""The general hinge's load cycle with effects: apply, solve, post-process.

``run_cycle_with_effects`` applies the enabled effects to the condensed configurations
(condensed once per mesh and clearance, reusable for every amplitude and effect), runs
``fe.general.cycle.run_cycle`` and post-processes its increments
(``fe.effects.registry.post_increments``), so the returned loop and its metrics (η,
U_max, the energy balance) are consistent.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from threadpoolctl import threadpool_limits

from fe.contact.memo import start_afresh
from fe.cycle.protocol import CycleSettings
from fe.cycle.result import CycleResult
from fe.effects.base import EffectContext, FloatArray
from fe.effects.registry import apply_effects, post_increments, validate_effects
from fe.general.cycle import configurations, run_cycle
from fe.general.faces import faces_only, unloaded_state
from fe.general.system import GRIP, HingeSystem
from fe.structure.condensed import Condensed


@dataclass(frozen=True)
class EffectCycleResult:
    """A cycle computed with effects.

    Attributes:
        result: The post-processed cycle: increments' δ include the ``post`` effects and
            their elastic energy the series spring's, so its ``loop_arrays`` and
            ``metrics`` (η, U_max, energy balance) describe the loop the grips see; its
            ``configs`` are the effect-modified configurations.
        effects: The validated effects.
        base_configs: The configurations without effects: pass these (not
            ``result.configs``) to the next ``run_cycle_with_effects`` call.
    """

    result: CycleResult
    effects: Mapping[str, Mapping[str, float]]
    base_configs: dict[int, Condensed]

    def loop_arrays(
        self, *, with_free_play: bool = False
    ) -> tuple[FloatArray, FloatArray, npt.NDArray[np.int64]]:
        """Return (force (n+1,) [N], displacement (n+1,) [mm], stage (n+1,)), see ``CycleResult``."""
        return self.result.loop_arrays(with_free_play=with_free_play)

    def metrics(self) -> dict[str, float]:
        """Return η, W_cycle, U_max, … of the post-processed loop (``CycleResult.metrics``)."""
        return self.result.metrics()


def prestressed_zero(cond: Condensed, settings: CycleSettings, pin_centred: bool = False) -> float:
    """Return the grip displacement of the unloaded, prestressed hinge δ₀ [mm].

    With an initial overlap (``w0_n < 0`` somewhere) the hinge is prestressed before any
    load and the clevis settles at δ₀ ≠ 0 under F = 0. A test machine zeroes its
    displacement there, so the loop is referred to it. Computed as one frictional
    increment from the unloaded open state to F = 0 (``fe.general.faces.unloaded_state``),
    for any points with an overlap: pin–hole (interference) or clamped faces. With
    clearance (``pin_centred``) the unloaded hinge has the pin centred, touching nothing:
    the faces alone, δ₀ relative to the centred clevis (``fe.general.freeplay``).
    """
    contact = EffectContext.contact_of(settings)
    if pin_centred:
        return float(unloaded_state(faces_only(cond), contact).alpha[0])
    return float(unloaded_state(cond, contact).alpha[GRIP])


def run_cycle_with_effects(
    system: HingeSystem,
    clearance_mm: float,
    settings: CycleSettings,
    effects: Mapping[str, Mapping[str, float]],
    configs: Mapping[int, Condensed] | None = None,
) -> EffectCycleResult:
    """Run the load cycle with effects switched on.

    Args:
        system: The factorised hinge.
        clearance_mm: Radial clearance Δr [mm].
        settings: Load protocol and solver options.
        effects: Effect name → parameter → value (absent parameters take defaults).
        configs: Configurations *without* effects to reuse (``configurations``); condensed
            here if None.

    Returns:
        The post-processed cycle and the base configurations for reuse.

    Raises:
        ParameterError: An unknown effect or parameter, or a value out of range.
        ConvergenceError: As ``fe.general.cycle.run_cycle`` (its ``partial`` is not post-processed).
    """
    values = validate_effects(effects)
    start_afresh()  # the effects' own solves too learn nothing from earlier cycles
    base = dict(configs) if configs is not None else configurations(system, clearance_mm)
    t0 = time.perf_counter()
    with threadpool_limits(limits=settings.blas_threads, user_api="blas"):  # as run_cycle's solves
        modified = apply_effects(base, values, EffectContext(system, settings))
        overlap = any(np.any(np.asarray(c.w0)[:, 0] < 0.0) for c in modified.values())
        zero = prestressed_zero(modified[1], settings, clearance_mm > 0) if overlap else 0.0
    t_apply = time.perf_counter() - t0
    raw = run_cycle(system, clearance_mm, settings, configs=modified)
    result = post_increments(raw, values, zero) if values else raw
    object.__setattr__(result, "timings_s", {**raw.timings_s, "effects": t_apply})
    return EffectCycleResult(result, values, base)
