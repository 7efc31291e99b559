"""``hingelab compare`` end to end: measurements made from the model itself pass, a wrong scale fails."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from studies.cli.main import main

AMPLITUDES = {"c200": (200.0, 1.0), "c400": (400.0, 1.0), "c300_bad": (300.0, 1.3)}
"""case → (amplitude [N], displacement scale applied to the measurement)."""


def _model_file(path):
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.file import write_model
    from model.spec import ModelSpec

    spec = ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(mu=0.2, increments_per_stage=6, clearance_increments=6),
    )
    return spec, write_model(spec, path)


def _measured(F, d, n, rng):
    """Resample the model loop densely along its path, add a dwell at zero, offsets and noise."""
    s = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(F)))])
    t = np.linspace(0.0, s[-1], n)
    Fm = np.concatenate([np.zeros(40), np.interp(t, s, F)])
    dm = np.concatenate([np.zeros(40), np.interp(t, s, d)])
    Fm = Fm + 1.2 + rng.normal(0.0, 0.002 * F.max(), Fm.size)
    dm = dm + 0.004 + rng.normal(0.0, 0.002 * d.max(), dm.size)
    return Fm, dm


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Model file + 3 measured cases: the model at 400 N, scaled (the zero-clearance model is
    positively homogeneous: F and δ scale together), resampled, noised; c300_bad has δ × 1.3."""
    from validation.measurements import Case
    from validation.workflow import run_model_for_cases

    root = tmp_path_factory.mktemp("compare")
    spec, model_path = _model_file(root / "MODEL.toml")
    results, _ = run_model_for_cases(spec, [Case("ref", "general", {"clearance_mm": 0.0}, 400.0)])
    F0, d0 = results["ref"].loop.force_n, results["ref"].loop.displacement_mm
    data = root / "data"
    data.mkdir()
    rng = np.random.default_rng(5)
    rows = ["case_id,hinge,clearance_mm,preload_N,amplitude_N,loop_file,temperature_C"]
    for cid, (amp, scale) in AMPLITUDES.items():
        F, d = _measured(F0 * amp / 400.0, d0 * amp / 400.0 * scale, 1200, rng)
        if cid == "c200":  # handed over by the lab as a Bluehill export in kN and µm
            lines = [
                '"Sample ID","hinge G"',
                '"Method","cyclic.im_cyc"',
                "",
                '"Time","Extension","Load"',
                '"(s)","(µm)","(kN)"',
            ]
            lines += [
                f'"{0.05 * i:.2f}","{x * 1e3:.6f}","{f / 1e3:.7f}"'
                for i, (f, x) in enumerate(zip(F, d, strict=True))
            ]
            (data / f"{cid}.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
        else:
            np.savetxt(
                data / f"{cid}.csv",
                np.column_stack([F, d]),
                delimiter=",",
                header="force_N,displacement_mm",
                comments="",
            )
        rows.append(f"{cid},general,0,0,{amp:g},{cid}.csv,21")
    (data / "cases.csv").write_text("\n".join(rows) + "\n")
    return root, model_path, data


@pytest.fixture(autouse=True)
def _compare_registered(monkeypatch):
    """Register the subcommand if studies/cli/main.py does not list it yet."""
    import studies.cli.main

    if "studies.cli.compare" not in studies.cli.main.SUBCOMMAND_MODULES:
        monkeypatch.setattr(
            studies.cli.main,
            "SUBCOMMAND_MODULES",
            (*studies.cli.main.SUBCOMMAND_MODULES, "studies.cli.compare"),
        )


def test_compare_cli_json_passes_true_cases_and_fails_the_wrong_scale(dataset, capsys):
    root, model_path, data = dataset
    out = root / "out"
    assert main(["compare", str(model_path), str(data), "--out", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    cases = {c["case_id"]: c for c in report["cases"]}
    assert cases["c200"]["passed"]
    assert cases["c400"]["passed"]
    assert not cases["c300_bad"]["passed"]
    assert {"disp_at_peak_mm", "secant_stiffness_N_per_mm"} <= set(cases["c300_bad"]["failed"])
    assert "eta" not in cases["c300_bad"]["failed"]
    for cid in ("c200", "c400"):
        for metric, err in cases[cid]["errors"].items():
            assert abs(err) < 0.02, (cid, metric, err)
    assert cases["c300_bad"]["errors"]["disp_at_peak_mm"] == pytest.approx(1 / 1.3 - 1, abs=0.02)
    # validation.loops measures the model loop as the FE does, except that it closes the
    # loop by the chord: W differs by exactly Fg × (δ_end − δ_start) of the last loop
    for c in cases.values():
        m = c["model"]
        closure_work = c["amplitude_N"] * m["fe_loop_closure_mm"]
        assert m["W_cycle_Nmm"] == pytest.approx(m["fe_W_cycle_Nmm"] - closure_work, rel=1e-9)
        assert m["U_max_Nmm"] == pytest.approx(m["fe_U_max_Nmm"], rel=1e-12)
        assert m["eta"] == pytest.approx(m["fe_eta"], rel=2e-3)
    assert report["summary"]["n_pass"] == 2
    (fit,) = report["fingerprint"]
    assert fit["slope_eta_model"] == pytest.approx(0.0, abs=1e-6)  # homogeneous model
    assert fit["slope_W_model"] == pytest.approx(2.0, abs=1e-6)
    assert json.loads((out / "comparison.json").read_text())["summary"] == report["summary"]
    for name in ("error_map.png", "residuals.png", "fingerprint.png", "loops/c300_bad.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG", name
    assert len(list((out / "model_loops").glob("*.csv"))) == 3


@pytest.fixture(scope="module")
def compared(dataset):
    """The CLI run whose files the table test reads (its own, so it runs alone too)."""
    root, model_path, data = dataset
    out = root / "out_table"
    assert main(["compare", str(model_path), str(data), "--out", str(out)]) == 0
    return out / "model_loops", data


def test_table_printed_from_the_written_files(compared):
    """The text table, formed from the model loops the CLI run wrote (no second FE run)."""
    from studies.cli.compare import format_table
    from validation.compare import ModelResult, compare
    from validation.loop_files import read_loop_csv
    from validation.measurements import read_measurement_set

    loops, data = compared
    ms = read_measurement_set(data)
    models = {
        c.case_id: ModelResult(read_loop_csv(loops / f"c0.000_F{c.amplitude_n:g}.csv"))
        for c in ms.cases
    }
    table = format_table(compare(models, ms))
    lines = table.splitlines()
    assert lines[0].split()[:3] == ["case", "design", "Fg"]
    assert "Δr = 0 mm" in next(line for line in lines if line.startswith("c200"))
    assert "FAIL" in next(line for line in lines if line.startswith("c300_bad"))
    assert "pass" in next(line for line in lines if line.startswith("c200"))
    assert "2/3 cases pass" in table


@pytest.mark.parametrize(
    ("model_text", "cases_row", "match"),
    [
        (
            '[hinge]\nkind = "general"\n',
            "c1,bearing,0,0,200,c1.csv",
            "hinge 'bearing', but the model is the general hinge",
        ),
        (
            '[hinge]\nkind = "general"\n',
            "c1,general,0,50,200,c1.csv",
            "preload_N = 50, but the general hinge has no preload",
        ),
        (
            '[hinge]\nkind = "general"\ncolour = "red"\n',
            "c1,general,0,0,200,c1.csv",
            r"unknown key\(s\) \['colour'\]",
        ),
        (
            '[hinge]\nkind = "general"\n',
            "c1,general,0,0,250,c1.csv",
            "never reaches the stated amplitude",
        ),
    ],
    ids=["bearing-case", "preload", "unknown-key", "amplitude"],
)
def test_compare_cli_bad_input_exits_1(tmp_path, capsys, model_text, cases_row, match):
    theta = math.pi / 2 + np.linspace(0, 2 * math.pi, 41)[1:]
    F = np.concatenate([np.linspace(0, 200, 11), 200 * np.sin(theta)])
    d = np.concatenate([np.linspace(0, 1e-3, 11), 1e-3 * np.sin(theta)])
    np.savetxt(
        tmp_path / "c1.csv",
        np.column_stack([F, d]),
        delimiter=",",
        header="force_N,displacement_mm",
        comments="",
    )
    (tmp_path / "cases.csv").write_text(
        "case_id,hinge,clearance_mm,preload_N,amplitude_N,loop_file\n" + cases_row + "\n"
    )
    (tmp_path / "MODEL.toml").write_text(model_text)
    assert (
        main(["compare", str(tmp_path / "MODEL.toml"), str(tmp_path), "--out", str(tmp_path / "o")])
        == 1
    )
    err = capsys.readouterr().err
    assert err.startswith("hingelab compare: error:")
    assert re.search(match, err), err


def test_compare_runs_the_models_effects(tmp_path):
    """A calibrated model file holds effects: compare must run them, not the bare model."""
    import dataclasses

    from validation.measurements import Case
    from validation.workflow import run_model_for_cases

    spec, _ = _model_file(tmp_path / "MODEL.toml")
    c_f = 2e-5  # mm/N
    framed = dataclasses.replace(spec, effects={"frame_compliance": {"compliance_mm_per_n": c_f}})
    case = [Case("c", "general", {"clearance_mm": 0.0}, 400.0)]
    bare, _ = run_model_for_cases(spec, case)
    with_frame, _ = run_model_for_cases(framed, case)
    d0 = bare["c"].metrics["disp_at_peak_mm"]
    assert with_frame["c"].metrics["disp_at_peak_mm"] == pytest.approx(d0 + c_f * 400.0, rel=1e-9)
    assert with_frame["c"].loop.displacement_mm.max() == pytest.approx(
        bare["c"].loop.displacement_mm.max() + c_f * 400.0, rel=1e-9
    )


def test_eta_only_case_is_compared_without_the_free_play(tmp_path):
    """A stated η (the paper's tables, `hingelab cycle`) excludes the free play 4Δr."""
    from validation.compare import compare
    from validation.measurements import Case, MeasurementSet
    from validation.workflow import run_model_for_cases

    spec, _ = _model_file(tmp_path / "MODEL.toml")
    case = Case("e", "general", {"clearance_mm": 0.1}, 400.0, eta=0.05)
    models, runs = run_model_for_cases(spec, [case])
    from model.spec import DesignPoint

    fe_eta = runs[DesignPoint(400.0, {"clearance_mm": 0.1})].metrics()["eta"]
    (c,) = compare(models, MeasurementSet((case,), tmp_path)).cases
    # same η up to the chord that closes the loop (0.2 % here); with the free play in δ_max
    # it would be 40× smaller (δ_max 0.2 mm + 5 µm instead of 5 µm)
    assert c.model["eta"] == pytest.approx(fe_eta, rel=1e-2)
    assert c.errors["eta"] == pytest.approx(c.model["eta"] / 0.05 - 1.0, rel=1e-12)
