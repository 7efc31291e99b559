"""The free-play crossing's geometry: face points, where the pin engages, the state carried over.

Helpers of ``fe.general.freeplay`` (the cycle of a hinge with clearance and clamped faces): which
points of a configuration are face points, the consistent relative displacement of a state,
its status counts, the linear program that finds where the pin first touches as the clevis
slides, and the state carried from one touching configuration into the other.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.optimize import linprog

from cad.errors import ConvergenceError
from fe.contact.law import ContactStatus
from fe.contact.state import ContactState
from fe.general.system import GRIP, N_PIN_MODES
from fe.structure.condensed import Condensed

FloatArray = npt.NDArray[np.float64]


def face_mask(cond: Condensed) -> npt.NDArray[np.bool_]:
    """True for the face points of a configuration (``fe.general.faces.FACE_PAIR_CODE`` < 0)."""
    return np.asarray(cond.geo.pair) < 0


def has_faces(cond: Condensed) -> bool:
    """True if the configuration has face points."""
    return bool(np.any(face_mask(cond)))


def face_rows(mask: npt.NDArray[np.bool_]) -> npt.NDArray[np.int64]:
    """Rows (3 per point, node-major) of the points selected by ``mask``, shape (3 k,)."""
    idx = np.flatnonzero(mask)
    return (3 * idx[:, None] + np.arange(3)).ravel().astype(np.int64)


def consistent_w(cond: Condensed, p: FloatArray, alpha: FloatArray) -> FloatArray:
    """``w = W p + G α + w0``, shape (m, 3)."""
    w = cond.W @ np.ravel(p) + cond.G @ alpha
    return np.asarray(w.reshape(-1, 3) + np.asarray(cond.w0), dtype=np.float64)


def status_counts(status: npt.NDArray[np.int8]) -> tuple[int, int, int]:
    """(open, stick, slip) point counts of a status array."""
    return (
        int(np.sum(status == ContactStatus.OPEN)),
        int(np.sum(status == ContactStatus.STICK)),
        int(np.sum(status == ContactStatus.SLIP)),
    )


def engagement(cond: Condensed, p: FloatArray, direction: int) -> tuple[float, FloatArray]:
    """Where the pin first touches as the clevis slides ``direction``: (δ [mm], pin modes (6,)).

    The pin carries nothing (``p`` is zero on its points); its gaps under the faces' forces
    ``p`` are ``g = (W p + w0)_n + G_pin α + G_δ δ``. The first touch is the extreme
    ``direction · δ`` for which some pin position keeps every gap ≥ 0 (a linear program).
    """
    pin = ~face_mask(cond)
    rows_n = 3 * np.flatnonzero(pin)
    base = (np.asarray(cond.W)[rows_n] @ np.ravel(p)) + np.asarray(cond.w0)[pin, 0]
    A = np.asarray(cond.G)[rows_n][:, : N_PIN_MODES + 1]
    c = np.zeros(N_PIN_MODES + 1)
    c[GRIP] = -float(direction)
    bounds = [(-1.0, 1.0)] * (N_PIN_MODES + 1)
    bounds[2] = bounds[5] = (0.0, 0.0)  # axial slide and spin of the pin: no gap changes
    lp = linprog(c, A_ub=-A, b_ub=base, bounds=bounds, method="highs")
    if lp.status != 0:
        raise ConvergenceError(
            f"pin engagement: linear program failed ({lp.message})",
            increment=0,
            iteration=0,
            residual=float("nan"),
        )
    x = np.asarray(lp.x, dtype=np.float64)
    return float(x[GRIP]), x[:N_PIN_MODES]


def switched_state(
    old: Condensed, new: Condensed, state: ContactState, shift_mm: float
) -> ContactState:
    """The state carried into another configuration: faces as they are, pin points open.

    ``shift_mm`` is added to the grip coordinate (``(s_old − s_new)·2Δr``); the pin's modes
    stay (it carries nothing). The face points' relative displacement moves with the grip.
    """
    fo, fn = face_mask(old), face_mask(new)
    m = len(new.geo.slave)
    p = np.zeros((m, 3))
    p[fn] = np.asarray(state.p)[fo]
    alpha = np.array(state.alpha, dtype=np.float64, copy=True)
    alpha[GRIP] += shift_mm
    w = consistent_w(new, p, alpha)
    G_f = np.asarray(new.G)[face_rows(fn), GRIP].reshape(-1, 3)
    w[fn] = np.asarray(state.w)[fo] + G_f * shift_mm  # the old w moved rigidly
    status = np.zeros(m, dtype=np.int8)
    status[fn] = np.asarray(state.status)[fo]
    return ContactState(p, w, status, alpha)
