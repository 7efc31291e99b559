"""The joint's slip asymmetry (a self-energising brake): closed form, energy, tangent."""

from __future__ import annotations

import numpy as np
import pytest

from cad.errors import ParameterError
from fe.joint.element import JointParams
from fe.joint.history import displacement_history, force_history
from fe.joint.step import step

RIGID = {"k_tension_n_per_mm": 1e12, "k_compression_n_per_mm": 1e12}


def test_a_single_branch_slips_at_fs_1_plus_a_forwards_and_fs_1_minus_a_backwards() -> None:
    k, fs, a, X = 1000.0, 10.0, 0.3, 0.05
    p = JointParams(
        k_elastic_n_per_mm=0.0,
        k_slip_n_per_mm=k,
        slip_force_n=fs,
        n_branches=1,
        slip_asymmetry=a,
        **RIGID,
    )
    u = X * np.cos(2 * np.pi * np.linspace(0, 2, 801))
    h = displacement_history(p, np.concatenate([np.linspace(0, X, 50), u]))
    last = slice(-401, None)
    # one branch: φ = 2Fs/k (the midpoint of one bin), slip force kφ(1 ± a)/2·2 = Fs(1 ± a)
    assert h.force_n[last].max() == pytest.approx(fs * (1 + a), rel=1e-9)
    assert h.force_n[last].min() == pytest.approx(-fs * (1 - a), rel=1e-9)
    # loop area of the rectangle: (F₊ + F₋)(2X − (F₊ + F₋)/k)
    span = 2 * fs
    loop = h.dissipation_nmm[-1] - h.dissipation_nmm[-401]
    assert loop == pytest.approx(span * (2 * X - span / k), rel=1e-6)


def test_energy_balance_and_tangent_hold_with_asymmetry() -> None:
    p = JointParams(
        k_slip_n_per_mm=5e4,
        slip_force_n=20.0,
        free_play_mm=0.01,
        slip_asymmetry=-0.4,
        k_tension_n_per_mm=1e5,
        k_compression_n_per_mm=2e5,
    )
    u = 0.02 * np.sin(2 * np.pi * np.linspace(0, 5, 2001)) * np.linspace(0.3, 1.0, 2001)
    h = displacement_history(p, u, exact_path=True)
    f, d = h.force_n, h.disp_mm
    work = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(d))])
    balance = work - h.elastic_energy_nmm - h.dissipation_nmm
    assert h.dissipation_nmm[-1] > 1.0
    assert np.max(np.abs(balance)) < 1e-9 * h.dissipation_nmm[-1]
    s = h.state
    for u_end in (s.disp_mm + 0.004, s.disp_mm - 0.0031, s.disp_mm - 0.03):
        out = step(p, s, u_end)
        fd = (step(p, s, u_end + 1e-9).force_n - step(p, s, u_end - 1e-9).force_n) / 2e-9
        assert out.tangent_n_per_mm == pytest.approx(fd, rel=1e-6)


def test_force_control_is_limited_by_the_weaker_direction() -> None:
    p = JointParams(k_elastic_n_per_mm=0.0, slip_force_n=10.0, slip_asymmetry=0.5, n_branches=4)
    assert p.capacity_n() == pytest.approx(5.0)
    h = force_history(p, np.array([12.0, 0.0]))  # forwards 15 N is carried
    assert h.force_n[0] == pytest.approx(12.0)
    with pytest.raises(ParameterError, match="capacity"):
        force_history(p, np.array([-6.0]))


def test_asymmetry_out_of_range_is_refused_naming_it() -> None:
    with pytest.raises(ParameterError, match="slip_asymmetry"):
        JointParams(slip_asymmetry=1.0)
