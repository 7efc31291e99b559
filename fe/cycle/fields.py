"""A cycle's fields as a ParaView time series (.pvd + .vtu), for any kind's mesh.

Each kind recovers its displacement fields and adds its own point data
(``fe.general.report.write_time_series``, ``fe.bearing.report``); :func:`write_series`
writes the frames, with the stress, von Mises stress and part of every element, and the
.pvd index whose time is the load path (:func:`load_path`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np
import numpy.typing as npt

from fe.assembly import stress_field
from fe.cycle.result import CycleResult
from fe.element import ElementType, von_mises
from mesh.hexmesh import HexMesh
from mesh.io import add_vtu_field_data, vtu_name_codes

FloatArray = npt.NDArray[np.float64]


def load_path(result: CycleResult) -> FloatArray:
    """Load-path parameter ``τ = Σ|ΔF| / Fg`` at the origin and every increment, shape (n+1,)."""
    F, _, _ = result.loop_arrays()
    steps = np.abs(np.diff(F)) / result.settings.amplitude_n
    return np.concatenate([[0.0], np.cumsum(steps)])


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
