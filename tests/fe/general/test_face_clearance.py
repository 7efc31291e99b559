"""Face friction with clearance: the free play crossed by sliding clamped faces (fe.general.freeplay).

Coarse mesh, Δr = 0.1 mm, 6 increments per stage, the default clamp (300 N per face,
μ = 0.2: the faces let go near 2μN = 120 N).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cad.general import make_general_hinge
from cad.general_params import GeneralHingeParams
from fe.cycle.protocol import CycleSettings
from fe.effects.cycle import run_cycle_with_effects
from fe.effects.registry import REGISTRY
from fe.general.crossing import face_mask
from fe.general.cycle import configurations, run_cycle
from fe.general.faces import face_normal_forces
from fe.general.system import build_system
from mesh.build import mesh_hinge
from mesh.settings import MeshSettings

CLEARANCE = 0.1
MU = 0.2
CLAMP = 300.0


def settings(amp: float, mu: float = MU, n: int = 6) -> CycleSettings:
    return CycleSettings(amplitude_n=amp, mu=mu, increments_per_stage=n, clearance_increments=n)


def _faces(clamp: float = CLAMP) -> dict[str, dict[str, float]]:
    return {"face_friction": {"clamp_force_n": clamp}}


@pytest.fixture(scope="module")
def loose():
    mesh, _ = mesh_hinge(
        make_general_hinge(GeneralHingeParams(clearance_mm=CLEARANCE)), MeshSettings.coarse()
    )
    system = build_system(mesh)
    return system, configurations(system, CLEARANCE)


@pytest.fixture(scope="module")
def slid(loose):
    system, configs = loose
    return run_cycle_with_effects(system, CLEARANCE, settings(400.0), _faces(), configs=configs)


def test_face_friction_no_longer_needs_zero_clearance():
    """``diagnose`` skips effects with a ``zero_clearance_reason``; face friction has none now."""
    assert REGISTRY["face_friction"].zero_clearance_reason == ""


def test_the_free_play_is_crossed_at_the_faces_slip_force(slid):
    """Each crossing is one slide at F = μ Σ p_n of the faces (≈ 2μN), clevis side changed."""
    r = slid.result
    assert len(r.slides) == 3  # centred → tension, → compression, → tension
    for k in r.slides:
        inc, state, cond = r.increments[k], r.states[k], r.configs[r.increments[k].side]
        p = np.asarray(state.p)
        f_slide = MU * sum(face_normal_forces(cond, p).values())
        assert abs(inc.force_n) == pytest.approx(f_slide, rel=1e-6)
        assert abs(inc.force_n) == pytest.approx(2 * MU * CLAMP, rel=0.05)  # 116 / 124 N
        assert not np.any(p[~face_mask(cond)])  # the pin carries nothing while it slides
        assert np.sign(inc.force_n) == inc.side  # the pin engaged on the side pulled to
    sides = [r.increments[k - 1].side != r.increments[k].side for k in r.slides]
    assert sides == [False, True, True]


def test_the_loop_contains_the_crossing_rectangle(slid):
    """On the grips' path each slide is a horizontal segment of about 4Δr at ±F_slide."""
    r = slid.result
    F, d = r.machine_path()
    assert (F[0], d[0]) == (0.0, 0.0)  # starts centred: no zero-force traverse inserted
    assert len(F) == len(r.increments) + 1
    for k in r.slides[1:]:
        f0, f1 = F[k], F[k + 1]  # path point k is increment k − 1, the slide's start
        travel = abs(d[k + 1] - d[k])
        assert f1 == pytest.approx(f0, rel=1e-3)  # slip directions settle along the slide
        assert travel == pytest.approx(4 * CLEARANCE, rel=0.1)  # the arms' bend moves it
        inc = r.increments[k]
        rect = inc.friction_work + inc.normal_work  # the slide's friction work …
        rect += inc.elastic_energy - r.increments[k - 1].elastic_energy  # … and ΔE (tiny)
        assert rect == pytest.approx(0.5 * (f0 + f1) * (d[k + 1] - d[k]), rel=1e-9)
        assert inc.friction_work == pytest.approx(abs(f1) * travel, rel=1e-3)
    m = slid.metrics()
    assert m["delta_max_mm"] == pytest.approx(2 * CLEARANCE, rel=0.05)  # free play included
    rects = sum(r.increments[k].friction_work for k in r.slides[1:])
    assert rects > 0.9 * m["W_cycle_Nmm"]  # the rectangles dominate the loop's area


def test_energy_balance_closes_with_the_slides(slid):
    """Friction work at pin and face points, slides included, equals the loop area."""
    r, m = slid.result, slid.metrics()
    assert m["energy_balance_rel_err"] < 1e-8
    F, d = r.machine_path()
    sl = r.last_loop()
    area = float(np.sum(0.5 * (F[sl][1:] + F[sl][:-1]) * np.diff(d[sl])))
    assert area == pytest.approx(m["W_cycle_Nmm"], rel=1e-12)
    incs = r.increments[sl.start :]
    works = sum(i.friction_work + i.normal_work for i in incs)
    dE = incs[-1].elastic_energy - r.increments[sl.start - 1].elastic_energy
    assert abs(area - dE - works) <= 1e-8 * area


def test_clamp_zero_is_the_clearance_cycle_bit_for_bit(loose):
    system, configs = loose
    run_cycle(system, CLEARANCE, settings(400.0), configs=configs)  # the first run in a
    # process differs from the next ones in the last bits (5e-14 relative), with or without
    # effects: compare warm runs
    base = run_cycle(system, CLEARANCE, settings(400.0), configs=configs)
    off = run_cycle_with_effects(system, CLEARANCE, settings(400.0), _faces(0.0), configs=configs)
    assert off.result.slides == ()
    assert off.result.start_disp_mm == 0.0
    assert off.metrics()["eta"] == base.metrics()["eta"]
    assert [i.disp_mm for i in off.result.increments] == [i.disp_mm for i in base.increments]


def test_frictionless_faces_make_no_rectangle(loose, slid):
    system, configs = loose
    r = run_cycle_with_effects(
        system, CLEARANCE, settings(400.0, mu=0.0), _faces(), configs=configs
    ).result
    assert len(r.slides) == 3
    for k in r.slides:
        assert abs(r.increments[k].force_n) < 1e-9 * 400.0
        assert r.increments[k].friction_work == 0.0
    assert abs(r.metrics()["W_cycle_Nmm"]) < 1e-3 * slid.metrics()["W_cycle_Nmm"]


def test_below_the_slip_force_the_pin_is_never_touched(loose):
    """At 100 N < F_slide the faces hold the clevis centred: no crossing, the pin floats."""
    system, configs = loose
    r = run_cycle_with_effects(system, CLEARANCE, settings(100.0), _faces(), configs=configs)
    res = r.result
    assert res.slides == ()
    assert res.start_disp_mm == -2 * CLEARANCE
    cond = res.configs[1]
    for state in res.states:  # round-off only (the floating pin's minimum-norm position)
        assert np.abs(np.asarray(state.p)[~face_mask(cond)]).sum() < 1e-9 * 100.0
    m = r.metrics()
    assert m["delta_max_mm"] < 0.05 * CLEARANCE  # the faces' elastic travel only
    assert m["energy_balance_rel_err"] < 1e-8
    assert (
        m["eta"]
        > 10 * run_cycle(system, CLEARANCE, settings(100.0), configs=configs).metrics()["eta"]
    )


def test_stored_result_keeps_its_slides(slid, tmp_path):
    from model.store import ResultStore

    store = ResultStore(tmp_path)
    store.put("k", slid.result)
    back = store.get("k")
    assert back is not None
    assert back.slides == slid.result.slides
    assert back.start_disp_mm == slid.result.start_disp_mm
    m0 = slid.result.metrics()
    assert back.metrics().keys() == m0.keys()
    np.testing.assert_array_equal(list(back.metrics().values()), list(m0.values()))
    F, d = back.machine_path()
    F0, d0 = slid.result.machine_path()
    np.testing.assert_array_equal(F, F0)
    np.testing.assert_array_equal(d, d0)


def test_result_replace_keeps_the_sliding_fields(slid):
    r = dataclasses.replace(slid.result, increments=slid.result.increments)
    assert r.slides == slid.result.slides
    assert r.faces_slide


def test_held_clevis_keeps_the_pin_centred_inside_a_contact_window(loose):
    """With a contact window (the service's default) the far side of the holes is only
    checked at the peaks: the pin must stay centred while the faces hold the clevis, not
    float against it (that failed the window check)."""
    system, _ = loose
    windowed = configurations(system, CLEARANCE, 0.5)
    assert windowed[1].outside is not None
    r = run_cycle_with_effects(system, CLEARANCE, settings(100.0), _faces(), configs=windowed)
    assert r.result.slides == ()
    for state in r.result.states:
        assert float(state.alpha[0]) == -CLEARANCE  # centred: −Δr from the tension position


def test_loop_files_of_a_sliding_cycle(slid, tmp_path):
    """The loop CSV with the free play is the grips' path; the figure is drawn on it."""
    from fe.cycle.loop_files import write_loop_csv, write_loop_png

    csv_path = write_loop_csv(slid.result, tmp_path / "loop.csv", with_free_play=True)
    rows = csv_path.read_text().splitlines()
    assert len(rows) == len(slid.result.increments) + 2  # header and the origin
    assert write_loop_png(slid.result, tmp_path / "loop.png").stat().st_size > 0
