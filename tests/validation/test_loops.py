"""Loop processing against loops whose area is known exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cad.errors import DataError
from validation.loop_metrics import loop_area
from validation.loops import loop_distance, process_loop, split_stages

FG, D, PHI = 300.0, 0.004, 0.1  # N, mm, rad: η = tan φ


def ellipse_record(n_loop: int, *, fg=FG, d=D, phi=PHI, n_load=None, cycles=1):
    """0 → +Fg (straight) then the ellipse F = Fg sin θ, δ = D sin(θ − φ) for θ ∈ [π/2, π/2 + 2π·cycles].

    ``n_loop`` samples per closed loop (a multiple of 4 puts samples on both peaks).
    """
    peak_d = d * math.sin(math.pi / 2 - phi)
    n_load = n_load or max(2, n_loop // 4)
    s = np.linspace(0.0, 1.0, n_load + 1)
    theta = math.pi / 2 + np.linspace(0, 2 * math.pi * cycles, n_loop * cycles + 1)[1:]
    F = np.concatenate([fg * s, fg * np.sin(theta)])
    x = np.concatenate([peak_d * s, d * np.sin(theta - phi)])
    return F, x


def ellipse_area_exact(n_loop):
    """Area of the polygon inscribed at n equal parameter steps: π Fg D sin φ · sinc."""
    h = 2 * math.pi / n_loop
    return math.pi * FG * D * math.sin(PHI) * math.sin(h) / h


def bilinear_record(fg=300.0, fy=120.0, k1=80e3, k2=30e3, n=61):
    """Bilinear Masing loop under force control, sampled with the kinks as samples."""

    def backbone(F):
        a = np.abs(F)
        return np.sign(F) * np.where(a <= fy, a / k1, fy / k1 + (a - fy) / k2)

    F1 = np.linspace(0, fg, n)
    F2 = np.linspace(fg, -fg, 2 * n - 1)[1:]
    F3 = np.linspace(-fg, fg, 2 * n - 1)[1:]
    d1 = backbone(F1)
    d2 = d1[-1] + 2 * backbone((F2 - fg) / 2)
    d3 = d2[-1] + 2 * backbone((F3 + fg) / 2)
    W = 4 * fy * (fg - fy) * (1 / k2 - 1 / k1)
    return np.concatenate([F1, F2, F3]), np.concatenate([d1, d2, d3]), W


@pytest.mark.parametrize("n_loop", [8, 12, 40, 10_000], ids=lambda n: f"{n}-samples")
def test_ellipse_area_and_eta_exact_for_any_sampling(n_loop):
    F, x = ellipse_record(n_loop)
    m = process_loop(F, x, "ellipse").metrics
    W = ellipse_area_exact(n_loop)
    assert m.W_cycle_Nmm == pytest.approx(W, rel=1e-10)
    assert m.delta_max_mm == pytest.approx(D * math.cos(PHI), rel=1e-12)
    assert m.U_max_Nmm == pytest.approx(0.5 * FG * D * math.cos(PHI), rel=1e-12)
    assert m.eta == pytest.approx(W / (math.pi * FG * D * math.cos(PHI)), rel=1e-10)
    assert m.secant_stiffness_N_per_mm == pytest.approx(FG / (D * math.cos(PHI)))
    assert m.f_max_n == pytest.approx(FG)
    assert m.closure_mm == pytest.approx(0.0, abs=1e-15)


def test_sparse_and_dense_sampling_agree_within_discretisation_error():
    coarse = process_loop(*ellipse_record(12), "coarse").metrics
    fine = process_loop(*ellipse_record(10_000), "fine").metrics
    assert fine.eta == pytest.approx(math.tan(PHI), rel=1e-6)
    h = 2 * math.pi / 12
    # the chord error of the inscribed polygon, 1 − sinc(h) ≈ h²/6, and nothing else
    assert coarse.W_cycle_Nmm / fine.W_cycle_Nmm == pytest.approx(math.sin(h) / h, rel=1e-6)


def test_bilinear_masing_loop_area_exact():
    F, x, W = bilinear_record()
    m = process_loop(F, x, "bilinear").metrics
    assert m.W_cycle_Nmm == pytest.approx(W, rel=1e-12)
    assert m.disp_at_peak_mm == pytest.approx(x[60])
    assert m.eta == pytest.approx(W / (2 * math.pi * 0.5 * 300.0 * x[60]), rel=1e-12)


def test_offsets_removed_from_initial_zero():
    F, x = ellipse_record(400)
    F0 = np.concatenate([np.zeros(20), F])
    x0 = np.concatenate([np.zeros(20), x])
    ref = process_loop(F0, x0, "clean")
    shifted = process_loop(F0 + 2.5, x0 - 0.03, "shifted")
    assert shifted.force_offset_n == pytest.approx(2.5)
    assert shifted.displacement_offset_mm == pytest.approx(-0.03)
    for name, value in ref.metrics.as_dict().items():
        assert getattr(shifted.metrics, name) == pytest.approx(value, rel=1e-9, abs=1e-12), name


def test_noise_and_offsets_leave_w_and_eta_within_a_percent():
    rng = np.random.default_rng(3)
    F, x = ellipse_record(4000)
    n = F.size + 50
    F = np.concatenate([np.zeros(50), F]) + 1.0 + rng.normal(0, 0.003 * FG, n)
    x = np.concatenate([np.zeros(50), x]) + 0.01 + rng.normal(0, 0.003 * D, n)
    m = process_loop(F, x, "noisy").metrics
    assert m.W_cycle_Nmm == pytest.approx(math.pi * FG * D * math.sin(PHI), rel=0.01)
    assert m.eta == pytest.approx(math.tan(PHI), rel=0.03)
    assert m.disp_at_peak_mm == pytest.approx(D * math.cos(PHI), rel=0.03)


def test_unclosed_loop_closed_by_chord_is_offset_independent():
    F, x = ellipse_record(200)
    x = x + np.linspace(0, 2e-4, x.size)  # creep: the loop does not close
    a = process_loop(F, x, "creep").metrics
    b = process_loop(F + 5.0, x + 1.0, "creep+offsets").metrics
    assert a.closure_mm > 1e-4
    assert b.W_cycle_Nmm == pytest.approx(a.W_cycle_Nmm, rel=1e-9)
    # the chord closes it: the area of the polygon, by the shoelace formula
    sl = slice(50, 251)
    xs, ys = x[sl], F[sl]
    shoelace = 0.5 * (np.dot(ys, np.roll(xs, -1)) - np.dot(xs, np.roll(ys, -1)))
    assert a.W_cycle_Nmm == pytest.approx(shoelace, rel=1e-12)


def test_last_of_several_cycles_is_measured():
    F, x = ellipse_record(40, cycles=3)
    s = split_stages(F, "three cycles")
    assert s.n_cycles == 3
    assert s.peak_last == F.size - 1
    assert process_loop(F, x, "3").metrics.W_cycle_Nmm == pytest.approx(ellipse_area_exact(40))


def test_record_without_the_load_sequence_is_refused():
    F, x = ellipse_record(40)
    with pytest.raises(DataError, match=r"half\.csv: expected the load sequence .* found \+, −"):
        process_loop(F[:30], x[:30], "half.csv")
    with pytest.raises(DataError, match="row 3, column displacement_mm"):
        process_loop(F, np.where(np.arange(x.size) == 2, np.nan, x), "nan.csv")


def test_loop_area_independent_of_offsets_and_direction_sign():
    F, x = ellipse_record(40)
    sl = slice(10, 51)
    assert loop_area(F[sl] + 3, x[sl] - 1) == pytest.approx(loop_area(F[sl], x[sl]), rel=1e-9)
    assert loop_area(F[sl][::-1], x[sl][::-1]) == pytest.approx(-loop_area(F[sl], x[sl]))


def test_loop_distance_zero_for_shift_and_linear_in_scale():
    F, x = ellipse_record(400)
    a = process_loop(F, x, "a")
    assert loop_distance(a, process_loop(F, x + 0.05 * (np.arange(x.size) > 0), "b")) < 1e-12
    d1 = loop_distance(a, process_loop(F, 1.05 * x, "x1.05"))
    d2 = loop_distance(a, process_loop(F, 1.10 * x, "x1.10"))
    assert d1 > 0
    assert d2 == pytest.approx(2 * d1, rel=1e-9)


def test_inputs_not_modified():
    F, x = ellipse_record(40)
    F0, x0 = F.copy(), x.copy()
    process_loop(F, x, "keep")
    np.testing.assert_array_equal(F, F0)
    np.testing.assert_array_equal(x, x0)


def test_reversed_displacement_sign_is_refused_by_name():
    F, d = ellipse_record(200)
    process_loop(F, d, "ok")  # the right way round
    with pytest.raises(
        DataError, match=r"reversed\.csv: the displacement falls .* flip the displacement"
    ):
        process_loop(F, -d, "reversed.csv")


def test_a_cycle_loop_csv_reads_back_as_a_measurement(tmp_path):
    """`hingelab cycle` writes loop.csv with stage/increment/side columns: it reads as a loop."""
    from validation.loop_files import read_loop_file

    F, d = ellipse_record(40)
    lines = ["force_N,displacement_mm,stage,increment,side"]
    lines += [f"{f:.9g},{x:.9g},0,{k},1" for k, (f, x) in enumerate(zip(F, d, strict=True))]
    (tmp_path / "loop.csv").write_text("\n".join(lines) + "\n")
    loop = read_loop_file(tmp_path / "loop.csv")
    np.testing.assert_allclose(loop.force_n, F, rtol=1e-8)
    assert process_loop(loop.force_n, loop.displacement_mm, "model").metrics.eta == pytest.approx(
        process_loop(F, d, "x").metrics.eta, rel=1e-6
    )
    (tmp_path / "bad.csv").write_text("force_N,displacement_mm,colour\n" + "1,2,red\n" * 5)
    with pytest.raises(DataError, match=r"unexpected column\(s\) \['colour'\]"):
        read_loop_file(tmp_path / "bad.csv")


def test_a_loop_running_the_wrong_way_is_refused():
    F, d = ellipse_record(200, phi=-PHI)  # displacement leads the force: W < 0
    with pytest.raises(DataError, match=r"runs the wrong way round"):
        process_loop(F, d, "lead.csv")


def _free_play_record(n_per_stage, a=0.2, fg=300.0, k=1e5, crossing=0, noise=0.0, seed=0):
    """0 → +Fg → −Fg → +Fg of a hinge with free play ±a crossed at F = 0 (``crossing`` samples).

    Bilinear branches (δ = ±a + F/k ± a little friction lag) so the loop has some area.
    """
    rng = np.random.default_rng(seed)

    def stage(f0, f1):
        f = np.linspace(f0, f1, n_per_stage + 1)[1:]
        lag = 0.02 * a * np.sign(f0 - f1)  # descending branches sit a little to the right
        return f, np.sign(f0 + f1) * a + f / k + lag * (1 - np.abs(f) / fg)

    parts = [(np.array([0.0, 0.0]), np.array([0.0, a]))]
    parts.append(stage(0.0, fg))
    for f0, f1 in ((fg, 0.0), (0.0, -fg), (-fg, 0.0), (0.0, fg)):
        parts.append(stage(f0, f1))
        if f1 == 0.0:  # cross the free play at zero force
            side = -1.0 if f0 > 0 else 1.0
            x = np.linspace(-side * a, side * a, crossing + 2)[1:]
            parts.append((np.zeros_like(x), x))
    F = np.concatenate([p[0] for p in parts])
    d = np.concatenate([p[1] for p in parts])
    return F + rng.normal(0, noise, F.size), d


def test_loop_distance_ignores_the_free_play_crossing():
    """A coarse model path (the crossing two points at F = 0) against a dense, noisy record of
    the same hinge: the branches are compared on their own side of the crossing."""
    coarse = process_loop(*_free_play_record(6), "model")
    dense = process_loop(*_free_play_record(300, crossing=400, noise=0.2), "record")
    assert loop_distance(dense, coarse) < 0.01 * dense.metrics.delta_max_mm


def test_a_noisy_weakly_dissipative_loop_is_not_refused():
    """Noise alone can make W < 0 when the loop is thin: that is data, not a reversed channel."""
    F, d = ellipse_record(600, phi=0.002)
    rng = np.random.default_rng(0)
    noisy = process_loop(F + rng.normal(0, 1.5, F.size), d + rng.normal(0, 2e-4, d.size), "thin")
    assert noisy.metrics.eta < -0.002  # this seed's noise makes it clockwise: judged, not refused
