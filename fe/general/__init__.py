"""The general hinge as a mechanical system: its condensation and its load cycle.

Its contact points come from :mod:`fe.surfaces.geometry`, and the shared structure
(rigid modes, the 3-2-1 support, ``Condensed``) from :mod:`fe.structure`.

* :mod:`fe.general.system` — the general hinge assembled and factorised once (supports,
  grips, nodal compliances, low-memory mode), displacement recovery;
* :mod:`fe.general.condensation` — the hinge condensed onto the contact points of a
  configuration (the Delassus operator of :mod:`fe.contact`);
* :mod:`fe.general.memory` — whether that fits in memory, and which way to form it
  (``HINGELAB_CONDENSE``, ``HINGELAB_MEMORY_CHECK``);
* :mod:`fe.general.faces` — friction between the tang and clevis faces under an axial clamp;
* :mod:`fe.cycle.protocol` — the load history as data (``CycleSettings``);
* :mod:`fe.general.cycle` — the force-controlled cycle (``run_cycle``, its step ``HingeStep``
  for :mod:`fe.cycle.driver`); :mod:`fe.general.freeplay` — the step of clamped faces with
  clearance; :mod:`fe.general.increments` — the increments both solve and record;
* :mod:`fe.cycle.result` — its result (loop, η, energy balance);
* :mod:`fe.general.report` — its ParaView series (contact pressure and slip on the pin),
  written by :mod:`fe.cycle.fields`; the loop files are :mod:`fe.cycle.loop_files`.
"""
