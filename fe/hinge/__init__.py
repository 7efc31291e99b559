"""The hinge as a mechanical system: geometry of its contacts, condensation, the load cycle.

* :mod:`fe.hinge.geometry` — contact points and gaps on the exact surfaces of a mesh;
* :mod:`fe.hinge.system` — the general hinge factorised once and condensed onto its
  contact points (the Delassus operator of :mod:`fe.contact`), displacement recovery;
* :mod:`fe.hinge.twobody` — the same for any two elastic bodies (verification rigs);
* :mod:`fe.hinge.faces` — friction between the tang and clevis faces under an axial clamp;
* :mod:`fe.hinge.protocol` — the load history as data (``CycleSettings``);
* :mod:`fe.hinge.cycle` — the force-controlled cycle (``run_cycle``, its step ``HingeStep``
  for :mod:`fe.cycle.driver`); :mod:`fe.hinge.freeplay` — the step of clamped faces with
  clearance; :mod:`fe.hinge.increments` — the increments both solve and record;
* :mod:`fe.hinge.result` — its result (loop, η, energy balance);
* :mod:`fe.hinge.report` — loop CSV/PNG and the ParaView series.
"""
