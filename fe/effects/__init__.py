"""Physical effects a user can switch on, on top of elasticity + Coulomb contact.

* :mod:`fe.effects.base` — the ``Effect`` interface, parameter specs, the context;
* :mod:`fe.effects.models` — the five effects (frame compliance, roughness softening,
  tangential compliance, interference, face friction);
* :mod:`fe.effects.registry` — ``REGISTRY`` and the cycle with effects
  (``run_cycle_with_effects``), re-exported here.
"""

from fe.effects.registry import (
    REGISTRY,
    Effect,
    EffectContext,
    EffectCycleResult,
    FaceFriction,
    FrameCompliance,
    Interference,
    ParamSpec,
    RoughnessSoftening,
    TangentialCompliance,
    Values,
    apply_effects,
    effect_ranges,
    post_process,
    prestressed_zero,
    run_cycle_with_effects,
    validate_effects,
)

__all__ = [
    "REGISTRY",
    "Effect",
    "EffectContext",
    "EffectCycleResult",
    "FaceFriction",
    "FrameCompliance",
    "Interference",
    "ParamSpec",
    "RoughnessSoftening",
    "TangentialCompliance",
    "Values",
    "apply_effects",
    "effect_ranges",
    "post_process",
    "prestressed_zero",
    "run_cycle_with_effects",
    "validate_effects",
]
