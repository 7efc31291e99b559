"""``hingelab reduce``: the fit recovers a known element, writes runnable files; the FMU."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from fe.cycle.loop_files import write_loop_csv
from fe.cycle.protocol import CycleSettings
from fe.joint.element import JointParams
from fe.kinds.joint import run_joint_cycle
from studies.cli.main import main

TRUE = JointParams(
    k_tension_n_per_mm=1.4e5,
    k_compression_n_per_mm=2.6e5,
    k_elastic_n_per_mm=3.5e5,
    k_slip_n_per_mm=3.5e5,
    slip_ratio=0.25,
    n_branches=20,
)


def _fake_sweep(folder: Path, params: JointParams, amplitudes: list[float]) -> None:
    """A sweep folder in the format of studies.sweep_points, its loops made by ``params``."""
    for amp in amplitudes:
        pt = folder / "points" / f"c0.000_F{amp:g}"
        pt.mkdir(parents=True)
        res = run_joint_cycle(params, CycleSettings(amplitude_n=amp, increments_per_stage=20))
        write_loop_csv(res, pt / "loop.csv")
        rec = {
            "params": {"clearance_mm": 0.0, "amplitude_N": amp},
            "status": "ok",
            "results": {k: v for k, v in res.metrics().items() if isinstance(v, float)},
        }
        (pt / "result.json").write_text(json.dumps(rec))


@pytest.mark.slow  # two least-squares fits over three loops: ~5 s CPU
def test_reduce_recovers_a_known_element_and_writes_runnable_files(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    _fake_sweep(tmp_path / "sw", TRUE, [100.0, 250.0, 400.0])
    out = tmp_path / "red"
    assert (
        main(
            [
                "reduce",
                str(tmp_path / "sw"),
                "--out",
                str(out),
                "--no-fmu",
                "--pbush-amplitudes",
                "100,400",
            ]
        )
        == 0
    )
    fit = json.loads((out / "clearance_mm_0" / "fit.json").read_text())
    got = fit["fitted"]
    assert got["k_tension_n_per_mm"] == pytest.approx(1.4e5, rel=1e-3)
    assert got["k_compression_n_per_mm"] == pytest.approx(2.6e5, rel=1e-3)
    assert got["slip_ratio"] == pytest.approx(0.25, rel=1e-3)
    rows = (out / "validation.csv").read_text().splitlines()
    assert len(rows) == 4
    assert "clearance_mm=0" in capsys.readouterr().out
    cards = (out / "clearance_mm_0" / "pbush.bdf").read_text()
    assert cards.count("PBUSH") == 2
    assert (
        main(
            [
                "cycle",
                "--model",
                str(out / "clearance_mm_0" / "reduced.toml"),
                "--amplitude",
                "250",
                "--out",
                str(tmp_path / "c"),
                "--no-progress",
                "--frames",
                "0",
            ]
        )
        == 0
    )
    eta = json.loads((tmp_path / "c" / "result.json").read_text())["eta"]
    eta_true = run_joint_cycle(TRUE, CycleSettings(amplitude_n=250.0)).metrics()["eta"]
    assert eta == pytest.approx(eta_true, rel=1e-3)


def test_pbush_secant_and_ge_match_the_element_loop() -> None:
    from validation.reduce_export import equivalent_linear

    lin = equivalent_linear(TRUE, 300.0)
    m = run_joint_cycle(TRUE, CycleSettings(amplitude_n=300.0, n_cycles=2)).metrics()
    assert lin.stiffness_n_per_mm == pytest.approx(m["secant_stiffness_N_per_mm"], rel=1e-9)
    assert lin.ge == pytest.approx(m["eta"], rel=1e-9)


def test_reduce_refuses_a_folder_without_points(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["reduce", str(tmp_path), "--out", str(tmp_path / "o")]) == 1
    assert "no finished FE point" in capsys.readouterr().err


def test_the_fmu_reproduces_the_element_loop(tmp_path: Path) -> None:
    pytest.importorskip("pythonfmu")
    fmpy = pytest.importorskip("fmpy")
    from fe.joint.history import displacement_history
    from validation.reduce_export import write_fmu

    params = dataclasses.replace(TRUE, slip_force_n=8.0, free_play_mm=0.002)
    fmu = write_fmu(params, tmp_path / "joint.fmu")
    t = np.linspace(0.0, 2.0, 401)
    signal = np.array(
        list(zip(t, 0.004 * np.sin(2 * np.pi * t), strict=True)),
        dtype=[("time", np.float64), ("u", np.float64)],
    )
    res = fmpy.simulate_fmu(
        str(fmu),
        start_time=0.0,
        stop_time=2.0,
        output_interval=0.005,
        input=signal,
        output=["u", "F"],
        fmi_type="CoSimulation",
    )
    h = displacement_history(params, res["u"])
    scale = np.max(np.abs(h.force_n))
    assert scale > 100.0
    assert np.max(np.abs(res["F"] - h.force_n)) <= 1e-6 * scale


@pytest.mark.slow  # a coarse FE sweep (8 cycles, ~40 s) and two fits
def test_reduce_meets_the_targets_on_a_real_fe_sweep(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """Issue 34's targets on FE loops, not on loops of the element itself: at Δr = 0 over four
    amplitudes η within 5 % and δ(±Fg) within 2 % of the FE; at Δr = 0.1 mm the element's free
    play is the geometry's, 4Δr (the two sides of the pin in its hole, both lugs)."""
    sweep = tmp_path / "sw"
    argv = ["sweep", "--clearance", "0,0.1", "--amplitude", "100,200,300,400"]
    argv += ["--size", "4", "--contact-size", "2", "--out", str(sweep), "--json"]
    assert main(argv) == 0
    out = tmp_path / "red"
    assert main(["reduce", str(sweep), "--out", str(out), "--no-fmu", "--json"]) == 0
    capsys.readouterr()
    with (out / "validation.csv").open() as f:
        rows = list(csv.DictReader(f))
    zero = [r for r in rows if r["design"] == "clearance_mm=0"]
    assert len(zero) == 4
    for r in zero:  # measured on this sweep: +0.10 %, -0.07 %, -0.04 %
        for fe_key, el_key, tol in (
            ("eta_fe", "eta_el", 0.05),
            ("d_plus_fe_mm", "d_plus_el_mm", 0.02),
            ("d_minus_fe_mm", "d_minus_el_mm", 0.02),
        ):
            assert float(r[el_key]) == pytest.approx(float(r[fe_key]), rel=tol), (r, el_key)
    fit = json.loads((out / "clearance_mm_0.1" / "fit.json").read_text())
    assert fit["params"]["free_play_mm"] == pytest.approx(0.4, rel=1e-9)
    assert fit["free_play_geometry_mm"] == pytest.approx(0.4, rel=1e-9)
