"""Closed-form and reduced models of the bearing hinge's ball bearings.

The foundations the bearing-hinge cycle (``--ball-model hertz``) and its verification
rest on; these closed forms import ``cad``, numpy and scipy, and nothing else from ``fe``.

* :mod:`fe.bearing.hertz` — Hertz point contact of two curved bodies: curvature sum and
  difference, the ellipticity from the exact elliptic-integral equation (or Hamrock &
  Brewe's approximations), the contact ellipse, approach, peak pressure, stiffness and the
  load–deflection constant ``K`` of ``Q = K δ^{3/2}``; ball–raceway curvatures.
* :mod:`fe.bearing.pair` — one angular-contact bearing under axial load (Jones' equation,
  with the change of contact angle) and a preloaded pair: load sharing, stiffness, lift-off.
* :mod:`fe.bearing.rings` — Jones' five-DOF equilibrium of the shared inner ring under
  radial, axial and moment load: per-ball loads Q_ψ and contact angles, stiffness matrix.

The hinge's cycles build on them, each a step of :mod:`fe.cycle.driver`, with the ``hertz``
ball law of :mod:`fe.bearing.balls` and the preload, targets and result of
:mod:`fe.bearing.loading`: :mod:`fe.bearing.cycle` (``hertz`` balls),
:mod:`fe.bearing.fit_cycle` (frictional fits) and :mod:`fe.bearing.full_cycle` (``full``
balls: the meshed one-ball rig of :mod:`fe.bearing.ball_rig`, condensed once with friction,
as the contact law of every ball, :mod:`fe.bearing.meshed_ball`).

A 708C ball (3.969 mm, pitch 15 mm, 15°) on its inner race (f_i = 0.52), 200 N:

>>> from cad.materials import GCR15
>>> from fe.bearing.hertz import Race, contact_ellipse, effective_modulus, race_curvatures
>>> curv = race_curvatures(3.969, 15.0, 15.0, 0.52, Race.INNER)
>>> c = contact_ellipse(curv, effective_modulus(GCR15, GCR15), 200.0)
>>> print(f"a = {c.semi_major_mm:.3f} mm, b = {c.semi_minor_mm:.4f} mm, "
...       f"δ = {1e3 * c.approach_mm:.2f} µm, p_max = {c.max_pressure_mpa:.0f} MPa")
a = 0.614 mm, b = 0.0631 mm, δ = 5.00 µm, p_max = 2468 MPa

The hinge's preloaded pair (F_p = 100 N) under the clevis force 400 N, radial on the pin:

>>> from cad.bearing_geometry import BearingHingeParams
>>> from fe.bearing.pair import bearing_from_params, pair_axial
>>> from fe.bearing.rings import pair_from_params, solve_ring
>>> p = BearingHingeParams(preload_n=100.0)
>>> at_rest = pair_axial(bearing_from_params(p), 100.0, 0.0)
>>> print(f"axial stiffness {at_rest.stiffness_n_per_mm:.0f} N/mm")
axial stiffness 33364 N/mm
>>> eq = solve_ring(pair_from_params(p), [400.0, 0.0, 0.0, 0.0, 0.0])
>>> print(f"δ_r = {1e3 * eq.displacement[0]:.2f} µm, Q_max = {eq.balls[0].load_n.max():.1f} N")
δ_r = 2.83 µm, Q_max = 84.2 N
"""
