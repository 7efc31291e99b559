"""Mesh files: .msh and .vtu round trips keep nodes, hexes, parts and set names."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from cad.general import make_general_hinge
from cad.general_params import GeneralHingeParams
from mesh.build import mesh_hinge
from mesh.io import read_msh_summary, write_msh, write_vtu


@pytest.fixture(scope="module")
def mesh():
    return mesh_hinge(make_general_hinge(GeneralHingeParams()))[0]


def test_msh_round_trip(mesh, tmp_path):
    path = write_msh(mesh, tmp_path / "m.msh")
    back = read_msh_summary(path)
    assert np.allclose(back["nodes"], mesh.nodes)
    assert np.array_equal(back["hexes"], mesh.hexes)
    for i, part in enumerate(mesh.part_names):
        assert back["groups"][part] == int((mesh.elem_part == i).sum())
    for name, facets in mesh.facet_sets.items():
        assert back["groups"][name] == len(facets)


def test_msh_opens_in_gmsh_with_names(mesh, tmp_path):
    import gmsh

    path = write_msh(mesh, tmp_path / "m.msh")
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        names = {gmsh.model.getPhysicalName(d, t) for d, t in gmsh.model.getPhysicalGroups()}
    finally:
        gmsh.finalize()
    assert names == set(mesh.part_names) | set(mesh.facet_sets)


def test_vtu_holds_parts_and_sets(mesh, tmp_path):
    m = meshio.read(write_vtu(mesh, tmp_path / "m.vtu"))
    hexes = next(c for c in m.cells if c.type == "hexahedron").data
    assert np.array_equal(hexes, mesh.hexes)
    part = np.concatenate(m.cell_data["part"])
    assert np.array_equal(np.bincount(part[part >= 0]), np.bincount(mesh.elem_part))
    n_quads = sum(len(c.data) for c in m.cells if c.type == "quad")
    assert n_quads == sum(len(f) for f in mesh.facet_sets.values())


def test_vtu_names_its_part_and_set_codes(mesh, tmp_path):
    """ParaView shows the field data: every part and set code comes with its name."""
    m = meshio.read(write_vtu(mesh, tmp_path / "m.vtu"))
    names = {k: int(np.ravel(v)[0]) for k, v in m.field_data.items()}
    assert names == {f"part:{p}": i for i, p in enumerate(mesh.part_names)} | {
        f"set:{s}": i for i, s in enumerate(sorted(mesh.facet_sets))
    }
    part = np.concatenate(m.cell_data["part"])
    assert np.array_equal(part[: mesh.n_elem], mesh.elem_part)
    set_code = np.concatenate(m.cell_data["set"])[mesh.n_elem :]
    sizes = {s: int((set_code == names[f"set:{s}"]).sum()) for s in mesh.facet_sets}
    assert sizes == {s: len(f) for s, f in mesh.facet_sets.items()}


def test_field_data_of_a_series_frame(tmp_path):
    """A time-series frame can carry its load: ints stay ints, floats round-trip exactly."""
    from mesh.io import add_vtu_field_data
    from tests.helpers import box_mesh

    path = write_vtu(box_mesh(1.0, 1.0, 1.0, 1, 1, 1), tmp_path / "f.vtu")
    add_vtu_field_data(path, {"force_N": -123.456789012345, "stage": 2})
    m = meshio.read(path)
    assert float(m.field_data["force_N"][0]) == -123.456789012345
    assert m.field_data["stage"].dtype.kind == "i"
    assert int(m.field_data["stage"][0]) == 2
    assert "part:block" in m.field_data
