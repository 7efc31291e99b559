"""Files and tables of a bearing-hinge cycle: ball loads at ±Fg, preload, ParaView series."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from fe.bearing.cycle import ball_law, ball_state_of
from fe.bearing.system import BearingSystem
from fe.hinge.report import frames_of, write_series
from fe.hinge.result import CycleResult

FloatArray = npt.NDArray[np.float64]


def ball_table(system: BearingSystem, result: CycleResult) -> dict[str, Any]:
    """Ball loads after the preload and at +Fg and −Fg of the last loop.

    Returns:
        ``{"preload": [...], "plus_Fg": [...], "minus_Fg": [...]}``, each a list of one
        row per ball: bearing, ball, azimuth [deg], load Q on the inner and on the outer
        contact [N] (equal: a free-rolling rigid ball), loaded contact angle [deg].
    """
    sl = result.last_loop()
    F, _, _ = result.loop_arrays()
    f = F[sl]
    at = {"plus_Fg": sl.stop - 2, "minus_Fg": sl.start + int(np.argmin(f)) - 1}
    states = {k: result.states[i] for k, i in at.items()}
    if result.preload_state is not None:
        states = {"preload": result.preload_state, **states}
    balls = system.balls
    out: dict[str, Any] = {}
    for key, st in states.items():
        b = ball_state_of(system, st)
        out[key] = [
            {
                "bearing": int(balls.bearing[j]),
                "ball": int(balls.index[j]),
                "azimuth_deg": float(np.degrees(balls.theta[j])),
                "inner_load_N": float(b.load_n[j]),
                "outer_load_N": float(b.load_n[j]),
                "contact_angle_deg": float(b.angle_deg[j]),
            }
            for j in range(system.n_balls)
        ]
    return out


def fit_ball_table(system: Any, result: CycleResult) -> dict[str, Any]:
    """As ``ball_table`` for the frictional-fit hinge (``fe.bearing.fits.FitSystem``).

    Its balls are read from ``result.ball_coordinates`` (row 0: after the preload).
    """
    if result.ball_coordinates is None:
        return {}
    sl = result.last_loop()
    F, _, _ = result.loop_arrays()
    # loop-array index i is increment i − 1, i.e. ball_coordinates row i
    rows = {"preload": 0, "plus_Fg": sl.stop - 1, "minus_Fg": sl.start + int(np.argmin(F[sl]))}
    balls = system.balls
    out: dict[str, Any] = {}
    for key, i in rows.items():
        c = np.asarray(result.ball_coordinates[i])
        v = c[:-1] + c[-1] * system.preload_shift
        d = balls.d0 + v.reshape(-1, 2)
        _, Q, _, _ = ball_law(balls.d0, v.reshape(-1, 2), balls.k_n)
        angle = np.degrees(np.arctan2(np.abs(d[:, 1]), d[:, 0]))
        out[key] = [
            {
                "bearing": int(balls.bearing[j]),
                "ball": int(balls.index[j]),
                "azimuth_deg": float(np.degrees(balls.theta[j])),
                "inner_load_N": float(Q[j]),
                "outer_load_N": float(Q[j]),
                "contact_angle_deg": float(angle[j]),
            }
            for j in range(len(Q))
        ]
    return out


def increment_fields(system: BearingSystem, result: CycleResult, chosen: list[int]) -> FloatArray:
    """Displacement fields of chosen increments, shape (k, n_nodes, 3) [mm]."""
    f = np.zeros((2 * system.n_balls, len(chosen)))
    alpha = np.zeros((3, len(chosen)))
    for c, k in enumerate(chosen):
        st = result.states[k]
        f[:, c] = ball_law(system.balls.d0, np.asarray(st.w[:, 1:]), system.balls.k_n)[0].ravel()
        alpha[:, c] = st.alpha
    u = system.displacement(f, alpha)
    return np.moveaxis(u.reshape(system.mesh.n_nodes, 3, -1), 2, 0)


def write_bearing_series(
    system: BearingSystem, result: CycleResult, folder: Path, *, every: int = 1
) -> Path:
    """ParaView series of a bearing cycle (as ``fe.hinge.report.write_time_series``).

    Point data besides ``displacement``: ``ball_load`` [N], each ball's Q on the nodes of
    its two raceway patches.
    """
    mesh = system.mesh
    chosen = frames_of(result, every)
    fields = increment_fields(system, result, chosen)
    patches = []
    for b, k in zip(system.balls.bearing, system.balls.index, strict=True):
        nodes = [mesh.set_nodes(f"{race}_ring_{b}_groove_{k}") for race in ("inner", "outer")]
        patches.append(np.concatenate(nodes))

    def ball_data(k: int) -> dict[str, FloatArray]:
        load = np.zeros(mesh.n_nodes)
        for j, nodes in enumerate(patches):
            load[nodes] = result.states[k].p[j, 0]
        return {"ball_load": load}

    return write_series(mesh, result, chosen, fields, ball_data, folder)
