"""A PNG picture of a hinge mesh (pyvista, off-screen)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mesh.hexmesh import HexMesh

PART_COLOURS = ("#b8c4d0", "#d9c9a3", "#8fa3b8", "#c7b3cf", "#a8c9a0")
CONTACT_COLOUR = "#d62728"
BONDED_COLOUR = "#ff9f1c"
EXPLODE_MAX_PARTS = 4
"""Above this many parts the detail view is a half-section instead of an exploded view."""


def _grid(mesh: HexMesh, elements: np.ndarray, shift: np.ndarray):  # type: ignore[no-untyped-def]
    import pyvista as pv

    cells = np.hstack([np.full((len(elements), 1), 8), mesh.hexes[elements]]).ravel()
    types = np.full(len(elements), pv.CellType.HEXAHEDRON, dtype=np.uint8)
    return pv.UnstructuredGrid(cells, types, np.asarray(mesh.nodes) + shift).extract_surface(
        algorithm="dataset_surface"
    )


def _quads(mesh: HexMesh, names: list[str], shift: np.ndarray):  # type: ignore[no-untyped-def]
    import pyvista as pv

    quads = np.concatenate([mesh.facet_sets[n] for n in names])
    faces = np.hstack([np.full((len(quads), 1), 4), quads]).ravel()
    return pv.PolyData(np.asarray(mesh.nodes) + shift, faces)


def write_mesh_png(mesh: HexMesh, path: Path, *, title: str = "") -> Path:
    """Draw the assembled hinge and an exploded view with the contact zones in red.

    Args:
        mesh: The mesh.
        path: Output PNG.
        title: Caption drawn on the left view.

    Returns:
        The path written.
    """
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger

    # Off-screen rendering needs no X server; VTK still says so on stderr. Silence it.
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    extent = np.ptp(np.asarray(mesh.nodes), axis=0)
    kinds = {side: pair.kind.value for pair in mesh.pairs for side in (pair.slave, pair.master)}
    contact = [n for n in mesh.facet_sets if n in kinds]
    section = len(mesh.part_names) > EXPLODE_MAX_PARTS
    plotter = pv.Plotter(off_screen=True, shape=(1, 2), window_size=[1800, 800])
    for col, detail in ((0, False), (1, True)):
        plotter.subplot(0, col)
        for i, part in enumerate(mesh.part_names):
            shift = np.zeros(3)
            if detail and not section:  # pull parts apart along y so the pin and the holes show
                shift[1] = (i - (len(mesh.part_names) - 1) / 2) * 1.3 * extent[1]
            surface = _grid(mesh, mesh.part_elements(part), shift)
            if detail and section:  # half-section through the pin axis: balls in their raceways
                surface = surface.clip(normal="y", origin=(0.0, 0.0, 0.0))
                if surface.n_points == 0:
                    continue
            plotter.add_mesh(
                surface,
                color=PART_COLOURS[i % len(PART_COLOURS)],
                show_edges=True,
                edge_color="#404040",
                line_width=0.5,
            )
            mine = [
                n for n in contact if np.isin(mesh.facet_sets[n][:, 0], mesh.part_nodes(part)).all()
            ]
            for kind, colour in (("contact", CONTACT_COLOUR), ("bonded", BONDED_COLOUR)):
                names = [n for n in mine if kinds[n] == kind]
                if not (detail and names):
                    continue
                quads = _quads(mesh, names, shift + 0.01)
                if section:
                    quads = quads.clip(normal="y", origin=(0.0, 0.0, 0.0))
                if quads.n_points:
                    plotter.add_mesh(
                        quads, color=colour, show_edges=True, edge_color="#400000", line_width=0.5
                    )
            if detail and not section:
                centre = np.asarray(mesh.nodes)[mesh.part_nodes(part)].mean(axis=0) + shift
                plotter.add_point_labels(
                    [centre + np.array([0.0, 0.0, extent[2]])],
                    [part],
                    font_size=18,
                    shape_opacity=0.6,
                    always_visible=True,
                )
        # pyvista's decorators hide these signatures from mypy
        plotter.add_axes()  # type: ignore[call-arg]
        if detail and section:  # look straight at the cut, centred on the pin axis
            plotter.view_xz(negative=True)  # type: ignore[call-arg]
            plotter.set_focus((0.0, 0.0, 0.0))  # type: ignore[arg-type]
            plotter.camera.zoom(2.2)  # type: ignore[no-untyped-call]
        else:
            plotter.view_isometric()  # type: ignore[call-arg]
            plotter.camera.azimuth = -30 if detail else 20
            plotter.camera.elevation = 25
        text = title
        if detail:
            text = (
                "half-section through the pin axis — contact red, bonded orange"
                if section
                else "exploded along y — contact surfaces in red"
            )
        plotter.add_text(text, font_size=12, position="upper_left")
    plotter.screenshot(str(path))
    plotter.close()
    return path
