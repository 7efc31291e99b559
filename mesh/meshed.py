"""CAD → mesh → files: the geometry half of a model run, shared by every command."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from cad.model import HingeModel
from mesh.build import MeshReport, mesh_hinge
from mesh.hexmesh import HexMesh
from mesh.settings import MeshSettings


@dataclass(frozen=True)
class MeshedHinge:
    """A hinge built, meshed and (optionally) written out.

    Attributes:
        model: The CAD model.
        mesh: Its mesh.
        report: Mesh quality figures.
        files: Kind → path of what was written (step, msh, vtu, png); empty if nothing was.
        timings_s: Step → wall time [s].
    """

    model: HingeModel
    mesh: HexMesh
    report: MeshReport
    files: dict[str, Path]
    timings_s: dict[str, float]


def build_and_mesh(
    model: HingeModel, settings: MeshSettings, out: Path | None, *, picture: bool = True
) -> MeshedHinge:
    """Mesh a model and, when ``out`` is given, write its STEP, .msh, .vtu and PNG files there."""
    from cad.step import write_step
    from mesh.io import write_msh, write_vtu
    from mesh.picture import write_mesh_png

    files: dict[str, Path] = {}
    t = time.perf_counter()
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        files["step"] = write_step(model, out / "hinge.step")
    t_step = time.perf_counter() - t
    mesh, report = mesh_hinge(model, settings)
    t = time.perf_counter()
    if out is not None:
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
