"""Frictional contact on a condensed (Delassus) system ``(W, w_free, μ, G, e)``.

This sub-package is the contact algebra only: it imports nothing else from ``fe``.

* :mod:`fe.contact.law` — the Alart–Curnier/Coulomb law at one point;
* :mod:`fe.contact.state` — settings, the converged state, the increment result, checks;
* :mod:`fe.contact.residual` — the increment (``Problem``), an iterate and its residual;
* :mod:`fe.contact.newton` — the reduced active-set Newton step;
* :mod:`fe.contact.dense` — its dense LU (and the LU thread rule), bordered solves;
* :mod:`fe.contact.krylov` — the same step by GMRES (:mod:`fe.contact.gmres`) with a
  kept, updated LU: its options and kept state; :mod:`fe.contact.preconditioner` — the
  operators on a kept ``W`` block and the updated LU; :mod:`fe.contact.krylov_step` —
  the step;
* :mod:`fe.contact.globalise` — the Newton loop: line search, rescues;
* :mod:`fe.contact.proximal` — the fallback where no Newton step exists (singular ``W``);
* :mod:`fe.contact.working` — open-point elimination: the increment on the points that
  may close, checked on all (``ContactSettings.working_set``, opt-in);
* :mod:`fe.contact.solve` — :func:`solve_increment`, which runs them.
* :mod:`fe.contact.measure` — Siconos' common error measure, to score a solution.

The stiffness is linear and constant; the caller condenses it once onto ``m`` contact
points (slave nodes) and passes, per load increment,

* ``W`` — the Delassus operator ``C K⁻¹ Cᵀ``, shape (3m, 3m), float64 [mm/N], positive
  (semi)definite, rows and columns node-major ``[n, t1, t2]`` per point; symmetric for
  the hinge (a nonsymmetric ``W``, as from rigid-body impulse models, is detected once
  per array and handled by general products and the LU path);
* ``w_free`` — the relative displacement with zero contact force, shape (m, 3) [mm];
* optionally ``G`` (3m, k) [mm per rigid amplitude] and ``e`` (k,) for floating bodies.

Conventions:
    * ``p_i = (p_n, p_t1, p_t2)`` [N] is the contact force on the slave at point ``i``
      (``-p_i`` acts on the master); ``p_n >= 0`` is compressive.
    * ``w = W p + G α + w_free`` (flattened node-major) is the relative displacement of
      slave w.r.t. master [mm]; ``w_n`` is the gap (``>= 0`` open, ``W_nn > 0``).
    * ``α`` (k,) are rigid-body amplitudes of floating bodies with equilibrium
      ``Gᵀ p = e``. Rigid directions the contact forces cannot see are undetermined:
      ``p`` stays unique and the minimum-norm ``α`` is returned.
    * Signorini ``w_n >= 0, p_n >= 0, w_n p_n = 0`` and Coulomb ``|p_t| <= μ p_n`` with
      ``Δw_t = w_t - w_t_prev = 0`` where ``|p_t| < μ p_n``, else ``Δw_t = -γ p_t/|p_t|``,
      ``γ >= 0``, written as the Alart–Curnier equations ``C(p) = p - λ(p - r g) = 0`` of
      :mod:`fe.contact.law` with ``g = (w_n, Δw_t)``.

Algorithm: semismooth (generalised) Newton on ``C(p, α) = 0, Gᵀp = e`` with the active
set read off the trial force. Open points are eliminated (``p = 0``), the component of a
slipping point's tangential force along the slip direction is eliminated
(``p_t·u = μ p_n``), so each step factorises a dense system of size
``3 n_stick + 2 n_slip + n_frictionless`` (``+ k`` rigid amplitudes via a k×k Schur
complement solved by least squares with ``rcond``, which gives the minimum-norm ``α``).
While the unknown layout is unchanged and the iteration converges fast, the last LU
factors are reused (chord steps: exact residual, stale matrix; see ``chord_rate``).
From ``KrylovOptions.single_min`` unknowns the kept LU (a preconditioner only) is float32.
Friction ``μ`` is one coefficient or one per point (``ContactSettings.mu``).

Globalisation: Armijo backtracking on the merit ``φ = ½|C/r|² + ½|(Gᵀp - e)/r̄|²``.
If no step ``>= min_step`` decreases ``φ`` (or the step matrix is singular) a rescue is
taken, alternately (a) if some points are open, a full predictor step: floating bodies
with unbalanced load are first moved rigidly to first contact and the touching points
closed (without floating bodies all open points are closed), frictionless; this is how a
floating pin in a clearance finds contact, and (b) rescaling ``r`` by the next factor of
``RESCUE_FACTORS``, which changes the merit and the active-set path but not the solution. The line search keeps ``φ``
monotone between rescues, so the plain Newton cycle between active sets cannot occur;
the loop stops at ``max_iter`` with a ConvergenceError.

Singular step matrices: where ``W`` is rank deficient (more contact constraints than
body freedoms, e.g. stacked rigid bodies) the reduced Jacobian of a sticking set is
singular and no Newton step exists. The first such step hands the iterate to the
regularised Newton fallback of :mod:`fe.contact.proximal` (each step is the Newton step
of the proximal problem on ``W + ε D`` with a shifted ``w_free``, which has the original
residual; ``ε`` follows ``ρ`` down, Levenberg–Marquardt style, and a nonmonotone line
search accepts the steps), which shares the ``max_iter`` budget (one iteration per step,
rejected ones included); problems with a nonsingular active set never reach it.

Convergence: the scaled residual ``ρ = max(|C/r|_∞ / d_ref, |Gᵀp - e|_∞ / f_ref)`` must
drop to ``tol``, where ``d_ref = max(|W p|_∞, |G α|_∞, |w_free - (0, w_t_prev)|_∞)`` [mm]
and ``f_ref = max(|e|_∞, ||G|ᵀ |p||_∞, r̄ d_ref max|G|)`` [N] (the last term is the load
one point takes at the displacement scale, so ``ρ`` stays meaningful when ``e = 0``).
``C/r`` is the violation in displacement units (penetration, stick drift, or force/r),
so ``ρ`` is a relative error that is invariant under scaling the load and independent
of units.

Energy: for increment ``p_prev → p`` the consistent (trapezoidal) works are
``friction_work_i = -½ (p_t,prev + p_t)·Δw_t`` and
``normal_work_i = -½ (p_n,prev + p_n) Δw_n``. With ``K u = f + Cᵀ p`` and the
trapezoidal external work ``½ (f_prev + f)·Δu`` they satisfy exactly
``W_ext = ΔE_elastic + Σ (friction_work + normal_work)``, so over a cycle that closes
(``ΔE = 0``) the summed works equal the loop area. ``normal_work`` is zero for points that
stay closed or stay open and is a first-order discretisation term at increments where a
point opens or closes. ``dissipation_i = -p_t·Δw_t >= 0`` is the backward-Euler value
(it tends to ``friction_work`` as the increments shrink).

Example:
    >>> import numpy as np
    >>> from fe.contact.solve import solve_increment
    >>> from fe.contact.state import ContactSettings, ContactState
    >>> W = np.diag([1.0, 2.0, 2.0])            # one point, mm/N
    >>> w_free = np.array([[-1.0, 0.5, 0.0]])   # 1 mm interference, 0.5 mm drag
    >>> res = solve_increment(W, w_free, ContactState.initial(1), ContactSettings(mu=0.2))
    >>> res.state.p.round(12).tolist(), res.n_slip
    ([[1.0, -0.2, 0.0]], 1)
"""
