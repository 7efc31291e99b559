"""The bearing hinge with frictional fits (``interfaces = "contact"``): the paper's ABAQUS model.

Sec. IV.B of the paper puts *contacts*, not ties, on the outer race–tang, inner ring–shaft
and shaft–lug interfaces. Here those six cylindrical fits (pin–clevis arm ×2, pin–inner
ring ×2, tang bore–outer ring ×2) are Coulomb contacts at zero clearance, solved by
``fe.contact`` exactly as the general hinge's pin in its holes; what stays tied is what
holds the pair together axially: outer ring 0 on the tang's lip, outer ring 1 under the
plate, and the two inner rings against each other (a face-to-face pair is clamped at its
inner rings). The plate is held by its screws (its top face fixed).

Bodies and their rigid modes (each carried as a ``G`` column, supported only to factorise):
the pin floats (six modes, 3-2-1 supports, as the general hinge's pin); the inner-ring
pair is held by its balls in every direction but its spin about the axis (balls roll),
which only friction on the pin resists (one mode); the clevis moves with the grip.

Balls: as in ``fe.bearing.system`` (Hertz along the line of the groove centres, free to
roll), now in series with frictional contacts. The factorised stiffness carries a fixed
reference ball stiffness ``H_ref`` (so the inner rings are not singular); each increment
iterates on the true ball law (Newton: the ball tangent ``H`` enters the contact operator
as a rank-40 update, ``W_eff = W_c − X (H − H_ref)(I + W_b (H − H_ref))⁻¹ Xᵀ``) around one
frictional contact solve per iteration, from the same previous state, so the friction
work is that of the converged iterate.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from cad.bearing_geometry import BearingHingeParams
from cad.errors import MeshQualityError
from cad.model import HingeModel, PairKind, SurfacePair
from fe.assembly import dofs_of
from fe.bearing.balls import ball_law, block_diag
from fe.bearing.system import BallCounts, BallLines, ball_lines, patch_rows
from fe.bearing.ties import Ties, assemble_tied, unit_field
from fe.element import ElementType
from fe.linalg.sparse import Factorization
from fe.structure.condensed import BLOCK_RHS
from fe.structure.supports import nearest_node, rigid_modes, three_two_one
from fe.surfaces.geometry import ContactGeometry, contact_geometry, contact_operator
from mesh.hexmesh import HexMesh

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

FIT_PAIRS = {
    "pin-clevis_1": ("pin_clevis_1", "clevis_hole_1"),
    "pin-clevis_2": ("pin_clevis_2", "clevis_hole_2"),
    "pin-inner_ring_0": ("pin_inner_ring_0", "inner_ring_0_bore"),
    "pin-inner_ring_1": ("pin_inner_ring_1", "inner_ring_1_bore"),
    # the tang's bore (coarse) is the slave of the ring's finer OD: 224 points, not 3 032
    "outer_ring_0-tang": ("tang_bore_0", "outer_ring_0_od"),
    "outer_ring_1-tang": ("tang_bore_1", "outer_ring_1_od"),
}
"""The fits that become frictional contacts: pair name → (slave face, master face)."""

N_PIN = 6
RING_SPIN = 6
GRIP = 7
N_RIGID = 8
"""Rigid amplitudes: the pin's six modes, the inner rings' spin, the grip δ [mm]."""

LOCKED_RATIO = 1e-9
"""A contact point whose compliance is below this fraction of the median is locked."""

REF_BALL_LOAD_N = 30.0
"""Ball load at which the reference stiffness ``H_ref`` in the factorisation is taken."""


def with_frictional_fits(model: HingeModel) -> HingeModel:
    """The bearing hinge (without balls) with its six fits as contact pairs."""
    pairs = [p for p in model.pairs if p.name not in FIT_PAIRS]
    pairs += [SurfacePair(n, s, m, PairKind.CONTACT) for n, (s, m) in FIT_PAIRS.items()]
    return dataclasses.replace(model, pairs=tuple(pairs))


@dataclass
class FitSystem(BallCounts):
    """The bearing hinge with frictional fits, factorised and condensed.

    Attributes:
        mesh: The mesh (no balls).
        params: Hinge parameters.
        balls: The ball lines.
        ties: The remaining bonded interfaces.
        geo: The contact points of the six fits (m of them).
        W_c: Contact compliance, shape (3m, 3m) [mm/N], node-major [n, t1, t2].
        X: Contact–ball cross compliance, shape (3m, 2 n_b) [mm/N].
        W_b: Ball compliance, shape (2 n_b, 2 n_b) [mm/N].
        H_ref: Reference ball stiffness in the factorisation, shape (2 n_b, 2 n_b) [N/mm].
        G: Contact rows of the rigid amplitudes, shape (3m, N_RIGID) [mm per unit α].
        preload_shift: Ball coordinates per unit preload shift σ, shape (2 n_b,).
        C: Contact rows on the independent DOFs, shape (3m, n_ind): ``C u_ind`` is the
            relative displacement (slave − master) of the points in their frames [mm].
        Bt: Ball rows on the independent DOFs, shape (2 n_b, n_ind): the balls' (radial,
            axial) coordinates ``v = Bt u_ind`` [mm].
        free: Free independent DOFs (not fixed, gripped or a rigid-mode support).
        factor: Factorisation of ``K0 = Tᵀ K T + Btᵀ H_ref Bt`` on ``free``, kept for the
            field recovery (``displacement``). It exists during the build anyway, so
            keeping it adds no peak memory, but it stays alive with the system (as
            ``BearingSystem.factor``): a few hundred MB resident on the coarse mesh,
            growing with the factor's fill on finer meshes; ``fields`` adds 8 n_dof
            floats (benchmarks/bench_bearing_cycle.txt, 'FitSystem').
        fields: Unit fields of the rigid amplitudes (pin modes, ring spin, grip) on all
            DOFs, shape (n_dof, N_RIGID) [mm per unit α], ``C`` of them is ``G``.
        timings_s: Wall times [s].
    """

    mesh: HexMesh
    params: BearingHingeParams
    balls: BallLines
    ties: Ties
    geo: ContactGeometry
    W_c: FloatArray
    X: FloatArray
    W_b: FloatArray
    H_ref: FloatArray
    G: FloatArray
    preload_shift: FloatArray
    C: sp.csr_matrix
    Bt: sp.csr_matrix
    free: IntArray
    factor: Factorization
    fields: FloatArray
    timings_s: dict[str, float] = field(default_factory=dict)

    @property
    def n_points(self) -> int:
        """Contact points of the fits."""
        return len(self.geo.slave)

    def ball_residual(self, v: FloatArray, sigma: FloatArray) -> FloatArray:
        """``r_b = f(v + σ s) − H_ref v``: the balls' force beyond the factorised reference.

        Args:
            v: Ball coordinates (radial, axial per ball), shape (2 n_b, k) [mm].
            sigma: Preload shift per column, shape (k,) [mm].

        Returns:
            Shape (2 n_b, k) [N]; ``f`` is the Hertz force on the inner rings (∂E/∂v).
        """
        shifted = v + np.outer(self.preload_shift, sigma)
        f = np.column_stack(
            [
                ball_law(self.balls.d0, shifted[:, j].reshape(-1, 2), self.balls.k_n)[0].ravel()
                for j in range(v.shape[1])
            ]
        )
        return np.asarray(f - self.H_ref @ v)

    def displacement(
        self, p: FloatArray, v: FloatArray, alpha: FloatArray, sigma: FloatArray
    ) -> FloatArray:
        """Nodal displacement of converged states, shape (n_dof, k) [mm].

        The structure's equilibrium on the independent DOFs, with the reference ball
        stiffness in ``K0`` and the rest of the ball force as a load::

            K0 u = Cᵀ p − Btᵀ r_b,   r_b = f(v + σ s) − H_ref v,   u += fields α

        (the contact forces ``p`` act on the slaves, ``−p`` on the masters; the balls push
        the inner rings by ``−f`` and the outer ones by ``+f``), so that ``C u = W_c p −
        X r_b + G α`` is the relative displacement ``w − w0`` of ``fe.bearing.fit_cycle``
        and ``Bt u = Xᵀ p − W_b r_b`` is ``v`` where the balls are in equilibrium.

        Args:
            p: Contact forces, shape (3m, k) [N], node-major (n, t1, t2) per point.
            v: Ball coordinates, shape (2 n_b, k) [mm].
            alpha: Rigid amplitudes, shape (N_RIGID, k) [mm or rad].
            sigma: Preload shift σ, shape (k,) [mm].
        """
        p = np.asarray(p, dtype=np.float64)
        f_ind = self.C.T @ p - self.Bt.T @ self.ball_residual(v, np.asarray(sigma, dtype=float))
        u_ind = np.zeros((self.C.shape[1], p.shape[1]))
        u_ind[self.free] = self.factor.solve(f_ind[self.free]).reshape(len(self.free), -1)
        return np.asarray(self.ties.T @ u_ind + self.fields @ alpha)


def reference_stiffness(balls: BallLines, load_n: float = REF_BALL_LOAD_N) -> FloatArray:
    """A fixed positive ball stiffness (Hertz tangent at ``load_n`` along each line)."""
    e = balls.d0 / np.linalg.norm(balls.d0, axis=1)[:, None]
    approach = (load_n / balls.k_n) ** (2.0 / 3.0)
    _, _, _, H = ball_law(balls.d0, e * approach, balls.k_n)
    return block_diag(H)


def _once_per_node(geo: ContactGeometry) -> ContactGeometry:
    """Keep one contact point per slave node.

    A pin node on the line where two fits meet (z = 0, between the two inner rings, which
    are tied there) would otherwise be two points with the same motion, and ``W`` two equal
    rows: singular.
    """
    _, first = np.unique(geo.slave, return_index=True)
    keep = np.sort(first)
    return ContactGeometry(
        *(np.asarray(getattr(geo, f.name))[keep] for f in dataclasses.fields(geo))
    )


def build_fit_system(
    mesh: HexMesh, params: BearingHingeParams, kind: ElementType = ElementType.INCOMPATIBLE
) -> FitSystem:
    """Assemble, tie, factorise and condense the bearing hinge with frictional fits.

    Raises:
        MeshQualityError: If the mesh lacks a fit, a grip face, or a raceway patch.
    """
    required = ("tang_fixed", "clevis_load", "plate_preload", *(s for s, _ in FIT_PAIRS.values()))
    K, ties, t = assemble_tied(mesh, kind, required)
    t0 = time.perf_counter()
    T = ties.T
    n_dof = 3 * mesh.n_nodes
    balls = ball_lines(params)
    B = patch_rows(mesh, balls)
    Bt = (B @ T).tocsr()
    H_ref = reference_stiffness(balls)
    K0 = (T.T @ K @ T + Bt.T @ sp.csr_matrix(H_ref) @ Bt).tocsr()
    pos = ties.position()
    grip = mesh.set_nodes("clevis_load")
    held_nodes = np.concatenate(
        [mesh.set_nodes("tang_fixed"), grip, mesh.set_nodes("plate_preload")]
    )
    # the pin: 3-2-1 supports (as fe.general.system); the inner rings: one spin support
    pin = mesh.part_nodes("pin")
    x = np.asarray(mesh.nodes)
    xp = x[pin]
    rings = np.concatenate([mesh.part_nodes("inner_ring_0"), mesh.part_nodes("inner_ring_1")])
    free_rings = rings[pos[3 * rings] >= 0]
    d = nearest_node(mesh, free_rings, (0.5 * params.bore_mm + 0.5, 0.0, 0.5 * params.width_mm))
    support = np.append(three_two_one(mesh, pin), 3 * d + 1)
    held = ties.held(np.concatenate([dofs_of(held_nodes), support]), "fixed, grip or support")
    free = np.setdiff1d(np.arange(len(ties.independent)), held)
    t["ties"] += time.perf_counter() - t0  # the tied stiffness and its held DOFs
    t0 = time.perf_counter()
    factor = Factorization(K0[free][:, free])
    t["factorisation"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    geo = _once_per_node(
        contact_geometry(mesh, {n: np.zeros(3) for n in FIT_PAIRS}, max_overshoot=0.05)
    )
    C = (contact_operator(geo, n_dof) @ T).tocsr()
    # rigid fields on all DOFs: pin modes, ring spin, grip (solved: the grip face moves)
    fields = np.zeros((n_dof, N_RIGID))
    fields[dofs_of(pin), :N_PIN] = rigid_modes(xp, xp.mean(axis=0))
    spin = np.zeros((len(rings), 3))
    spin[:, 0], spin[:, 1] = -x[rings, 1], x[rings, 0]
    fields[dofs_of(rings), RING_SPIN] = spin.ravel()
    fields[:, GRIP] = unit_field(ties, K0, factor, free, pos[3 * grip])
    # fields on the independent DOFs (tied nodes follow their masters)
    f_ind = fields[ties.independent]
    G = np.column_stack([C @ f_ind[:, j] for j in range(N_RIGID)])
    Gb = np.column_stack([Bt @ f_ind[:, j] for j in range(N_RIGID)])
    fields = np.asarray(T @ f_ind)  # the same, the tied DOFs following
    del f_ind
    if np.abs(Gb).max() > 1e-9:
        raise MeshQualityError("a rigid mode of the pin, ring spin or grip moves a ball patch")
    # condensation: one block of right-hand sides at a time
    rows = sp.vstack([C, Bt]).tocsr()[:, free]
    rows.sort_indices()
    # the DOFs the rows touch: only they of each solution enter the product
    touched = np.unique(rows.indices)
    rows_t = rows[:, touched]
    n_c = C.shape[0]
    WW = np.zeros((rows.shape[0], rows.shape[0]))

    def condense(solver: Factorization, start: int) -> None:  # its own columns of WW
        block = rows[start : start + BLOCK_RHS].toarray().T  # column-major, as PARDISO's
        WW[:, start : start + BLOCK_RHS] = rows_t @ solver.solve(block, rows=touched)

    factor.in_parallel(range(0, rows.shape[0], BLOCK_RHS), condense)
    WW = 0.5 * (WW + WW.T)
    # A tang node at the corner of bore and lip, facing ring 0's bottom edge (tied to the
    # lip), moves with its master: a zero row of W. It cannot carry load; drop it.
    d = np.diag(WW)[:n_c].reshape(-1, 3).sum(axis=1)
    keep = np.flatnonzero(d > LOCKED_RATIO * np.median(d))
    rows_kept = (3 * keep[:, None] + np.arange(3)).ravel()
    sel = np.concatenate([rows_kept, n_c + np.arange(WW.shape[0] - n_c)])
    WW = WW[np.ix_(sel, sel)]
    G = G[rows_kept]
    geo = ContactGeometry(
        *(np.asarray(getattr(geo, f.name))[keep] for f in dataclasses.fields(geo))
    )
    n_c = 3 * len(keep)
    t["condensation"] = time.perf_counter() - t0
    shift = np.zeros(2 * len(balls.bearing))
    shift[1::2] = np.where(balls.bearing == 1, 1.0, 0.0)  # outer ring 1 set down by σ
    logger.info(
        "bearing fits: %d DOF, %d contact points, factorised %.1f s, condensed %.1f s",
        n_dof,
        len(geo.slave),
        t["factorisation"],
        t["condensation"],
    )
    return FitSystem(
        mesh,
        params,
        balls,
        ties,
        geo,
        WW[:n_c, :n_c],
        WW[:n_c, n_c:],
        WW[n_c:, n_c:],
        H_ref,
        G,
        shift,
        C[rows_kept],
        Bt,
        free,
        factor,
        fields,
        t,
    )
