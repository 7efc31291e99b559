"""Our loop against CalculiX's on the same mesh (docs/calculix_crosscheck.md).

The general hinge on a coarse *conforming* mesh (``CONFORMING``: uniform arcs, pin and hole
nodes at the same angles, so ccx's faceted surfaces start without overclosure; at Δr 0.1 mm
with a 1 mm contact size, ``FINE_CONTACT``, which ccx needs there), 400 N, μ = 0.2,
Δr = 0 and 0.1 mm: our solver runs through its command line (``hingelab cycle``,
whose loop.csv is a stable interface), ccx runs the deck ``DeckSettings.exact_mortar()``
writes for the same model file and mesh: mortar contact, hard normal contact, exact stick.
Compared: the grip displacement at ±Fg (within 5 %) and the loop area (within 15 %). A
frictionless first loading with node-to-surface penalty contact (the default coarse mesh),
the penalty slope raised step by step, must approach our Lagrange-multiplier answer.

ccx is installed with apt when it is missing (the test says so on stderr); where that is
impossible the tests skip and say why.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from fe.interop.ccx import find_ccx, loop_figures, loop_from_dat, parse_dat, run_ccx
from fe.interop.deck_settings import DeckSettings
from fe.interop.inp import write_deck
from fe.interop.inp_names import GRIP_REF_SET
from studies.cli.main import main

pytestmark = pytest.mark.slow

AMPLITUDE_N = 400.0
MU = 0.2
CONFORMING = {"slave_ratio": 1.0, "arc_grading": 1.0}
"""MeshSettings.coarse() overrides: 16 equal facets around pin and holes, at the same angles."""


@pytest.fixture(scope="module")
def ccx():
    """The ccx executable, else skip with the command that installs it (no installs here)."""
    exe = find_ccx()
    if exe is None:
        pytest.skip("CalculiX (ccx) is not installed: run `make peers` (needs root) to install it")
    return exe


def model_file(tmp_path, clearance_mm, increments_per_stage=20, **mesh):
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.file import write_model
    from model.spec import ModelSpec

    spec = ModelSpec(
        "general",
        GeneralHingeParams(clearance_mm=clearance_mm),
        MeshSettings.coarse(**mesh),
        CycleSettings(amplitude_n=AMPLITUDE_N, mu=MU, increments_per_stage=increments_per_stage),
    )
    return write_model(spec, tmp_path / "MODEL.toml")


def ours(tmp_path, toml, *extra):
    """Run ``hingelab cycle``; return (result.json, force, displacement, stage) of loop.csv."""
    out = tmp_path / "ours"
    argv = ["cycle", "--model", str(toml), "--out", str(out), "--json", "--no-progress"]
    assert main([*argv, "--frames", "0", *extra]) == 0
    with (out / "loop.csv").open() as f:
        rows = list(csv.DictReader(f))
    col = {k: np.array([float(r[k]) for r in rows]) for k in ("force_N", "displacement_mm")}
    stage = np.array([int(r["stage"]) for r in rows], dtype=np.int64)
    result = json.loads((out / "result.json").read_text())
    return result, col["force_N"], col["displacement_mm"], stage


def theirs_mortar(tmp_path, toml, timeout_s=2400.0):
    """Write the model file's deck with ccx's exact mortar contact, run it; return (n_elem, loop)."""
    from cad.general import make_general_hinge
    from fe.effects.registry import REGISTRY
    from mesh.build import mesh_hinge
    from model.file import read_model

    spec = read_model(toml, REGISTRY)
    model = make_general_hinge(spec.hinge)
    mesh, _ = mesh_hinge(model, spec.mesh)
    settings = DeckSettings.exact_mortar(
        amplitude_n=spec.cycle.amplitude_n,
        mu=spec.cycle.mu,
        clearance_mm=spec.hinge.clearance_mm,
        increments_per_stage=spec.cycle.increments_per_stage,
    )
    deck = write_deck(mesh, model.faces, settings, tmp_path / "ccx" / "hinge.inp")
    run = run_ccx(deck, timeout_s=timeout_s)
    return mesh.n_elem, loop_from_dat(parse_dat(run.dat), GRIP_REF_SET, ["tang_fixed"])


def theirs(tmp_path, toml, *extra, timeout_s=1200.0):
    """Export the deck, run ccx (at most ``timeout_s``); return its loop."""
    deck = tmp_path / "ccx" / "hinge.inp"
    assert main(["export-inp", str(toml), "--out", str(deck), *extra]) == 0
    run = run_ccx(deck, timeout_s=timeout_s)
    return loop_from_dat(parse_dat(run.dat), GRIP_REF_SET, ["tang_fixed"])


FINE_CONTACT = {**CONFORMING, "contact_size_mm": 1.0}
"""The conforming mesh with a 1 mm contact size (7 496 hexahedra at Δr 0.1, 25 facets around).

The contact at Δr 0.1 is best resolved there (δ(±Fg) agree to 0.6 %; 2.6 and 4.7 % on the 2 mm mesh).
On the 2 mm mesh ccx's raw loop was 9.4 times ours: it ends the free-play crossing 10 µm
before the touch with 0.18 N on the tang, which the loop measure counted over the whole
crossing until it removed the free play from every point (then 1.09;
docs/calculix_crosscheck.md)."""


@pytest.mark.parametrize(
    ("clearance_mm", "increments_per_stage", "mesh", "timeout_s"),
    [
        # ccx's first increment after a reversal or a zero crossing overshoots by an amount
        # that shrinks with the increment: at 20 per stage its loop area is 0.80 of ours,
        # at 40 it is 0.953 (ours is converged: 0.0630 N·mm at both). ccx: ~8-20 minutes.
        pytest.param(0.0, 40, CONFORMING, 2400.0, id="dr0"),
        # measured: δ(±Fg) 0.995 / 0.994, loop area 1.105 (lobes 1.13 / 1.04); ccx 239
        # increments, 767 iterations; the test took 85 minutes with the cores shared
        pytest.param(0.1, 20, FINE_CONTACT, 7200.0, id="dr0.1"),
    ],
)
def test_loop_matches_calculix(
    ccx, tmp_path, clearance_mm, increments_per_stage, mesh, timeout_s, capsys
):
    toml = model_file(tmp_path, clearance_mm, increments_per_stage, **mesh)
    result, f, d, stage = ours(tmp_path, toml)
    capsys.readouterr()
    mine = loop_figures(f, d, stage, AMPLITUDE_N, loop_stages=(1, 2))
    # loop.csv carries 8 significant digits; the shoelace sum cancels ~25-fold over 160 points
    assert mine.disp_at_plus_mm == pytest.approx(result["disp_at_peak_mm"], rel=1e-7)
    assert mine.area_nmm == pytest.approx(result["W_cycle_Nmm"], rel=1e-4)
    n_elem, loop = theirs_mortar(tmp_path, toml, timeout_s)
    assert n_elem == result["n_hex"]  # the same mesh
    assert loop.time[-1] == pytest.approx(3.0)  # ccx completed the cycle
    other = loop_figures(
        loop.hinge_force_n,
        loop.grip_disp_mm,
        loop.step,
        AMPLITUDE_N,
        free_play_mm=4.0 * clearance_mm,
    )
    measured = (
        f"ccx/ours: δ(+Fg) {other.disp_at_plus_mm / mine.disp_at_plus_mm:.3f}, "
        f"δ(−Fg) {other.disp_at_minus_mm / mine.disp_at_minus_mm:.3f}, "
        f"area {other.area_nmm / mine.area_nmm:.3f}"
    )
    assert other.disp_at_plus_mm == pytest.approx(mine.disp_at_plus_mm, rel=0.05), measured
    assert other.disp_at_minus_mm == pytest.approx(mine.disp_at_minus_mm, rel=0.05), measured
    assert other.area_nmm == pytest.approx(mine.area_nmm, rel=0.15), measured


def test_frictionless_penalty_converges_to_lagrange(ccx, tmp_path, capsys):
    """ccx's δ(+Fg) at μ = 0, first loading, approaches ours as the penalty slope grows."""
    toml = model_file(tmp_path, 0.0)
    _, _, d, stage = ours(tmp_path, toml, "--mu", "0")
    capsys.readouterr()
    target = float(d[np.flatnonzero(stage == 0)[-1]])
    errors = []
    for k in (1e4, 1e5, 1e6, 1e8):
        loop = theirs(
            tmp_path / f"k{k:g}", toml, "--mu", "0", "--penalty", f"{k:g}", "--steps", "1"
        )
        errors.append(loop.grip_disp_mm[-1] / target - 1.0)
    # Measured: +53.8 %, +7.1 %, +2.9 %, +2.5 %. What is left at 1e8 is the faceted hole
    # (ADJUST moves the pin nodes onto its chords) against our exact cylinders.
    assert errors[0] > errors[1] > errors[2] > errors[3] > 0.0, errors
    assert errors[3] < 0.03, errors
    assert errors[2] - errors[3] < 0.01, errors


def test_default_deck_completes_in_calculix(ccx, tmp_path, capsys):
    """``hingelab export-inp MODEL.toml`` with no options writes a deck ccx finishes (issue 33,
    item 9): on the coarse model mesh, 6 increments per stage, the mortar deck on the
    conforming mesh took 2.7 min (node-to-surface had run > 20 min without finishing)."""
    toml = model_file(tmp_path, 0.0, increments_per_stage=6)  # the graded coarse mesh
    loop = theirs(tmp_path, toml, timeout_s=1200.0)
    assert "caution" not in capsys.readouterr().err
    assert loop.time[-1] == pytest.approx(3.0)  # all three steps
    peak = np.max(np.abs(loop.hinge_force_n))
    assert peak == pytest.approx(AMPLITUDE_N, rel=1e-3)
