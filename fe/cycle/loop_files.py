"""The loop of a cycle as files: loop.csv (force, grip displacement) and loop.png."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from fe.cycle.result import CycleResult

LOOP_COLUMNS = ("force_N", "displacement_mm", "stage", "increment", "side")
"""Columns of loop.csv; the first two are those of a measured loop."""


def write_loop_csv(result: CycleResult, path: Path, *, with_free_play: bool = False) -> Path:
    """Write the loop: force [N] and grip displacement [mm], one row per increment."""
    F, d, stage = result.loop_arrays(with_free_play=with_free_play)
    side = [1] + [i.side for i in result.increments]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(LOOP_COLUMNS)
        for k in range(len(F)):
            w.writerow([f"{F[k]:.9g}", f"{d[k]:.9g}", int(stage[k]), k, side[k]])
    return path


def write_loop_png(result: CycleResult, path: Path, *, title: str = "") -> Path:
    """Plot the loop with the free play removed (left) and, if there is any, with it (right)."""
    from matplotlib.figure import Figure  # no pyplot: no global state, no backend to choose

    m = result.metrics()
    play = result.free_play_mm > 0
    fig = Figure(figsize=(13 if play else 7.5, 5.5))
    axes = fig.subplots(1, 2 if play else 1, squeeze=False)
    ax = axes[0, 0]
    F, d, stage = result.loop_arrays(with_free_play=result.faces_slide)  # where η is measured
    names = ["0 → +Fg (initial)"] + [
        ("+Fg → −Fg" if s % 2 else "−Fg → +Fg") for s in range(1, stage.max() + 1)
    ]
    for s in range(stage.max() + 1):
        sel = np.flatnonzero(stage == s)
        if s > 0:
            sel = np.concatenate([[sel[0] - 1], sel])
        ax.plot(d[sel] * 1e3, F[sel], "-o", ms=2.5, lw=1.4, label=f"stage {s}: {names[s]}")
    dm = m["delta_max_mm"] * 1e3
    ax.plot(
        [0, dm],
        [0, result.settings.amplitude_n],
        "k--",
        lw=0.8,
        label="U_max = ½·Fg·δ_max, δ_max = (δ(+Fg) − δ(−Fg))/2",
    )
    ax.axhline(0, color="k", lw=0.5)
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel(
        "grip displacement δ [µm], "
        + ("with the free play (slid by the faces)" if result.faces_slide else "free play removed")
    )
    ax.set_ylabel("force F [N]")
    ax.set_title(title or "hysteresis loop")
    ax.legend(
        loc="upper left",
        fontsize=8,
        title=f"η = {m['eta']:.4f},  W = {m['W_cycle_Nmm']:.4g} N·mm",
        title_fontsize=9,
    )
    ax.grid(alpha=0.3)
    if play:
        ax2 = axes[0, 1]
        F_raw, d_raw = result.machine_path()
        ax2.plot(d_raw * 1e3, F_raw, "-", color="grey", lw=1.2)
        ax2.axhline(0, color="k", lw=0.5)
        ax2.set_xlabel("grip displacement [µm], with the free play 4Δr")
        ax2.set_ylabel("force F [N]")
        where = "at the faces' slip force" if result.faces_slide else "at F ≈ 0"
        ax2.set_title(
            f"as a test machine sees it: free play {result.free_play_mm * 1e3:.0f} µm {where}"
        )
        ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    return path
