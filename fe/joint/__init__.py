"""The reduced-order joint: a hinge as one nonlinear element for structural dynamics.

An Iwan bank of Jenkins branches (fixed and load-proportional slip) in series with a
linear stiffness (k₊ in tension, k₋ in compression) and a free play, with an optional
dashpot (:mod:`fe.joint.element`); exact monotone segments (:mod:`fe.joint.segment`) and
vectorised histories (:mod:`fe.joint.history`); the hinge kind ``joint`` that runs it in
the load cycle is :mod:`fe.kinds.joint`.

>>> import numpy as np
>>> from fe.joint.element import JointParams, initial_state
>>> from fe.joint.step import step
>>> p = JointParams(k_slip_n_per_mm=1000.0, k_elastic_n_per_mm=0.0, slip_force_n=10.0,
...                 n_branches=1, k_tension_n_per_mm=1e9, k_compression_n_per_mm=1e9)
>>> out = step(p, initial_state(p), 0.05)   # a single Jenkins element slides at 10 N
>>> round(out.force_n, 6), round(out.tangent_n_per_mm, 6)
(10.0, 0.0)
"""
