"""An independent generator of the worked example's records (docs/worked_example_user_effect.md).

Not ``synth`` and not the example's ``Damper``: a Jenkins element (spring ``K0`` in
parallel with a spring ``K1`` in series with a Coulomb slider ``FS``, the ``jenkins_pin``
kind's physics) with a Kelvin–Voigt element (dashpot of fluidity ``PHI`` ∥ spring ``K_KV``)
in series, loaded 0 → +Fg → −Fg → +Fg at a constant force rate after a dwell at zero.
The Kelvin–Voigt ODE dh/dt = φ (F(t) − k h) is integrated by ``scipy.integrate.solve_ivp``
leg by leg (the force kinks at the turns); the Jenkins element is solved exactly at the
turns and the samples. The record is sampled at its own clock (uniform in time, the
turns between samples), with noise on force and displacement and an arbitrary
displacement zero.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

K0, K1, FS = 2000.0, 6000.0, 60.0  # the jenkins_pin kind's defaults [N/mm, N/mm, N]
PHI = 5e-6  # fluidity of the hidden dashpot [mm/(N·s)]
K_KV = 1e4  # the spring beside it [N/mm]
RATES = (20.0, 80.0, 320.0)  # loading rates of the records [N/s]
AMPLITUDES = (200.0, 400.0)  # [N]
SIGMA_F, SIGMA_D = 0.05, 2e-4  # noise of the load cell [N] and the transducer [mm]
SHIFT_MM = 0.37  # the transducer's zero [mm]
SAMPLES = 900  # samples per record
DWELL_S = 2.0  # at zero force before the loading [s]


def force_path(amp: float, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Turning times [s] and forces [N] of the dwell and the three ramps."""
    legs = np.array([0.0, 0.0, amp, -amp, amp])
    dt = np.concatenate([[0.0, DWELL_S], np.abs(np.diff(legs[1:])) / rate])
    return np.cumsum(dt), legs


def jenkins(force: np.ndarray) -> np.ndarray:
    """δ of the Jenkins element along a force path, shape (n,) [mm] (return map per point)."""
    d = np.empty_like(force)
    s = 0.0
    for i, f in enumerate(force):
        x = (f + K1 * s) / (K0 + K1)
        q = K1 * (x - s)
        if abs(q) > FS:
            q = math.copysign(FS, q)
            x = (f - q) / K0
            s = x - q / K1
        d[i] = x
    return d


def kelvin_voigt(t_turn: np.ndarray, f_turn: np.ndarray, t: np.ndarray, phi: float) -> np.ndarray:
    """h at the times ``t`` by solve_ivp, one leg at a time, shape (n,) [mm]."""
    h = np.zeros_like(t)
    h0 = 0.0
    for a, b in zip(range(len(t_turn) - 1), range(1, len(t_turn)), strict=True):
        ta, tb = t_turn[a], t_turn[b]
        if tb <= ta:
            continue
        fa, fb = f_turn[a], f_turn[b]

        def rhs(time: float, y: np.ndarray, ta=ta, tb=tb, fa=fa, fb=fb) -> np.ndarray:
            f = fa + (fb - fa) * (time - ta) / (tb - ta)
            return phi * (f - K_KV * y)

        inside = (t > ta) & (t < tb)
        t_eval = np.append(t[inside], tb)
        sol = solve_ivp(rhs, (ta, tb), [h0], t_eval=t_eval, rtol=1e-10, atol=1e-14)
        h[inside] = sol.y[0, :-1]
        h[t == tb] = h0 = float(sol.y[0, -1])
    return h


def record(
    amp: float, rate: float, phi: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(time [s], force [N], displacement [mm]) of one record, each shape (SAMPLES,)."""
    t_turn, f_turn = force_path(amp, rate)
    t = np.linspace(0.0, t_turn[-1], SAMPLES)
    t_all = np.union1d(t, t_turn)  # the Jenkins element sees the true turns
    F_all = np.interp(t_all, t_turn, f_turn)
    d_all = jenkins(F_all)
    keep = np.isin(t_all, t)
    F, d = F_all[keep], d_all[keep]
    h = kelvin_voigt(t_turn, f_turn, t, phi) if phi > 0.0 else np.zeros_like(t)
    noisy_F = F + rng.normal(0.0, SIGMA_F, F.size)
    noisy_d = d + h + SHIFT_MM + rng.normal(0.0, SIGMA_D, F.size)
    return t, noisy_F, noisy_d


def write_set(folder: Path, phi: float, seed: int) -> Path:
    """A measurement folder: one record per (amplitude, rate), the rate a test condition."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True)
    rows = ["case_id,hinge,slip_force_N,amplitude_N,cond_rate_N_per_s,loop_file"]
    for amp in AMPLITUDES:
        for rate in RATES:
            cid = f"a{amp:g}_r{rate:g}"
            t, F, d = record(amp, rate, phi, rng)
            lines = ["time_s,force_N,displacement_mm"]
            lines += [f"{a:.6f},{b:.6f},{c:.8f}" for a, b, c in zip(t, F, d, strict=True)]
            (folder / f"{cid}.csv").write_text("\n".join(lines) + "\n")
            rows.append(f"{cid},jenkins_pin,{FS:g},{amp:g},{rate:g},{cid}.csv")
    (folder / "cases.csv").write_text("\n".join(rows) + "\n")
    return folder
