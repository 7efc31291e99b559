"""``hingelab synth`` end to end on a coarse model: readable, deterministic, finer mesh, manifest."""

from __future__ import annotations

import json

import pytest

from studies.cli.main import main

CASES = "0:300;0.1:300"


@pytest.fixture(scope="module", autouse=True)
def _synth_registered():
    """Register the subcommand if studies/cli/main.py does not list it yet (module scope: the
    data set fixture runs the CLI once for the module)."""
    import studies.cli.main

    with pytest.MonkeyPatch.context() as mp:
        if "studies.cli.synth" not in studies.cli.main.SUBCOMMAND_MODULES:
            mp.setattr(
                studies.cli.main,
                "SUBCOMMAND_MODULES",
                (*studies.cli.main.SUBCOMMAND_MODULES, "studies.cli.synth"),
            )
        yield


@pytest.fixture(scope="module")
def model_path(tmp_path_factory):
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
    return write_model(spec, tmp_path_factory.mktemp("synth") / "MODEL.toml")


def _synth(model_path, out, seed=7):
    argv = [
        "synth",
        str(model_path),
        "--effect",
        "frame_compliance:compliance_mm_per_n=2e-5",
        "--effect",
        "roughness_softening",
        "--noise-force",
        "0.1",
        "--noise-disp",
        "2e-5",
        "--seed",
        str(seed),
        "--cases",
        CASES,
        "--out",
        str(out),
    ]
    return main(argv)


@pytest.fixture(scope="module")
def dataset(model_path, _synth_registered):
    out = model_path.parent / "data"
    assert _synth(model_path, out) == 0
    return out


def test_writes_a_readable_measurement_set_reaching_the_amplitudes(dataset):
    from validation.loops import process_loop
    from validation.measurements import read_measurement_set

    ms = read_measurement_set(dataset)  # checks amplitude, stages, format
    assert [(c.values["clearance_mm"], c.amplitude_n) for c in ms.cases] == [
        (0.0, 300.0),
        (0.1, 300.0),
    ]
    manifest = json.loads((dataset / "manifest.json").read_text())
    for case, rec in zip(ms.cases, manifest["cases"], strict=True):
        assert case.loop.time_s is not None
        assert case.loop.n_samples > 200
        p = process_loop(case.loop.force_n, case.loop.displacement_mm, case.case_id)
        assert p.metrics.f_max_n == pytest.approx(case.amplitude_n, rel=0.01)
        # the noisy, sampled loop measures what the FE computed (free play included)
        fe = rec["fe_metrics"]
        assert p.metrics.delta_max_mm == pytest.approx(
            fe["delta_max_mm"] + fe["free_play_mm"] / 2, rel=0.03
        )


def test_manifest_holds_the_truth_and_a_finer_mesh(dataset):
    m = json.loads((dataset / "manifest.json").read_text())
    assert m["seed"] == 7
    assert m["hidden_effects"] == {
        "frame_compliance": {"compliance_mm_per_n": 2e-5},
        "roughness_softening": {"compliance_mm3_per_n": 2e-4},
    }
    assert m["truth_effects"] == m["hidden_effects"]
    assert m["synth_mesh"]["contact_size_mm"] < m["model_mesh"]["contact_size_mm"]
    assert m["synth_mesh"]["size_mm"] < m["model_mesh"]["size_mm"]
    assert m["synth_mesh"]["arc_grading"] != m["model_mesh"]["arc_grading"]
    assert m["synth_increments_per_stage"] > m["model_increments_per_stage"]
    assert m["mu"] == 0.2
    assert len(m["cases"]) == 2


@pytest.mark.slow
def test_same_seed_same_files_other_seed_other_noise(model_path, dataset, tmp_path):
    assert _synth(model_path, tmp_path / "again") == 0
    for f in ("cases.csv", "loops/dr0mm_F300N.csv", "loops/dr0.1mm_F300N.csv"):
        assert (tmp_path / "again" / f).read_bytes() == (dataset / f).read_bytes(), f
    assert _synth(model_path, tmp_path / "other", seed=8) == 0
    a = (dataset / "loops/dr0mm_F300N.csv").read_text()
    assert (tmp_path / "other" / "loops/dr0mm_F300N.csv").read_text() != a


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--effect", "bolt_creep"], r"unknown effect\(s\) \['bolt_creep'\]"),
        (["--effect", "frame_compliance:compliance_mm_per_n"], "is not PARAM=NUMBER"),
        (
            ["--effect", "interference:interference_mm=1"],
            r"interference_mm must be in \[0, 0.01\] mm",
        ),
        (["--cases", "0:100;0.1"], "is not clearance_mm:amplitude_N"),
        (["--seed", "-2"], "seed must be an integer"),
    ],
    ids=["unknown-effect", "no-value", "out-of-range", "bad-cases", "seed"],
)
def test_bad_input_exits_1_naming_it(model_path, tmp_path, capsys, extra, match):
    import re

    argv = ["synth", str(model_path), "--out", str(tmp_path / "o"), *extra]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.startswith("hingelab synth: error:")
    assert re.search(match, err), err
