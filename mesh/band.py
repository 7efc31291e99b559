"""A pin's profile as a structured band under its contact circle around an unstructured core.

The cad profile of a pin is an O-grid (``cad.general``): every arc and chord gets the
contact circle's segment count, so the whole section, core square included, is as
fine as the contact surface, and the pin held 43/52/58 % of the general hinge's DOF at
refinement 0/1/2. ``MeshSettings.pin_band_sizes`` replaces it by four quarter-annulus
patches a few contact sizes deep, with the circle's segment counts and grading (the
contact surface's nodes do not move), around a core disk meshed unstructured from the
band's inner segments toward the pin's global size. ``mesh.sweep.mesh_profile`` meshes
it; this module builds the geometry and repairs the core's boundary ears.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from cad.errors import GeometryError
from cad.model import Sweep

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

PILLOW_FRACTION = 0.5
"""Inward offset of the pillow ring's nodes, in segments of the band's inner circle."""

SMOOTHING_SWEEPS = 10
"""Laplace sweeps over the pin core's nodes after pillowing."""


def check_band(sweep: Sweep, radius_mm: float, band_mm: float) -> None:
    """Raise GeometryError unless a band ``band_mm`` deep can replace the sweep's profile.

    The profile must lie inside the circle of ``radius_mm`` (a solid pin section) and
    every slab must extrude all its faces, since the band replaces them all at once.
    """
    if not 0.0 < band_mm < radius_mm:
        raise GeometryError(f"band_mm must be in (0, {radius_mm:g}), got {band_mm!r}")
    everything = set(range(len(sweep.profile)))
    if any(set(slab.faces) != everything for slab in sweep.slabs):
        raise GeometryError("a pin band needs a profile extruded whole in every slab")
    for face in sweep.profile:
        box = face.bounding_box()
        reach = max(abs(box.min.X), abs(box.max.X), abs(box.min.Y), abs(box.max.Y))
        if reach > radius_mm * (1.0 + 1e-9):
            raise GeometryError(
                f"a pin band needs a profile inside its circle of radius {radius_mm:g} mm; "
                f"a face reaches {reach:g} mm"
            )


def banded_disk(gmsh: Any, radius_mm: float, band_mm: float) -> tuple[dict[int, int], set[int]]:
    """Build, in gmsh's OCC model, a disk of four band patches around a core disk.

    The patches are split at 0°, 90°, 180°, 270°, as the O-grid they replace, so that
    every arc ends on the load line (±x) where the grading puts its shortest segments.

    Args:
        gmsh: The gmsh module, in an open session.
        radius_mm: Radius of the pin (its contact circle) [mm].
        band_mm: Depth of the band [mm], in (0, radius_mm).

    Returns:
        (gmsh surface tag → profile face 0 for every surface, the core's surface tags).
    """
    occ = gmsh.model.occ
    inner = radius_mm - band_mm
    centre = occ.addPoint(0.0, 0.0, 0.0)
    angles = [0.5 * math.pi * i for i in range(4)]
    outer_pts = [
        occ.addPoint(radius_mm * math.cos(a), radius_mm * math.sin(a), 0.0) for a in angles
    ]
    inner_pts = [occ.addPoint(inner * math.cos(a), inner * math.sin(a), 0.0) for a in angles]
    outer = [occ.addCircleArc(outer_pts[i], centre, outer_pts[(i + 1) % 4]) for i in range(4)]
    arcs = [occ.addCircleArc(inner_pts[i], centre, inner_pts[(i + 1) % 4]) for i in range(4)]
    spokes = [occ.addLine(inner_pts[i], outer_pts[i]) for i in range(4)]
    band = [
        occ.addPlaneSurface(
            [occ.addCurveLoop([spokes[i], outer[i], -spokes[(i + 1) % 4], -arcs[i]])]
        )
        for i in range(4)
    ]
    core = occ.addPlaneSurface([occ.addCurveLoop(arcs)])
    occ.remove([(0, centre)])
    occ.synchronize()
    return dict.fromkeys([*band, core], 0), {core}


def corner_sines(xy: FloatArray, quads: IntArray) -> FloatArray:
    """Return the scaled Jacobian (sine of the corner angle) of every quad corner.

    Args:
        xy: Node coordinates, shape (n, 2) [mm].
        quads: Counter-clockwise quads, shape (n_q, 4), int64.

    Returns:
        Shape (n_q, 4): at corner i, cross(e_next, e_prev) / (|e_next| |e_prev|);
        negative where the corner is re-entrant.
    """
    p = xy[quads]  # (n_q, 4, 2)
    e_next = np.roll(p, -1, axis=1) - p
    e_prev = np.roll(p, 1, axis=1) - p
    cross = e_next[..., 0] * e_prev[..., 1] - e_next[..., 1] * e_prev[..., 0]
    norms = np.linalg.norm(e_next, axis=2) * np.linalg.norm(e_prev, axis=2)
    return np.asarray(cross / norms, dtype=np.float64)


def pillow_core(xy: FloatArray, quads: IntArray, circle_mm: float) -> tuple[FloatArray, IntArray]:
    """Return the profile with a ring of quads inserted inside a circle, then smoothed.

    gmsh's quad core occasionally has an ear, a quad (b0, b1, b2, x) with three
    consecutive nodes on the band's inner circle: its corner at b1 is 180° − 360°/N
    wide for N segments round the circle, so its scaled Jacobian halves with each
    refinement (0.049 at level 2) and no edge swap removes it, since its neighbours
    along the circle have two nodes on it too. Pillowing copies every node of the
    circle inward (by ``PILLOW_FRACTION`` of its segment), gives the core the copies,
    joins each pair of segments by a new quad, and then smooths the core's nodes
    (Laplace, ``SMOOTHING_SWEEPS``): the former ear's corner is no longer on the
    circle and opens up.

    Args:
        xy: Node coordinates, shape (n, 2) [mm].
        quads: Counter-clockwise quads, shape (n_q, 4), int64; those with every node
            within the circle are the core, the others the band.
        circle_mm: Radius of the band's inner circle [mm].

    Returns:
        (xy (n + N, 2) [mm], quads (n_q + N, 4) int64), new arrays.
    """
    r = np.hypot(xy[:, 0], xy[:, 1])
    tol = 1e-6 * max(circle_mm, 1.0)
    on = np.flatnonzero(np.abs(r - circle_mm) < tol)
    on = on[np.argsort(np.arctan2(xy[on, 1], xy[on, 0]))]  # counter-clockwise round the circle
    n_on = len(on)
    segment = 2.0 * math.pi * circle_mm / n_on
    copy = len(xy) + np.arange(n_on, dtype=np.int64)
    new_xy = np.vstack([xy, xy[on] * (1.0 - PILLOW_FRACTION * segment / circle_mm)])
    core = (r[quads] < circle_mm + tol).all(axis=1)
    renumber = np.arange(len(xy), dtype=np.int64)
    renumber[on] = copy
    new_quads = quads.copy()
    new_quads[core] = renumber[quads[core]]
    nxt = np.roll(np.arange(n_on), -1)
    ring = np.column_stack([copy, on, on[nxt], copy[nxt]])  # counter-clockwise
    new_quads = np.vstack([new_quads, ring])
    free = np.setdiff1d(np.unique(new_quads[np.append(core, np.zeros(n_on, dtype=bool))]), on)
    return _laplace(new_xy, new_quads, free), new_quads


def _laplace(xy: FloatArray, quads: IntArray, free: IntArray) -> FloatArray:
    """Move the ``free`` nodes to the mean of their edge neighbours, SMOOTHING_SWEEPS times."""
    edges = np.vstack([quads[:, [0, 1]], quads[:, [1, 2]], quads[:, [2, 3]], quads[:, [3, 0]]])
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    both = np.vstack([edges, edges[:, ::-1]])  # (2 n_edges, 2): node, neighbour
    degree = np.bincount(both[:, 0], minlength=len(xy)).astype(np.float64)
    out = xy.copy()
    for _ in range(SMOOTHING_SWEEPS):
        total = np.zeros_like(out)
        np.add.at(total, both[:, 0], out[both[:, 1]])
        out[free] = total[free] / degree[free, None]
    return out
