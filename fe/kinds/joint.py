"""The reduced-order joint as a registered hinge kind (``joint``): no mesh, no CAD.

A model file with ``[hinge] kind = "joint"`` and the fields of
:class:`fe.joint.element.JointParams` (what ``hingelab reduce`` writes) runs through
``hingelab cycle --model``, ``sweep`` and ``compare`` like any kind. Its cycle is the
protocol's force-controlled 0 → +Fg → −Fg → +Fg …, solved exactly with every kink of
the response added as an increment, so the trapezoidal loop area is the exact loop area.
The displacement δ of an increment is, as for the FE kinds, the one with the free play
removed (``CycleResult.free_play_mm`` = the element's free play 2g, ``side`` the end of
the play the element bears on).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from cad.errors import ParameterError
from fe.cycle.protocol import CycleSettings, stage_targets
from fe.cycle.result import CycleResult, Increment
from fe.joint.element import JointParams, initial_state
from fe.joint.history import displacement_history, force_history
from fe.kinds import Built, DesignVariable, Effects, Progress
from mesh.settings import MeshSettings

FloatArray = npt.NDArray[np.float64]

SLIP_FORCE = DesignVariable(
    name="slip_force_n",
    column="slip_force_N",
    symbol="F_s",
    word="slip force",
    unit="N",
    lo=0.0,
    hi=1e9,
    tag="s",
    structural=False,
    study_levels=(0.0, 10.0),
    synth_levels=(0.0, 10.0, 20.0),
    case_tag="fs",
)
"""The bank's fixed friction capacity F_s (a preload or band tension sets it)."""


def run_joint_cycle(params: JointParams, settings: CycleSettings) -> CycleResult:
    """The protocol's force-controlled cycle on the element, every kink an increment.

    Raises:
        ParameterError: If ±Fg exceeds the element's capacity.
    """
    if settings.amplitude_n > params.capacity_n():
        raise ParameterError(
            f"amplitude_n = {settings.amplitude_n:g} N exceeds the joint's capacity "
            f"{params.capacity_n():g} N (slip_force_n without an elastic path)"
        )
    g = params.gap_mm
    incs: list[Increment] = []
    state = initial_state(params)
    for stage, (f_from, f_to, n) in enumerate(settings.stages()):
        forces = stage_targets(f_from, f_to, n, settings.grading)
        disp = force_history(params, forces, state=state).disp_mm
        hist = displacement_history(params, disp, state=state, exact_path=True)
        d_prev = state.dissipation_nmm
        for k in range(hist.force_n.size):
            play = float(hist.play_mm[k])
            side = 1 if play > 0 or (play == 0 and hist.force_n[k] >= 0) else -1
            work = float(hist.dissipation_nmm[k]) - d_prev
            d_prev = float(hist.dissipation_nmm[k])
            incs.append(
                Increment(
                    stage=stage,
                    force_n=float(hist.force_n[k]),
                    disp_mm=float(hist.disp_mm[k] - play) if g > 0 else float(hist.disp_mm[k]),
                    side=side,
                    iterations=0,
                    n_open=0,
                    n_stick=0,
                    n_slip=int(work > 0),
                    friction_work=work,
                    normal_work=0.0,
                    elastic_energy=float(hist.elastic_energy_nmm[k]),
                )
            )
        state = hist.state
    return CycleResult(settings, 0.0, tuple(incs), params.free_play_mm, (), {}, {})


def run_joint_displacement(
    params: JointParams,
    time_s: npt.ArrayLike,
    disp_mm: npt.ArrayLike,
    passes: int = 2,
) -> tuple[FloatArray, FloatArray]:
    """The element driven through one measured cycle, repeated until it is steady.

    The element starts unloaded at u = 0, ramps to the cycle's first displacement over
    ``RAMP_SAMPLES`` samples, then runs the cycle ``passes`` times; the last pass is
    returned (a rate-independent element with a free play repeats itself from the
    second pass on). With a dashpot the cycle's own times give the rate.

    Args:
        params: The element.
        time_s: The cycle's times, shape (n,) [s], strictly increasing.
        disp_mm: Its displacements, shape (n,) [mm] (one cycle +δ → −δ → +δ).
        passes: Times the cycle is run (≥ 1).

    Returns:
        (F [N], u [mm]) of the last pass, each shape (n,).
    """
    t = np.asarray(time_s, dtype=np.float64).ravel()
    u = np.asarray(disp_mm, dtype=np.float64).ravel()
    if t.shape != u.shape or t.size < 2:
        raise ParameterError(
            f"time_s and disp_mm must be two equal arrays of ≥ 2 samples, got {t.size}, {u.size}"
        )
    dt = float(np.median(np.diff(t)))
    ramp_u = u[0] * np.linspace(0.0, 1.0, RAMP_SAMPLES + 1)[1:]
    ramp_t = dt * np.arange(1, RAMP_SAMPLES + 1)
    span = t[-1] - t[0] + dt
    parts_t = [ramp_t] + [ramp_t[-1] + dt + k * span + (t - t[0]) for k in range(max(passes, 1))]
    parts_u = [ramp_u] + [u] * max(passes, 1)
    hist = displacement_history(params, np.concatenate(parts_u), np.concatenate(parts_t))
    return hist.force_n[-u.size :], hist.disp_mm[-u.size :]


RAMP_SAMPLES = 16
"""Samples of the ramp from rest to a measured cycle's first displacement."""


class JointKind:
    """The hinge kind ``joint``: the reduced-order element of ``fe.joint``."""

    name = "joint"
    title = "reduced-order joint"
    params_type = JointParams
    design_variables = (SLIP_FORCE,)

    def mesh_settings(
        self, *, cycle: bool = True, coarse: bool = False, **overrides: Any
    ) -> MeshSettings:
        """No mesh: ``MeshSettings``' defaults, kept only because a spec carries one."""
        return MeshSettings(**overrides)

    def check(self, params: Any, effects: Effects) -> None:
        """Nothing beyond the parameters' and effects' own checks."""

    def resolve(
        self, params: Any, cycle: CycleSettings, effects: Effects
    ) -> tuple[Any, CycleSettings, Effects]:
        """No effect changes the element's structure: returned as given."""
        return params, cycle, effects

    def structure(self, params: Any) -> Any:
        """One structure for every slip force (a load-like variable)."""
        return dataclasses.replace(params, slip_force_n=0.0)

    def build(
        self, params: Any, mesh: MeshSettings, out: Path | None, cache_dir: Path | None
    ) -> Built:
        """Nothing to build."""
        return Built(system=None, meshed=None)

    def run(
        self,
        built: Built,
        params: Any,
        settings: CycleSettings,
        effects: Effects,
        progress: Progress | None,
    ) -> CycleResult:
        """Run the cycle (``run_joint_cycle``), then the effects' post-processing."""
        result = run_joint_cycle(params, settings)
        if effects:
            from fe.effects.registry import post_increments, validate_effects

            result = post_increments(result, validate_effects(effects))
        if progress is not None:
            progress(len(result.increments), len(result.increments))
        return result

    def displacement_loop(
        self, params: Any, time_s: npt.ArrayLike, disp_mm: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """The element driven by a measured cycle's displacement (``run_joint_displacement``).

        A kind that has this method can be compared with displacement-controlled records
        (``validation.stroke_fit``); the meshed kinds do not have it.
        """
        return run_joint_displacement(params, time_s, disp_mm)

    def summary(self, built: Built, params: Any, result: CycleResult) -> dict[str, Any]:
        """The element's parameters."""
        return {"hinge": self.name, "n_dof": 1, "joint": dataclasses.asdict(params)}

    def headline(self, summary: Mapping[str, Any]) -> str:
        """η and W of the element's loop."""
        return (
            f"η = {summary['eta']:.5f}   W_cycle = {summary['W_cycle_Nmm']:.5g} N·mm   "
            "(reduced-order joint)"
        )

    def write_fields(
        self, built: Built, result: CycleResult, folder: Path, every: int
    ) -> Path | None:
        """No fields: the element has no mesh."""
        return None

    def cad(self, params: Any) -> Any:
        """No CAD model."""
        raise ParameterError("the reduced-order joint has no CAD model")


JOINT = JointKind()
