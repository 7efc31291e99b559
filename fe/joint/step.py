"""The joint element increment by increment: what a dynamics code calls each time step.

``step(params, state, u, dt)`` returns the force, the consistent tangent dF/du and the
new state (displacement control); ``step_force`` the same under force control. Both are
exact (``fe.joint.segment``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from cad.errors import ParameterError
from fe.joint.element import JointParams, JointState
from fe.joint.segment import advance_displacement, advance_force


class Step(NamedTuple):
    """One increment's answer: force F [N], consistent tangent dF/du [N/mm], the new state."""

    force_n: float
    tangent_n_per_mm: float
    state: JointState


def step(params: JointParams, state: JointState, disp_mm: float, dt_s: float | None = None) -> Step:
    """Advance the element to the displacement ``disp_mm`` (displacement control).

    Args:
        params: The element.
        state: The state after the previous increment (``initial_state`` to start).
        disp_mm: The total displacement u at the end of the increment [mm].
        dt_s: The increment's duration [s]; needed when ``damping_n_s_per_mm`` > 0
            (F_v = c·(u − u_prev)/Δt, the backward-Euler rate).

    Returns:
        The force, the consistent tangent dF/du (the slope of the piecewise-linear
        response where the increment ends, + c/Δt) and the new state.

    Raises:
        ParameterError: If damping needs ``dt_s`` and it is missing or not positive.
    """
    c = _rate_factor(params, dt_s)
    out = advance_displacement(params, state, np.array([float(disp_mm)]), c)
    return Step(float(out.force[-1]), float(out.tangent[-1]), out.state)


def step_force(
    params: JointParams, state: JointState, force_n: float, dt_s: float | None = None
) -> Step:
    """Advance the element to the force ``force_n`` (force control).

    Returns:
        The force, the consistent tangent dF/du at the end of the increment and the new
        state; the displacement is ``state.disp_mm``.

    Raises:
        ParameterError: If the force exceeds the element's capacity, or damping needs
            ``dt_s``.
    """
    c = _rate_factor(params, dt_s)
    out = advance_force(params, state, np.array([float(force_n)]), c)
    return Step(float(out.force[-1]), float(out.tangent[-1]), out.state)


def _rate_factor(params: JointParams, dt_s: float | None) -> float:
    """c/Δt [N/mm] of an increment (0 without a dashpot)."""
    if params.damping_n_s_per_mm == 0.0:
        return 0.0
    if dt_s is None or not dt_s > 0.0:
        raise ParameterError(f"dt_s must be > 0 with damping_n_s_per_mm > 0, got {dt_s}")
    return params.damping_n_s_per_mm / dt_s
