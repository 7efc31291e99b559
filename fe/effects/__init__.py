"""Physical effects a user can switch on, on top of elasticity + Coulomb contact.

* :mod:`fe.effects.base` — the ``Effect`` interface, parameter specs, the context;
* :mod:`fe.effects.models` — the general hinge's five effects (frame compliance, roughness
  softening, tangential compliance, interference, face friction);
* :mod:`fe.effects.interfaces` — the bearing hinge's interface friction (its bonded fits
  made Coulomb contacts);
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
    InterfaceFriction,
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
    "InterfaceFriction",
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
