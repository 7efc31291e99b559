"""The meshed-ball superelement of ``ball_model = "full"``: one ball condensed with friction.

The one-ball model of :mod:`fe.bearing.one_ball` (a meshed 708C ball between an inner and
an outer raceway block, exact sphere and torus nodes, half model y ≥ 0) is built once and
condensed on the **three** directions of its contact points (normal and both tangents),
so it carries Coulomb friction. Supports and amplitudes, in the local frame of
:func:`fe.bearing.one_ball.local_frame` (z along the contact line toward the outer
contact, y the rolling direction, x across the groove):

* the inner block's far face is clamped;
* the outer block's far face is a rigid grip with two prescribed components, ``u_x``
  and ``u_z`` (displacement control; its y component is held, as the symmetry asks);
* the ball floats: its translations along x and z and its rotation about y are rigid
  amplitudes with zero load (``G`` columns of :func:`fe.contact.solve_increment`), held by
  the contact forces only — friction holds the rotation, which frictionless forces
  through the centre leave undetermined (``solve_increment`` then returns its
  minimum-norm value).

Half model: geometry and loads are symmetric about the meridional plane y = 0 (the grip
moves in x and z only, the ball's amplitudes are the three symmetric rigid modes), so the
y = 0 plane is a symmetry plane, exactly, with friction too (Coulomb is isotropic); every
force and work of the half model is half the ball's.

The condensed operators depend only on the bearing geometry, its material and the grid,
never on the structure of the hinge: one build serves all balls of both bearings and
every increment. Building it costs a factorisation and 3m solves for the condensation
(build times: benchmarks/bench_bearing_full.txt), so the result is kept on disk
(:func:`load_or_build_rig`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from cad.bearing_geometry import BearingHingeParams
from cad.errors import ParameterError
from cad.provenance import library_versions, source_digest
from fe.assembly import dofs_of
from fe.bearing.one_ball import MESH_LEVELS, contact_points_of, model_bodies
from fe.structure.condensed import Condensed
from fe.structure.twobody import build_two_body, zero_energy_map
from fe.surfaces.geometry import contact_operator
from mesh.ball_block import BallBlockGrid, ball_block_mesh
from mesh.hexmesh import HexMesh

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

DEFAULT_RIG_LEVEL = 1
"""Mesh level (``fe.bearing.one_ball.MESH_LEVELS``) of the rig the cycle uses by default:
the level verified against Hertz within 2.5 % (``docs/one_ball_hertz.md``)."""

RIG_FORMAT = 2
"""Version of the cached rig's file layout (part of its key)."""

GRIP_X, GRIP_Z, BALL_X, BALL_Z, BALL_ROT_Y = range(5)
"""Columns of the rigid fields: the grip's two components, then the ball's three modes."""

LOCKED_RTOL = 1e-12
"""A contact row whose norm on the free DOFs is below this fraction of the largest is
locked. On the symmetry plane the rolling direction t2 is y only up to the round-off
of the groove's computed normal (|n_y| ≈ 1e-9 … 1e-6): those rows are locked by where
their point is (``on_plane``), not by their size; left in W, they make it singular to
round-off (a zero pivot for every sticking point there)."""

CONDENSE_BLOCK = 256
"""Right-hand sides per solve in the condensation (memory: n_free × block floats)."""


@dataclass(frozen=True)
class FrictionRig:
    """The one-ball model condensed on its contact points, all three directions.

    Attributes:
        grid: Mesh grid of the rig.
        W: Delassus operator, shape (3m, 3m) [mm/N], symmetric, node-major [n, t1, t2].
        w0: Relative displacement at zero force and zero grip, shape (m, 3) [mm]
            (the initial gaps in the normal column).
        G_grip: Relative displacement per unit grip displacement (local x, z), shape
            (3m, 2) [mm/mm].
        G_ball: Relative displacement per unit ball amplitude (x, z translation [mm],
            rotation about y [rad]), shape (3m, 3).
        race_of: Raceway of each contact point (0 inner, 1 outer), shape (m,).
        normal: Each point's contact normal (master → slave) in the local frame,
            shape (m, 3).
        rim: Points on the edge of their contact window, shape (m,), bool: a closed
            one means the patch may reach beyond the window.
        n_dof: Degrees of freedom of the rig's mesh.
        timings_s: Mesh, assembly, factorisation and condensation wall times [s].
    """

    grid: BallBlockGrid
    W: FloatArray
    w0: FloatArray
    G_grip: FloatArray
    G_ball: FloatArray
    race_of: IntArray
    normal: FloatArray
    rim: npt.NDArray[np.bool_]
    n_dof: int
    timings_s: dict[str, float]

    @property
    def n_points(self) -> int:
        """Contact points m (both raceways)."""
        return len(self.race_of)


def rigid_fields(mesh: HexMesh) -> FloatArray:
    """Unit rigid fields, shape (n_dof, 5): grip x, grip z, ball x, ball z, ball about y.

    The rotation is about the y axis through the ball centre (the local origin):
    ``u = ω e_y × x = (z, 0, −x) ω`` [mm/rad].
    """
    fields = np.zeros((3 * mesh.n_nodes, 5))
    outer = mesh.part_nodes("outer")
    fields[3 * outer, GRIP_X] = 1.0
    fields[3 * outer + 2, GRIP_Z] = 1.0
    ball = mesh.part_nodes("ball")
    x = np.asarray(mesh.nodes)[ball]
    fields[3 * ball, BALL_X] = 1.0
    fields[3 * ball + 2, BALL_Z] = 1.0
    fields[3 * ball, BALL_ROT_Y] = x[:, 2]
    fields[3 * ball + 2, BALL_ROT_Y] = -x[:, 0]
    return fields


def _supports(mesh: HexMesh, radius_mm: float) -> IntArray:
    """Fixed DOFs: symmetry, inner base, outer grip, and a statically determinate ball hold.

    The ball's hold (its centre in x and z, one axis node in x against the rotation about
    y) only removes the modes that the amplitudes carry; with ``Gᵀ p = 0`` its reactions
    vanish.
    """
    axis = mesh.set_nodes("ball_axis")
    holder = axis[np.argmin(np.abs(np.asarray(mesh.nodes)[axis, 2] - 0.5 * radius_mm))]
    return np.concatenate(
        [
            dofs_of(mesh.set_nodes("symmetry"), [1]),
            dofs_of(mesh.set_nodes("inner_base"), [0, 1, 2]),
            dofs_of(mesh.set_nodes("outer_grip"), [0, 1, 2]),
            dofs_of(mesh.set_nodes("ball_centre"), [0, 2]),
            dofs_of(np.array([holder], dtype=np.int64), [0]),
        ]
    ).astype(np.int64)


def condense_full(
    solve: Callable[[FloatArray], FloatArray],
    C_free: sp.csr_matrix,
    on_plane: npt.NDArray[np.bool_],
    block: int = CONDENSE_BLOCK,
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Return ``W = C_f K_ff⁻¹ C_fᵀ``, shape (3m, 3m) [mm/N], by blocks of right-hand sides.

    ``K_ff⁻¹ C_fᵀ`` is never stored whole: memory stays ``n_free × block`` beyond W.
    Locked directions (the rolling direction t2 = ±y of the points on the symmetry plane,
    where both bodies are held in y, and any other row of ``C_f`` that vanishes) get the
    mean diagonal
    compliance, as in :func:`fe.structure.twobody.condense`: nothing drives them (their
    ``w_free`` and ``G`` rows are zero), so their force stays zero, and ``W`` stays
    nonsingular for sticking points.

    Args:
        solve: ``K_ff⁻¹`` applied to right-hand sides of shape (n_free, k).
        C_free: Contact rows on the free DOFs, shape (3m, n_free), CSR.
        on_plane: Points on the symmetry plane y = 0, shape (m,).
        block: Right-hand sides per solve.

    Returns:
        (W, locked: shape (3m,), bool).
    """
    norms = np.sqrt(np.asarray(C_free.multiply(C_free).sum(axis=1)).ravel())
    locked = norms <= LOCKED_RTOL * max(float(norms.max()), 1e-300)
    locked[3 * np.flatnonzero(on_plane) + 2] = True
    if np.any(locked[0::3]):
        raise ParameterError(
            f"contact point {int(np.flatnonzero(locked[0::3])[0])} of the ball rig cannot move "
            "normally: its normal direction is fully constrained"
        )
    live = np.flatnonzero(~locked)
    C_live = sp.csr_matrix(C_free[live])
    n = C_free.shape[0]
    W_live = np.zeros((len(live), len(live)))
    for j in range(0, len(live), block):
        X = solve(C_live[j : j + block].T.toarray())
        W_live[:, j : j + block] = C_live @ X
    W = np.zeros((n, n))
    W[np.ix_(live, live)] = 0.5 * (W_live + W_live.T)
    W[locked, locked] = float(np.mean(np.diag(W_live)))
    return W, locked


def build_friction_rig(
    grid: BallBlockGrid | None = None, params: BearingHingeParams | None = None
) -> FrictionRig:
    """Mesh, assemble, factorise and condense the one-ball rig with friction.

    Args:
        grid: Mesh grid; ``MESH_LEVELS[DEFAULT_RIG_LEVEL]`` when None.
        params: Bearing parameters; the default 708C when None.

    Raises:
        ParameterError: If a rigid field is not zero-energy (a support is wrong).
    """
    g = MESH_LEVELS[DEFAULT_RIG_LEVEL] if grid is None else grid
    p = BearingHingeParams() if params is None else params
    t0 = time.perf_counter()
    mesh = ball_block_mesh(model_bodies(p), g)
    geo, race_of, mesh = contact_points_of(mesh, g)
    t_mesh = time.perf_counter() - t0
    system = build_two_body(
        mesh, "ball_inner_window", "inner_race", _supports(mesh, 0.5 * p.ball_diameter_mm)
    )
    t1 = time.perf_counter()
    C = contact_operator(geo, system.n_dof)
    on_plane = np.abs(np.asarray(mesh.nodes)[geo.slave, 1]) < 1e-12
    W, locked = condense_full(system.factor.solve, sp.csr_matrix(C[:, system.free]), on_plane)
    w0 = np.column_stack([geo.g0, np.zeros((len(geo.g0), 2))])
    cond = Condensed(geo=geo, C=C, W=W, w0=w0, wall_s=time.perf_counter() - t1, locked=locked)
    G = zero_energy_map(system, cond, rigid_fields(mesh))
    G[locked] = 0.0  # a locked direction is driven by nothing
    # Rolling leaves a sphere's surface where it is: the rotation moves the ball's points
    # along their tangent planes only. The node-based n·(ω × x) is not zero because the
    # frame's normal is the groove's (through the groove centre, not the ball's), and
    # in the geometrically linear rig it would turn the contact line back with the ball
    # (the forces keep the normals of where the nodes were): the rotation's normal
    # components are dropped.
    G[0::3, BALL_ROT_Y] = 0.0
    timings = {"mesh": t_mesh, **system.timings_s, "condensation": time.perf_counter() - t1}
    logger.info(
        "ball rig: %d DOF, %d contact points, built in %.1f s",
        system.n_dof,
        len(race_of),
        sum(timings.values()),
    )
    return FrictionRig(
        g,
        W,
        w0,
        np.ascontiguousarray(G[:, :2]),
        np.ascontiguousarray(G[:, 2:]),
        race_of,
        np.asarray(geo.frame[:, 0, :]),
        window_rim(np.asarray(mesh.nodes)[geo.slave], race_of),
        system.n_dof,
        timings,
    )


def window_rim(xyz: FloatArray, race_of: IntArray) -> npt.NDArray[np.bool_]:
    """Points on the edge of their raceway's contact window (largest |x| or y), (m,) bool.

    Args:
        xyz: Slave node positions in the local frame, shape (m, 3) [mm].
        race_of: Raceway of each point, shape (m,).
    """
    rim = np.zeros(len(xyz), dtype=bool)
    for k in np.unique(race_of):
        sel = race_of == k
        x, y = np.abs(xyz[sel, 0]), xyz[sel, 1]
        rim[sel] = (x >= x.max() - 1e-9) | (y >= y.max() - 1e-9)
    return rim


RIG_CODE = ("cad", "mesh", "fe")
"""The packages whose source keys a cached rig (with the libraries' versions): a rig built
by other code is built again, not read back."""


def rig_key(grid: BallBlockGrid, params: BearingHingeParams) -> str:
    """Hash of what the rig depends on: grid, bearing geometry and material, format, code.

    The code is the source of ``RIG_CODE`` and the computing libraries' versions
    (``cad.provenance``): the cache lives in the user's folder, shared by every checkout
    and version of hingelab on the machine.
    """
    geometry = {
        k: v
        for k, v in dataclasses.asdict(params).items()
        if k
        in (
            "ball_diameter_mm",
            "contact_angle_deg",
            "inner_curvature_ratio",
            "outer_curvature_ratio",
            "bore_mm",
            "outer_diameter_mm",
            "width_mm",
            "arrangement",
            "bearing_material",
        )
    }
    text = json.dumps(
        {
            "grid": dataclasses.asdict(grid),
            "bearing": geometry,
            "format": RIG_FORMAT,
            "code": source_digest(RIG_CODE),
            "libraries": library_versions(),
        },
        sort_keys=True,
        default=str,
    )
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def rig_cache_dir() -> Path:
    """Return the folder of cached rigs.

    ``$HINGELAB_CACHE_DIR``, else ``$XDG_CACHE_HOME/hingelab``, else ``~/.cache/hingelab``.
    """
    if os.environ.get("HINGELAB_CACHE_DIR"):
        return Path(os.environ["HINGELAB_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "hingelab"


_MEMO: dict[str, FrictionRig] = {}


def load_or_build_rig(
    grid: BallBlockGrid | None = None,
    params: BearingHingeParams | None = None,
    cache_dir: Path | None = None,
) -> FrictionRig:
    """The rig from memory, from ``cache_dir`` (an ``.npz`` keyed by grid and bearing), or built.

    Args:
        grid: Mesh grid; ``MESH_LEVELS[DEFAULT_RIG_LEVEL]`` when None.
        params: Bearing parameters; the default 708C when None.
        cache_dir: Folder of cached rigs; :func:`rig_cache_dir` when None.
    """
    g = MESH_LEVELS[DEFAULT_RIG_LEVEL] if grid is None else grid
    p = BearingHingeParams() if params is None else params
    key = rig_key(g, p)
    if key in _MEMO:
        return _MEMO[key]
    path = (rig_cache_dir() if cache_dir is None else cache_dir) / f"ball_rig_{key}.npz"
    rig = _read(path, g)
    if rig is None:
        rig = build_friction_rig(g, p)
        _write(path, rig)
    _MEMO[key] = rig
    return rig


def _write(path: Path, rig: FrictionRig) -> None:
    """Store the rig (atomically: a partial file is never read back)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez(
            tmp,
            W=rig.W,
            w0=rig.w0,
            G_grip=rig.G_grip,
            G_ball=rig.G_ball,
            race_of=rig.race_of,
            normal=rig.normal,
            rim=rig.rim,
            n_dof=np.array(rig.n_dof),
            timings=np.array(json.dumps(rig.timings_s)),
        )
        tmp.replace(path)
    except OSError as err:  # a read-only cache costs a rebuild, never the run
        logger.warning("could not cache the ball rig at %s: %s", path, err)


def _read(path: Path, grid: BallBlockGrid) -> FrictionRig | None:
    """The cached rig at ``path``, or None if absent or unreadable."""
    if not path.exists():
        return None
    try:
        with np.load(path) as z:
            rig = FrictionRig(
                grid,
                np.array(z["W"]),
                np.array(z["w0"]),
                np.array(z["G_grip"]),
                np.array(z["G_ball"]),
                np.array(z["race_of"], dtype=np.int64),
                np.array(z["normal"]),
                np.array(z["rim"], dtype=bool),
                int(z["n_dof"]),
                {k: float(v) for k, v in json.loads(str(z["timings"])).items()},
            )
    except (OSError, KeyError, ValueError) as err:
        logger.warning("ignoring the unreadable cached ball rig %s: %s", path, err)
        return None
    m = len(rig.race_of)
    if rig.W.shape != (3 * m, 3 * m) or rig.G_grip.shape != (3 * m, 2):
        raise ParameterError(f"cached ball rig {path} has inconsistent shapes {rig.W.shape}")
    return rig
