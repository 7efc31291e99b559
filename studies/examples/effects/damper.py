"""A viscous damper in series with the hinge: a user's own effect (docs/user_effects.md).

A Kelvin–Voigt element — a dashpot of fluidity φ = 1/c in parallel with a spring k — sits
in the load path between the hinge and the grips. Under the force F(t) its extension h obeys

    dh/dt = φ (F − k h),    h(0) = 0,

so the grips see δ + h. The force is linear in time between two samples, and the equation
is solved exactly there (τ = 1/(φ k)): with the slope s = ΔF/Δt,

    h(t₁) = h_p(t₁) + (h(t₀) − h_p(t₀)) e^{−Δt/τ},    h_p(t) = (F(t) − s τ) / k,

and for k = 0 (a bare dashpot) h(t₁) = h(t₀) + φ Δt (F₀ + F₁)/2. The spring stores ½ k h²;
the dashpot dissipates the rest of the work done on the element, which hingelab books as
``effect_work_Nmm`` (the loop's area is then friction work plus viscous work).

Named in a MODEL.toml next to it::

    [effects.damper]
    from = "effects/damper.py:Damper"
    fluidity_mm_per_ns = 5e-6
    stiffness_n_per_mm = 1e4
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fe.effects.base import Effect, FloatArray, History, ParamSpec, PostResult, Values


def kelvin_voigt(
    force_n: FloatArray, time_s: FloatArray, fluidity: float, stiffness: float
) -> FloatArray:
    """Extension h of the element at every sample, shape (n,) [mm], from h = 0 at the start."""
    h = np.zeros_like(force_n)
    for i in range(1, force_n.size):
        dt = time_s[i] - time_s[i - 1]
        f0, f1 = force_n[i - 1], force_n[i]
        if dt <= 0.0 or fluidity == 0.0:
            h[i] = h[i - 1]  # a dashpot does not move in no time
        elif stiffness == 0.0:
            h[i] = h[i - 1] + fluidity * dt * 0.5 * (f0 + f1)
        else:
            tau = 1.0 / (fluidity * stiffness)
            slope = (f1 - f0) / dt
            hp0 = (f0 - slope * tau) / stiffness
            hp1 = (f1 - slope * tau) / stiffness
            h[i] = hp1 + (h[i - 1] - hp0) * np.exp(-dt / tau)
    return h


@dataclass(frozen=True)
class Damper(Effect):
    """A Kelvin–Voigt element (dashpot ∥ spring) in series with the hinge; off at φ = 0."""

    name: str = "damper"
    params: tuple[ParamSpec, ...] = (
        ParamSpec("fluidity_mm_per_ns", 0.0, 1e-4, 1e-6, "mm/(N·s)", "1/c of the dashpot"),
        ParamSpec("stiffness_n_per_mm", 0.0, 1e7, 1e4, "N/mm", "spring beside the dashpot"),
    )

    def post(self, history: History, values: Values) -> PostResult:
        """Return δ + h and the spring's energy ½ k h² (the dashpot dissipates the rest)."""
        k = values["stiffness_n_per_mm"]
        h = kelvin_voigt(history.force_n, history.time_s, values["fluidity_mm_per_ns"], k)
        return PostResult(history.disp_mm + h, 0.5 * k * h**2)
