"""Importing rig records (validation.rig_records, rig_cycles, rig_import) on synthetic records.

The synthetic rig drives x = a(t)·sin(2πft) with a(t) ramping linearly from 0 to A, holding
A for exactly N periods between two displacement peaks, and ramping back to 0. Its force is
a spring and a dashpot, F = k x + c ẋ, so every steady cycle dissipates W = π c ω A²
(an independent closed form). The file stores time in ms, the displacement in inches with
the opposite sign (undone by ``flip``) and the force in kip, its unit in the metadata.
"""

from __future__ import annotations

import copy
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cad.errors import DataError
from studies.cli.main import main
from validation.measurements import read_measurement_set
from validation.rig_cycles import split_cycles
from validation.rig_import import import_records
from validation.rig_mapping import Control, parse_mapping
from validation.rig_records import read_record

KIP_N = 4448.2216152605
IN_MM = 25.4
K_N_PER_MM = 40.0
C_NS_PER_MM = 6.0
FREQ_HZ = 1.0
RATE_HZ = 512.0

MAPPING: dict[str, Any] = {
    "source": {"format": "json", "rows": "data", "control": "displacement", "hinge": "general"},
    "columns": {
        "time": {"index": 0, "unit": "ms"},
        "displacement": {"index": 2, "unit": "in", "flip": True},
        "force": {"index": 1, "unit_key": "force units"},
    },
    "name": {"pattern": r"T(?P<tension>[\d.]+)lb_A(?P<amp>[\d.]+)in"},
    "design": {
        "tension": {"unit": "lbf", "to": "N"},
        "nominal_amplitude": {"group": "amp", "unit": "in", "to": "mm"},
    },
    "constants": {"clearance_mm": 0.0},
}


def _envelope(
    t: np.ndarray, amp: float, n_steady: int, ramp_in: float, ramp_out: float
) -> np.ndarray:
    t_a = ramp_in  # ends at a displacement peak (ramp_in = k + 0.25 periods)
    t_b = t_a + n_steady / FREQ_HZ
    return amp * np.clip(np.minimum(t / t_a, (t_b + ramp_out - t) / ramp_out), 0.0, 1.0)


def synthetic(
    amp_mm: float = 20.0,
    n_steady: int = 3,
    noise: float = 0.002,
    seed: int = 0,
    ramp_in: float = 2.25,
    ramp_out: float = 2.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t [s], x [mm], F [N]) of the synthetic rig; noise is relative to A and to k·A."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, ramp_in + n_steady / FREQ_HZ + ramp_out + 0.5, 1.0 / RATE_HZ)
    w = 2 * math.pi * FREQ_HZ
    a = _envelope(t, amp_mm, n_steady, ramp_in, ramp_out)
    x = a * np.sin(w * t)
    v = np.gradient(x, t)
    F = K_N_PER_MM * x + C_NS_PER_MM * v
    x = x + noise * amp_mm * rng.standard_normal(t.size)
    F = F + noise * K_N_PER_MM * amp_mm * rng.standard_normal(t.size)
    return t, x, F


def write_json(path: Path, t: np.ndarray, x: np.ndarray, F: np.ndarray, **meta: Any) -> Path:
    rows = np.column_stack([t * 1e3, F / KIP_N, -x / IN_MM]).tolist()  # ms, kip, −in
    path.write_text(json.dumps({"force units": "kip", **meta, "data": rows}), encoding="utf-8")
    return path


def mapping(**changes: Any) -> Any:
    data = copy.deepcopy(MAPPING)
    for key, value in changes.items():
        section, name = key.split("__")
        data[section][name] = value
    return parse_mapping(data, "rig.toml")


# --------------------------------------------------------------------------- reading


def test_a_record_reads_in_project_units_with_its_flip_and_design(tmp_path: Path) -> None:
    t, x, F = synthetic()
    rec = read_record(write_json(tmp_path / "T30lb_A0.75in.json", t, x, F), mapping())
    np.testing.assert_allclose(rec.time_s, t, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(rec.displacement_mm, x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(rec.force_n, F, rtol=1e-12, atol=1e-9)
    assert rec.design == pytest.approx(
        {"tension": 30 * 4.4482216152605, "nominal_amplitude": 19.05}
    )


def test_a_csv_record_reads_its_columns_by_header(tmp_path: Path) -> None:
    t, x, F = synthetic()
    path = tmp_path / "T0lb_A1in.csv"
    lines = ["Time (s);Load (kN);Position (um)"]
    lines += [
        f"{a:.6f};{b / 1e3:.9f};{c * 1e3:.6f}".replace(".", ",")
        for a, b, c in zip(t, F, x, strict=True)
    ]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    m = mapping(
        source__format="csv",
        columns__time={"name": "Time (s)", "unit": "s"},
        columns__displacement={"name": "Position (um)", "unit": "um"},
        columns__force={"name": "Load (kN)", "unit": "kN"},
    )
    rec = read_record(path, m)
    np.testing.assert_allclose(rec.displacement_mm, x, atol=1e-6)
    np.testing.assert_allclose(rec.force_n, F, atol=1e-5)


# --------------------------------------------------------------------------- cycles


@pytest.mark.parametrize("n_steady", [2, 3, 5], ids=["2-steady", "3-steady", "5-steady"])
@pytest.mark.parametrize("seed", [0, 1], ids=["seed0", "seed1"])
def test_cycles_split_at_peaks_and_only_the_steady_ones_are_kept(n_steady: int, seed: int) -> None:
    t, x, _ = synthetic(n_steady=n_steady, noise=0.003, seed=seed)
    split = split_cycles(x, 0.02, "synthetic")
    assert split.n_steady == n_steady
    starts = t[split.bounds[split.steady, 0]]
    np.testing.assert_allclose(starts, 2.25 + np.arange(n_steady), atol=0.03)  # the plateau's peaks
    assert split.steady_peak_to_peak_mm == pytest.approx(40.0, rel=0.01)
    ramp = split.peak_to_peak_mm[~split.steady]
    assert ramp.size >= 2
    assert np.all(ramp < 0.98 * split.steady_peak_to_peak_mm)


def test_a_record_whose_amplitude_only_grows_has_no_steady_cycle() -> None:
    t = np.arange(0.0, 8.0, 1 / RATE_HZ)
    x = (1.0 + 0.15 * t) * np.sin(2 * math.pi * t)  # +15 % a cycle: never steady
    with pytest.raises(
        DataError, match=r"synthetic: no steady cycle: fewer than 2 of its \d+ cycles"
    ):
        split_cycles(x, 0.02, "synthetic")


# --------------------------------------------------------------------------- import


def test_import_writes_steady_cycles_as_replicates_with_their_energy(tmp_path: Path) -> None:
    files = [
        write_json(
            tmp_path / f"T{T}lb_A{a}in.json", *synthetic(amp_mm=a * IN_MM, n_steady=n, seed=i)
        )
        for i, (T, a, n) in enumerate([(0, 0.5, 3), (30, 0.5, 4), (30, 1, 2)])
    ]
    mset, done = import_records(mapping(), files, tmp_path / "out")
    assert [len(r.case_ids) for r in done] == [3, 4, 2]
    groups = mset.replicate_groups()
    assert sorted(len(g) for g in groups.values()) == [2, 3, 4]
    w = 2 * math.pi * FREQ_HZ
    for case in mset.cases:
        assert case.control is Control.DISPLACEMENT
        amp = case.conditions["nominal_amplitude_mm"]
        assert case.amplitude_mm == pytest.approx(amp, rel=0.005)
        assert case.amplitude_n == pytest.approx(
            math.hypot(K_N_PER_MM, C_NS_PER_MM * w) * amp, rel=0.02
        )
        assert set(case.conditions) == {"tension_N", "nominal_amplitude_mm"}
        assert case.values == {"clearance_mm": 0.0}
        loop = case.loop
        assert loop is not None
        W = np.sum(0.5 * (loop.force_n[1:] + loop.force_n[:-1]) * np.diff(loop.displacement_mm))
        assert pytest.approx(math.pi * C_NS_PER_MM * w * amp**2, rel=0.01) == W
    header = (tmp_path / "out" / "cases.csv").read_text(encoding="utf-8").splitlines()[0]
    assert header.split(",") == [
        "case_id", "hinge", "clearance_mm", "amplitude_N", "loop_file", "replicate", "control",
        "amplitude_mm", "cond_nominal_amplitude_mm", "cond_tension_N",
    ]  # fmt: skip
    prov = json.loads((tmp_path / "out" / "import.json").read_text(encoding="utf-8"))
    assert [sum(c["steady"] for c in r["cycles"]) for r in prov["records"]] == [3, 4, 2]


def test_without_the_flip_the_loop_runs_backwards_and_is_refused(tmp_path: Path) -> None:
    f = write_json(tmp_path / "T0lb_A1in.json", *synthetic())
    cols = copy.deepcopy(MAPPING["columns"])
    cols["displacement"]["flip"] = False
    with pytest.raises(DataError, match="runs the wrong way round") as err:
        import_records(mapping(columns__displacement=cols["displacement"]), [f], tmp_path / "out")
    assert str(err.value).startswith(f"{f}: cycle ")
    assert not (tmp_path / "out").exists()
    assert not list(tmp_path.glob(".out-*")), "the temporary folder is removed"


def _doc(path: Path) -> dict[str, Any]:
    return json.loads(path.read_text(encoding="utf-8"))


def _bad(tmp_path: Path, name: str, change: Any) -> Path:
    good = write_json(tmp_path / "T30lb_A1in.json", *synthetic())
    doc = _doc(good)
    change(doc)
    path = tmp_path / name
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def _set(row: int, col: int, value: Any) -> Any:
    return lambda d: d["data"][row].__setitem__(col, value)


def _swap_time(d: dict[str, Any]) -> None:
    d["data"][41][0], d["data"][42][0] = d["data"][42][0], d["data"][41][0]


NAME = "T30lb_A1in.json"
BAD = [
    ("missing-column", NAME, lambda d: d["data"][7].pop(), r"row 8: missing column 2 \(displacement\)"),
    ("unknown-unit", NAME, lambda d: d.update({"force units": "kipz"}), r"column 1 \(force\): unknown unit 'kipz'"),
    ("no-unit", NAME, lambda d: d.pop("force units"),
     r"column 1 \(force\): its unit's metadata key 'force units' is missing"),
    ("time-back", NAME, _swap_time, r"row 43, column 0 \(time\): time does not increase"),
    ("nan", NAME, _set(99, 1, float("nan")), r"row 100, column 1 \(force\): not a finite number \(nan\)"),
    ("text", NAME, _set(4, 2, "abc"), r"row 5, column 2 \(displacement\): not a number: 'abc'"),
    ("too-short", NAME, lambda d: d.update({"data": d["data"][:10]}), r"too short: 10 rows"),
    ("no-rows", NAME, lambda d: d.pop("data"), r"key 'data' \(source.rows\) missing"),
    ("one-stroke", NAME, lambda d: d.update({"data": d["data"][:700]}), r"column 2 \(displacement\): no full cycle"),
    ("bad-name", "run7.json", lambda d: None, r"the file name does not match name.pattern"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("name", "change", "message"), [b[1:] for b in BAD], ids=[b[0] for b in BAD]
)
def test_a_bad_record_gets_one_line_naming_file_column_and_problem(
    tmp_path: Path, name: str, change: Any, message: str
) -> None:
    path = _bad(tmp_path, name, change)
    with pytest.raises(DataError, match=message) as err:
        import_records(mapping(), [path], tmp_path / "out")
    text = str(err.value)
    assert text.startswith(f"{path}: ")
    assert "\n" not in text
    assert not (tmp_path / "out").exists()


def test_an_out_folder_with_files_is_not_overwritten(tmp_path: Path) -> None:
    f = write_json(tmp_path / "T0lb_A1in.json", *synthetic())
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "keep.txt").write_text("mine", encoding="utf-8")
    with pytest.raises(DataError, match="--out exists and is not an empty folder"):
        import_records(mapping(), [f], tmp_path / "out")
    assert (tmp_path / "out" / "keep.txt").read_text(encoding="utf-8") == "mine"


# --------------------------------------------------------------------------- format


def test_existing_columns_still_refuse_typos_and_cond_columns_are_conditions(
    tmp_path: Path,
) -> None:
    f = write_json(tmp_path / "T0lb_A1in.json", *synthetic())
    import_records(mapping(), [f], tmp_path / "out")
    cases = tmp_path / "out" / "cases.csv"
    text = cases.read_text(encoding="utf-8")
    cases.write_text(text.replace("cond_tension_N", "tension_N"), encoding="utf-8")
    with pytest.raises(DataError, match=re.escape("unknown column(s) ['tension_N']")):
        read_measurement_set(tmp_path / "out")
    cases.write_text(text.replace(",displacement,", ",velocity,"), encoding="utf-8")
    with pytest.raises(
        DataError,
        match=r"column control: must be one of \['force', 'displacement'\], got 'velocity'",
    ):
        read_measurement_set(tmp_path / "out")


def test_force_controlled_cases_keep_their_design_point() -> None:
    root = Path(__file__).resolve().parents[2] / "studies" / "examples" / "measurements"
    mset = read_measurement_set(root)
    case = mset.cases[0]
    assert case.control is Control.FORCE
    assert case.amplitude_mm is None
    assert not case.conditions
    assert case.design_point == ("general", (("clearance_mm", 0.0),), 200.0)


# --------------------------------------------------------------------------- command line


def test_cli_imports_and_prints_the_yardstick(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "src"
    src.mkdir()
    for i, a in enumerate((0.25, 0.5, 0.75)):
        write_json(src / f"T30lb_A{a}in.json", *synthetic(amp_mm=a * IN_MM, seed=i))
    rig = tmp_path / "rig.toml"
    rig.write_text(
        (Path(__file__).parent / "data" / "rig_synthetic.toml").read_text(encoding="utf-8"),
        encoding="utf-8",
    )
    out = tmp_path / "out"
    assert (
        main(
            [
                "import-records",
                str(rig),
                str(src),
                "--out",
                str(out),
                "--yardstick",
                "tension_N",
                "--json",
            ]
        )
        == 0
    )
    summary = json.loads(capsys.readouterr().out)
    assert (summary["records"], summary["cases"]) == (3, 9)
    # a viscous loop's energy is quadratic in the amplitude, W = b·A²: the line through the
    # other two records (x2, x3) predicts b·(x1(x2 + x3) − x2·x3) at x1
    errors = {r["amplitude_mm"]: r["line_error"] for r in summary["yardstick"]["records"]}
    x1, x2, x3 = sorted(errors)
    assert errors[x1] == pytest.approx((x1 * (x2 + x3) - x2 * x3) / x1**2 - 1, abs=0.03)
    assert errors[x3] == pytest.approx((x3 * (x1 + x2) - x1 * x2) / x3**2 - 1, abs=0.03)
    assert (out / "yardstick.json").is_file()
    assert (
        main(["import-records", str(rig), str(src / "nope.json"), "--out", str(tmp_path / "o2")])
        == 1
    )
    assert "nope.json: no such record file or folder" in capsys.readouterr().err


@settings(max_examples=25, deadline=None)
@given(
    amp_mm=st.floats(1e-3, 1e3),
    n_steady=st.integers(2, 6),
    noise=st.floats(0.0, 0.004),
    seed=st.integers(0, 2**16),
)
def test_any_amplitude_and_noise_keep_exactly_the_plateau_cycles(
    amp_mm: float, n_steady: int, noise: float, seed: int
) -> None:
    _, x, _ = synthetic(amp_mm=amp_mm, n_steady=n_steady, noise=noise, seed=seed)
    split = split_cycles(x, 0.02, "synthetic")
    assert split.n_steady == n_steady
    assert split.steady_peak_to_peak_mm == pytest.approx(2 * amp_mm, rel=0.01 + 4 * noise)


def test_a_force_controlled_record_is_one_case_with_its_stated_amplitude(tmp_path: Path) -> None:
    n = 40
    force = np.concatenate(
        [
            np.linspace(0, 300, n),
            np.linspace(300, -300, 2 * n)[1:],
            np.linspace(-300, 300, 2 * n)[1:],
        ]
    )
    disp = force / 1e4 + np.concatenate(
        [np.zeros(n), np.full(2 * n - 1, 0.002), np.full(2 * n - 1, -0.002)]
    )
    t = np.arange(force.size) * 0.1
    write_json(tmp_path / "T0lb_A300in.json", t, disp, force)
    m = mapping(
        source__control="force",
        design__amplitude={"group": "amp", "unit": "N", "to": "N"},
    )
    mset, done = import_records(m, [tmp_path / "T0lb_A300in.json"], tmp_path / "out")
    (case,) = mset.cases
    assert case.control is Control.FORCE
    assert case.amplitude_n == 300.0
    assert case.loop is not None
    assert case.loop.n_samples == force.size
    assert done[0].split is None
