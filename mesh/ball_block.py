"""Structured hex mesh of one ball pressed between two raceway blocks (half model).

Local frame (mm): the origin is the ball centre, ``z`` runs along the contact line from
the inner contact (z = −R) to the outer contact (z = +R), ``y`` is the rolling
(circumferential) direction and ``x = y × z`` lies in the groove cross-section. The
model is the half ``y ≥ 0`` (symmetry about the meridional plane y = 0)::

        +------------- outer_grip (flat, z = R + depth) -------------+
        |               outer ring block                            |
        +~~~~~~~~~~~~ outer_race: nodes on the outer-groove torus ~~~+
               .--~~ ball_outer: nodes on the sphere, z > 0 ~~--.
              |   ball column |x| <= X, 0 <= y <= Y, both caps     |
               '--~~ ball_inner: nodes on the sphere, z < 0 ~~--'
        +~~~~~~~~~~~~ inner_race: nodes on the inner-groove torus ~~~+
        |               inner ring block                            |
        +------------- inner_base (flat, z = −R − depth) ------------+

All three bodies are tensor-product grids on one x axis (so the slave nodes of the ball
sit over master nodes); the rings' y axis continues the ball's with graded cells. Every
column of nodes is vertical: the ball's column (x, y) spans ``|z| <= sqrt(R² − x² − y²)``
(both end nodes exactly on the sphere), a ring's column spans from its flat far face to
the point where the vertical line meets the exact torus (Newton on the signed
distance). Cells are uniform (size ``h_x``, ``h_y``, ``h_z``) over the fine window
around the contacts and grow geometrically outside it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import MeshQualityError
from cad.materials import Material
from cad.surfaces import Sphere, Torus
from mesh.hexmesh import HexMesh, structured_hexes

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True)
class BallBlockGrid:
    """Grid of the one-ball model [mm].

    Attributes:
        h_x: Fine cell size across the groove (x, the Hertz major axis a).
        h_y: Fine cell size along the rolling direction (y, the minor axis b).
        h_z: Fine cell size in depth from both contact surfaces.
        fine_x: Uniform x grid over |x| <= fine_x.
        fine_y: Uniform y grid over 0 <= y <= fine_y.
        fine_z: Uniform depth grid over this depth below each contact surface.
        ball_x: The ball column spans |x| <= ball_x.
        ball_y: The ball column spans 0 <= y <= ball_y.
        ring_y: The ring blocks span 0 <= y <= ring_y (and |x| <= ball_x).
        ring_depth: Depth of each ring block below its contact point.
        growth: Ratio of neighbouring cells outside the fine window.
    """

    h_x: float
    h_y: float
    h_z: float
    fine_x: float = 0.75
    fine_y: float = 0.11
    fine_z: float = 0.06
    ball_x: float = 1.5
    ball_y: float = 1.0
    ring_y: float = 2.5
    ring_depth: float = 3.0
    growth: float = 1.4


def graded_axis(h: float, fine: float, length: float, growth: float) -> FloatArray:
    """Return coordinates 0 … length: cells of size h up to ``fine``, then growing.

    Args:
        h: Fine cell size [mm].
        fine: Length of the uniform part [mm] (rounded to whole cells).
        length: Total length [mm], > fine.
        growth: Ratio of neighbouring graded cells, > 1.

    Returns:
        Increasing coordinates, shape (n + 1,) [mm]; the graded cells are scaled so the
        last node lands on ``length`` exactly.
    """
    n_fine = max(1, round(fine / h))
    cells = [h] * n_fine
    rest = length - n_fine * h
    if rest <= 0.0:
        raise MeshQualityError(f"fine part {n_fine * h:g} mm exceeds the length {length:g} mm")
    graded: list[float] = []
    size = h * growth
    while sum(graded) + size < rest:
        graded.append(size)
        size *= growth
    g = np.asarray(graded) * (rest / sum(graded)) if graded else np.asarray([rest])
    return np.concatenate([[0.0], np.cumsum(np.concatenate([cells, g]))])


def symmetric_axis(h: float, fine: float, length: float, growth: float) -> FloatArray:
    """Return −length … length, the :func:`graded_axis` mirrored about 0, shape (2n + 1,)."""
    half = graded_axis(h, fine, length, growth)
    return np.concatenate([-half[:0:-1], half])


def _block(xs: FloatArray, ys: FloatArray, zs: FloatArray) -> tuple[FloatArray, IntArray]:
    """Nodes and hexes of a structured block whose node (i, j, k) is (xs[i], ys[j], zs[i, j, k]).

    ``zs`` has shape (nx + 1, ny + 1, nz + 1) and must increase with k (positive Jacobian).
    Node (i, j, k) has index ``i + (nx + 1) (j + (ny + 1) k)``.
    """
    nx, ny, nz = len(xs) - 1, len(ys) - 1, zs.shape[2] - 1
    grids = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij")
    i, j, k = (np.asarray(a.transpose(2, 1, 0).ravel(), dtype=np.int64) for a in grids)
    nodes = np.column_stack([xs[i], ys[j], zs[i, j, k]]).astype(np.float64)
    return nodes, structured_hexes(nx, ny, nz)


def _faces(nx: int, ny: int, nz: int, top: bool) -> IntArray:
    """Outward quads (n, 4) of the face k = nz (top) or k = 0 of a :func:`_block`."""
    i, j = (a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij"))
    k = nz if top else 0
    base = i + (nx + 1) * (j + (ny + 1) * k)
    a, b, c, d = base, base + 1, base + 1 + (nx + 1), base + (nx + 1)
    quads = np.stack([a, b, c, d] if top else [a, d, c, b], axis=1)
    return quads.astype(np.int64)


def torus_height(torus: Torus, x: FloatArray, y: FloatArray, z0: float) -> FloatArray:
    """Return z where the vertical lines through (x, y) meet the torus near z0 [mm].

    Newton on the signed distance d(z), whose z-derivative is the outward normal's z.

    Args:
        torus: The exact surface.
        x: Line positions, shape (n,) [mm].
        y: Line positions, shape (n,) [mm].
        z0: Start (the nominal contact point's z) [mm].

    Raises:
        MeshQualityError: If Newton does not reach 1e-12 mm.
    """
    z = np.full(len(x), z0)
    for _ in range(50):
        p = np.column_stack([x, y, z])
        d = torus.distance_outside(p)
        z = z - d / torus.outward_normal(p)[:, 2]
        if np.max(np.abs(d)) < 1e-12:
            return z
    raise MeshQualityError("vertical grid lines do not meet the raceway torus")


@dataclass(frozen=True)
class BallBlockBodies:
    """Exact surfaces and materials of the one-ball model (local frame, mm).

    Attributes:
        radius_mm: Ball radius R.
        inner_race: Inner-groove torus (material outside the tube).
        outer_race: Outer-groove torus.
        ball: Ball material.
        rings: Ring material.
    """

    radius_mm: float
    inner_race: Torus
    outer_race: Torus
    ball: Material
    rings: Material


def ball_block_mesh(bodies: BallBlockBodies, grid: BallBlockGrid) -> HexMesh:
    """Return the mesh: parts ball, inner, outer.

    Facet sets: ``ball_inner`` and ``ball_outer`` (ball caps, z < 0 and z > 0, slaves),
    ``inner_race`` and ``outer_race`` (ring faces on the tori, masters with exact
    surfaces), ``inner_base`` and ``outer_grip`` (flat far faces). Node sets:
    ``symmetry`` (y = 0), ``ball_centre``, ``ball_axis`` (x = y = 0 in the ball),
    ``inner_axis``, ``outer_axis`` (x = y = 0 in each ring).
    """
    g, r = grid, bodies.radius_mm
    if g.ball_x**2 + g.ball_y**2 >= r * r:
        raise MeshQualityError("the ball column's corner lies outside the ball")
    xs = symmetric_axis(g.h_x, g.fine_x, g.ball_x, g.growth)
    ys = graded_axis(g.h_y, g.fine_y, g.ball_y, g.growth)
    # rings: the ball's y axis continued by graded cells to ring_y
    tail = graded_axis(ys[-1] - ys[-2], ys[-1] - ys[-2], g.ring_y - g.ball_y, g.growth)
    ys_ring = np.concatenate([ys, g.ball_y + tail[1:]])
    depth = graded_axis(g.h_z, g.fine_z, r, g.growth)  # from the pole inward
    s_ball = np.concatenate([-1.0 + depth[:-1] / r, (1.0 - depth / r)[::-1]])  # (nz + 1,)
    t_ring = graded_axis(g.h_z, g.fine_z, g.ring_depth, g.growth) / g.ring_depth

    X, Y = np.meshgrid(xs, ys, indexing="ij")
    half_height = np.sqrt(r * r - X**2 - Y**2)
    ball_nodes, ball_hex = _block(xs, ys, half_height[:, :, None] * s_ball[None, None, :])

    Xr, Yr = (a.ravel() for a in np.meshgrid(xs, ys_ring, indexing="ij"))
    shape = (len(xs), len(ys_ring))
    zi = torus_height(bodies.inner_race, Xr, Yr, -r).reshape(shape)
    zo = torus_height(bodies.outer_race, Xr, Yr, r).reshape(shape)
    bottom, top = -r - g.ring_depth, r + g.ring_depth
    inner_z = bottom + (zi - bottom)[:, :, None] * (1.0 - t_ring[::-1])[None, None, :]
    outer_z = zo[:, :, None] + (top - zo)[:, :, None] * t_ring[None, None, :]
    inner_nodes, inner_hex = _block(xs, ys_ring, inner_z)
    outer_nodes, outer_hex = _block(xs, ys_ring, outer_z)

    nx, ny, nyr = len(xs) - 1, len(ys) - 1, len(ys_ring) - 1
    nzb, nzr = len(s_ball) - 1, len(t_ring) - 1
    off_i, off_o = len(ball_nodes), len(ball_nodes) + len(inner_nodes)
    nodes = np.concatenate([ball_nodes, inner_nodes, outer_nodes])
    hexes = np.concatenate([ball_hex, inner_hex + off_i, outer_hex + off_o])
    parts = np.repeat(np.arange(3), [len(ball_hex), len(inner_hex), len(outer_hex)])
    facets = {
        "ball_inner": _faces(nx, ny, nzb, top=False),
        "ball_outer": _faces(nx, ny, nzb, top=True),
        "inner_race": _faces(nx, nyr, nzr, top=True) + off_i,
        "inner_base": _faces(nx, nyr, nzr, top=False) + off_i,
        "outer_race": _faces(nx, nyr, nzr, top=False) + off_o,
        "outer_grip": _faces(nx, nyr, nzr, top=True) + off_o,
    }
    on_axis = (np.abs(nodes[:, 0]) < 1e-12) & (np.abs(nodes[:, 1]) < 1e-12)
    body = np.repeat(np.arange(3), [len(ball_nodes), len(inner_nodes), len(outer_nodes)])
    node_sets = {
        "symmetry": np.flatnonzero(np.abs(nodes[:, 1]) < 1e-12),
        "ball_centre": np.flatnonzero(on_axis & (body == 0) & (np.abs(nodes[:, 2]) < 1e-12)),
        "ball_axis": np.flatnonzero(on_axis & (body == 0)),
        "inner_axis": np.flatnonzero(on_axis & (body == 1)),
        "outer_axis": np.flatnonzero(on_axis & (body == 2)),
    }
    return HexMesh(
        nodes=nodes,
        hexes=hexes,
        elem_part=parts,
        part_names=("ball", "inner", "outer"),
        materials=(bodies.ball, bodies.rings, bodies.rings),
        facet_sets=facets,
        surfaces={
            "inner_race": bodies.inner_race,
            "outer_race": bodies.outer_race,
            "ball_inner": Sphere((0.0, 0.0, 0.0), r),
            "ball_outer": Sphere((0.0, 0.0, 0.0), r),
        },
        node_sets=node_sets,
    )
