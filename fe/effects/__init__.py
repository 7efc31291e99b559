"""Physical effects a user can switch on, on top of elasticity + Coulomb contact.

* :mod:`fe.effects.base` — the ``Effect`` interface, parameter specs, the context, the
  ``History`` (force, displacement, time) the ``post`` hook sees;
* :mod:`fe.effects.models` — the general hinge's five effects (frame compliance, roughness
  softening, tangential compliance, interference, face friction);
* :mod:`fe.effects.interfaces` — the bearing hinge's interface friction (its bonded fits
  made Coulomb contacts);
* :mod:`fe.effects.plugins` — a user's own effects: from a file named in MODEL.toml or an
  installed package (entry-point group ``hingelab.effects``), checked and guarded;
* :mod:`fe.effects.history` — the time of a model's loop (the protocol's force rate, or a
  measured record's clock);
* :mod:`fe.effects.registry` — ``REGISTRY`` (a live view of every known effect) and the
  hooks applied in order (``post_increments`` books the energies);
* :mod:`fe.effects.cycle` — the general hinge's cycle with effects
  (``run_cycle_with_effects``). Import each name from its module.
"""
