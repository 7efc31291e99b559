"""Where two meshed bodies meet: contact points on a mesh's facets and exact surfaces.

* :mod:`fe.surfaces.geometry` — node-to-surface contact points of a configuration: the
  projection of slave nodes on the master's bilinear facets, local frames and exact gaps
  from the master's ``cad.surfaces`` surface, and the contact operator ``C``.

It imports ``cad``, ``mesh``, numpy and scipy, nothing else from ``fe``: every hinge kind
and the tied interfaces of the bearing hinge (``fe.bearing.ties``) use it.
"""
