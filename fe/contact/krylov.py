"""Newton directions by GMRES, preconditioned by an earlier LU updated to the new layout.

Internal to :mod:`fe.contact` (notation of :mod:`fe.contact.newton`). The reduced
Jacobian ``J = R W T + diag(d)`` changes in every Newton iteration, but mostly a little:
stick blocks are entries of ``W``, slip rows and columns turn with the slip direction,
and a few points change status. So the LU of an earlier ``J₀`` (same ``W``) is kept as
a *base* and turned into a preconditioner ``M`` of the new system that is exact on every
row and column of a point whose status (or slip direction, beyond ``turn_cos``) changed:

* unknowns are split into ``S`` (points with the same status in both layouts), ``N``
  (the other unknowns of the new layout) and ``O`` (the other unknowns of ``J₀``);
* ``J₀,SS⁻¹`` follows from ``J₀⁻¹`` by a Schur complement on ``O``:
  ``J₀,SS⁻¹ y = x_S - Z_S (Z_O)⁻¹ x_O`` with ``x = J₀⁻¹ [y; 0]`` and ``Z = J₀⁻¹ E_O``;
* ``M = [[J₀,SS, J_SN], [J_NS, J_NN]]`` is inverted by a Schur complement on ``N``;
* the rigid amplitudes are bordered on as in :func:`fe.contact.dense.solve_bordered`.

The setup costs ``|N| + |O| + k`` triangular solves; each GMRES iteration one solve with
the base and one product with ``W`` on the closed points' DOFs. ``M`` differs from the
exact matrix only by the turn of the slip directions of ``S``, so right-preconditioned
GMRES (which minimises the true residual) converges in a few iterations. When the layout
changed too much, GMRES stalls, or the rigid Schur complement is rank deficient (where
the exact path's minimum-norm ``α`` is wanted), the exact ``J`` is formed and factorised
and becomes the new base. The preconditioner only changes how fast the direction is
found: every iterate is still accepted on the exact residual ``ρ``.

This module holds the tuning (``KrylovOptions``) and what is kept per ``W`` between steps
(``Base``, ``Workspace``, :func:`workspace_for`, :func:`release`);
:mod:`fe.contact.preconditioner` builds ``M`` and :mod:`fe.contact.krylov_step` takes
the step.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cad.errors import check_range
from fe.contact.dense import Factor
from fe.contact.memo import ArrayMemo

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True)
class KrylovOptions:
    """Tuning of the Krylov path (algorithmic only: the solution does not depend on it).

    Attributes:
        max_update: Refactorise instead of updating the base when ``|N| + |O|`` exceeds
            this fraction of the number of unknowns.
        max_iter: GMRES iterations before giving up and refactorising.
        refresh_iter: Refactorise at the next step after a solve that needed more
            GMRES iterations than this.
        turn_cos: A slipping point whose slip direction turned so that ``u·u₀`` is
            below this counts as changed (its rows and columns become exact).
        forcing: Relative GMRES tolerance is ``min(forcing, ρ²)`` (inexact Newton that
            keeps the final equilibrium error, hence the energy balance, near round-off),
            but not below ``oversolve · tol / ρ``.
        oversolve: Safeguard against oversolving the last steps: a step from ``ρ``
            needs a relative linear residual of about ``tol / ρ`` to end below the
            Newton tolerance ``tol``, not ``ρ²``; the factor leaves room for the 2-norm
            of GMRES against the max-norm of ``ρ`` (``√n`` at most) and keeps the
            equilibrium error, hence the energy balance, near round-off. 0 solves every
            step to ``ρ²``; against it 1e-4 saves GMRES iterations and keeps the energy
            balance at 1e-14, where 1e-2 raised it to 6e-12
            (benchmarks/bench_contact_variants.txt, 'oversolve').
        kappa_change: A slipping point whose slip ratio ``κ`` moved by more than this
            counts as changed too: its row ``κ v·dw_t + (1-κ)/r b`` is rescaled and its
            diagonal moved, which the base cannot know. At Δr 0 it halves the
            refactorisations after slow solves (``refresh_iter``) against 1 (off); 0.03
            and 0.3 were within noise of 0.1 (benchmarks/bench_contact_variants.txt,
            'kappa_change').
        min_size: Smaller systems are always factorised (dense LU is cheap there).
        single_min: Reduced systems of at least this many unknowns get a float32 LU as
            their base (half the time of float64; it is a preconditioner, the steps
            still solve the exact system), with a float64 LU where GMRES fails on it.
    """

    max_update: float = 0.15
    max_iter: int = 40
    refresh_iter: int = 12
    turn_cos: float = 0.9
    forcing: float = 1e-3
    oversolve: float = 1e-4
    min_size: int = 0
    single_min: int = 2000
    kappa_change: float = 0.1

    def __post_init__(self) -> None:
        check_range("krylov.max_update", self.max_update, 0.0, 1.0)
        check_range("krylov.max_iter", self.max_iter, 1, float("inf"))
        check_range("krylov.refresh_iter", self.refresh_iter, 1, float("inf"))
        check_range("krylov.turn_cos", self.turn_cos, -1.0, 1.0)
        check_range("krylov.forcing", self.forcing, 0.0, 1.0, lo_open=True, hi_open=True)
        check_range("krylov.oversolve", self.oversolve, 0.0, 1.0)
        check_range("krylov.min_size", self.min_size, 0, float("inf"))
        check_range("krylov.single_min", self.single_min, 1, float("inf"))
        check_range("krylov.kappa_change", self.kappa_change, 0.0, 1.0)


class Base(NamedTuple):
    """An LU of an earlier reduced Jacobian and the layout it belongs to.

    Attributes:
        factor: The LU factors (of ``J₀ᵀ``) and the unknown keys, shape (n₀,).
        closed: Closed points of that layout, shape (c₀,), int64.
        kind: 0 stick, 1 slip, 2 frictionless per closed point, shape (c₀,), int8.
        u: Slip direction per closed point, shape (c₀, 2), float64.
        kappa: Slip ratio ``κ`` per closed point, shape (c₀,), float64.
    """

    factor: Factor
    closed: IntArray
    kind: npt.NDArray[np.int8]
    u: FloatArray
    kappa: FloatArray


@dataclass
class Workspace:
    """Mutable per-``W`` cache of the Krylov path (preconditioner data only).

    Attributes:
        base: The LU kept as preconditioner (None until the first factorisation).
        refresh: Refactorise at the next step.
        block: Points whose DOFs ``W_block`` holds, shape (n_b,) (None: none yet).
        W_block: ``W`` on those DOFs; kept across increments while ``W``'s fingerprint
            ``w_sum`` is unchanged and the block holds the closed points without too
            much slack (``BLOCK_SLACK``).
        W_single: ``W_block`` (or ``W``) in float32, made on first use: float32 bases
            are formed from it (half the memory traffic of forming them in float64).
        w_sum: Fingerprint of ``W`` (``Problem.w_sum``) that ``W_block`` was taken from.
        gmres_iterations: GMRES iterations done (a counter for reports).
    """

    base: Base | None = None
    refresh: bool = False
    block: IntArray | None = None
    W_block: FloatArray | None = field(default=None, repr=False)
    W_single: npt.NDArray[np.float32] | None = field(default=None, repr=False)
    w_sum: float = float("nan")
    gmres_iterations: int = 0


_WORKSPACES: ArrayMemo[Workspace] = ArrayMemo(per_thread=True, learned=True)


def workspace_for(W: FloatArray, w_sum: float = float("nan")) -> Workspace:
    """Return this thread's workspace for ``W`` (kept while ``W`` lives).

    The base LU carries over between increments on the same ``W``; being only a
    preconditioner, a stale or foreign base can cost iterations but not accuracy. The
    gathered ``W`` block enters the Krylov operator, so it is kept only while ``w_sum``
    (``Problem.w_sum``, NaN: unknown) shows that ``W`` did not change in place.
    """
    ws = _WORKSPACES.setdefault(W, Workspace)
    if ws.w_sum != w_sum:  # W changed in place since the last call (NaN: unknown)
        ws.block, ws.W_block, ws.W_single = None, None, None
    ws.w_sum = w_sum
    return ws


def release(W: FloatArray) -> Workspace | None:
    """Forget this thread's workspace for ``W`` and return it (None if there is none).

    Its ``W`` block, float32 copy and base LU are freed once the caller drops the
    returned workspace (the working set hands the base on, :mod:`fe.contact.working`).
    """
    return _WORKSPACES.pop(W)
