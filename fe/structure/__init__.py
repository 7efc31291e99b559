"""Elastic structures condensed on their contact points, shared by every hinge kind.

* :mod:`fe.structure.supports` — a floating body's rigid-body modes and the 3-2-1 support
  that lets it be factorised;
* :mod:`fe.structure.condensed` — ``Condensed``, the operators every builder returns (the
  Delassus operator ``W``, the free gap ``w0``, the rigid map ``G``), and the block size of
  the solves that form them;
* :mod:`fe.structure.twobody` — any two elastic bodies in contact, condensed on the slave
  nodes (verification rigs, the bearing hinge's one-ball rig).

The contact points themselves come from :mod:`fe.surfaces`, and :mod:`fe.contact` solves on
the condensed operators. Each kind's own system (``fe.general``, ``fe.bearing``) builds on
these; nothing here knows a kind.
"""
