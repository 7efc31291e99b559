"""Holding a floating body for factorisation: its rigid-body modes and a 3-2-1 support.

A body held only by contact (the general hinge's pin, the bearing hinge's pin in its
frictional fits) is supported on six DOFs (:func:`three_two_one`) only so that its
stiffness can be factorised; its rigid motion is carried as amplitudes of
:func:`rigid_modes` instead.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from mesh.hexmesh import HexMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def rigid_modes(nodes: FloatArray, centre: FloatArray) -> FloatArray:
    """Six rigid-body modes of a node set, shape (3 n, 6): translations x, y, z [mm/mm], rotations [mm/rad]."""
    d = nodes - centre
    R = np.zeros((len(nodes), 3, 6))
    R[:, 0, 0] = R[:, 1, 1] = R[:, 2, 2] = 1.0
    R[:, :, 3] = np.cross([1.0, 0, 0], d)
    R[:, :, 4] = np.cross([0, 1.0, 0], d)
    R[:, :, 5] = np.cross([0, 0, 1.0], d)
    return R.reshape(-1, 6)


def nearest_node(mesh: HexMesh, nodes: IntArray, point: tuple[float, float, float]) -> int:
    """The node of ``nodes`` closest to ``point`` [mm]."""
    x = np.asarray(mesh.nodes)[nodes]
    return int(nodes[np.argmin(np.linalg.norm(x - np.asarray(point), axis=1))])


def three_two_one(mesh: HexMesh, nodes: IntArray) -> IntArray:
    """Six DOFs that hold a floating body along the z axis rigidly and no more (3-2-1).

    The node nearest the axis at each end (x, y, z and x, y) and one on the rim at the
    low end (y), shape (6,). Only to factorise the body: its rigid modes are carried as
    amplitudes, and the reactions at these DOFs vanish for a self-equilibrated load.
    """
    x = np.asarray(mesh.nodes)[nodes]
    lo, hi = x[:, 2].min(), x[:, 2].max()
    r = float(np.hypot(x[:, 0], x[:, 1]).max())
    a = nearest_node(mesh, nodes, (0, 0, lo))
    b = nearest_node(mesh, nodes, (0, 0, hi))
    c = nearest_node(mesh, nodes, (r, 0, lo))
    return np.array([3 * a, 3 * a + 1, 3 * a + 2, 3 * b, 3 * b + 1, 3 * c + 1], dtype=np.int64)
