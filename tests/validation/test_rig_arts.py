"""The ARTS-Lab friction-damper records (../shared/realdata/arts-brfd) through the example mapping.

The data are CC BY-SA and not in the repository: the tests read them where they lie
(``HINGELAB_ARTS_DIR`` overrides the place) and skip when they are absent. Expected values
come from the data set's README (nominal amplitudes 0.5, 1, 1.5 in; the 1.5 in tests reached
about 36.7 mm; tensions 0, 30, 36 lb), from the raw JSON integrated here with the README's
conversion constants, and from issue 34's yardstick (straight line of energy per cycle
against amplitude per tension: about 23 % RMS leave-one-amplitude-out error).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from validation.measurements import MeasurementSet
from validation.rig_import import import_records
from validation.rig_mapping import Control, read_mapping
from validation.rig_yardstick import energy_yardstick

ROOT = Path(__file__).resolve().parents[2]
ARTS = Path(os.environ.get("HINGELAB_ARTS_DIR", ROOT.parent / "shared" / "realdata" / "arts-brfd"))
MAPPING = ROOT / "studies" / "examples" / "rig_arts_brfd.toml"
KIP_N, IN_MM = 4448.2216, 25.4  # the data set's README

pytestmark = pytest.mark.skipif(
    not (ARTS / "1Hz30lbtension1amplitude.json").is_file(),
    reason=f"the ARTS data set is not at {ARTS} (set HINGELAB_ARTS_DIR to its folder)",
)


@pytest.fixture(scope="module")
def arts(tmp_path_factory: pytest.TempPathFactory) -> tuple[MeasurementSet, list]:
    out = tmp_path_factory.mktemp("arts") / "measurements"
    return import_records(read_mapping(MAPPING), [ARTS], out)


def test_the_1hz_grid_imports_as_three_steady_cycles_per_record(arts) -> None:
    mset, done = arts
    assert len(done) == 9
    assert len(mset.cases) == 27
    assert all(len(r.case_ids) == 3 for r in done)
    assert len(mset.replicate_groups()) == 9
    grid = sorted(
        {(c.conditions["band_tension_N"], c.conditions["nominal_amplitude_mm"]) for c in mset.cases}
    )
    expected = [(t * 4.4482216152605, a * IN_MM) for t in (0, 30, 36) for a in (0.5, 1, 1.5)]
    assert np.array(grid) == pytest.approx(np.array(expected), rel=1e-9)
    assert {c.conditions["frequency_Hz"] for c in mset.cases} == {1.0}
    assert all(c.control is Control.DISPLACEMENT for c in mset.cases)


def test_measured_amplitudes_are_the_readme_s(arts) -> None:
    mset, _ = arts
    for c in mset.cases:
        nominal = c.conditions["nominal_amplitude_mm"]
        expected = 36.7 if nominal > 30 else nominal  # the 1.5 in tests fell short (README)
        assert c.amplitude_mm == pytest.approx(expected, rel=0.015), c.case_id  # 12.83, 25.6, 36.5


def test_each_cycle_s_energy_is_the_raw_record_s_integral(arts) -> None:
    """The loop file of a cycle holds the same ∮F dδ as the raw JSON over the same rows."""
    _, done = arts
    for r in done[:3]:
        raw = np.array(json.loads(r.record.path.read_text(encoding="utf-8"))["data"])
        F, x = raw[:, 2] * KIP_N, raw[:, 1] * IN_MM
        for k in np.flatnonzero(r.split.steady):
            i, j = r.split.bounds[k]
            Fc, xc = np.append(F[i : j + 1], F[i]), np.append(x[i : j + 1], x[i])
            w_raw = float(np.sum(0.5 * (Fc[1:] + Fc[:-1]) * np.diff(xc)))
            assert r.energies_nmm[k] == pytest.approx(w_raw, rel=1e-6)


def test_the_straight_line_yardstick_is_the_issue_s(arts) -> None:
    mset, _ = arts
    y = energy_yardstick(mset, "band_tension_N", "nominal_amplitude_mm")
    assert len(y.rows) == 9
    assert y.rms_error == pytest.approx(0.23, abs=0.02)  # issue 34: "about 23 % RMS"
    at_half_inch = {r.record.group: r.error for r in y.rows if r.record.x < 13}
    # the line overestimates the smallest amplitude at 30 and 36 lb by ~40 % (issue: +46 %)
    assert all(0.3 < at_half_inch[t] < 0.5 for t in at_half_inch if t > 0)
    # the steady cycles of one record agree within 2.5 % (the issue's ±10 % at 1.5 in
    # needs the 97 % ramp cycle counted as steady; see docs/arts_brfd.md)
    assert y.max_scatter < 0.025
