"""Tiny canonical meshes shared by the tests of every layer."""

from __future__ import annotations

import numpy as np

from cad.materials import Material
from mesh.hexmesh import HexMesh, structured_hexes

TEST_MATERIAL = Material("test steel", 200_000.0, 0.3)

# Outward (counter-clockwise seen from outside) local node order of the six hex faces,
# for the VTK order documented in mesh.hexmesh.
HEX_FACES = {
    "xmin": (0, 4, 7, 3),
    "xmax": (1, 2, 6, 5),
    "ymin": (0, 1, 5, 4),
    "ymax": (3, 7, 6, 2),
    "zmin": (0, 3, 2, 1),
    "zmax": (4, 5, 6, 7),
}


def box_mesh(
    lx: float,
    ly: float,
    lz: float,
    nx: int,
    ny: int,
    nz: int,
    *,
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
    distort: float = 0.0,
    seed: int = 0,
    part: str = "block",
    material: Material = TEST_MATERIAL,
    set_prefix: str = "",
) -> HexMesh:
    """Return a structured nx×ny×nz hex mesh of the box origin + [0,lx]×[0,ly]×[0,lz] [mm].

    Node (i, j, k) has index i + (nx+1) * (j + (ny+1) * k). ``distort`` moves every interior
    node (not on the boundary) by up to ``distort`` times the smallest cell size in each
    coordinate, uniformly at random, so the boundary stays flat. Facet sets "xmin" … "zmax"
    (prefixed by ``set_prefix``) have outward node order.
    """
    hx, hy, hz = lx / nx, ly / ny, lz / nz
    i, j, k = np.meshgrid(
        np.arange(nx + 1, dtype=np.int64),
        np.arange(ny + 1, dtype=np.int64),
        np.arange(nz + 1, dtype=np.int64),
        indexing="ij",
    )
    i, j, k = (a.transpose(2, 1, 0).ravel() for a in (i, j, k))  # i fastest
    nodes = np.stack([i * hx, j * hy, k * hz], axis=1).astype(np.float64) + np.asarray(origin)
    if distort:
        interior = (i > 0) & (i < nx) & (j > 0) & (j < ny) & (k > 0) & (k < nz)
        rng = np.random.default_rng(seed)
        shift = rng.uniform(-1.0, 1.0, size=(int(interior.sum()), 3)) * distort * min(hx, hy, hz)
        nodes[interior] += shift

    hexes = structured_hexes(nx, ny, nz)
    e = np.arange(len(hexes))
    ei, ej, ek = e % nx, (e // nx) % ny, e // (nx * ny)  # cell (i, j, k), i fastest

    on_face = {
        "xmin": ei == 0,
        "xmax": ei == nx - 1,
        "ymin": ej == 0,
        "ymax": ej == ny - 1,
        "zmin": ek == 0,
        "zmax": ek == nz - 1,
    }
    facet_sets = {
        set_prefix + name: hexes[on_face[name]][:, list(HEX_FACES[name])] for name in HEX_FACES
    }
    return HexMesh(
        nodes=nodes,
        hexes=hexes,
        elem_part=np.zeros(len(hexes), dtype=np.int64),
        part_names=(part,),
        materials=(material,),
        facet_sets=facet_sets,
    )


def merge_meshes(a: HexMesh, b: HexMesh) -> HexMesh:
    """Return one multi-part mesh holding ``a`` then ``b``; no nodes are shared.

    Facet sets, node sets and surfaces keep their names; b's node indices are shifted by
    a.n_nodes. Raises ValueError if a part name or a set name occurs in both meshes.
    """
    clash_parts = set(a.part_names) & set(b.part_names)
    clash_sets = (set(a.facet_sets) | set(a.node_sets)) & (set(b.facet_sets) | set(b.node_sets))
    if clash_parts or clash_sets:
        raise ValueError(
            f"cannot merge: parts {sorted(clash_parts)} and sets {sorted(clash_sets)} occur in both"
        )
    off = a.n_nodes
    return HexMesh(
        nodes=np.concatenate([a.nodes, b.nodes]),
        hexes=np.concatenate([a.hexes, b.hexes + off]),
        elem_part=np.concatenate([a.elem_part, b.elem_part + len(a.part_names)]),
        part_names=a.part_names + b.part_names,
        materials=a.materials + b.materials,
        facet_sets={**a.facet_sets, **{k: v + off for k, v in b.facet_sets.items()}},
        surfaces={**a.surfaces, **b.surfaces},
        pairs=a.pairs + b.pairs,
        node_sets={**a.node_sets, **{k: v + off for k, v in b.node_sets.items()}},
    )
