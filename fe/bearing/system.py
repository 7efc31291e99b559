"""The bearing hinge with ``hertz`` balls: the tied structure condensed on the ball lines.

The structure (tang, clevis, pin, preload plate, four rings; ``interfaces = "bonded"``:
every interface tied, ``fe.bearing.ties``) is assembled, factorised once and condensed on
the 2·Z balls. Each ball is a rigid sphere rolling freely between two raceway patches:

* a ball touches its raceways at two diametrically opposite points, so with free rotation
  its contact forces carry no tangential resultant (force and moment balance about its
  centre, ``docs/bearing_model.md`` §3) — the ball pushes along its contact line only;
* its normal law is Hertz in series for the two contacts, ``Q = K_n ⟨Δ⟩^{3/2}``, and its
  approach is the change of distance between the inner and outer groove-curvature centres
  in the ball's meridional plane (Jones; Harris & Kotzalas), ``Δ = |d_0 + v| − |d_0|``
  with ``|d_0| = (f_i + f_o − 1) D``. The contact line turns with ``v``: with only
  0.2 mm between the groove centres, a few µm turn it by degrees, which is why a
  preloaded angular-contact bearing stiffens faster than δ^{3/2};
* ``v`` (radial, axial) is the relative displacement inner − outer of the two raceway
  patches (the ``{inner,outer}_ring_{b}_groove_{k}`` faces, area-weighted means: an
  RBE3-like average, so a point load does not probe the mesh's local singularity); the
  circumferential component is free (the ball rolls along the grooves).

Condensation: with ``B`` the (2 n_b, n_dof) rows of ``v``, ``W = B K⁻¹ Bᵀ`` [mm/N] (structure,
tang fixed, clevis grip held) and three load parameters whose unit fields cost no strain
energy: the grip displacement δ_x (the clevis, pin and inner rings translate in x), their
axial float δ_z (free while the pair is preloaded, before the hinge is clamped in the
machine) and the preload shift σ (outer ring 1 and the plate set down toward ring 0
before the bond cures: the classical rigid spacer of a preloaded pair).
``v = −W f + G α`` with ``f`` the ball forces on the inner rings in (r, z), and ``Gᵀ f``
equals the grip force, the axial float force and the plate preload.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from cad.bearing_geometry import BearingHingeParams, contact_points, race_geometry
from cad.errors import MeshQualityError
from fe.assembly import dofs_of
from fe.bearing.pair import bearing_from_params, contact_constants
from fe.bearing.ties import Ties, assemble_tied, unit_field
from fe.element import ElementType
from fe.linalg.sparse import Factorization
from mesh.hexmesh import HexMesh

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

GRIP_PARTS = ("clevis", "pin", "inner_ring_0", "inner_ring_1")
"""Parts the grip carries (tied together): they translate rigidly with δ_x and δ_z."""

PRELOAD_PARTS = ("outer_ring_1", "preload_plate")
"""Parts the preload shift σ sets down toward outer ring 0."""

PARAMS = ("grip_x", "grip_z", "preload")
"""The load parameters α, in order: δ_x [mm], δ_z [mm], σ [mm]."""


@dataclass(frozen=True)
class BallLines:
    """The balls of the pair and their unloaded geometry.

    Attributes:
        bearing: Bearing index (0 below, 1 above the mid-plane) per ball, shape (n_b,).
        index: Ball index k within its bearing, shape (n_b,).
        theta: Azimuth of each ball, shape (n_b,) [rad].
        d0: Inner minus outer groove-curvature centre in the ball's meridional plane
            (radial, axial), shape (n_b, 2) [mm]; its length is (f_i + f_o − 1) D.
        inner: Nominal inner contact point, shape (n_b, 3) [mm].
        outer: Nominal outer contact point, shape (n_b, 3) [mm].
        k_n: Hertz constant of a ball (both contacts in series) [N/mm^1.5].
    """

    bearing: IntArray
    index: IntArray
    theta: FloatArray
    d0: FloatArray
    inner: FloatArray
    outer: FloatArray
    k_n: float

    def radial_axial(self) -> FloatArray:
        """Unit radial and axial directions of each ball's plane, shape (n_b, 2, 3)."""
        c, s = np.cos(self.theta), np.sin(self.theta)
        z = np.zeros_like(c)
        return np.stack([np.stack([c, s, z], 1), np.stack([z, z, z + 1.0], 1)], 1)


def ball_lines(p: BearingHingeParams) -> BallLines:
    """Return the 2·Z balls of the hinge's pair, bearing 0 first."""
    bearing, index, theta, d0, inner, outer = [], [], [], [], [], []
    for b in (0, 1):
        g = race_geometry(p, b)
        for k in range(p.ball_count):
            pts = contact_points(p, b, k)
            bearing.append(b)
            index.append(k)
            theta.append(2.0 * np.pi * k / p.ball_count)
            d0.append(np.subtract(g.inner_groove, g.outer_groove))
            inner.append(pts["inner"])
            outer.append(pts["outer"])
    k_n = contact_constants(bearing_from_params(p)).ball
    return BallLines(
        np.array(bearing),
        np.array(index),
        np.array(theta),
        np.array(d0),
        np.array(inner),
        np.array(outer),
        k_n,
    )


class BallCounts:
    """Sizes shared by the bearing hinge's condensed systems (``mesh`` and ``balls`` given)."""

    mesh: HexMesh
    balls: BallLines

    @property
    def n_dof(self) -> int:
        """DOFs of the whole mesh (before the ties eliminate the slave ones)."""
        return 3 * self.mesh.n_nodes

    @property
    def n_balls(self) -> int:
        """Balls of the pair."""
        return len(self.balls.bearing)


@dataclass
class BearingSystem(BallCounts):
    """The tied bearing-hinge structure, factorised and condensed on its balls.

    Attributes:
        mesh: The structure's mesh (no balls).
        params: The hinge parameters (``preload_n`` is a load, not used here).
        balls: The balls and their geometry.
        ties: The bonded interfaces as constraints.
        K: Stiffness of the whole mesh, shape (n_dof, n_dof) [N/mm].
        free: Free independent DOFs (not at the fixed face or the grip), shape (n_free,).
        factor: Factorisation of ``Tᵀ K T`` on ``free``.
        B: Relative-displacement rows, shape (2 n_b, n_dof): ``v = B u`` [mm/mm], per ball
            (radial, axial) of the inner minus the outer patch.
        W: Condensed compliance, shape (2 n_b, 2 n_b) [mm/N], symmetric positive definite.
        G: ``v`` per unit load parameter (``PARAMS``), shape (2 n_b, 3) [mm/mm].
        fields: Unit fields of the load parameters, shape (n_dof, 3) [mm/mm].
        timings_s: Assembly, ties, factorisation and condensation wall times [s].
    """

    mesh: HexMesh
    params: BearingHingeParams
    balls: BallLines
    ties: Ties
    K: sp.csr_matrix
    free: IntArray
    factor: Factorization
    B: sp.csr_matrix
    W: FloatArray
    G: FloatArray
    fields: FloatArray
    timings_s: dict[str, float] = field(default_factory=dict)

    def displacement(self, f: FloatArray, alpha: FloatArray) -> FloatArray:
        """Displacement fields under ball forces and load parameters, shape (n_dof, k) [mm].

        Args:
            f: Ball forces on the inner rings (radial, axial per ball), shape (2 n_b, k) [N].
            alpha: Load parameters (``PARAMS``), shape (3, k) [mm].
        """
        nodal = -(self.B.T @ f)  # the balls push the inner rings by −f, the outer by +f
        f_ind = self.ties.T.T @ nodal
        u_ind = np.zeros((self.ties.T.shape[1], f.shape[1]))
        u_ind[self.free] = self.factor.solve(f_ind[self.free]).reshape(len(self.free), -1)
        return np.asarray(self.ties.T @ u_ind + self.fields @ alpha)


def _centred(area: FloatArray, x: FloatArray, theta: float) -> FloatArray:
    """Patch weights (sum 1) whose circumferential moment about the ball's azimuth is zero.

    Area weights on an unstructured patch put its centroid a fraction of a degree off the
    ball's azimuth, and a spin of the ring about the axis would then move the patch
    radially (0.07 mm/rad measured). A linear correction ``w (1 + λ s)``, ``s = r sin(φ − θ)``
    removes that moment, so a spin is invisible to the ball, as it is to a rolling ball.
    """
    w = area / area.sum()
    s = np.hypot(x[:, 0], x[:, 1]) * np.sin(np.arctan2(x[:, 1], x[:, 0]) - theta)
    lam = -float(w @ s) / float(w @ s**2)
    w = w * (1.0 + lam * s)
    return np.asarray(w / w.sum())


def patch_rows(mesh: HexMesh, balls: BallLines) -> sp.csr_matrix:
    """Rows ``B`` (2 n_b, n_dof): area-weighted patch means, inner − outer, radial and axial."""
    nodes = np.asarray(mesh.nodes)
    frames = balls.radial_axial()
    rows, cols, vals = [], [], []
    for j, (b, k) in enumerate(zip(balls.bearing, balls.index, strict=True)):
        for race, sign in (("inner", 1.0), ("outer", -1.0)):
            name = f"{race}_ring_{b}_groove_{k}"
            if name not in mesh.facet_sets:
                raise MeshQualityError(f"the mesh has no raceway patch {name!r}")
            facets = np.asarray(mesh.facet_sets[name])
            q = nodes[facets]
            area = 0.5 * np.linalg.norm(np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1]), axis=1)
            w = np.zeros(mesh.n_nodes)
            np.add.at(w, facets.ravel(), np.repeat(area / 4.0, 4))
            on = np.flatnonzero(w)
            w_on = _centred(w[on], nodes[on], balls.theta[j])
            for a in range(2):
                for c in range(3):
                    rows.append(np.full(len(on), 2 * j + a))
                    cols.append(3 * on + c)
                    vals.append(sign * frames[j, a, c] * w_on)
    return sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(2 * len(balls.bearing), 3 * mesh.n_nodes),
    )


def build_bearing_system(
    mesh: HexMesh, params: BearingHingeParams, kind: ElementType = ElementType.INCOMPATIBLE
) -> BearingSystem:
    """Assemble, tie, factorise and condense the bearing hinge's structure.

    Raises:
        MeshQualityError: If the mesh lacks a grip face, a raceway patch or a part, a tie
            does not find its master face, or the grip parts are not one tied body.
    """
    K, ties, t = assemble_tied(mesh, kind, ("tang_fixed", "clevis_load"))
    t0 = time.perf_counter()
    T = ties.T
    K_ind = (T.T @ K @ T).tocsr()
    grip_nodes = mesh.set_nodes("clevis_load")
    held = ties.held(
        np.concatenate([dofs_of(mesh.set_nodes("tang_fixed")), dofs_of(grip_nodes)]), "grip"
    )
    free = np.setdiff1d(np.arange(len(ties.independent)), held)
    t["ties"] += time.perf_counter() - t0  # the tied stiffness and its held DOFs
    t0 = time.perf_counter()
    factor = Factorization(K_ind[free][:, free])
    t["factorisation"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    fields = np.zeros((3 * mesh.n_nodes, len(PARAMS)))
    pos = ties.position()
    for col, comp in ((0, 0), (1, 2)):  # the grip face moves; the rest in equilibrium
        fields[:, col] = unit_field(ties, K_ind, factor, free, pos[3 * grip_nodes + comp])
    for part in PRELOAD_PARTS:
        fields[3 * mesh.part_nodes(part) + 2, 2] = -1.0
    balls = ball_lines(params)
    B = patch_rows(mesh, balls)
    B_free = (B @ T).tocsr()[:, free]
    B_free.sort_indices()
    touched = np.unique(B_free.indices)  # only these rows of the solutions enter W
    X = factor.solve(B_free.toarray().T, rows=touched)  # column-major, as PARDISO's
    W = np.asarray(B_free[:, touched] @ X)
    W = 0.5 * (W + W.T)
    t["condensation"] = time.perf_counter() - t0
    scale = abs(K.diagonal()).max()
    for col in range(2):
        energy = float(fields[:, col] @ (K @ fields[:, col]))
        if energy > 1e-8 * scale:
            raise MeshQualityError(
                f"moving the grip ({PARAMS[col]}) strains the structure ({energy:.3g} N·mm "
                "per mm²): the clevis, pin and inner rings are not one tied body"
            )
    logger.info(
        "bearing structure: %d DOF, %d tied nodes (worst gap %.3g mm), %d balls",
        3 * mesh.n_nodes,
        len(ties.slave_nodes),
        ties.max_distance_mm,
        len(balls.bearing),
    )
    return BearingSystem(
        mesh, params, balls, ties, K, free, factor, B, W, np.asarray(B @ fields), fields, t
    )
