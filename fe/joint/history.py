"""Histories of the joint element, vectorised over monotone segments.

A history is cut where its driving quantity reverses; each monotone segment is solved at
once (``fe.joint.segment``), so a 10 000-sample sine of ten cycles costs twenty segment
solves (benchmarks/bench_joint.py). Displacement control takes the dashpot exactly
(F_v = c·Δu/Δt per sample, a backward difference); force control with a dashpot is an
implicit equation per increment and runs increment by increment (``step_force``).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import ParameterError
from fe.joint.element import JointParams, JointState, initial_state
from fe.joint.segment import Advance, advance_displacement, advance_force, breakpoints
from fe.joint.step import step_force

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class History:
    """The element along a history, each array shape (n,).

    Attributes:
        force_n: Force F [N] (dashpot included).
        disp_mm: Displacement u [mm].
        tangent_n_per_mm: dF/du of the increment ending at each sample [N/mm] (without
            the dashpot in a history).
        elastic_energy_nmm: Energy stored in the springs [N·mm].
        dissipation_nmm: Friction work dissipated since the start state [N·mm].
        viscous_nmm: Dashpot work dissipated since the start state [N·mm].
        play_mm: Position in the free play [mm].
        state: The state after the last sample.
    """

    force_n: FloatArray
    disp_mm: FloatArray
    tangent_n_per_mm: FloatArray
    elastic_energy_nmm: FloatArray
    dissipation_nmm: FloatArray
    viscous_nmm: FloatArray
    play_mm: FloatArray
    state: JointState


def segments(values: FloatArray, start: float) -> list[slice]:
    """Slices of ``values`` (shape (n,)) on which it moves one way from the previous value."""
    dv = np.diff(np.concatenate([[start], values]))
    sign = np.sign(dv)
    nz = np.flatnonzero(sign)
    if nz.size == 0:
        return [slice(0, values.size)] if values.size else []
    filled = sign[nz][np.maximum(np.searchsorted(nz, np.arange(values.size), side="right") - 1, 0)]
    cuts = np.flatnonzero(np.diff(filled) != 0) + 1
    edges = [0, *cuts.tolist(), values.size]
    return [slice(a, b) for a, b in itertools.pairwise(edges)]


def _collect(parts: list[Advance], state: JointState, viscous: FloatArray) -> History:
    cat = [np.concatenate([getattr(a, f) for a in parts]) for f in Advance._fields[:-1]]
    force, disp, tangent, energy, dissipation, play, _bank = cat
    return History(force, disp, tangent, energy, dissipation, viscous, play, state)


def displacement_history(
    params: JointParams,
    disp_mm: npt.ArrayLike,
    time_s: npt.ArrayLike | None = None,
    state: JointState | None = None,
    *,
    exact_path: bool = False,
) -> History:
    """The element driven through displacements (displacement control).

    Args:
        params: The element.
        disp_mm: Displacements u, shape (n,) [mm], any number of cycles.
        time_s: Their times, shape (n,) [s]; needed with a dashpot.
        state: The start (default: the unloaded element).
        exact_path: Insert every kink of the response between the samples, so that the
            history is exactly piecewise linear between its points (a trapezoidal ∮F du
            is then the exact work).

    Returns:
        The history (with the kinks inserted when ``exact_path``).

    Raises:
        ParameterError: A dashpot without ``time_s``, or times that do not increase.
    """
    state = state or initial_state(params)
    u = np.asarray(disp_mm, dtype=np.float64).ravel()
    if exact_path:
        u = _with_kinks(params, u, state)
    parts, s = [], state
    for sl in segments(u, s.disp_mm):
        out = advance_displacement(params, s, u[sl])
        parts.append(out)
        s = out.state
    if not parts:
        raise ParameterError("disp_mm must hold at least one sample, got none")
    hist = _collect(parts, s, np.zeros(u.size) + state.viscous_nmm)
    return _with_dashpot(params, hist, u, time_s, state) if params.damping_n_s_per_mm else hist


def _with_kinks(params: JointParams, u: FloatArray, state: JointState) -> FloatArray:
    out, s = [], state
    for sl in segments(u, s.disp_mm):
        seg = u[sl]
        kinks = breakpoints(params, s, float(seg[-1]))
        merged = np.concatenate([seg, kinks])
        merged = merged[np.argsort(merged * np.sign(seg[-1] - s.disp_mm or 1.0), kind="stable")]
        out.append(merged)
        s = advance_displacement(params, s, seg[-1:]).state
    return np.concatenate(out)


def _with_dashpot(
    params: JointParams,
    hist: History,
    u: FloatArray,
    time_s: npt.ArrayLike | None,
    state: JointState,
) -> History:
    if time_s is None:
        raise ParameterError("time_s is needed with damping_n_s_per_mm > 0, got None")
    t = np.asarray(time_s, dtype=np.float64).ravel()
    if t.shape != u.shape or np.any(np.diff(t) <= 0):
        raise ParameterError("time_s must increase strictly, one time per displacement")
    du = np.diff(np.concatenate([[state.disp_mm], u]))
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0] if t.size > 1 else 1.0))
    fv = params.damping_n_s_per_mm * du / dt
    viscous = state.viscous_nmm + np.cumsum(fv * du)
    s = hist.state
    end = JointState(
        s.disp_mm,
        s.force_n + float(fv[-1]),
        s.bank_mm,
        s.play_mm,
        s.sliders_mm,
        s.dissipation_nmm,
        float(viscous[-1]),
    )
    return History(
        hist.force_n + fv,
        hist.disp_mm,
        hist.tangent_n_per_mm,
        hist.elastic_energy_nmm,
        hist.dissipation_nmm,
        viscous,
        hist.play_mm,
        end,
    )


def force_history(
    params: JointParams,
    force_n: npt.ArrayLike,
    time_s: npt.ArrayLike | None = None,
    state: JointState | None = None,
) -> History:
    """The element driven through forces (force control); the free play is crossed at F = 0.

    Args:
        params: The element.
        force_n: Forces F, shape (n,) [N].
        time_s: Their times, shape (n,) [s]; needed with a dashpot (then solved
            increment by increment).
        state: The start (default: the unloaded element).

    Raises:
        ParameterError: A force beyond the element's capacity, or a dashpot without times.
    """
    state = state or initial_state(params)
    f = np.asarray(force_n, dtype=np.float64).ravel()
    if params.damping_n_s_per_mm:
        return _force_with_dashpot(params, f, time_s, state)
    parts, s = [], state
    for sl in segments(f, s.force_n):
        out = advance_force(params, s, f[sl])
        parts.append(out)
        s = out.state
    if not parts:
        raise ParameterError("force_n must hold at least one sample, got none")
    return _collect(parts, s, np.zeros(f.size) + state.viscous_nmm)


def _force_with_dashpot(
    params: JointParams, f: FloatArray, time_s: npt.ArrayLike | None, state: JointState
) -> History:
    if time_s is None:
        raise ParameterError("time_s is needed with damping_n_s_per_mm > 0, got None")
    t = np.asarray(time_s, dtype=np.float64).ravel()
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0] if t.size > 1 else 1.0))
    rows, s = [], state
    for k in range(f.size):
        st = step_force(params, s, float(f[k]), float(dt[k]))
        s = st.state
        rows.append(
            (
                st.force_n,
                s.disp_mm,
                st.tangent_n_per_mm,
                s.elastic_energy_nmm(params),
                s.dissipation_nmm,
                s.viscous_nmm,
                s.play_mm,
            )
        )
    F, u, kt, e, w, v, g = (np.array(c, dtype=np.float64) for c in zip(*rows, strict=True))
    return History(F, u, kt, e, w, v, g, state=s)
