"""The general hinge's ParaView time series: displacements, contact pressure and slip on the pin."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

from fe.cycle.fields import frames_of, write_series
from fe.cycle.result import CycleResult
from fe.element import ElementType
from fe.general.increments import increment_displacements
from fe.general.system import HingeSystem

FloatArray = npt.NDArray[np.float64]


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
