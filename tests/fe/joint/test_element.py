"""The joint element against closed forms, its energy balance, tangent and control modes."""

from __future__ import annotations

import numpy as np
import pytest

from cad.errors import ParameterError
from fe.joint.element import JointParams, initial_state
from fe.joint.history import displacement_history, force_history
from fe.joint.step import step, step_force

RIGID = {"k_tension_n_per_mm": 1e12, "k_compression_n_per_mm": 1e12}


def _trapezoid_work(h) -> np.ndarray:  # type: ignore[no-untyped-def]
    f, u = h.force_n, h.disp_mm
    return np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(u))])


def _sine(amp: float, cycles: int, n: int = 2001) -> np.ndarray:
    return amp * np.sin(2 * np.pi * np.linspace(0, cycles, n))


def test_a_single_jenkins_loop_area_is_4Fs_X_minus_Fs_over_k() -> None:
    k, fs, X = 1000.0, 10.0, 0.05
    p = JointParams(
        k_elastic_n_per_mm=0.0, k_slip_n_per_mm=k, slip_force_n=fs, n_branches=1, **RIGID
    )
    # start at +X, then two full cycles: the dissipation of the second is one loop
    u = X * np.cos(2 * np.pi * np.linspace(0, 2, 801))
    h = displacement_history(p, np.concatenate([np.linspace(0, X, 50), u]))
    loop = h.dissipation_nmm[-1] - h.dissipation_nmm[-401]
    expected = 4 * fs * (X - fs / k)
    assert loop == pytest.approx(expected, rel=1e-6)  # the rigid series spring costs ~1e-8


def test_uniform_iwan_bank_follows_its_backbone_and_masing_branch() -> None:
    n, kt, fs = 8, 800.0, 40.0
    p = JointParams(
        k_elastic_n_per_mm=200.0, k_slip_n_per_mm=kt, slip_force_n=fs, n_branches=n, **RIGID
    )
    phi = 2 * fs / kt * (np.arange(n) + 0.5) / n

    def backbone(x: np.ndarray) -> np.ndarray:
        return 200.0 * x + (kt / n) * np.minimum(np.abs(x)[:, None], phi).sum(axis=1) * np.sign(x)

    X = 0.15
    up = np.linspace(0, X, 301)[1:]
    down = np.linspace(X, -X, 601)[1:]
    h = displacement_history(p, np.concatenate([up, down]))
    assert np.allclose(h.force_n[:300], backbone(up), rtol=1e-7, atol=1e-7)
    masing = backbone(np.array([X]))[0] - 2 * backbone((X - down) / 2)
    assert np.allclose(h.force_n[300:], masing, rtol=1e-7, atol=1e-7)


@pytest.mark.parametrize(
    "params",
    [
        JointParams(
            k_slip_n_per_mm=5e4,
            slip_force_n=20.0,
            free_play_mm=0.01,
            k_tension_n_per_mm=1e5,
            k_compression_n_per_mm=2e5,
        ),
        JointParams(
            k_slip_n_per_mm=5e4,
            slip_ratio=0.3,
            free_play_mm=0.0,
            k_tension_n_per_mm=1e5,
            k_compression_n_per_mm=2e5,
        ),
        JointParams(k_slip_n_per_mm=5e4, slip_ratio=0.5, slip_force_n=15.0, free_play_mm=0.004),
    ],
    ids=["fixed-slip-play", "load-proportional", "both-play"],
)
def test_energy_balance_holds_to_round_off_over_many_cycles(params: JointParams) -> None:
    u = _sine(0.02, 5) * np.linspace(0.3, 1.0, 2001)  # growing amplitude: new slip each cycle
    h = displacement_history(params, u, exact_path=True)
    work = _trapezoid_work(h)
    balance = work - h.elastic_energy_nmm - h.dissipation_nmm
    assert h.dissipation_nmm[-1] > 1.0
    assert np.max(np.abs(balance)) < 1e-12 * h.dissipation_nmm[-1] * 1e3
    # and without the kinks the trapezoid is not exact: the inserted kinks matter
    coarse = displacement_history(params, u[::40])
    assert (
        abs(
            _trapezoid_work(coarse)[-1] - coarse.elastic_energy_nmm[-1] - coarse.dissipation_nmm[-1]
        )
        > 1e-6
    )


def test_load_proportional_bank_is_homogeneous() -> None:
    p = JointParams(
        k_slip_n_per_mm=5e4, slip_ratio=0.4, k_tension_n_per_mm=1e5, k_compression_n_per_mm=3e5
    )
    u = _sine(0.01, 2)
    h1, h3 = displacement_history(p, u), displacement_history(p, 3 * u)
    assert np.allclose(h3.force_n, 3 * h1.force_n, rtol=1e-10, atol=1e-9)
    assert h3.dissipation_nmm[-1] == pytest.approx(9 * h1.dissipation_nmm[-1], rel=1e-10)


def test_free_play_is_a_dead_zone_of_total_width_2g() -> None:
    g = 0.005
    p = JointParams(k_slip_n_per_mm=5e4, slip_force_n=10.0, free_play_mm=2 * g)
    u = np.linspace(0.0, 0.03, 301)
    h = displacement_history(p, u)
    assert np.all(h.force_n[u <= g] == 0.0)
    assert np.all(h.force_n[u > g + 1e-12] > 0.0)
    back = displacement_history(p, np.linspace(0.03, -0.03, 601)[1:], state=h.state)
    f0 = np.flatnonzero(back.force_n == 0.0)
    width = back.disp_mm[f0].max() - back.disp_mm[f0].min()
    assert width == pytest.approx(2 * g, abs=2e-4)  # sampled at 1e-4 mm


@pytest.mark.parametrize("u_end", [0.004, 0.0123, -0.0031], ids=["stick", "slip", "reverse"])
def test_tangent_matches_central_differences(u_end: float) -> None:
    p = JointParams(
        k_slip_n_per_mm=5e4,
        slip_ratio=0.3,
        slip_force_n=12.0,
        free_play_mm=0.002,
        k_tension_n_per_mm=1e5,
        k_compression_n_per_mm=2e5,
        damping_n_s_per_mm=3.0,
    )
    s = displacement_history(p, np.array([0.0, 0.01]), time_s=np.array([0.0, 1.0])).state
    dt, h = 1e-3, 1e-9
    out = step(p, s, u_end, dt)
    fd = (step(p, s, u_end + h, dt).force_n - step(p, s, u_end - h, dt).force_n) / (2 * h)
    assert out.tangent_n_per_mm == pytest.approx(fd, rel=1e-6)


def test_force_and_displacement_control_agree() -> None:
    p = JointParams(
        k_slip_n_per_mm=5e4,
        slip_ratio=0.3,
        slip_force_n=20.0,
        free_play_mm=0.01,
        k_tension_n_per_mm=1e5,
        k_compression_n_per_mm=2e5,
    )
    u = _sine(0.02, 3)
    hd = displacement_history(p, u)
    hf = force_history(p, hd.force_n)
    engaged = hd.force_n != 0.0
    assert np.allclose(hf.disp_mm[engaged], u[engaged], rtol=0, atol=1e-13)
    s = initial_state(p)
    for f in (100.0, 300.0, -50.0):
        out = step_force(p, s, f)
        s = out.state
    assert s.force_n == pytest.approx(-50.0, abs=1e-9)


def test_force_beyond_capacity_is_refused_naming_it() -> None:
    p = JointParams(k_elastic_n_per_mm=0.0, k_slip_n_per_mm=1e3, slip_force_n=10.0)
    with pytest.raises(ParameterError, match="capacity 10 N"):
        force_history(p, np.array([5.0, 12.0]))


def test_a_bank_whose_tangent_could_turn_negative_is_refused() -> None:
    with pytest.raises(ParameterError, match="k_elastic_n_per_mm must exceed"):
        JointParams(k_elastic_n_per_mm=100.0, k_slip_n_per_mm=1e4, slip_ratio=0.5)


def test_increment_by_increment_equals_the_history_across_the_free_play() -> None:
    # regression: a step starting inside the play with a round-off bank force jumped to contact
    p = JointParams(
        k_slip_n_per_mm=3.5e5,
        k_elastic_n_per_mm=3.5e5,
        slip_ratio=0.25,
        slip_force_n=8.0,
        free_play_mm=0.002,
        k_tension_n_per_mm=1.4e5,
        k_compression_n_per_mm=2.6e5,
    )
    u = 0.004 * np.sin(2 * np.pi * np.linspace(0, 2, 401))
    s, forces = initial_state(p), []
    for x in u:
        out = step(p, s, float(x))
        s = out.state
        forces.append(out.force_n)
    h = displacement_history(p, u)
    assert np.allclose(forces, h.force_n, rtol=0, atol=1e-9 * np.abs(h.force_n).max())
