"""What a bearing-hinge cycle reports besides the loop: preload step, ball loads, model choices."""

from __future__ import annotations

from typing import Any

from cad.bearing_geometry import BallModel
from fe.bearing.balls import ball_state_of, elastic_energy
from fe.bearing.report import ball_table, fit_ball_table
from fe.cycle.result import CycleResult


def model_choices(system: Any, params: Any) -> dict[str, Any]:
    """The model choices every bearing-hinge cycle summary starts with."""
    return {
        "hinge": "bearing",
        "preload_N": params.preload_n,
        "ball_model": params.ball_model.value,
        "interfaces": params.interfaces.value,
        "n_balls": system.n_balls,
    }


def model_size(system: Any, result: CycleResult) -> dict[str, Any]:
    """Degrees of freedom, contact points, surface pairs and the system's build timings."""
    return {
        "n_dof": system.n_dof,
        "n_contact_pairs": len(result.configs[1].geo.slave)
        if result.configs
        else len(result.states[-1].p),
        "n_surface_pairs": len(system.mesh.pairs),
        "timings_s": dict(system.timings_s),
    }


def bearing_summary(result: CycleResult, system: Any, params: Any) -> dict[str, Any]:
    """The Hertz-ball (or meshed-ball) hinge: preload step, ball loads, energy note."""
    if result.preload_state is None:
        raise ValueError("a bearing-hinge cycle result without its preload state")
    pre = ball_state_of(system, result.preload_state)
    m = result.metrics()
    out = {
        **model_choices(system, params),
        **model_size(system, result),
        "n_contact_points": 2 * system.n_balls,  # each ball's inner and outer contact
        "ball_hertz_constant_N_per_mm1.5": system.balls.k_n,
        "preload_step": {
            "plate_travel_mm": float(pre.alpha[2]),
            "axial_float_mm": float(pre.alpha[1]),
            "ball_load_mean_N": float(pre.load_n.mean()),
            "contact_angle_mean_deg": float(pre.angle_deg.mean()),
            "elastic_energy_Nmm": elastic_energy(system, pre),
            "dissipation_Nmm": 0.0,
        },
        "balls": ball_table(system, result),
        "energy_balance_abs_Nmm": abs(
            m["W_cycle_Nmm"]
            - m["elastic_energy_change_Nmm"]
            - m["friction_work_Nmm"]
            - m["effect_work_Nmm"]
        ),
        "energy_balance_note": "nothing can dissipate (bonded interfaces, free-rolling balls): "
        "W_cycle is the loop's quadrature error, compare energy_balance_abs_Nmm with U_max_Nmm",
    }
    if params.ball_model is BallModel.FULL:
        out |= full_ball_notes(result)
    return out


def full_ball_notes(result: CycleResult) -> dict[str, Any]:
    """What differs in the summary of a cycle with meshed (``full``) balls."""
    fric = sum(i.friction_work for i in result.increments[result.last_loop().start :])
    return {
        "ball_friction_work_loop_Nmm": fric,
        "energy_balance_note": "friction (micro-slip in the meshed ball patches) and "
        "open/close work of all ball contacts against the trapezoidal loop area",
        "preload_note": "the pair is seated frictionless (dissipation 0 by that choice); the "
        "ball patches' friction history starts after the preload",
    }


def fit_summary(result: CycleResult, system: Any, params: Any) -> dict[str, Any]:
    """The hinge with frictional fits: ball loads, contact points, the preload note."""
    return {
        "balls": fit_ball_table(system, result),
        **model_choices(system, params),
        **model_size(system, result),
        "n_contact_points": system.n_points + 2 * system.n_balls,  # fits, and each ball's two
        "preload_step": {
            "dissipation_Nmm": 0.0,
            "note": "assembled frictionlessly: the fits' friction history starts after it",
        },
    }
