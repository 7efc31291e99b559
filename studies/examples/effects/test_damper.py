"""Tests of the example damper (docs/user_effects.md): its hook against closed forms, no FE.

Run with ``pytest effects/test_damper.py`` next to your MODEL.toml.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from damper import Damper

from fe.effects.base import History


def history(force_n: np.ndarray, time_s: np.ndarray) -> History:
    """A history with the hinge's displacement 0 (the damper's own extension is the output)."""
    return History(force_n, np.zeros_like(force_n), time_s)


def test_a_bare_dashpot_under_a_held_force_creeps_at_phi_f() -> None:
    """A bare dashpot (k = 0), F = 100 N held for 10 s after a 1 s ramp: h = φ (½ F·1 s + F·10 s)."""
    t = np.array([0.0, 1.0, 11.0])
    F = np.array([0.0, 100.0, 100.0])
    out = Damper().post(history(F, t), {"fluidity_mm_per_ns": 1e-6, "stiffness_n_per_mm": 0.0})
    assert out.disp_mm[-1] == pytest.approx(1e-6 * (50.0 + 1000.0), rel=1e-12)
    assert np.all(out.stored_energy_nmm == 0.0)  # a bare dashpot stores nothing


def test_a_kelvin_voigt_element_relaxes_to_f_over_k() -> None:
    """A held force: h = F/k (1 − e^{−t/τ}), τ = 1/(φ k), after an instant step (Δt → 0 ramp)."""
    phi, k, f = 5e-6, 1e4, 200.0
    tau = 1.0 / (phi * k)
    t = np.concatenate([[0.0], 1e-9 + np.linspace(0.0, 5 * tau, 50)])
    F = np.concatenate([[0.0], np.full(50, f)])
    out = Damper().post(history(F, t), {"fluidity_mm_per_ns": phi, "stiffness_n_per_mm": k})
    expected = f / k * (1.0 - np.exp(-(t[1:] - t[1]) / tau))
    np.testing.assert_allclose(out.disp_mm[1:], expected, atol=1e-9 * f / k)
    assert out.stored_energy_nmm[-1] == pytest.approx(0.5 * k * out.disp_mm[-1] ** 2)


def test_it_is_off_at_zero_fluidity_and_starts_at_zero() -> None:
    """φ = 0: the dashpot is rigid, the element never moves."""
    t = np.linspace(0.0, 10.0, 11)
    F = 100.0 * np.sin(t)
    out = Damper().post(history(F, t), {"fluidity_mm_per_ns": 0.0, "stiffness_n_per_mm": 1e4})
    assert np.all(out.disp_mm == 0.0)
    assert math.isclose(out.disp_mm[0], 0.0)
