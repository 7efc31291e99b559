"""Files of a hysteresis cycle: loop CSV and PNG, ParaView time series (.pvd + .vtu)."""

from __future__ import annotations

import csv
from collections.abc import Callable, Iterable
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np
import numpy.typing as npt

from fe.assembly import stress_field
from fe.cycle.result import CycleResult
from fe.element import ElementType, von_mises
from fe.general.increments import increment_displacements
from fe.general.system import HingeSystem
from mesh.hexmesh import HexMesh
from mesh.io import add_vtu_field_data, vtu_name_codes

FloatArray = npt.NDArray[np.float64]

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


def load_path(result: CycleResult) -> FloatArray:
    """Load-path parameter ``τ = Σ|ΔF| / Fg`` at the origin and every increment, shape (n+1,)."""
    F, _, _ = result.loop_arrays()
    steps = np.abs(np.diff(F)) / result.settings.amplitude_n
    return np.concatenate([[0.0], np.cumsum(steps)])


def write_time_series(
    system: HingeSystem,
    result: CycleResult,
    folder: Path,
    *,
    every: int = 1,
    kind: ElementType = ElementType.INCOMPATIBLE,
) -> Path:
    """Write a ParaView time series: one .vtu per written increment and a .pvd index.

    Point data: ``displacement`` [mm], ``contact_pressure`` [MPa] and ``slip`` [mm]
    (tangential relative displacement since the start of the configuration) on the
    pin's contact nodes. Cell data: ``stress`` (Voigt, [MPa]), ``von_mises`` [MPa], ``part``.
    Field data of every frame: ``force_N``, ``grip_disp_mm``, ``stage``, ``load_path``, and
    the names of the part and set codes (``part:NAME``, ``set:NAME``).

    The time value of a frame is the load path ``τ = Σ|ΔF| / Fg`` (ParaView needs times
    that increase, and the force goes up and down): 0 → 1 on the first loading, 1 → 3 from
    +Fg to −Fg, 3 → 5 back to +Fg, so τ = 1, 3, 5 are the load peaks.

    Returns:
        The .pvd file.
    """
    mesh = system.mesh
    chosen = frames_of(result, every)
    fields = increment_displacements(system, result, chosen)

    def contact_data(k: int) -> dict[str, FloatArray]:
        state, cond = result.states[k], result.configs[result.increments[k].side]
        pressure = np.zeros(mesh.n_nodes)
        slip = np.zeros(mesh.n_nodes)
        pressure[cond.geo.slave] = state.p[:, 0] / cond.geo.area_mm2
        slip[cond.geo.slave] = np.linalg.norm(state.w[:, 1:] - cond.w0[:, 1:], axis=1)
        return {"contact_pressure": pressure, "slip": slip}

    return write_series(mesh, result, chosen, fields, contact_data, folder, kind)


def frames_of(result: CycleResult, every: int) -> list[int]:
    """Increments written to a series: every ``every``-th and the last."""
    n = len(result.increments)
    return [k for k in range(n) if k % every == 0 or k == n - 1]


def write_series(
    mesh: HexMesh,
    result: CycleResult,
    chosen: list[int],
    fields: Iterable[FloatArray],
    point_data: Callable[[int], dict[str, FloatArray]],
    folder: Path,
    kind: ElementType = ElementType.INCOMPATIBLE,
) -> Path:
    """Write the .vtu frames of ``chosen`` increments (displacement ``fields``) and the .pvd.

    ``point_data(k)`` adds a hinge's own point fields to frame ``k``.
    """
    folder.mkdir(parents=True, exist_ok=True)
    entries = []
    names = vtu_name_codes(mesh)
    tau = load_path(result)
    for k, u in zip(chosen, fields, strict=True):
        inc = result.increments[k]
        sigma = stress_field(mesh, u, kind)
        name = f"step_{k:04d}.vtu"
        meshio.write(
            folder / name,
            meshio.Mesh(
                np.asarray(mesh.nodes),
                [("hexahedron", mesh.hexes)],
                point_data={"displacement": u, **point_data(k)},
                cell_data={
                    "stress": [sigma],
                    "von_mises": [von_mises(sigma)],
                    "part": [mesh.elem_part],
                },
            ),
            binary=True,
        )
        add_vtu_field_data(
            folder / name,
            {
                "force_N": float(inc.force_n),
                "grip_disp_mm": float(inc.disp_mm),
                "stage": int(inc.stage),
                "load_path": float(tau[k + 1]),
            }
            | names,
        )
        entries.append(
            f'    <DataSet timestep="{tau[k + 1]:.9g}" part="0" file={quoteattr(name)}/>'
        )
    pvd = folder / "cycle.pvd"
    pvd.write_text(
        '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n  <Collection>\n'
        + "\n".join(entries)
        + "\n  </Collection>\n</VTKFile>\n"
    )
    return pvd
