"""The time of a model's loop taken from a measured record, and effects evaluated at it."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from cad.errors import DataError
from fe.effects.history import record_turns, time_from_reference
from fe.effects.registry import post_process

EXAMPLE = Path(__file__).parents[3] / "studies" / "examples" / "effects" / "damper.py"
FG, PERIOD, DWELL = 400.0, 40.0, 3.0


def sine_record(n_cycles: float = 1.25, hz: float = 50.0, noise: float = 0.3, seed: int = 1):  # type: ignore[no-untyped-def]
    """A record 0 → +Fg → −Fg → +Fg as a sine after a dwell, with load-cell noise."""
    t = np.arange(0.0, DWELL + n_cycles * PERIOD, 1.0 / hz)
    F = FG * np.sin(2 * math.pi * np.clip(t - DWELL, 0.0, None) / PERIOD)
    return t, F + np.random.default_rng(seed).normal(0.0, noise, t.size)


def model_path(n: int = 20) -> np.ndarray:
    """A model's force path 0 → +Fg → −Fg → +Fg in uniform steps, shape (2.5 n + 1,) [N]."""
    up = np.linspace(0.0, FG, n // 2 + 1)
    down = np.linspace(FG, -FG, n + 1)[1:]
    back = np.linspace(-FG, FG, n + 1)[1:]
    return np.concatenate([up, down, back])


def true_time(F: np.ndarray) -> np.ndarray:
    """The sine's own time of each model point, on its ramp (from the first point)."""
    s = np.arcsin(np.clip(F / FG, -1.0, 1.0)) / (2 * math.pi)  # in [-1/4, 1/4] periods
    k = np.argmax(F)  # the +Fg turn
    j = k + int(np.argmin(F[k:]))  # the −Fg turn
    phase = np.where(np.arange(F.size) <= k, s, np.where(np.arange(F.size) <= j, 0.5 - s, 1.0 + s))
    return phase * PERIOD


def test_the_model_gets_the_time_at_which_the_record_passed_its_force() -> None:
    F = model_path()
    t_ref, F_ref = sine_record()
    t = time_from_reference(F, F_ref, t_ref)
    expected = true_time(F)
    # noise 0.3 N on a slope ≥ 2π Fg/T·cos: off by a few samples near the turns only
    assert np.max(np.abs(t - expected)) < 0.6
    assert np.median(np.abs(t - expected)) < 0.05
    assert np.all(np.diff(t) >= 0.0)


def test_a_record_with_too_few_ramps_is_refused() -> None:
    t_ref, F_ref = sine_record(n_cycles=0.5)
    assert len(record_turns(F_ref)) - 1 == 2
    with pytest.raises(DataError, match=r"the record has 2 load ramp\(s\), the model's path 3"):
        time_from_reference(model_path(), F_ref, t_ref)


def test_a_dashpot_on_a_sine_record_dissipates_its_closed_form(jenkins, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Through ``loop_at_record_times``: the viscous work per loop is φ Fg² T / 2 (a sine)."""
    from hingelab_jenkins import JenkinsParams, loop_area

    from model.file import read_model
    from model.spec import DesignPoint
    from validation.evaluate import loop_at_record_times

    (tmp_path / "effects").mkdir()
    shutil.copy(EXAMPLE, tmp_path / "effects" / "damper.py")
    phi = 2e-6
    (tmp_path / "MODEL.toml").write_text(
        '[hinge]\nkind = "jenkins_pin"\n\n[cycle]\nincrements_per_stage = 60\ngrading = 1.0\n\n'
        '[effects.damper]\nfrom = "effects/damper.py:Damper"\n'
        f"fluidity_mm_per_ns = {phi!r}\nstiffness_n_per_mm = 0.0\n"
    )
    spec = read_model(tmp_path / "MODEL.toml")
    t_ref, F_ref = sine_record(hz=20.0, noise=0.2)
    F, d = loop_at_record_times(spec, DesignPoint(FG, {"slip_force_n": 60.0}), F_ref, t_ref)
    k = int(np.argmax(F))
    area = float(np.sum(0.5 * (F[k + 1 :] + F[k:-1]) * np.diff(d[k:])))
    viscous = phi * FG**2 * PERIOD / 2
    assert area - loop_area(JenkinsParams(), FG) == pytest.approx(viscous, rel=0.02)


def test_without_a_time_the_protocols_clock_is_used() -> None:
    """``post_process`` at 20 N/s equals it at the explicit protocol time."""
    from fe.effects.history import protocol_time

    F = model_path()
    d = 1e-3 * F
    effects = {"frame_compliance": {"compliance_mm_per_n": 1e-5}}
    a = post_process(F, d, effects, force_rate_n_per_s=20.0)
    b = post_process(F, d, effects, time_s=protocol_time(F, 20.0))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(a - d, 1e-5 * F, rtol=1e-12)
