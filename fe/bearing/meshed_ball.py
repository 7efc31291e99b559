"""The meshed-ball law of ``ball_model = "full"``: one frictional contact solve per ball.

Given a ball's relative groove displacement ``v`` (radial, axial; inner − outer raceway
patch, as for the ``hertz`` balls of :mod:`fe.bearing.cycle`) and its last converged
contact state, :meth:`MeshedBallLaw.solve` solves the frictional contact of the condensed
one-ball rig (:mod:`fe.bearing.ball_rig`) by displacement control and returns what the
bearing cycle needs: the force on the inner ring ``f`` (2,), the ball load, the tangent
``∂f/∂v`` (2 × 2), the contact state and the works of the step.

Kinematics: the rig's local frame has z along the unloaded contact line (toward the
outer contact) and x across the groove, in the ball's meridional plane; a ball of the
other bearing is its mirror image in the axial direction. ``R_j`` (2 × 2, rows e_x, e_z
in (radial, axial) coordinates) maps ``v`` to the rig: ``v_loc = R_j v``; the inner block
is clamped, so the outer grip moves by ``u = −v_loc``; the force on the inner ring in
(radial, axial) is ``f = R_jᵀ f_loc``. With the rig's ``e = G_gripᵀ p`` (minus the force
on the grip, half ball), ``f_loc = 2 e`` is ``∂E/∂v_loc`` — the same convention as
:func:`fe.bearing.cycle.ball_law`, so ``f`` enters the structure's equations unchanged.

Tangent: exact for the active set of the converged state. With the Alart–Curnier law's
``D = ∂λ/∂ξ`` (``fe.contact.law.coulomb_step``) on the closed points ``c``::

    [(I − D) + r D W_cc    r D G_ball,c] [dp_c]   [−r D G_grip,c du]
    [G_ball,cᵀ             0           ] [dα  ] = [0              ]

and ``d f_loc = 2 G_grip,cᵀ dp_c``. It is the derivative of the solution along paths that
keep the active set (stick stays stick, slip keeps its direction), i.e. the consistent
tangent of the incremental (backward-Euler) return map: a Newton iteration on ``v`` built
on it converges quadratically once the active sets settle. Where all closed points slip
the ball's rotation is undetermined (the minimum-norm solution of the bordered system is
taken: the force does not depend on it).

Unloaded balls cost nothing: if no point was closed and every gap stays open at the
last ball position, the step is the empty contact (``p = 0``) without a solve.

Re-seating: a ball with no closed point floats (its position is whatever it was when it
lost contact), and its first loaded step is solved frictionless — the ball seats on the
groove-centre line, and friction acts from its next step. A frictional step that does
not converge (seen only on balls with a handful of closed points, ≲ 1 N, where the
floating ball is barely held: the contact Newton of :mod:`fe.contact` stalls) is retried
with other augmentations (``RETRY_R_SCALES``) and, failing those, taken frictionless
too; each such fallback is counted (``MeshedBallLaw.n_reseated``) and logged.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from cad.bearing_geometry import BearingHingeParams
from cad.errors import ConvergenceError, ParameterError
from fe.bearing.ball_rig import FrictionRig
from fe.bearing.one_ball import local_frame
from fe.bearing.system import BallLines
from fe.contact.law import ContactStatus, coulomb_step
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState, IncrementResult, LinearSolver

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]

LOCAL_R_SCALE = 0.1
"""Augmentation of the local solves (``ContactSettings.r_scale``): on the rig, whose ball
floats between two stiff contacts, 0.1 took 2–10 Newton iterations per step where the
default 1 took up to 130 with rescues (measured on ``MESH_LEVELS[0]``). Algorithmic only."""

RETRY_R_SCALES = (0.03, 0.01, 0.3)
"""Augmentations tried, from the committed state, when a local solve fails."""

GAP_ROUNDOFF_MM = 1e-12
"""Gaps above −this count as open for skipping an unloaded ball: the nodes at the nominal
contact points have g0 = 0 up to round-off (−1.3e-15 mm measured)."""

LOCAL_TOL = 1e-10
"""Tolerance of the local solves (the scaled residual of :mod:`fe.contact`)."""


def rig_maps(params: BearingHingeParams, balls: BallLines) -> FloatArray:
    """Per ball, the map from (radial, axial) to the rig's (x, z), shape (n_b, 2, 2).

    The rig is built on bearing 1's geometry; a ball whose unloaded groove-centre vector
    ``d0`` points the other way axially is its mirror image (axial component negated).

    Raises:
        ParameterError: If a ball's ``d0`` is not along the rig's contact line (the rig
            would not fit the ball).
    """
    rows = local_frame(params)[[0, 2]][:, [0, 2]]  # e_x, e_z in (X = radial, Z = axial)
    ref = rows[1]
    out = np.zeros((len(balls.d0), 2, 2))
    for j, d0 in enumerate(balls.d0):
        mirror = np.diag([1.0, -1.0]) if d0[1] * ref[1] < 0 else np.eye(2)
        out[j] = rows @ mirror
        local = out[j] @ d0
        if abs(local[0]) > 1e-9 * np.linalg.norm(d0) or local[1] <= 0:
            raise ParameterError(
                f"ball {j}: its groove-centre vector d0 = {d0.tolist()} is not along the "
                f"rig's contact line (local {local.tolist()})"
            )
    return out


@dataclass(frozen=True)
class BallStep:
    """One ball's contact step (full ball: twice the half rig's forces and works).

    Attributes:
        force_n: Force on the inner ring's groove centre (radial, axial), shape (2,) [N].
        load_n: Ball load Q = |force| [N] (inner and outer contact resultants are equal
            and opposite: the ball is in equilibrium).
        tangent: ``∂f/∂v``, shape (2, 2) [N/mm].
        state: The rig's contact state (half model).
        friction_work: Friction work of the step [N·mm].
        normal_work: Open/close work of the step [N·mm].
        dissipation: Backward-Euler dissipation of the step [N·mm].
        energy: Strain energy of the ball and its raceway blocks [N·mm].
        iterations: Contact Newton iterations (0: unloaded, no solve).
        n_closed: Closed points (half model). n_slip: Of which slipping.
        mu: The friction coefficient the step was solved with (0 if it re-seated
            frictionless), which its tangent needs.
    """

    force_n: FloatArray
    load_n: float
    tangent: FloatArray
    state: ContactState
    friction_work: float
    normal_work: float
    dissipation: float
    energy: float
    iterations: int
    n_closed: int
    n_slip: int
    mu: float = 0.0


@dataclass
class MeshedBallLaw:
    """The rig and the per-ball maps: the contact law of every ball of the pair.

    Attributes:
        rig: The condensed one-ball rig.
        maps: Per ball (radial, axial) → rig (x, z), shape (n_b, 2, 2).
        mu: Coulomb friction coefficient of the ball–raceway contacts.
        n_solves: Local contact solves done (for the benchmark).
        n_skipped: Local steps skipped as unloaded.
        n_reseated: Frictional steps that failed and were taken frictionless.
    """

    rig: FrictionRig
    maps: FloatArray
    mu: float
    n_solves: int = 0
    n_skipped: int = 0
    n_reseated: int = 0
    _r: FloatArray = field(init=False, repr=False)
    _settings: ContactSettings = field(init=False, repr=False)

    def __post_init__(self) -> None:
        blocks = np.diagonal(self.rig.W).reshape(-1, 3)
        self._r = LOCAL_R_SCALE / blocks.mean(axis=1)
        self._settings = ContactSettings(
            mu=self.mu,
            tol=LOCAL_TOL,
            max_iter=200,
            r_scale=LOCAL_R_SCALE,
            linear_solver=LinearSolver.LU,
        )

    def initial_state(self) -> ContactState:
        """The unloaded rig: no force, all open, ball at its nominal position."""
        return ContactState.initial(self.rig.n_points, 3)

    def with_mu(self, mu: float) -> MeshedBallLaw:
        """The same rig and maps with another friction coefficient."""
        return MeshedBallLaw(self.rig, self.maps, mu)

    def solve(
        self,
        ball: int,
        v: FloatArray,
        prev: ContactState,
        start: ContactState | None = None,
        *,
        tangent: bool = True,
    ) -> BallStep:
        """The ball's step from its converged state ``prev`` to the relative displacement ``v``.

        Args:
            ball: Ball index (selects its map).
            v: Relative displacement inner − outer groove centre (radial, axial),
                shape (2,) [mm].
            prev: The ball's last converged rig state (slip reference, works).
            start: Where the contact Newton starts (e.g. the last iterate); ``prev`` if None.
            tangent: Compute ``∂f/∂v`` (else zeros).

        Raises:
            ConvergenceError: If the local contact solve does not converge.
        """
        rig = self.rig
        R = self.maps[ball]
        u = -(R @ np.asarray(v, dtype=np.float64))
        w_free = rig.w0 + (rig.G_grip @ u).reshape(-1, 3)
        if not np.any(prev.p[:, 0] > 0.0):
            w_open = w_free + (rig.G_ball @ prev.alpha).reshape(-1, 3)
            if np.all(w_open[:, 0] >= -GAP_ROUNDOFF_MM):
                self.n_skipped += 1
                return self._unloaded(prev, w_open)
        res, mu = self._contact(w_free, prev, prev if start is None else start)
        self.n_solves += 1
        st = res.state
        f_loc = 2.0 * (rig.G_grip.T @ st.p.ravel())
        f = R.T @ f_loc
        K = self._tangent(st, prev, mu) if tangent else np.zeros((2, 2))
        p = st.p.ravel()
        # W p from the converged w = W p + G_ball α + w_free (solve_increment's exact
        # product), not another pass over the rig's W
        Wp = (st.w - w_free).ravel() - rig.G_ball @ np.asarray(st.alpha)
        return BallStep(
            force_n=f,
            load_n=float(np.linalg.norm(f)),
            tangent=-(R.T @ K @ R),  # u = −R v
            state=st,
            friction_work=2.0 * float(res.friction_work.sum()),
            normal_work=2.0 * float(res.normal_work.sum()),
            dissipation=2.0 * float(res.dissipation.sum()),
            energy=float(p @ Wp),  # 2 · ½ pᵀ W p
            iterations=res.iterations,
            n_closed=res.n_stick + res.n_slip,
            n_slip=res.n_slip,
            mu=mu,
        )

    def tangent_of(self, ball: int, step: BallStep, prev: ContactState) -> FloatArray:
        """``∂f/∂v`` of a step solved with ``tangent=False``, shape (2, 2) [N/mm].

        The same matrix ``solve`` returns with ``tangent=True``: the ball Newton asks for it
        only for an accepted iterate that is not yet converged, not for line-search trials
        or the converged state.

        Args:
            ball: Ball index (selects its map).
            step: The ball's step.
            prev: The state the step was taken from.
        """
        R = self.maps[ball]
        K: FloatArray = -(R.T @ self._tangent(step.state, prev, step.mu) @ R)
        return K

    def _contact(
        self, w_free: FloatArray, prev: ContactState, start: ContactState
    ) -> tuple[IncrementResult, float]:
        """The rig's contact step, with the fallbacks of the module docstring, and its μ.

        Raises:
            ConvergenceError: If even the frictionless solve does not converge.
        """
        rig = self.rig

        def run(settings: ContactSettings, st: ContactState) -> IncrementResult:
            return solve_increment(
                rig.W, w_free, prev, settings, G=rig.G_ball, e=np.zeros(3),
                start=(np.asarray(st.p), np.asarray(st.alpha)), symmetric=True,
            )  # fmt: skip

        frictionless = dataclasses.replace(self._settings, mu=0.0)
        if self.mu == 0.0 or not np.any(prev.p[:, 0] > 0.0):
            return run(frictionless, start), 0.0  # a ball that was unloaded re-seats
        for r_scale, st in ((LOCAL_R_SCALE, start), *((r, prev) for r in RETRY_R_SCALES)):
            try:
                return run(dataclasses.replace(self._settings, r_scale=r_scale), st), self.mu
            except ConvergenceError:
                continue
        self.n_reseated += 1
        logger.info("a meshed ball re-seats frictionlessly (its frictional step failed)")
        return run(frictionless, prev), 0.0

    def _unloaded(self, prev: ContactState, w: FloatArray) -> BallStep:
        m = self.rig.n_points
        status = np.full(m, ContactStatus.OPEN, dtype=np.int8)
        st = ContactState(np.zeros((m, 3)), w, status, prev.alpha)
        zero2 = np.zeros(2)
        return BallStep(zero2, 0.0, np.zeros((2, 2)), st, 0.0, 0.0, 0.0, 0.0, 0, 0, 0)

    def _tangent(self, st: ContactState, prev: ContactState, mu: float) -> FloatArray:
        """``∂f_loc/∂u`` of the converged state's active set at friction ``mu``, (2, 2) [N/mm]."""
        rig = self.rig
        c = np.flatnonzero(st.status != ContactStatus.OPEN)
        if len(c) == 0:
            return np.zeros((2, 2))
        g = np.array(st.w)
        g[:, 1:] -= prev.w[:, 1:]
        D = coulomb_step(g[c], np.asarray(st.p)[c], mu, self._r[c]).tangent  # (n_c, 3, 3)
        rows = (3 * c[:, None] + np.arange(3)[None, :]).ravel()
        n = len(rows)
        # Without a sticking point nothing holds the ball's rotation (its column is
        # tangential only): it is left out, as its amplitude does not move the forces.
        k = 3 if np.any(st.status == ContactStatus.STICK) else 2
        Gb = rig.G_ball[rows, :k]
        # rows divided by r: (I − D)/r + D W (mm per N), well scaled for stick and slip
        A = np.zeros((n + k, n + k))
        blk = np.arange(n).reshape(-1, 3)
        A[blk[:, :, None], blk[:, None, :]] = (np.eye(3) - D) / self._r[c, None, None]
        DW = np.einsum("cab,cbj->caj", D, rig.W[rows].reshape(len(c), 3, -1))  # (n_c, 3, 3m)
        A[:n, :n] += DW.reshape(n, -1)[:, rows]
        A[:n, n:] = np.einsum("cab,cbk->cak", D, Gb.reshape(len(c), 3, k)).reshape(n, k)
        A[n:, :n] = Gb.T
        DGg = np.einsum("cab,cbk->cak", D, rig.G_grip[rows].reshape(len(c), 3, 2))
        rhs = np.zeros((n + k, 2))
        rhs[:n] = -DGg.reshape(n, 2)
        try:
            x = np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError:
            x = np.linalg.lstsq(A, rhs, rcond=None)[0]
        out: FloatArray = 2.0 * (rig.G_grip[rows].T @ x[:n])
        return out


def check_converged(step: BallStep, ball: int) -> None:
    """Raise if a local step's forces are not finite (a diverged solve reported as converged).

    Raises:
        ConvergenceError: Naming the ball.
    """
    if not (np.all(np.isfinite(step.force_n)) and np.all(np.isfinite(step.state.alpha))):
        raise ConvergenceError(
            f"the meshed ball {ball} returned non-finite forces",
            increment=-1,
            iteration=step.iterations,
            residual=float("inf"),
        )
