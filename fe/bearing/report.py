"""Files and tables of a bearing-hinge cycle: ball loads at ±Fg, preload, ParaView series."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from cad.bearing_geometry import BallModel
from cad.errors import ParameterError
from fe.bearing.balls import ball_law, ball_state_of, contact_angles
from fe.bearing.fits import FitSystem
from fe.bearing.system import BearingSystem
from fe.cycle.fields import frames_of, write_series
from fe.cycle.result import CycleResult

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def _peaks(result: CycleResult) -> dict[str, int]:
    """Loop-array indices (origin = 0) of +Fg and −Fg of the last loop."""
    sl = result.last_loop()
    F, _, _ = result.loop_arrays()
    return {"plus_Fg": sl.stop - 1, "minus_Fg": sl.start + int(np.argmin(F[sl]))}


def _rows(balls: Any, load_n: FloatArray, angle_deg: FloatArray) -> list[dict[str, Any]]:
    """One row per ball: where it is, its load on both contacts, its contact angle."""
    return [
        {
            "bearing": int(balls.bearing[j]),
            "ball": int(balls.index[j]),
            "azimuth_deg": float(np.degrees(balls.theta[j])),
            "inner_load_N": float(load_n[j]),
            "outer_load_N": float(load_n[j]),  # a free-rolling rigid ball: the same
            "contact_angle_deg": float(angle_deg[j]),
        }
        for j in range(len(load_n))
    ]


def ball_table(system: BearingSystem, result: CycleResult) -> dict[str, Any]:
    """Ball loads after the preload and at +Fg and −Fg of the last loop.

    Returns:
        ``{"preload": [...], "plus_Fg": [...], "minus_Fg": [...]}``, each a list of one
        row per ball: bearing, ball, azimuth [deg], load Q on the inner and on the outer
        contact [N] (equal: a free-rolling rigid ball), loaded contact angle [deg].
    """
    # loop-array index i is increment i − 1
    states = {k: result.states[i - 1] for k, i in _peaks(result).items()}
    if result.preload_state is not None:
        states = {"preload": result.preload_state, **states}
    out: dict[str, Any] = {}
    for key, st in states.items():
        b = ball_state_of(system, st)
        out[key] = _rows(system.balls, b.load_n, b.angle_deg)
    return out


def fit_ball_table(system: Any, result: CycleResult) -> dict[str, Any]:
    """As ``ball_table`` for the frictional-fit hinge (``fe.bearing.fits.FitSystem``).

    Its balls are read from ``result.ball_coordinates`` (row 0: after the preload).
    """
    if result.ball_coordinates is None:
        return {}
    # loop-array index i is increment i − 1, i.e. ball_coordinates row i
    balls = system.balls
    out: dict[str, Any] = {}
    for key, i in {"preload": 0, **_peaks(result)}.items():
        c = np.asarray(result.ball_coordinates[i])
        v = (c[:-1] + c[-1] * system.preload_shift).reshape(-1, 2)
        _, Q, _, _ = ball_law(balls.d0, v, balls.k_n)
        out[key] = _rows(balls, Q, contact_angles(balls.d0, v))
    return out


def increment_fields(system: BearingSystem, result: CycleResult, chosen: list[int]) -> FloatArray:
    """Displacement fields of chosen increments, shape (k, n_nodes, 3) [mm]."""
    f = np.zeros((2 * system.n_balls, len(chosen)))
    alpha = np.zeros((3, len(chosen)))
    full = system.params.ball_model is BallModel.FULL
    for c, k in enumerate(chosen):
        st = result.states[k]
        if full:  # the meshed balls' forces are stored with the state (fe.bearing.full_cycle)
            f[:, c] = np.asarray(st.p[:, 1:]).ravel()
        else:
            v = np.asarray(st.w[:, 1:])
            f[:, c] = ball_law(system.balls.d0, v, system.balls.k_n)[0].ravel()
        alpha[:, c] = st.alpha
    u = system.displacement(f, alpha)
    return np.moveaxis(u.reshape(system.mesh.n_nodes, 3, -1), 2, 0)


def write_bearing_series(
    system: BearingSystem, result: CycleResult, folder: Path, *, every: int = 1
) -> Path:
    """ParaView series of a bearing cycle (as ``fe.general.report.write_time_series``).

    Point data besides ``displacement``: ``ball_load`` [N], each ball's Q on the nodes of
    its two raceway patches.
    """
    mesh = system.mesh
    chosen = frames_of(result, every)
    fields = increment_fields(system, result, chosen)
    patches = _raceway_patches(system)

    def ball_data(k: int) -> dict[str, FloatArray]:
        return {"ball_load": _on_patches(mesh.n_nodes, patches, result.states[k].p[:, 0])}

    return write_series(mesh, result, chosen, fields, ball_data, folder)


def _raceway_patches(system: BearingSystem | FitSystem) -> list[IntArray]:
    """Nodes of each ball's two raceway patches (inner and outer groove), one array per ball."""
    mesh, balls = system.mesh, system.balls
    return [
        np.concatenate(
            [mesh.set_nodes(f"{race}_ring_{b}_groove_{k}") for race in ("inner", "outer")]
        )
        for b, k in zip(balls.bearing, balls.index, strict=True)
    ]


def _on_patches(n_nodes: int, patches: list[IntArray], load_n: FloatArray) -> FloatArray:
    """Each ball's load on the nodes of its patches, zero elsewhere, shape (n_nodes,) [N]."""
    out = np.zeros(n_nodes)
    for j, nodes in enumerate(patches):
        out[nodes] = load_n[j]
    return out


def fit_fields(system: FitSystem, result: CycleResult, chosen: list[int]) -> FloatArray:
    """Displacement fields of chosen increments of a fits cycle, shape (k, n_nodes, 3) [mm].

    Raises:
        ParameterError: If the result carries no ball coordinates (not a fits cycle).
    """
    coords = _ball_coordinates(result)[np.asarray(chosen, dtype=np.int64) + 1].T  # row 0: preload
    p = np.column_stack([np.ravel(result.states[k].p) for k in chosen])
    alpha = np.column_stack([np.asarray(result.states[k].alpha) for k in chosen])
    u = system.displacement(p, coords[:-1], alpha, coords[-1])
    return np.moveaxis(u.reshape(system.mesh.n_nodes, 3, -1), 2, 0)


def _ball_coordinates(result: CycleResult) -> FloatArray:
    if result.ball_coordinates is None:
        raise ParameterError(
            "the result has no ball coordinates: not a cycle of the bearing hinge with "
            "frictional fits (fe.bearing.fit_cycle)"
        )
    return np.asarray(result.ball_coordinates, dtype=np.float64)


def write_fit_series(
    system: FitSystem, result: CycleResult, folder: Path, *, every: int = 1
) -> Path:
    """ParaView series of a cycle of the bearing hinge with frictional fits.

    As ``write_bearing_series``: ``displacement`` [mm] (the structure's; the preload
    shift σ is a misfit in the ball law, not a displacement) and ``ball_load`` [N] on the
    raceway patches; and on the fits' slave nodes (zero elsewhere) ``fit_pressure`` [MPa],
    the normal contact force of a point over its nodal area, and ``fit_slip`` [mm], the
    magnitude of the tangential relative displacement since the preload step (where the
    fits' friction history starts; the preload's frictionless settling is not counted).

    Raises:
        ParameterError: If the result carries no ball coordinates (not a fits cycle).
    """
    mesh, geo = system.mesh, system.geo
    coords = _ball_coordinates(result)
    chosen = frames_of(result, every)
    fields = fit_fields(system, result, chosen)
    patches = _raceway_patches(system)
    balls = system.balls
    if result.preload_state is not None:
        w_t0 = np.asarray(result.preload_state.w)[:, 1:]
    else:
        w_t0 = np.zeros((system.n_points, 2))

    def fit_data(k: int) -> dict[str, FloatArray]:
        c = coords[k + 1]
        _, Q, _, _ = ball_law(balls.d0, (c[:-1] + c[-1] * system.preload_shift).reshape(-1, 2),
                              balls.k_n)  # fmt: skip
        st = result.states[k]
        pressure = np.zeros(mesh.n_nodes)
        slip = np.zeros(mesh.n_nodes)
        pressure[geo.slave] = np.asarray(st.p)[:, 0] / geo.area_mm2
        slip[geo.slave] = np.linalg.norm(np.asarray(st.w)[:, 1:] - w_t0, axis=1)
        return {
            "ball_load": _on_patches(mesh.n_nodes, patches, Q),
            "fit_pressure": pressure,
            "fit_slip": slip,
        }

    return write_series(mesh, result, chosen, fields, fit_data, folder)
