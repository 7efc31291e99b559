"""Physical effects a user can switch on, on top of elasticity + Coulomb contact.

* :mod:`fe.effects.base` — the ``Effect`` interface, parameter specs, the context;
* :mod:`fe.effects.models` — the general hinge's five effects (frame compliance, roughness
  softening, tangential compliance, interference, face friction);
* :mod:`fe.effects.interfaces` — the bearing hinge's interface friction (its bonded fits
  made Coulomb contacts);
* :mod:`fe.effects.registry` — ``REGISTRY`` and the cycle with effects
  (``run_cycle_with_effects``). Import each name from its module.
"""
