"""Angular-contact bearing and preloaded pair (fe.bearing.pair) against the classical relations.

References: Jones' equation and the geometry of the groove centres (Harris & Kotzalas,
*Rolling Bearing Analysis*, 2007, §7.3); the preloaded-pair diagram. Lift-off of two
identical Hertzian bearings: with F = c δ^{3/2}, the unloaded bearing reaches zero
approach when the inner rings have moved x = δ_p, so the loaded one is at 2 δ_p and
carries c (2 δ_p)^{3/2} = 2^{3/2} F_p, all of it external: F_lift = 2^{3/2} F_p ≈ 2.83 F_p.
For the 708C (α0 = 15°, BD = 0.2 mm) the contact angle changes by 2–4° under 50–200 N,
F(δ_a) is stiffer than δ^{3/2}, and the ratio is 3.4–4.0; it tends to 2^{3/2} as F_p → 0.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from cad.bearing_geometry import BearingHingeParams
from cad.errors import ParameterError
from fe.bearing.hertz import Race, contact_ellipse, race_curvatures
from fe.bearing.pair import (
    BallBearing,
    axial_state_from_deflection,
    axial_state_from_load,
    bearing_from_params,
    contact_constants,
    liftoff_load,
    pair_axial,
)

B708 = bearing_from_params(BearingHingeParams())
B40 = dataclasses.replace(B708, contact_angle_deg=40.0)


def test_bearing_from_params_copies_the_hinge_bearing():
    p = BearingHingeParams()
    b = bearing_from_params(p)
    assert (b.ball_diameter_mm, b.pitch_diameter_mm, b.ball_count) == (3.969, 15.0, 10)
    assert (b.inner_curvature_ratio, b.outer_curvature_ratio) == (0.52, 0.53)
    assert (b.young_mpa, b.poisson, b.contact_angle_deg) == (208_000.0, 0.3, 15.0)
    assert b.groove_distance_mm == pytest.approx(0.05 * 3.969, rel=1e-14)


def test_ball_constant_is_the_two_hertz_contacts_in_series():
    q = 80.0
    approach = 0.0
    for race, f in ((Race.INNER, 0.52), (Race.OUTER, 0.53)):
        curv = race_curvatures(3.969, 15.0, 15.0, f, race)
        approach += contact_ellipse(curv, B708.effective_modulus_mpa, q).approach_mm
    assert (q / contact_constants(B708).ball) ** (2 / 3) == pytest.approx(approach, rel=1e-13)


@pytest.mark.parametrize("fa", [1.0, 100.0, 400.0])
@pytest.mark.parametrize("b", [B708, B40], ids=["15deg", "40deg"])
def test_axial_state_satisfies_jones_equation_and_the_geometry(b, fa):
    s = axial_state_from_load(b, fa)
    a, a0 = math.radians(s.contact_angle_deg), b.free_angle_rad
    bd, k_n = b.groove_distance_mm, contact_constants(b).ball
    rhs = b.ball_count * k_n * bd**1.5 * math.sin(a) * (math.cos(a0) / math.cos(a) - 1) ** 1.5
    assert rhs == pytest.approx(fa, rel=1e-12)
    assert s.axial_deflection_mm == pytest.approx(bd * math.sin(a - a0) / math.cos(a), rel=1e-12)
    assert s.ball_load_n * b.ball_count * math.sin(a) == pytest.approx(fa, rel=1e-12)
    assert s.normal_approach_mm == pytest.approx((s.ball_load_n / k_n) ** (2 / 3), rel=1e-12)


@pytest.mark.parametrize("b", [B708, B40], ids=["15deg", "40deg"])
def test_axial_deflection_tends_to_the_two_thirds_power_law(b):
    a0 = b.free_angle_rad
    k_n = contact_constants(b).ball
    for fa in (1e-6, 1e-4):
        limit = (fa / (b.ball_count * k_n * math.sin(a0))) ** (2 / 3) / math.sin(a0)
        got = axial_state_from_load(b, fa).axial_deflection_mm
        assert got == pytest.approx(limit, rel=2e-3 if fa > 1e-5 else 1e-4)
    ratio = axial_state_from_load(b, 8e-4).axial_deflection_mm
    ratio /= axial_state_from_load(b, 1e-4).axial_deflection_mm
    assert ratio == pytest.approx(4.0, rel=2e-3)


def test_stiffness_is_the_derivative_of_the_axial_load():
    for delta in (0.002, 0.01, 0.03):
        h = 1e-7
        fd = axial_state_from_deflection(B708, delta + h).axial_load_n
        fd = (fd - axial_state_from_deflection(B708, delta - h).axial_load_n) / (2 * h)
        assert axial_state_from_deflection(B708, delta).stiffness_n_per_mm == pytest.approx(
            fd, rel=1e-7
        )


@pytest.mark.parametrize("fp", [0.0, 50.0, 100.0, 200.0])
def test_pair_without_external_load_has_both_bearings_at_the_preload(fp):
    s = pair_axial(B708, fp, 0.0)
    assert s.loaded.axial_load_n == pytest.approx(fp, rel=1e-12, abs=1e-12)
    assert s.unloaded.axial_load_n == pytest.approx(fp, rel=1e-12, abs=1e-12)
    assert s.displacement_mm == 0.0
    single = axial_state_from_load(B708, fp).stiffness_n_per_mm
    assert s.stiffness_n_per_mm == pytest.approx(2 * single, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("fa", [10.0, 150.0, 600.0])
def test_pair_bearings_share_the_external_load(fa):
    s = pair_axial(B708, 100.0, fa)
    assert s.loaded.axial_load_n - s.unloaded.axial_load_n == pytest.approx(fa, abs=1e-9)
    dp = axial_state_from_load(B708, 100.0).axial_deflection_mm
    assert s.loaded.axial_deflection_mm == pytest.approx(dp + s.displacement_mm, rel=1e-14)
    assert s.unloaded.axial_deflection_mm == pytest.approx(dp - s.displacement_mm, rel=1e-12)


def test_liftoff_tends_to_two_to_the_three_halves_of_the_preload():
    for b in (B708, B40):
        assert liftoff_load(b, 1e-6) / 1e-6 == pytest.approx(2**1.5, rel=1e-3)
    # With the change of contact angle the ratio grows with F_p, faster at small α0.
    r708 = [liftoff_load(B708, fp) / fp for fp in (50.0, 100.0, 200.0)]
    r40 = [liftoff_load(B40, fp) / fp for fp in (50.0, 100.0, 200.0)]
    assert 2**1.5 < r40[0] < r40[1] < r40[2] < r708[0] < r708[1] < r708[2]


def test_liftoff_is_where_the_pair_unloads_one_bearing():
    f_lift = liftoff_load(B708, 100.0)
    below, above = pair_axial(B708, 100.0, 0.999 * f_lift), pair_axial(B708, 100.0, 1.001 * f_lift)
    assert not below.lifted_off
    assert above.lifted_off
    assert above.unloaded.axial_load_n == 0.0
    assert above.loaded.axial_load_n == pytest.approx(1.001 * f_lift, rel=1e-12)
    dp = axial_state_from_load(B708, 100.0).axial_deflection_mm
    assert pair_axial(B708, 100.0, f_lift).displacement_mm == pytest.approx(dp, rel=1e-9)


@pytest.mark.parametrize(
    ("field", "value"),
    [("ball_count", True), ("inner_curvature_ratio", 0.5), ("contact_angle_deg", 50.0)],
    ids=["bool-count", "f_i=0.5", "alpha=50"],
)
def test_bad_bearing_parameters_name_themselves(field, value):
    with pytest.raises(ParameterError, match=field):
        dataclasses.replace(B708, **{field: value})


def test_negative_loads_are_refused():
    with pytest.raises(ParameterError, match="preload_n"):
        pair_axial(B708, -1.0, 0.0)
    with pytest.raises(ParameterError, match="axial_load_n"):
        axial_state_from_load(B708, -5.0)
    assert isinstance(B708, BallBearing)
