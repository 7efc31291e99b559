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

from cad.errors import ParameterError
from fe.cycle.protocol import CycleSettings, stage_targets
from fe.cycle.result import CycleResult, Increment
from fe.joint.element import JointParams, initial_state
from fe.joint.history import displacement_history, force_history
from fe.kinds import Built, DesignVariable, Effects, Progress
from mesh.settings import MeshSettings

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
