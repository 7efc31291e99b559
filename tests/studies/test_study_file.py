"""Study files: validated on load (before any meshing), designs of experiments, the ``study`` command."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cad.errors import ParameterError
from studies.cli.main import main
from studies.study_file import read_study

EXAMPLES = Path(__file__).parents[2] / "studies" / "examples"

ONE_CLEARANCE = """
[study]
name = "fast"
[mesh]
preset = "coarse"
[solver]
increments = 6
[design]
type = "full_factorial"
[design.clearance_mm]
levels = [0.0]
[design.amplitude_N]
levels = [200.0, 400.0]
[surface]
x = ["amplitude_N"]
y = "eta"
degree = 1
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "study.toml"
    path.write_text(text)
    return path


def test_shipped_examples_load():
    coarse = read_study(EXAMPLES / "coarse_2x2.toml")
    assert len(coarse.points) == 4
    assert coarse.spec.mesh.size_mm == 4.0  # the coarse preset
    assert coarse.spec.cycle.increments_per_stage == 6
    assert coarse.spec.cycle.clearance_increments == 60  # converged with clearance (issue 33)
    paper = read_study(EXAMPLES / "paper_general_5x5.toml")
    assert len(paper.points) == 25
    assert paper.points[:2] == ((0.0, 100.0), (0.0, 200.0))  # the paper's row order
    assert paper.surface is not None
    assert paper.surface.degree == 4


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            ("[solver]", "[solver]\nmuu = 0.3"),
            r"\[solver\] unknown key\(s\) \['muu'\]; allowed: .*mu",
        ),
        (
            ("increments = 6", "increments = 6\nmu = -0.1"),
            r"\[solver\] mu must be in \[0, 2\], got -0.1",
        ),
        (("increments = 6", 'increments = "six"'), r"increments must be an integer, got 'six'"),
        (
            ("[200.0, 400.0]", "[200.0, -5.0]"),
            r"point 2 \(clearance_mm = 0, amplitude_N = -5\): amplitude_N must be in",
        ),
        (
            ('preset = "coarse"', 'preset = "tiny"'),
            r"preset must be one of \['default', 'coarse'\], got 'tiny'",
        ),
        (
            ("degree = 1", "degree = 2"),
            r"degree 2 in 1 variables has 3 terms, but the design has only 2 points",
        ),
        (('y = "eta"', 'y = "etta"'), r"y must be one of \['eta'"),
        (('type = "full_factorial"', 'type = "sobol"'), r"type must be one of"),
        (
            ("[design.amplitude_N]", "[design.force_N]"),
            r"\[design\] unknown key\(s\) \['force_N'\]",
        ),
    ],
    ids=[
        "unknown-key",
        "mu-range",
        "wrong-type",
        "bad-amplitude",
        "preset",
        "too-few-points",
        "response",
        "design-type",
        "variable",
    ],
)
def test_bad_study_refused_by_key_value_and_range(tmp_path, edit, message):
    path = _write(tmp_path, ONE_CLEARANCE.replace(*edit, 1))
    with pytest.raises(ParameterError, match=message):
        read_study(path)


def test_latin_hypercube_and_central_composite(tmp_path):
    lhs = _write(
        tmp_path,
        '[design]\ntype = "latin_hypercube"\nsamples = 7\nseed = 3\n'
        "[design.clearance_mm]\nmin = 0.0\nmax = 0.3\n[design.amplitude_N]\nmin = 100.0\nmax = 500.0\n",
    )
    s = read_study(lhs)
    assert len(s.points) == 7
    assert all(0.0 <= c <= 0.3 and 100.0 <= a <= 500.0 for c, a in s.points)
    assert read_study(lhs).points == s.points  # seeded: repeatable
    ccd = lhs.read_text().replace(
        '"latin_hypercube"\nsamples = 7\nseed = 3', '"central_composite"\nface = "faced"'
    )
    lhs.write_text(ccd)
    assert sorted(set(read_study(lhs).points)) == sorted(
        (c, a) for c in (0.0, 0.15, 0.3) for a in (100.0, 300.0, 500.0)
    )  # faced: the 3 × 3 grid of the box
    # circumscribed puts axial points outside the box: a negative clearance is refused on load
    lhs.write_text(ccd.replace('"faced"', '"circumscribed"'))
    with pytest.raises(ParameterError, match=r"\[design\] point \d+ \(clearance_mm = -"):
        read_study(lhs)


def test_dry_run_lists_points_without_meshing(tmp_path, capsys):
    out = tmp_path / "out"
    assert (
        main(["study", str(EXAMPLES / "coarse_2x2.toml"), "--out", str(out), "--dry-run", "--json"])
        == 0
    )
    report = json.loads(capsys.readouterr().out)
    assert report["counts"] == {"todo": 4}
    assert not (out / "geometry").exists()


def test_bad_study_is_one_line_and_exit_1(tmp_path, capsys):
    path = _write(tmp_path, ONE_CLEARANCE.replace("levels = [0.0]", "levels = [0.0, 12.0]"))
    assert main(["study", str(path), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "clearance_mm" in err
    assert "12" in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()  # refused before anything was created


def test_study_runs_fits_retries_failed(tmp_path, capsys, monkeypatch):
    from cad.errors import ConvergenceError
    from model.service import ModelService

    path = _write(tmp_path, ONE_CLEARANCE)
    out = tmp_path / "out"
    real = ModelService._compute

    def fail_400(self, spec, point, prepared, progress):
        if point.amplitude_n == 400.0:
            raise ConvergenceError("refused by the test", increment=1, iteration=60, residual=1.0)
        return real(self, spec, point, prepared, progress)

    monkeypatch.setattr(ModelService, "_compute", fail_400)
    assert main(["study", str(path), "--out", str(out), "--json"]) == 1
    first = json.loads(capsys.readouterr().out)
    assert (first["computed"], first["failed"]) == (1, 1)
    assert "--retry-failed" in first["next"]
    monkeypatch.setattr(ModelService, "_compute", real)
    assert main(["study", str(path), "--out", str(out), "--dry-run", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["counts"] == {"done": 1, "failed": 1}
    assert main(["study", str(path), "--out", str(out), "--retry-failed"]) == 0
    captured = capsys.readouterr()
    assert "[1/1]" in captured.err  # only the failed point ran
    assert "next: hingelab trace" in captured.out
    fit = json.loads((out / "rsm" / "fit.json").read_text())
    assert fit["n_points"] == 2
    # zero clearance: η does not depend on the amplitude, so the fitted slope vanishes
    slope = fit["coefficients"][1]["coefficient"]
    assert abs(slope) * 200.0 < 1e-6 * abs(fit["coefficients"][0]["coefficient"])
    assert (out / "study.toml").is_file()


BEARING = """
[study]
name = "bearing"
model = "MODEL_bearing.toml"
[design]
type = "full_factorial"
[design.preload_N]
levels = [0.0, 100.0, 200.0]
[design.amplitude_N]
levels = [200.0, 400.0]
"""


def _bearing(tmp_path: Path, text: str = BEARING) -> Path:
    """A bearing study beside a copy of the shipped bearing model."""
    (tmp_path / "MODEL_bearing.toml").write_text((EXAMPLES / "MODEL_bearing.toml").read_text())
    return _write(tmp_path, text)


def test_a_bearing_study_varies_preload_and_amplitude(tmp_path):
    s = read_study(EXAMPLES / "bearing_coarse_2x2.toml")
    assert (s.kind, s.variables) == ("bearing", ("preload_N", "amplitude_N"))
    assert s.points == ((0.0, 200.0), (0.0, 400.0), (200.0, 200.0), (200.0, 400.0))
    assert s.surface is not None
    assert s.surface.x == ("preload_N", "amplitude_N")
    pts = s.sweep_settings().design_points()
    assert [(p.values, p.amplitude_n) for p in pts] == [
        ({"preload_n": fp}, a) for fp, a in s.points
    ]
    # a variable left out stays at the model's value; [hinge] sets the bearing's numbers
    text = BEARING.replace("levels = [0.0, 100.0, 200.0]", "").replace("[design.preload_N]\n", "")
    text = text.replace(
        "[design]", "[hinge]\ncontact_angle_deg = 20.0\n[surface]\ndegree = 1\n[design]"
    )
    one = read_study(_bearing(tmp_path, text))
    assert one.points == ((100.0, 200.0), (100.0, 400.0))  # the model's preload_n = 100
    assert one.spec.hinge.contact_angle_deg == 20.0
    assert one.surface is not None
    assert one.surface.x == ("amplitude_N",)  # the default x: what the study varies
    # min/max designs as for the clearance
    lhs = BEARING.replace('"full_factorial"', '"latin_hypercube"\nsamples = 6').replace(
        "levels = [0.0, 100.0, 200.0]", "min = 50.0\nmax = 250.0"
    )
    lhs = lhs.replace("levels = [200.0, 400.0]", "min = 100.0\nmax = 500.0")
    points = read_study(_bearing(tmp_path, lhs)).points
    assert len(points) == 6
    assert all(50.0 <= fp <= 250.0 and 100.0 <= a <= 500.0 for fp, a in points)
    # the coarse preset of a bearing model is the coarse bearing mesh, not the general one
    coarse = read_study(_bearing(tmp_path, BEARING + '[mesh]\npreset = "coarse"\n'))
    assert (coarse.spec.mesh.size_mm, coarse.spec.mesh.contact_size_mm) == (4.0, 0.8)
    assert coarse.spec.mesh.part_sizes_mm == (("ring", 1.2),)
    # full balls bring their own meshed ball (fe.bearing.ball_rig): the structure is meshed
    # without balls, as for hertz
    preset = '[mesh]\npreset = "default"\n'
    hertz = read_study(_bearing(tmp_path, BEARING + preset)).spec.mesh
    path = _bearing(tmp_path, BEARING + preset)
    model = tmp_path / "MODEL_bearing.toml"
    model.write_text(model.read_text().replace('ball_model = "HERTZ"', 'ball_model = "FULL"'))
    full = read_study(path)
    assert full.spec.hinge.ball_model.value == "full"
    assert full.spec.mesh == hertz


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            ("[design.preload_N]", "[design.clearance_mm]"),
            r"\[design\] clearance_mm is a design variable of the general hinge; the model is the "
            r"bearing hinge, whose study varies preload_N, amplitude_N",
        ),
        (
            ("levels = [0.0, 100.0, 200.0]", "levels = [0.0, 600.0]"),
            r"\[design\] point 3 \(preload_N = 600, amplitude_N = 200\): preload_N must be in "
            r"\[0, 500\], got 600",
        ),
        (
            ("[design]", "[hinge]\npreload_n = 50.0\n[design]"),
            r"\[hinge\] unknown key\(s\) \['preload_n'\]; allowed: bore_mm",
        ),
        (
            ("[design]", "[hinge]\ncontact_angle_deg = 95.0\n[design]"),
            r"\[hinge\] contact_angle_deg",
        ),
        (
            ("[design]", '[surface]\nx = ["clearance_mm"]\n[design]'),
            r"\[surface\] x must list design variables the study varies",
        ),
    ],
    ids=["clearance-in-bearing", "preload-range", "preload-in-hinge", "hinge-range", "surface-x"],
)
def test_bad_bearing_study_refused_by_key_and_range(tmp_path, edit, message):
    with pytest.raises(ParameterError, match=message):
        read_study(_bearing(tmp_path, BEARING.replace(*edit, 1)))


def test_a_preload_in_a_general_study_is_refused_by_name(tmp_path):
    text = ONE_CLEARANCE.replace("[design.clearance_mm]", "[design.preload_N]")
    with pytest.raises(
        ParameterError,
        match=r"\[design\] preload_N is a design variable of the bearing hinge; the model is the "
        r"general hinge, whose study varies clearance_mm, amplitude_N",
    ):
        read_study(_write(tmp_path, text))


def test_bearing_dry_run_prints_preloads(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["study", str(EXAMPLES / "bearing_coarse_2x2.toml"), "--out", str(out), "--dry-run"]
    assert main([*argv, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert [(p["preload_N"], p["amplitude_N"]) for p in report["points"]] == [
        (0.0, 200.0), (0.0, 400.0), (200.0, 200.0), (200.0, 400.0)
    ]  # fmt: skip
    assert "clearance_mm" not in report["points"][0]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "F_p = 200 N" in text
    assert "Δr" not in text
    assert not (out / "geometry").exists()


def test_sweep_points_follow_the_hinge_kind():
    """Explicit points are (clearance, amplitude) on the general hinge, (preload, amplitude)
    on the bearing hinge; the general hinge's points and keys are unchanged."""
    from model.spec import DesignPoint
    from studies.sweep import SweepSettings

    bearing = SweepSettings(hinge="bearing", points=((100.0, 200.0), (100, 200.0), (0.0, 50.0)))
    assert bearing.design_points() == [
        DesignPoint(200.0, {"preload_n": 100.0}),
        DesignPoint(50.0, {"preload_n": 0.0}),
    ]
    general = SweepSettings(points=((0.1, 200.0),))
    assert general.design_points() == [DesignPoint(200.0, {"clearance_mm": 0.1})]
    with pytest.raises(ParameterError, match=r"preload_n must be in \[0, 500\], got 600"):
        SweepSettings(hinge="bearing", points=((600.0, 200.0),))
