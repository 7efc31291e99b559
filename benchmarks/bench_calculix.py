"""Our solver against CalculiX on the same cycle and mesh: wall time and peak memory.

Both solve the general hinge's 0 → +Fg → −Fg → +Fg cycle (400 N, μ = 0.2, Δr = 0) on
the same mesh. Ours (``hingelab cycle``) factorises the stiffness once and condenses it
onto the contact points; ccx (the deck of ``hingelab export-inp``: C3D8I, node-to-surface
penalty contact) assembles and refactorises the full unsymmetric system in every Newton
iteration. Each solver runs as its own process, one at a time, ccx on one thread; peak
memory is the process's maximum resident set (``wait4``).

Run:
    .venv/bin/python benchmarks/bench_calculix.py [coarse,default] [timeout_s] [mu] [ccx_steps]

``ccx_steps`` < 3 runs ccx on the first steps only (ours always runs the whole cycle): with
the default node-to-surface deck ccx does not finish the cycle (docs/calculix_crosscheck.md),
so its first loading is a lower bound of its cost.
    .venv/bin/python benchmarks/bench_calculix.py penalty   # frictionless δ(+Fg) vs slope
    .venv/bin/python benchmarks/bench_calculix.py mortar [clearance_mm] [timeout_s] [increments]

``mortar``: the whole cycle in both solvers on the conforming coarse mesh of the slow
cross-check (uniform arcs, pin and hole nodes at the same angles), ccx with the exact
mortar deck (``DeckSettings.exact_mortar``), which completes it; with the loop figures.
``increments`` per stage for ccx, and for ours at Δr = 0 (default 40: the slow cross-check's
Δr = 0 case, where ccx's loop area is within 5 % of ours; ours is converged at 20). With
clearance ours runs its ``clearance_increments`` (60) whatever this says.

The table goes into docs/calculix_crosscheck.md.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table

ROOT = Path(__file__).resolve().parents[1]
AMPLITUDE_N = 400.0
MU = 0.2
PENALTIES = (1e4, 1e5, 1e6, 1e7, 1e8)
CONFORMING = {"slave_ratio": 1.0, "arc_grading": 1.0}


def model_file(
    folder: Path, mesh: str, clearance_mm: float = 0.0, mu: float = MU, increments: int = 20
) -> Path:
    """Write the benchmark's MODEL.toml (coarse, default or conforming mesh)."""
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.file import write_model
    from model.spec import ModelSpec

    if mesh == "conforming":
        settings = MeshSettings.coarse(**CONFORMING)
    else:
        settings = MeshSettings.coarse() if mesh == "coarse" else MeshSettings()
    spec = ModelSpec(
        "general",
        GeneralHingeParams(clearance_mm=clearance_mm),
        settings,
        CycleSettings(amplitude_n=AMPLITUDE_N, mu=mu, increments_per_stage=increments),
    )
    return write_model(spec, folder / f"{mesh}.toml")


def timed(cmd: list[str], timeout_s: float, cwd: Path | None = None) -> tuple[float, float, int]:
    """Run ``cmd``; return (wall [s], peak resident memory [MB], exit status)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env
    )
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            return (
                time.perf_counter() - t0,
                usage.ru_maxrss / 1024.0,
                os.waitstatus_to_exitcode(status),
            )
        if time.perf_counter() - t0 > timeout_s:
            proc.kill()
            proc.wait()
            return float("inf"), float("nan"), -9
        time.sleep(0.1)


def compare(
    mesh: str, folder: Path, timeout_s: float, mu: float, steps: int = 3
) -> dict[str, object]:
    """Run both solvers on one mesh (ccx on the first ``steps`` steps); return a table row."""
    toml = model_file(folder, mesh, mu=mu)
    out = folder / f"ours_{mesh}"
    hingelab = str(ROOT / ".venv" / "bin" / "hingelab")
    ours_s, ours_mb, rc = timed(
        [
            hingelab,
            "cycle",
            "--model",
            str(toml),
            "--out",
            str(out),
            "--no-progress",
            "--frames",
            "0",
        ],
        timeout_s,
    )
    result = json.loads((out / "result.json").read_text()) if rc == 0 else {}
    deck = folder / f"ccx_{mesh}" / "hinge.inp"
    subprocess.run(
        [hingelab, "export-inp", str(toml), "--out", str(deck), "--steps", str(steps)],
        check=True,
        capture_output=True,
    )
    ccx_s, ccx_mb, ccx_rc = _ccx(deck, timeout_s)
    sta = deck.with_suffix(".sta")
    rows = [ln.split() for ln in sta.read_text().splitlines()] if sta.exists() else []
    rows = [r for r in rows if len(r) > 3 and r[0].isdigit()]  # skip the two header lines
    return {
        "mesh": mesh,
        "mu": mu,
        "ccx_steps": steps,
        "n_hex": result.get("n_hex", ""),
        "n_dof_ours": result.get("n_dof", ""),
        "ours_s": ours_s,
        "ours_MB": ours_mb,
        "ccx_s": ccx_s,
        "ccx_MB": ccx_mb,
        "ccx_incs": sum(not r[2].endswith("U") for r in rows),
        "ccx_iters": sum(int(r[3]) for r in rows),
        "ccx_ok": ccx_rc == 0,
        "time_ratio": ccx_s / ours_s,
        "mem_ratio": ccx_mb / ours_mb,
    }


def _ccx(deck: Path, timeout_s: float) -> tuple[float, float, int]:
    """Run ccx on a deck; exit status 1 if it stopped on a failed increment."""
    wall, mb, rc = timed(["ccx", "-i", deck.stem], timeout_s, cwd=deck.parent)
    log = deck.with_suffix(".sta")
    if rc == 0 and log.exists() and "U" in log.read_text().splitlines()[-1].split()[2]:
        rc = 1  # ccx exits 0 even when an increment fell below the minimum size
    return wall, mb, rc


def mortar_row(
    folder: Path, clearance_mm: float, timeout_s: float, increments: int = 40
) -> dict[str, object]:
    """The whole cycle in both solvers on the conforming mesh, ccx with exact mortar contact."""
    from cad.general import make_general_hinge
    from cad.general_params import GeneralHingeParams
    from fe.effects.registry import REGISTRY
    from fe.interop.ccx import loop_figures, loop_from_dat, parse_dat, parse_sta
    from fe.interop.deck_settings import DeckSettings
    from fe.interop.inp import write_deck
    from fe.interop.inp_names import GRIP_REF_SET
    from mesh.build import mesh_hinge
    from model.file import read_model

    toml = model_file(folder, "conforming", clearance_mm=clearance_mm, increments=increments)
    out = folder / "ours_conforming"
    hingelab = str(ROOT / ".venv" / "bin" / "hingelab")
    argv = [hingelab, "cycle", "--model", str(toml), "--out", str(out), "--no-progress"]
    ours_s, ours_mb, _ = timed([*argv, "--frames", "0"], timeout_s)
    result = json.loads((out / "result.json").read_text())
    spec = read_model(toml, REGISTRY)
    if not isinstance(spec.hinge, GeneralHingeParams):
        raise TypeError(f"{toml}: expected the general hinge, got {type(spec.hinge).__name__}")
    model = make_general_hinge(spec.hinge)
    mesh, _ = mesh_hinge(model, spec.mesh)
    settings = DeckSettings.exact_mortar(
        amplitude_n=AMPLITUDE_N,
        mu=MU,
        clearance_mm=clearance_mm,
        increments_per_stage=increments,
    )
    deck = write_deck(mesh, model.faces, settings, folder / "ccx_mortar" / "hinge.inp")
    ccx_s, ccx_mb, ccx_rc = _ccx(deck, timeout_s)
    sta = parse_sta(deck.with_suffix(".sta"))
    done = ccx_rc == 0 and sta.last_time > 2.999
    ratios = [float("nan")] * 3
    if done:  # a run stopped by the time limit has no loop to measure
        loop = loop_from_dat(parse_dat(deck.with_suffix(".dat")), GRIP_REF_SET, ["tang_fixed"])
        theirs = loop_figures(
            loop.hinge_force_n,
            loop.grip_disp_mm,
            loop.step,
            AMPLITUDE_N,
            free_play_mm=4.0 * clearance_mm,
        )
        ratios = [
            theirs.disp_at_plus_mm / result["disp_at_peak_mm"],
            theirs.disp_at_minus_mm / result["disp_at_minus_peak_mm"],
            theirs.area_nmm / result["W_cycle_Nmm"],
        ]
    return {
        "clearance_mm": clearance_mm,
        "n_hex": result["n_hex"],
        "ours_s": ours_s,
        "ours_MB": ours_mb,
        "ccx_s": ccx_s,
        "ccx_MB": ccx_mb,
        "ccx_incs": sta.increments,
        "ccx_iters": sta.iterations,
        "ccx_ok": done,
        "time_ratio": ccx_s / ours_s,
        "mem_ratio": ccx_mb / ours_mb,
        "d_plus_ratio": ratios[0],
        "d_minus_ratio": ratios[1],
        "area_ratio": ratios[2],
    }


def penalty_table(folder: Path) -> list[dict[str, object]]:
    """Frictionless first loading: ccx's δ(+Fg) per penalty slope against ours (μ = 0)."""
    from fe.interop.ccx import loop_from_dat, parse_dat, run_ccx
    from fe.interop.inp_names import GRIP_REF_SET
    from studies.cli.main import main

    toml = model_file(folder, "coarse")
    out = folder / "ours_mu0"
    main(
        [
            "cycle",
            "--model",
            str(toml),
            "--mu",
            "0",
            "--out",
            str(out),
            "--no-progress",
            "--frames",
            "0",
        ]
    )
    rows = list((out / "loop.csv").read_text().splitlines())[1:]
    ours = next(
        float(r.split(",")[1])
        for r in rows
        if r.split(",")[2] == "0" and float(r.split(",")[0]) == AMPLITUDE_N
    )
    table: list[dict[str, object]] = []
    for contact in ("node", "surface"):
        for k in PENALTIES:
            deck = folder / f"pen_{contact}_{k:g}" / "hinge.inp"
            argv = ["export-inp", str(toml), "--out", str(deck), "--mu", "0", "--steps", "1"]
            main([*argv, "--penalty", f"{k:g}", "--contact", contact])
            try:
                run = run_ccx(deck, timeout_s=1800.0)
                loop = loop_from_dat(parse_dat(run.dat), GRIP_REF_SET, ["tang_fixed"])
                d, wall = float(loop.grip_disp_mm[-1]), run.wall_s
            except Exception as err:  # a failed slope is a row of the table, not the end of it
                d, wall = float("nan"), float("nan")
                print(f"{contact} {k:g}: {err}", file=sys.stderr)
            table.append(
                {
                    "contact": contact,
                    "penalty_MPa_per_mm": f"{k:g}",
                    "ccx_um": d * 1e3,
                    "ours_um": ours * 1e3,
                    "rel_diff": d / ours - 1.0,
                    "ccx_s": wall,
                }
            )
    return table


if __name__ == "__main__":
    args = sys.argv[1:]
    if not any((Path(d) / "ccx").exists() for d in os.environ.get("PATH", "").split(os.pathsep)):
        print("bench_calculix: no ccx on PATH (apt-get install calculix-ccx); skipped")
        sys.exit(0)
    with tempfile.TemporaryDirectory(prefix="bench_calculix_") as tmp:
        if args[:1] == ["mortar"]:
            clearance = float(args[1]) if len(args) > 1 else 0.0
            timeout = float(args[2]) if len(args) > 2 else 2400.0
            increments = int(args[3]) if len(args) > 3 else 40
            row = mortar_row(Path(tmp), clearance, timeout, increments)
            print_table([row], list(row))
        elif args[:1] == ["penalty"]:
            rows = penalty_table(Path(tmp))
            print_table(
                rows, ["contact", "penalty_MPa_per_mm", "ccx_um", "ours_um", "rel_diff", "ccx_s"]
            )
        else:
            meshes = (args[0] if args else "coarse,default").split(",")
            timeout = float(args[1]) if len(args) > 1 else 7200.0
            mu = float(args[2]) if len(args) > 2 else MU
            steps = int(args[3]) if len(args) > 3 else 3
            rows = [compare(m, Path(tmp), timeout, mu, steps) for m in meshes]
            print_table(
                rows,
                [
                    "mesh",
                    "mu",
                    "ccx_steps",
                    "n_hex",
                    "n_dof_ours",
                    "ours_s",
                    "ours_MB",
                    "ccx_s",
                    "ccx_MB",
                    "ccx_incs",
                    "ccx_iters",
                    "ccx_ok",
                    "time_ratio",
                    "mem_ratio",
                ],
            )
