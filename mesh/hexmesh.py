"""The mesh object every later stage consumes.

Hexahedron node order (VTK_HEXAHEDRON, also gmsh's 8-node hexahedron)::

        7 -------- 6
       /|         /|        zeta
      4 -------- 5 |         |  eta
      | |        | |         | /
      | 3 -------|-2         |/
      |/         |/          +---- xi
      0 -------- 1

Reference coordinates: node 0 at (-1,-1,-1), 1 (1,-1,-1), 2 (1,1,-1), 3 (-1,1,-1),
4..7 the same at zeta = +1.

Facets are quadrilaterals whose nodes run counter-clockwise seen from outside the
body they bound, so the right-hand normal points out of the material.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from cad.errors import MeshQualityError
from cad.materials import Material
from cad.model import SurfacePair
from cad.surfaces import Surface

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


HEX_CORNERS = (
    (0, 0, 0),
    (1, 0, 0),
    (1, 1, 0),
    (0, 1, 0),
    (0, 0, 1),
    (1, 0, 1),
    (1, 1, 1),
    (0, 1, 1),
)
"""(di, dj, dk) of a hexahedron's eight nodes in the order of ``HexMesh.hexes`` (gmsh/VTK)."""


def structured_hexes(nx: int, ny: int, nz: int) -> IntArray:
    """Connectivity of an nx × ny × nz block of cells, shape (nx ny nz, 8).

    Node (i, j, k) is ``i + (nx + 1) (j + (ny + 1) k)`` and cell (i, j, k) is row
    ``i + nx (j + ny k)`` (i fastest), its nodes in ``HEX_CORNERS`` order.
    """
    grid = np.meshgrid(
        np.arange(nz, dtype=np.int64),
        np.arange(ny, dtype=np.int64),
        np.arange(nx, dtype=np.int64),
        indexing="ij",
    )
    ek, ej, ei = (a.ravel() for a in grid)
    return np.stack(
        [(ei + a) + (nx + 1) * ((ej + b) + (ny + 1) * (ek + c)) for a, b, c in HEX_CORNERS],
        axis=1,
    )


def _frozen(a: npt.ArrayLike, dtype: type) -> npt.NDArray[np.generic]:
    arr: npt.NDArray[np.generic] = np.array(a, dtype=dtype, copy=True)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class HexMesh:
    """A validated all-hexahedral mesh of several parts.

    Attributes:
        nodes: Coordinates, shape (n_nodes, 3), float64 [mm].
        hexes: Connectivity, shape (n_elem, 8), int64, node order as in the module docstring.
        elem_part: Part index of every element, shape (n_elem,), int64.
        part_names: Name of each part, indexed by ``elem_part``.
        materials: Material of each part, aligned with ``part_names``.
        facet_sets: Named quad facets, name → (n_facets, 4) int64, outward node order.
        surfaces: Exact geometry of named facet sets that take part in contact [mm].
        pairs: Contact and bonded pairs between facet sets.
        node_sets: Extra named node sets, name → (n,) int64 (facet sets also give node sets).
    """

    nodes: FloatArray
    hexes: IntArray
    elem_part: IntArray
    part_names: tuple[str, ...]
    materials: tuple[Material, ...]
    facet_sets: dict[str, IntArray]
    surfaces: dict[str, Surface] = field(default_factory=dict)
    pairs: tuple[SurfacePair, ...] = ()
    node_sets: dict[str, IntArray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "nodes", _frozen(self.nodes, np.float64))
        object.__setattr__(self, "hexes", _frozen(self.hexes, np.int64))
        object.__setattr__(self, "elem_part", _frozen(self.elem_part, np.int64))
        object.__setattr__(
            self,
            "facet_sets",
            {k: _frozen(v, np.int64).reshape(-1, 4) for k, v in self.facet_sets.items()},
        )
        object.__setattr__(
            self, "node_sets", {k: _frozen(v, np.int64) for k, v in self.node_sets.items()}
        )
        self._validate()

    def _validate(self) -> None:
        n = len(self.nodes)
        if self.nodes.ndim != 2 or self.nodes.shape[1] != 3:
            raise MeshQualityError(f"nodes must have shape (n_nodes, 3), got {self.nodes.shape}")
        if self.hexes.ndim != 2 or self.hexes.shape[1] != 8:
            raise MeshQualityError(f"hexes must have shape (n_elem, 8), got {self.hexes.shape}")
        if self.hexes.size and (self.hexes.min() < 0 or self.hexes.max() >= n):
            raise MeshQualityError(
                f"hexes index nodes outside [0, {n}): {self.hexes.min()}..{self.hexes.max()}"
            )
        if self.elem_part.shape != (len(self.hexes),):
            raise MeshQualityError(
                f"elem_part must have shape ({len(self.hexes)},), got {self.elem_part.shape}"
            )
        if len(self.part_names) != len(self.materials):
            raise MeshQualityError(
                f"{len(self.part_names)} part names but {len(self.materials)} materials"
            )
        for name, f in {
            **self.facet_sets,
            **{k: v[:, None] for k, v in self.node_sets.items()},
        }.items():
            if f.size == 0:
                raise MeshQualityError(f"named set {name!r} is empty")
            if f.min() < 0 or f.max() >= n:
                raise MeshQualityError(f"named set {name!r} indexes nodes outside [0, {n})")
        for p in self.pairs:
            for side in (p.slave, p.master):
                if side not in self.facet_sets:
                    raise MeshQualityError(
                        f"pair {p.name!r} names facet set {side!r}, which does not exist"
                    )

    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
        return len(self.nodes)

    @property
    def n_elem(self) -> int:
        """Number of hexahedra."""
        return len(self.hexes)

    def part_elements(self, part: str) -> IntArray:
        """Return the element indices of one part, shape (n,), int64."""
        return np.flatnonzero(self.elem_part == self.part_names.index(part)).astype(np.int64)

    def part_nodes(self, part: str) -> IntArray:
        """Return the sorted node indices used by one part, shape (n,), int64."""
        return np.unique(self.hexes[self.part_elements(part)]).astype(np.int64)

    def set_nodes(self, name: str) -> IntArray:
        """Return the sorted node indices of a facet set or node set, shape (n,), int64."""
        if name in self.facet_sets:
            return np.unique(self.facet_sets[name]).astype(np.int64)
        if name in self.node_sets:
            return np.unique(self.node_sets[name]).astype(np.int64)
        raise KeyError(
            f"no facet or node set named {name!r}; have {sorted(self.facet_sets) + sorted(self.node_sets)}"
        )

    def facet_normals_areas(self, name: str) -> tuple[FloatArray, FloatArray]:
        """Return outward unit normals (n_facets, 3) and areas (n_facets,) [mm²] of a facet set.

        The bilinear quad is split along both diagonals and averaged, exact for planar quads.
        """
        q = self.nodes[self.facet_sets[name]]  # (n_f, 4, 3)
        a = 0.5 * np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1])  # (n_f, 3) area vector
        area = np.linalg.norm(a, axis=1)
        return a / np.maximum(area, 1e-300)[:, None], area

    def nodal_areas(self, name: str) -> tuple[IntArray, FloatArray, FloatArray]:
        """Lump a facet set's area and normal onto its nodes.

        Returns:
            (node ids (n,), areas (n,) [mm²], area-weighted unit normals (n, 3)).
        """
        f = self.facet_sets[name]
        normals, area = self.facet_normals_areas(name)
        ids, inv = np.unique(f, return_inverse=True)
        inv = inv.reshape(f.shape)
        node_area = np.zeros(len(ids))
        node_normal = np.zeros((len(ids), 3))
        for k in range(4):
            np.add.at(node_area, inv[:, k], area / 4.0)
            np.add.at(node_normal, inv[:, k], normals * (area / 4.0)[:, None])
        node_normal /= np.maximum(np.linalg.norm(node_normal, axis=1), 1e-300)[:, None]
        return ids.astype(np.int64), node_area, node_normal

    def content_hash(self) -> str:
        """Return a SHA-256 of everything that defines the mesh as a model.

        Nodes, connectivity, parts, materials, named sets, exact surfaces and pairs: two
        meshes with the same hash give the same stiffness and contact geometry, so
        results computed from one (e.g. a condensed compliance) are valid for the other.
        """
        h = hashlib.sha256()
        for arr in (self.nodes, self.hexes, self.elem_part):
            h.update(np.ascontiguousarray(arr).tobytes())
        h.update(repr((self.part_names, self.materials, self.surfaces, self.pairs)).encode())
        for name in sorted(self.facet_sets):
            h.update(name.encode())
            h.update(np.ascontiguousarray(self.facet_sets[name]).tobytes())
        for name in sorted(self.node_sets):
            h.update(name.encode())
            h.update(np.ascontiguousarray(self.node_sets[name]).tobytes())
        return h.hexdigest()

    def summary(self) -> dict[str, object]:
        """Return a JSON-ready summary: element and node counts, part sizes, set sizes."""
        return {
            "n_nodes": self.n_nodes,
            "n_hex": self.n_elem,
            "parts": {p: int((self.elem_part == i).sum()) for i, p in enumerate(self.part_names)},
            "sets": {k: len(v) for k, v in self.facet_sets.items()}
            | {k: len(v) for k, v in self.node_sets.items()},
        }
