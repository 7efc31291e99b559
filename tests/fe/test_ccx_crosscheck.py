"""Our loop against CalculiX's on the same mesh (docs/calculix_crosscheck.md).

The general hinge on the coarse mesh, 400 N, μ = 0.2, Δr = 0 and 0.1 mm: our solver runs
through its command line (``hingelab cycle``, whose loop.csv is a stable interface), the
same model goes to ccx as the deck ``hingelab export-inp`` writes. Compared: the grip
displacement at ±Fg (within 5 %) and the loop area (within 15 %). A frictionless first
loading with the penalty slope raised step by step must approach our Lagrange-multiplier
answer.

ccx is installed with apt when it is missing (the test says so on stderr); where that is
impossible the tests skip and say why.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from cad.errors import ConvergenceError, SolverError
from fe.interop.ccx import find_ccx, loop_figures, loop_from_dat, parse_dat, run_ccx
from fe.interop.inp import GRIP_REF_SET
from studies.cli import main

pytestmark = pytest.mark.slow
pytest.importorskip("gmsh")

AMPLITUDE_N = 400.0
MU = 0.2


@pytest.fixture(scope="module")
def ccx():
    """The ccx executable; installed with apt-get if missing, else the module skips."""
    exe = find_ccx()
    if exe is not None:
        return exe
    if shutil.which("apt-get") is None or os.geteuid() != 0:
        pytest.skip("CalculiX (ccx) is not installed and apt-get is unavailable or not root")
    print("ccx missing: running apt-get install -y calculix-ccx", file=sys.__stderr__)
    for cmd in (["apt-get", "update"], ["apt-get", "install", "-y", "calculix-ccx"]):
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            pytest.skip(f"could not install CalculiX: {' '.join(cmd)} failed: {done.stderr[-300:]}")
    exe = find_ccx()
    if exe is None:
        pytest.skip("apt-get installed calculix-ccx but there is no ccx on PATH")
    return exe


def model_file(tmp_path, clearance_mm):
    from cad.general import GeneralHingeParams
    from fe.hinge.cycle import CycleSettings
    from mesh.settings import MeshSettings
    from validation.model_file import ModelSpec, write_model

    spec = ModelSpec(
        "general",
        GeneralHingeParams(clearance_mm=clearance_mm),
        MeshSettings.coarse(),
        CycleSettings(amplitude_n=AMPLITUDE_N, mu=MU),
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


def theirs(tmp_path, toml, *extra, timeout_s=1200.0):
    """Export the deck, run ccx (at most ``timeout_s``); return its loop."""
    deck = tmp_path / "ccx" / "hinge.inp"
    assert main(["export-inp", str(toml), "--out", str(deck), *extra]) == 0
    run = run_ccx(deck, timeout_s=timeout_s)
    return loop_from_dat(parse_dat(run.dat), GRIP_REF_SET, ["tang_fixed"])


# Measured on this machine with the default deck (node-to-surface, penalty 1e6 MPa/mm, stick
# slope 1e6 MPa/mm); the causes are worked out in docs/calculix_crosscheck.md.
XFAIL_DR0 = pytest.mark.xfail(
    raises=(ConvergenceError, SolverError),  # SolverError: the 20-minute limit
    reason="ccx's penalty friction stalls in step 2 at F = -318 N (Newton cycles stick/slip, "
    "increments shrink to 2e-4); up to there ccx/ours: first loading δ(+Fg) 1.017, "
    "unloading slope 1.044, δ at F = 0 on the way down 0.23 (the stick slope turns "
    "micro-slip into elastic shear: a thinner loop)",
)
XFAIL_DR01 = pytest.mark.xfail(
    raises=(AssertionError, ConvergenceError, SolverError),
    reason="the coarse hole facets sag up to 0.16 mm > Δr = 0.1 mm: ccx (faceted surfaces) "
    "sees an interference fit, no free play (δ = 4.6 µm at 369 N including the 0.2 mm "
    "of free play we remove); ours measures gaps on the exact cylinders",
)


@pytest.mark.parametrize(
    "clearance_mm",
    [pytest.param(0.0, marks=XFAIL_DR0), pytest.param(0.1, marks=XFAIL_DR01)],
    ids=["dr0", "dr0.1"],
)
def test_loop_matches_calculix(ccx, tmp_path, clearance_mm, capsys):
    toml = model_file(tmp_path, clearance_mm)
    result, f, d, stage = ours(tmp_path, toml)
    capsys.readouterr()
    mine = loop_figures(f, d, stage, AMPLITUDE_N, loop_stages=(1, 2))
    assert mine.disp_at_plus_mm == pytest.approx(result["disp_at_peak_mm"], rel=1e-9)
    assert mine.area_nmm == pytest.approx(result["W_cycle_Nmm"], rel=1e-6)
    loop = theirs(tmp_path, toml)
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
