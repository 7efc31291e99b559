"""Candidate physical effects that extend the baseline hinge model (elasticity + Coulomb contact).

An effect acts in one (or both) of two places, so that none of them needs a new mesh or a
new factorisation:

* ``apply(configs, values, ctx)`` on the condensed system ``w = W p + G α + w0`` of each
  touching configuration (``fe.structure.condensed.Condensed``): it returns new ``Condensed``
  objects (``dataclasses.replace``), never modifies its input. Interface compliances add
  to the diagonal blocks of ``W``; an interference shifts the normal gap ``w0``; face
  friction appends contact points (condensed with the factorised hinge ``ctx.system``,
  calibrated with the cycle's μ ``ctx.settings``).
* ``post(force_n, disp_mm, values)`` on the computed loop: a displacement in series with
  the hinge, a function of the force only (it must map F = 0 to 0).

``run_cycle_with_effects`` applies the enabled effects to the configurations (condensed
once per mesh and clearance, reusable for every amplitude and effect), runs
``fe.general.cycle.run_cycle`` and post-processes its increments, so the returned loop and its
metrics (η, U_max, the energy balance) are consistent.

Fingerprints: each effect's docstring gives a table measured on the coarse test mesh
(``MeshSettings.coarse()``: size 4, contact 2 mm; μ = 0.2),
baseline vs effect, η and δ(+Fg) [µm] at Fg = 100 and 400 N and Δr = 0 and 0.1 mm
(``tests/fe/effects/test_effects.py::fingerprint_table`` regenerates it; the slow test
``test_docstring_fingerprints_are_measured`` checks every row to 2 %), each effect at its
parameter's default strength, 40 increments per stage (with clearance, fewer increments
leave a first-order open/close work in the loop area: at 6 per stage η at Δr = 0.1 mm
is off by a factor 2). Baseline: Δr = 0: η = 0.01458 at both amplitudes (positively
homogeneous); Δr = 0.1 mm: η = 0.00094 / 0.00126 at 100 / 400 N.

Effects that only make sense without clearance say so in ``zero_clearance_reason``;
they raise a ``ParameterError`` naming their parameter when applied with Δr > 0, and
``validation.diagnose`` skips them for data with clearance.
"""

from __future__ import annotations

import dataclasses
import math
import time
import types
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from threadpoolctl import threadpool_limits

from cad.errors import ParameterError
from fe.cycle.protocol import CycleSettings
from fe.cycle.result import CycleResult, Increment
from fe.effects.base import Effect, EffectContext, FloatArray
from fe.effects.interfaces import InterfaceFriction
from fe.effects.models import (
    FaceFriction,
    FrameCompliance,
    Interference,
    RoughnessSoftening,
    TangentialCompliance,
)
from fe.general.cycle import configurations, run_cycle
from fe.general.faces import faces_only, unloaded_state
from fe.general.system import GRIP, HingeSystem
from fe.structure.condensed import Condensed

__all__ = [
    "REGISTRY",
    "EffectCycleResult",
    "apply_effects",
    "effect_ranges",
    "post_process",
    "prestressed_zero",
    "run_cycle_with_effects",
    "validate_effects",
]


REGISTRY: Mapping[str, Effect] = types.MappingProxyType(
    {
        e.name: e
        for e in (
            FrameCompliance(),
            RoughnessSoftening(),
            TangentialCompliance(),
            Interference(),
            FaceFriction(),  # last: the effects before it act on the pin–hole points only
            InterfaceFriction(),  # the bearing hinge's: swaps its structure (fe.kinds.bearing)
        )
    }
)
"""Effect name → effect, in the order they are applied."""


def effect_ranges() -> dict[str, dict[str, tuple[float, float]]]:
    """Return effect → parameter → (lo, hi): the shape ``model.file`` checks against."""
    return {n: {p.name: (p.lo, p.hi) for p in e.params} for n, e in REGISTRY.items()}


def validate_effects(
    effects: Mapping[str, Mapping[str, float]],
) -> Mapping[str, Mapping[str, float]]:
    """Check effect names, parameter names and ranges; fill absent parameters with defaults.

    Args:
        effects: Effect name → parameter → value.

    Returns:
        A read-only copy, effects in registry order, every parameter present.

    Raises:
        ParameterError: Unknown effect or parameter (the known ones listed), or a value
            outside its range (naming effect, parameter, value and range).
    """
    unknown = [n for n in effects if n not in REGISTRY]
    if unknown:
        raise ParameterError(f"unknown effect(s) {unknown}; known effects: {', '.join(REGISTRY)}")
    out: dict[str, Mapping[str, float]] = {}
    for name, effect in REGISTRY.items():
        if name not in effects:
            continue
        given = effects[name]
        specs = {p.name: p for p in effect.params}
        bad = [k for k in given if k not in specs]
        if bad:
            raise ParameterError(
                f"effect {name!r}: unknown parameter(s) {bad}; allowed: {', '.join(specs)}"
            )
        vals: dict[str, float] = {}
        for p in effect.params:
            v = float(given.get(p.name, p.default))
            if not (math.isfinite(v) and p.lo <= v <= p.hi):
                raise ParameterError(
                    f"effects.{name}.{p.name} must be in [{p.lo:g}, {p.hi:g}] {p.unit}, got {v:g}"
                )
            vals[p.name] = v
        out[name] = types.MappingProxyType(vals)
    return types.MappingProxyType(out)


def apply_effects(
    configs: Mapping[int, Condensed],
    effects: Mapping[str, Mapping[str, float]],
    ctx: EffectContext,
) -> dict[int, Condensed]:
    """Apply every enabled effect's ``apply`` hook, in registry order (inputs unchanged)."""
    values = validate_effects(effects)
    out = dict(configs)
    for name, vals in values.items():
        out = REGISTRY[name].apply(out, vals, ctx)
    return out


def post_process(
    force_n: FloatArray, disp_mm: FloatArray, effects: Mapping[str, Mapping[str, float]]
) -> FloatArray:
    """Apply every enabled effect's ``post`` hook, in registry order; shape (n,) [mm]."""
    values = validate_effects(effects)
    d = np.array(disp_mm, dtype=np.float64, copy=True)
    for name, vals in values.items():
        d = REGISTRY[name].post(np.asarray(force_n, dtype=np.float64), d, vals)
    return d


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


def post_increments(
    result: CycleResult, effects: Mapping[str, Mapping[str, float]], zero_mm: float = 0.0
) -> CycleResult:
    """Return ``result`` with post-processed δ; the series energy ``Σ ½(F_i + F_{i−1}) Δh`` is added.

    ``zero_mm`` is subtracted from every increment first (the prestressed zero δ₀).
    """
    F = np.array([0.0] + [i.force_n for i in result.increments])
    d = np.array([0.0] + [i.disp_mm - zero_mm for i in result.increments])
    d_new = post_process(F, d, effects)
    if d_new[0] != 0.0:
        raise ParameterError(f"a post effect must map F = 0 to δ = 0, got {d_new[0]:g} mm")
    h = d_new - d
    series = np.concatenate([[0.0], np.cumsum(0.5 * (F[1:] + F[:-1]) * np.diff(h))])
    incs: list[Increment] = [
        dataclasses.replace(
            inc,
            disp_mm=float(d_new[k + 1]),
            elastic_energy=inc.elastic_energy + float(series[k + 1]),
        )
        for k, inc in enumerate(result.increments)
    ]
    return dataclasses.replace(result, increments=tuple(incs))


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
