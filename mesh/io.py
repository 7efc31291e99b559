"""Mesh files: gmsh .msh and VTK .vtu (via meshio), with part and set labels.

Both files hold the hexahedra (cell data ``part``: index into the part names) and
every named facet set as quadrilaterals (cell data ``set``: index into the set
names; −1 on hexahedra, and ``part`` −1 on quads). The .msh file (format 2.2) carries the
names as physical groups (``gmsh:physical``), so gmsh and meshio read them back; the .vtu
file carries them in its field data: one one-value integer array per name, ``part:NAME``
= the part's ``part`` code and ``set:NAME`` = the set's ``set`` code, so ParaView's
Information panel lists what each code is and one can threshold by part or set.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

import meshio
import numpy as np

from cad.errors import MeshQualityError
from mesh.hexmesh import HexMesh


def _meshio_mesh(mesh: HexMesh) -> meshio.Mesh:
    names = sorted(mesh.facet_sets)
    quads = [mesh.facet_sets[n] for n in names]
    n_q = [len(q) for q in quads]
    cells = [("hexahedron", mesh.hexes)] + [("quad", q) for q in quads]
    part = [mesh.elem_part.astype(np.int64)] + [np.full(n, -1, dtype=np.int64) for n in n_q]
    set_id = [np.full(mesh.n_elem, -1, dtype=np.int64)] + [
        np.full(n, i, dtype=np.int64) for i, n in enumerate(n_q)
    ]
    # Physical tags: parts 1..P, sets P+1..P+S (gmsh wants them positive and unique).
    n_parts = len(mesh.part_names)
    physical = [mesh.elem_part + 1] + [
        np.full(n, n_parts + 1 + i, dtype=np.int64) for i, n in enumerate(n_q)
    ]
    field_data = {p: np.array([i + 1, 3]) for i, p in enumerate(mesh.part_names)}
    field_data |= {s: np.array([n_parts + 1 + i, 2]) for i, s in enumerate(names)}
    return meshio.Mesh(
        points=np.asarray(mesh.nodes),
        cells=cells,
        cell_data={
            "part": part,
            "set": set_id,
            "gmsh:physical": physical,
            "gmsh:geometrical": physical,
        },
        field_data=field_data,
    )


def write_msh(mesh: HexMesh, path: Path) -> Path:
    """Write a gmsh .msh file (format 2.2, which meshio writes for mixed cell types).

    Parts and sets are physical groups only: meshio cannot read back extra element data.
    """
    m = _meshio_mesh(mesh)
    del m.cell_data["part"], m.cell_data["set"]
    meshio.write(path, m, file_format="gmsh22", binary=False)
    return path


def write_vtu(mesh: HexMesh, path: Path) -> Path:
    """Write a .vtu file ParaView opens: hexahedra and set quads with ``part``/``set`` labels."""
    m = _meshio_mesh(mesh)
    del m.cell_data["gmsh:physical"], m.cell_data["gmsh:geometrical"]
    m.field_data = {}
    meshio.write(path, m, file_format="vtu", binary=True)
    return add_vtu_field_data(path, vtu_name_codes(mesh))


def vtu_name_codes(mesh: HexMesh) -> dict[str, int]:
    """Return the .vtu field-data table: ``part:NAME`` → part code, ``set:NAME`` → set code."""
    codes = {f"part:{p}": i for i, p in enumerate(mesh.part_names)}
    return codes | {f"set:{s}": i for i, s in enumerate(sorted(mesh.facet_sets))}


def add_vtu_field_data(path: Path, values: Mapping[str, int | float]) -> Path:
    """Insert a VTK ``<FieldData>`` block of one-value arrays into a .vtu file; return it.

    meshio reads FieldData from .vtu files but does not write it, so it is added to the
    XML here (ASCII arrays, which every VTK reader and meshio accept): Int64 for ints,
    Float64 for floats. Use it for names of codes (``vtu_name_codes``) or for per-file
    scalars of a time series (the load of an increment).

    Raises:
        MeshQualityError: If the file is not a VTK UnstructuredGrid.
    """
    tree = ET.parse(path)
    grid = tree.getroot().find("UnstructuredGrid")
    if grid is None:
        raise MeshQualityError(f"{path}: no UnstructuredGrid element to add field data to")
    block = grid.find("FieldData")
    if block is None:
        block = ET.Element("FieldData")
        grid.insert(0, block)
    for name, value in values.items():
        is_int = isinstance(value, int | np.integer)
        arr = ET.SubElement(
            block,
            "DataArray",
            {
                "type": "Int64" if is_int else "Float64",
                "Name": name,
                "NumberOfTuples": "1",
                "format": "ascii",
            },
        )
        arr.text = str(int(value)) if is_int else repr(float(value))
    tree.write(path, xml_declaration=True, encoding="utf-8")
    return path


def read_msh_summary(path: Path) -> dict[str, object]:
    """Read a .msh file back; return nodes, hexes and physical-group name → cell count.

    Raises:
        MeshQualityError: If the file has no hexahedra.
    """
    m = meshio.read(path)
    hexes = (
        np.concatenate([c.data for c in m.cells if c.type == "hexahedron"])
        if m.cells
        else np.empty((0, 8))
    )
    if len(hexes) == 0:
        raise MeshQualityError(f"{path} holds no hexahedra")
    tag_name = {int(v[0]): k for k, v in m.field_data.items()}
    counts: dict[str, int] = {}
    for tags in m.cell_data["gmsh:physical"]:
        for t, c in zip(*np.unique(tags, return_counts=True), strict=True):
            name = tag_name.get(int(t), str(t))
            counts[name] = counts.get(name, 0) + int(c)
    return {"nodes": m.points, "hexes": hexes, "groups": counts}
