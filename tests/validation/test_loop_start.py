"""A record cut mid-cycle: its loading start is found inside it, its zero is not its first force.

The records come from an independent generator: a Jenkins element (spring k1 in series with a
Coulomb slider of strength Fs) beside a spring k2, driven in force 0 → +Fg → −Fg → +Fg → −Fg
→ +Fg, sampled with white noise on both channels, then cut at several phases of the loop.
"""

from __future__ import annotations

import numpy as np
import pytest

from cad.errors import DataError
from validation.loop_files import Loop
from validation.loops import loading_start, process_loop
from validation.measurements import check_amplitude, read_measurement_set

FG = 400.0  # N
K1, K2, FS = 50e3, 20e3, 150.0  # N/mm, N/mm, N: slips beyond |q| = Fs, so W > 0
N_SEG = 200  # samples from 0 to +Fg
N_DWELL = 30  # samples at rest before loading
SIGMA_F, SIGMA_D = 0.4, 2e-5  # N, mm


def jenkins_displacement(force: np.ndarray) -> np.ndarray:
    """δ(F) of the Jenkins element beside a spring, integrated along the force path [mm]."""
    slider, out = 0.0, np.empty_like(force)
    for i, f in enumerate(force):
        x = (f + K1 * slider) / (K1 + K2)  # stick
        q = K1 * (x - slider)
        if abs(q) > FS:  # slip: the Jenkins branch carries ±Fs
            q = np.sign(q) * FS
            x = (f - q) / K2
            slider = x - q / K1
        out[i] = x
    return out


def clean_record() -> tuple[np.ndarray, np.ndarray]:
    """Dwell at zero, then 0 → +Fg → −Fg → +Fg → −Fg → +Fg (two full loops), no noise."""
    up = np.linspace(0.0, FG, N_SEG + 1)
    down = np.linspace(FG, -FG, 2 * N_SEG + 1)[1:]
    back = np.linspace(-FG, FG, 2 * N_SEG + 1)[1:]
    F = np.concatenate([np.zeros(N_DWELL), up, down, back, down, back])
    return F, jenkins_displacement(F)


def noisy_record(seed: int = 7) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(noisy F [N], noisy δ [mm], clean F [N]), the same noise for every cut."""
    F, d = clean_record()
    rng = np.random.default_rng(seed)
    return F + rng.normal(0.0, SIGMA_F, F.size), d + rng.normal(0.0, SIGMA_D, F.size), F


def cut_index(clean_f: np.ndarray, segment: int, force: float) -> int:
    """First sample of half-cycle ``segment`` (0: the virgin loading, 1: first +Fg → −Fg, ...)
    at which the clean force passes ``force`` (in the segment's direction)."""
    starts = [N_DWELL, N_DWELL + N_SEG + 1] + [
        N_DWELL + N_SEG + 1 + 2 * N_SEG * k for k in (1, 2, 3)
    ]
    lo, hi = starts[segment], starts[segment + 1] if segment + 1 < len(starts) else clean_f.size
    seg = clean_f[lo:hi]
    rising = segment % 2 == 0
    hit = np.flatnonzero(seg >= force) if rising else np.flatnonzero(seg <= force)
    return lo + int(hit[0])


# the phases a record can start at: (half-cycle, force where it is cut)
PHASES = {
    "-19N-rising": (2, -19.0),  # the issue's record: on the way up from −Fg
    "-19N-falling": (1, -19.0),
    "+300N-falling": (1, 300.0),
    "at-the-trough": (1, -FG),
    "-150N-rising": (2, -150.0),
    "+100N-virgin": (0, 100.0),  # past the start of the loading: a cycle later is used
}


@pytest.fixture(scope="module")
def full():
    F, d, clean = noisy_record()
    return F, d, clean, process_loop(F, d, "full")


def test_the_generator_gives_a_dissipative_loop_that_starts_at_its_centre(full):
    _, _, clean, p = full
    assert p.metrics.W_cycle_Nmm > 0.1  # slip on both sides: a real loop, not a line
    assert not p.mid_cycle
    assert p.force_offset_n == pytest.approx(0.0, abs=3 * SIGMA_F)
    x = jenkins_displacement(clean)
    # a symmetric element: its loops are centred on its unloaded position
    assert 0.5 * (x.max() + x.min()) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("phase", list(PHASES), ids=list(PHASES))
def test_a_record_cut_mid_cycle_measures_like_the_whole_record(full, phase):
    F, d, clean, ref = full
    i = cut_index(clean, *PHASES[phase])
    cut = process_loop(F[i:], d[i:], phase)
    assert cut.mid_cycle
    # its first force is not an offset: the zero is the midpoint of its peaks
    assert abs(F[i] - cut.force_offset_n) > 10.0 or phase == "-19N-rising"
    assert cut.force_offset_n == pytest.approx(0.0, abs=3 * SIGMA_F)
    # the last loop is the same samples: its metrics do not depend on offsets
    for name in ("W_cycle_Nmm", "eta", "f_max_n", "delta_max_mm", "closure_mm"):
        assert getattr(cut.metrics, name) == pytest.approx(
            getattr(ref.metrics, name), rel=1e-9, abs=1e-15
        ), name
    # δ(+Fg) is measured from the centre of the first full cycle, where the element started
    assert cut.metrics.disp_at_peak_mm == pytest.approx(
        ref.metrics.disp_at_peak_mm, abs=4 * SIGMA_D
    )
    # the protocol starts at an upward zero crossing
    s = cut.stages.start
    assert cut.force_n[s] <= 0.0 < np.max(cut.force_n[s + 1 : s + 20])
    check_amplitude(Loop(F[i:], d[i:], None, phase), FG, phase)  # reaches ±400 N: not refused


def test_the_issue_record_at_minus_19_n_is_read_from_a_measurement_folder(full, tmp_path):
    F, d, clean, _ = full
    i = cut_index(clean, *PHASES["-19N-rising"])
    assert F[i] == pytest.approx(-19.0, abs=3 * SIGMA_F)
    np.savetxt(
        tmp_path / "c1.csv", np.column_stack([F[i:], d[i:]]), delimiter=",",
        header="force_N,displacement_mm", comments="", fmt="%.9g",
    )  # fmt: skip
    (tmp_path / "cases.csv").write_text(
        "case_id,hinge,clearance_mm,amplitude_N,loop_file\nc1,general,0,400,c1.csv\n"
    )
    (case,) = read_measurement_set(tmp_path).cases
    assert case.loop is not None
    assert loading_start(case.loop.force_n, case.loop.displacement_mm).force_offset_n == (
        pytest.approx(0.0, abs=3 * SIGMA_F)
    )


def test_a_real_offset_at_rest_is_still_removed(full):
    F, d, _, ref = full
    shifted = process_loop(F + 19.0, d - 0.01, "offset")
    assert not shifted.mid_cycle
    assert shifted.force_offset_n == pytest.approx(19.0, abs=3 * SIGMA_F)
    assert shifted.metrics.disp_at_peak_mm == pytest.approx(ref.metrics.disp_at_peak_mm, rel=1e-12)
    check_amplitude(Loop(F + 19.0, d, None, "offset"), FG, "offset")


def test_a_record_cut_mid_cycle_with_a_real_offset_is_measured_from_its_peaks(full):
    F, d, clean, _ = full
    i = cut_index(clean, *PHASES["-19N-rising"])
    cut = process_loop(F[i:] + 12.0, d[i:], "cut+offset")
    assert cut.mid_cycle
    assert cut.force_offset_n == pytest.approx(12.0, abs=3 * SIGMA_F)
    check_amplitude(Loop(F[i:] + 12.0, d[i:], None, "cut+offset"), FG, "cut+offset")


def test_a_record_cut_mid_cycle_that_never_reaches_the_amplitude_is_refused(full):
    F, d, clean, _ = full
    i = cut_index(clean, *PHASES["-19N-rising"])
    small = Loop(0.75 * F[i:], d[i:], None, "small")  # spans ±300 N, stated ±400 N
    with pytest.raises(
        DataError,
        match=r"small: the loop never reaches the stated amplitude ±400 N within 2%: its force "
        r"spans \[-30\d(\.\d+)?, 30\d(\.\d+)?\] N \(the record starts mid-cycle at -1\d\.\d+ N; "
        r"its zero is the midpoint of its peaks",
    ):
        check_amplitude(small, FG, "small")


def test_a_record_at_rest_that_never_reaches_the_amplitude_is_refused(full):
    F, d, _, _ = full
    with pytest.raises(
        DataError, match=r"never reaches .* spans \[-30\d.*\(offset -?0\.\d+ N removed\)"
    ):
        check_amplitude(Loop(0.75 * F, d, None, "small"), FG, "small")


def test_a_record_cut_without_a_full_loop_after_its_zero_crossing_is_refused(full):
    F, d, clean, _ = full
    i = cut_index(clean, 3, 300.0)  # +300 N → −Fg → +Fg: after its zero crossing, + only
    with pytest.raises(
        DataError,
        match=r"late: expected the load sequence .* found \+ \(the record starts mid-cycle",
    ):
        process_loop(F[i:], d[i:], "late")


@pytest.mark.parametrize(
    "force",
    [
        np.concatenate([np.linspace(0, FG, 50), np.linspace(FG, 0, 50), np.linspace(0, FG, 50)]),
        -np.concatenate(
            [np.linspace(0, FG, 50), np.linspace(FG, -FG, 99), np.linspace(-FG, FG, 99)]
        ),
    ],
    ids=["tension-only", "compression-first-at-rest"],
)
def test_records_that_are_not_the_protocol_are_still_refused(force):
    with pytest.raises(DataError, match="expected the load sequence") as err:
        process_loop(force, force / 7e4, "odd")
    assert "mid-cycle" not in str(err.value)
