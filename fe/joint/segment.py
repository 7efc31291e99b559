"""The joint element along one monotone segment of its history, solved exactly.

Along a segment on which the displacement (or the force) moves one way, each branch
sticks until its spring's stretch reaches rᵢ(x) = φᵢ + λᵢ|x| and then slides with it to
the segment's end: its slider follows sᵢ(x) = max(sᵢ₀, x − rᵢ(x)) (moving forwards), a
non-decreasing function of the bank's deformation x because λᵢ < 1. The bank's force is
therefore piecewise linear in x, with kinks where a branch starts to slide (its onset)
and at x = 0; the free play is crossed at F = 0 and the series spring changes stiffness
there. The breakpoints form a table of (x, p, F, u), strictly increasing in u, and every
target of the segment is an exact linear interpolation in that table (``np.interp``):
the segment costs a few array operations whatever its number of samples.

A backward segment is the forward one in the mirrored frame (x, s, p, u, F → −x, −s, −p,
−u, −F, with k₊ and k₋ swapped), since rᵢ depends on |x| only; with a slip asymmetry a
the frame's φᵢ is φᵢ(1 + a·d) (``JointParams.branches_towards``).

The friction work of a branch sliding from x_a to x_b is exact: its slider moves by
ds = (1 − λ sgn x) dx at the force kᵢ rᵢ(x), so it is kᵢ [G(x_b) − G(x_a)] with
G(x) = (1 − λ sgn x)(φ x + λ x|x|/2).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cad.errors import ParameterError
from fe.joint.element import Branches, JointParams, JointState

FloatArray = npt.NDArray[np.float64]


class Advance(NamedTuple):
    """The element at each target of a segment, arrays of shape (n,).

    Attributes:
        force: Force F [N] (dashpot included). disp: Displacement u [mm].
        tangent: dF/du of the piece each target ends on [N/mm].
        energy: Elastic energy [N·mm]. dissipation: Friction work so far [N·mm].
        play: Play position p [mm]. bank: Bank deformation x [mm].
        state: The state at the last target.
    """

    force: FloatArray
    disp: FloatArray
    tangent: FloatArray
    energy: FloatArray
    dissipation: FloatArray
    play: FloatArray
    bank: FloatArray
    state: JointState


class _Frame(NamedTuple):
    """A segment's start in the forward frame and its breakpoint table.

    The columns have shape (m,); ``*_mid`` are at the pieces' midpoints, shape (m − 1,).
    """

    d: float  # +1 forwards, −1 backwards (the frame's sign)
    s0: FloatArray  # (N,) slider positions at the start
    x: FloatArray
    p: FloatArray
    f: FloatArray
    u: FloatArray
    energy: FloatArray
    energy_mid: FloatArray
    work: FloatArray
    work_mid: FloatArray


def _g(x: FloatArray, br: Branches) -> FloatArray:
    """Gᵢ(x) of every branch at every x, shape (n, N) [mm²] (friction work = kᵢ ΔG)."""
    xc = x[:, None]
    return (1.0 - br.lam * np.sign(xc)) * (br.phi * xc + 0.5 * br.lam * xc * np.abs(xc))


def _sliders(x: FloatArray, s0: FloatArray, br: Branches) -> FloatArray:
    """Slider positions at bank deformations x (forward frame), shape (n, N) [mm]."""
    xc = x[:, None]
    return np.maximum(s0, xc - br.phi - br.lam * np.abs(xc))


def _series(params: JointParams, d: float) -> tuple[float, float]:
    """(k for F' > 0, k for F' < 0) in the frame of sign d."""
    kt, kc = params.k_tension_n_per_mm, params.k_compression_n_per_mm
    return (kt, kc) if d > 0 else (kc, kt)


def _bank_force(params: JointParams, br: Branches, x: FloatArray, s0: FloatArray) -> FloatArray:
    """The bank's force at bank deformations x, shape (n,) [N]."""
    return params.k_elastic_n_per_mm * x + (x[:, None] - _sliders(x, s0, br)) @ br.k


def _frame(
    params: JointParams, br: Branches, state: JointState, d: float, reach_u: float, reach_f: float
) -> _Frame:
    """Build the breakpoint table of a segment in the direction d up to the reaches (frame)."""
    s0 = d * state.sliders_mm if state.sliders_mm.size else np.zeros(params.n_branches)
    x0, p0, g = d * state.bank_mm, d * state.play_mm, params.gap_mm
    y = s0 + br.phi
    onset = np.maximum(np.where(y >= 0, y * br.inv_minus, y * br.inv_plus), x0)
    xb = np.sort(np.concatenate([onset, [x0, max(x0, 0.0)]]))
    fb = _bank_force(params, br, xb, s0)
    if p0 < g:  # off the play's forward end the bank carries no tension (round-off aside)
        fb[0] = min(fb[0], 0.0)
    k_pos, k_neg = _series(params, d)
    slope = params.k_elastic_n_per_mm + float(br.k @ br.lam)  # dF/dx beyond the last kink
    u_last = xb[-1] + g + fb[-1] / (k_pos if fb[-1] > 0 else k_neg)
    far = max(reach_u - u_last, 0.0) + 1.0  # du/dx ≥ 1 there
    if reach_f > fb[-1]:
        if slope <= 0.0:
            raise ParameterError(
                f"force {d * reach_f:.6g} N exceeds the joint's capacity "
                f"{params.capacity_n():.6g} N (slip_force_n, no elastic path)"
            )
        far = max(far, 2.0 * (reach_f - fb[-1]) / slope + 1.0)
    xb = np.append(xb, xb[-1] + far)
    fb = np.append(fb, fb[-1] + slope * far)
    if fb[0] < 0 < fb[-1]:  # the force changes sign: a breakpoint at F = 0 exactly
        i = int(np.argmax(fb >= 0.0))
        if fb[i] != 0.0:
            xz = xb[i - 1] - fb[i - 1] * (xb[i] - xb[i - 1]) / (fb[i] - fb[i - 1])
            xb = np.concatenate([xb[:i], [xz], xb[i:]])
            fb = np.concatenate([fb[:i], [0.0], fb[i:]])
    x, p, f = _with_play(xb, fb, p0, g, fb[0] <= 0.0 < fb[-1])
    u = x + p + f / np.where(f > 0, k_pos, k_neg)
    keep = np.concatenate([[True], np.diff(u) > 0])  # drop zero-length pieces
    x, p, f, u = x[keep], p[keep], f[keep], u[keep]
    pts = np.concatenate([x, 0.5 * (x[1:] + x[:-1])])
    s = _sliders(pts, s0, br)
    fp = np.concatenate([f, 0.5 * (f[1:] + f[:-1])])
    energy = (
        0.5 * params.k_elastic_n_per_mm * pts**2
        + 0.5 * ((pts[:, None] - s) ** 2) @ br.k
        + fp**2 / (2.0 * np.where(fp > 0, k_pos, k_neg))
    )
    g_on = (1.0 - br.lam * np.sign(onset)) * (br.phi * onset + 0.5 * br.lam * onset * np.abs(onset))
    work = np.where(pts[:, None] > onset, _g(pts, br) - g_on, 0.0) @ br.k
    m = x.size
    return _Frame(d, s0, x, p, f, u, energy[:m], energy[m:], work[:m], work[m:])


def _with_play(
    xb: FloatArray, fb: FloatArray, p0: float, g: float, crosses: bool
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Breakpoints with the play: p0 while F < 0, crossed to +g at F = 0, +g while F > 0."""
    if not crosses:
        return xb, np.where(fb > 0, g, p0), fb
    i = int(np.argmax(fb >= 0.0))  # the first point at F = 0 (exactly: see _frame)
    x = np.concatenate([xb[: i + 1], xb[i:]])
    f = np.concatenate([fb[: i + 1], fb[i:]])
    p = np.where(np.arange(x.size) <= i, p0, g)
    return x, p, f


def _evaluate(
    params: JointParams, br: Branches, fr: _Frame, u: FloatArray, state: JointState, rate: float
) -> Advance:
    """The element at targets u (frame), inside the table's range.

    Between two breakpoints x, p and F are linear in u, the energy and the friction work
    quadratic (x is, and Gᵢ is on either side of x = 0): each is interpolated exactly
    from the table's ends and midpoints, so no (n, N) array is formed.
    """
    j = np.clip(np.searchsorted(fr.u, u, side="left") - 1, 0, fr.u.size - 2)
    du = fr.u[j + 1] - fr.u[j]
    t = (u - fr.u[j]) / du
    x = fr.x[j] + t * (fr.x[j + 1] - fr.x[j])
    play = fr.p[j] + t * (fr.p[j + 1] - fr.p[j])
    df = fr.f[j + 1] - fr.f[j]
    f_el = fr.f[j] + t * df
    tangent = df / du + rate
    l0, l1, l2 = (1 - t) * (1 - 2 * t), 4 * t * (1 - t), t * (2 * t - 1)  # nodes 0, ½, 1
    energy = l0 * fr.energy[j] + l1 * fr.energy_mid[j] + l2 * fr.energy[j + 1]
    work = l0 * fr.work[j] + l1 * fr.work_mid[j] + l2 * fr.work[j + 1]
    d = fr.d
    u0 = d * state.disp_mm
    force = d * (f_el + rate * (u - u0))
    dissipation = state.dissipation_nmm + work
    viscous = state.viscous_nmm + rate * (u[-1] - u0) ** 2
    new = JointState(
        d * float(u[-1]),
        float(force[-1]),
        d * float(x[-1]),
        d * float(play[-1]),
        d * _sliders(x[-1:], fr.s0, br)[0],
        float(dissipation[-1]),
        float(viscous),
    )
    return Advance(force, d * u, tangent, energy, dissipation, d * play, d * x, new)


def advance_displacement(
    params: JointParams, state: JointState, disp: FloatArray, rate: float = 0.0
) -> Advance:
    """The element at displacements that move monotonically from ``state.disp_mm``.

    Args:
        params: The element.
        state: The segment's start.
        disp: Targets u, shape (n,) [mm], all on one side of ``state.disp_mm`` and
            monotone (a segment of a history, or one increment).
        rate: c/Δt [N/mm] of a single increment (the dashpot; 0 for a segment).

    Returns:
        The element at each target.
    """
    d = 1.0 if disp[-1] >= state.disp_mm else -1.0
    br = params.branches_towards(d)
    fr = _frame(params, br, state, d, float(d * disp.max() if d > 0 else -disp.min()), -np.inf)
    return _evaluate(params, br, fr, d * disp, state, rate)


def advance_force(
    params: JointParams, state: JointState, force: FloatArray, rate: float = 0.0
) -> Advance:
    """The element at forces that move monotonically from ``state.force_n``.

    The free play is crossed at F = 0: a target of exactly 0 leaves the play where it is.

    Raises:
        ParameterError: If a force exceeds the element's capacity.
    """
    d = 1.0 if force[-1] >= state.force_n else -1.0
    br = params.branches_towards(d)
    reach = float(d * force.max() if d > 0 else -force.min())
    fr = _frame(params, br, state, d, -np.inf, reach)
    u0 = d * state.disp_mm
    total = fr.f + rate * (fr.u - u0)  # the force the table carries, dashpot included
    u = np.interp(d * force, total, fr.u)
    if rate == 0.0:  # F = 0 exactly: the first F = 0 point (the play not yet crossed)
        first = fr.u[int(np.argmax(fr.f >= 0.0))] if np.any(fr.f >= 0.0) else fr.u[0]
        u = np.where(force == 0.0, max(first, u0), u)
    return _evaluate(params, br, fr, u, state, rate)


def breakpoints(params: JointParams, state: JointState, disp_end: float) -> FloatArray:
    """The displacements where the response kinks, strictly inside the increment.

    Kinks: a branch's onset, x = 0, the free play's ends; shape (m,) [mm].
    """
    d = 1.0 if disp_end >= state.disp_mm else -1.0
    br = params.branches_towards(d)
    fr = _frame(params, br, state, d, d * disp_end, -np.inf)
    u = fr.u[(fr.u > d * state.disp_mm) & (fr.u < d * disp_end)]
    return np.asarray(d * u)
