"""Build → mesh → files: the steps every command and study shares."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cad.errors import ParameterError
from cad.model import HingeModel
from cad.step import write_step
from mesh.build import MeshReport, mesh_hinge
from mesh.hexmesh import HexMesh
from mesh.io import write_msh, write_vtu
from mesh.picture import write_mesh_png
from mesh.settings import MeshSettings

HINGES = ("general", "bearing")


def make_model(
    hinge: str, *, clearance_mm: float | None = None, preload_n: float | None = None
) -> HingeModel:
    """Build a hinge model from the command-line parameters.

    Raises:
        ParameterError: For an unknown hinge or a parameter the hinge does not take.
    """
    if hinge == "general":
        from cad.general import GeneralHingeParams, make_general_hinge

        if preload_n is not None:
            raise ParameterError(
                f"preload applies to the bearing hinge only, got --preload {preload_n} with --hinge general"
            )
        return make_general_hinge(
            GeneralHingeParams(clearance_mm=0.0 if clearance_mm is None else clearance_mm)
        )
    if hinge == "bearing":
        from cad.bearing import BearingHingeParams, make_bearing_hinge

        if clearance_mm is not None:
            raise ParameterError(
                f"the bearing hinge has no clearance, got --clearance {clearance_mm} with --hinge bearing"
            )
        kwargs = {} if preload_n is None else {"preload_n": preload_n}
        return make_bearing_hinge(BearingHingeParams(**kwargs))
    raise ParameterError(f"hinge must be one of {HINGES}, got {hinge!r}")


@dataclass(frozen=True)
class MeshedHinge:
    """A hinge built, meshed and written out.

    Attributes:
        model: The CAD model.
        mesh: Its mesh.
        report: Mesh quality figures.
        files: Kind → path of what was written (step, msh, vtu, png).
        timings_s: Step → wall time [s].
    """

    model: HingeModel
    mesh: HexMesh
    report: MeshReport
    files: dict[str, Path]
    timings_s: dict[str, float]


def build_and_mesh(
    model: HingeModel, settings: MeshSettings, out: Path, *, picture: bool = True
) -> MeshedHinge:
    """Mesh a model and write its STEP, .msh, .vtu and PNG files into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    files = {"step": write_step(model, out / "hinge.step")}
    t_step = time.perf_counter() - t
    mesh, report = mesh_hinge(model, settings)
    t = time.perf_counter()
    files["msh"] = write_msh(mesh, out / "mesh.msh")
    files["vtu"] = write_vtu(mesh, out / "mesh.vtu")
    if picture:
        title = f"{model.kind} hinge: {report.n_hex} hexes, {report.n_nodes} nodes"
        files["png"] = write_mesh_png(mesh, out / "mesh.png", title=title)
    return MeshedHinge(
        model,
        mesh,
        report,
        files,
        {"step": t_step, "mesh": report.wall_s, "write": time.perf_counter() - t},
    )


def mesh_summary(m: MeshedHinge, total_wall_s: float) -> dict[str, Any]:
    """Return the JSON summary the ``mesh`` command prints."""
    r = m.report
    return {
        "hinge": m.model.kind,
        "params": {
            k: v for k, v in vars(m.model.params).items() if isinstance(v, int | float | type(None))
        },
        "parts": {
            name: {
                "volume_mm3": p["volume_mm3"],
                "mesh_volume_mm3": p["mesh_volume_mm3"],
                "n_hex": int(p["n_hex"]),
            }
            for name, p in r.parts.items()
        },
        "n_nodes": r.n_nodes,
        "n_hex": r.n_hex,
        "hex_fraction": r.hex_fraction,
        "min_scaled_jacobian": r.min_scaled_jacobian,
        "sets": r.sets,
        "files": {k: str(v) for k, v in m.files.items()},
        "wall_s": total_wall_s,
    }


def dumps(obj: Any) -> str:
    """JSON with paths and numpy scalars turned into plain values."""
    return json.dumps(obj, default=lambda o: o.item() if hasattr(o, "item") else str(o), indent=2)
