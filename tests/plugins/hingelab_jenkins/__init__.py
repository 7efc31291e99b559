"""A rigid pin on a Jenkins element, registered as the hinge kind ``jenkins_pin`` (a test plug-in).

The pin is held by a spring ``k0`` in parallel with a Jenkins branch: a spring ``k1`` in
series with a Coulomb slider of strength ``Fs``. Under the force F it sits at δ with

    F = k0 δ + q,   q = k1 (δ − s),   |q| ≤ Fs,

s being the slider's position. Each increment is solved exactly (elastic predictor, then
the slider's return map), and the force at which the slider starts or stops is added to the
targets, so the loop is exactly piecewise linear and its trapezoidal area is exact.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from cad.errors import ParameterError, check_range
from fe.cycle.protocol import CycleSettings, stage_targets
from fe.cycle.result import CycleResult, Increment
from fe.kinds import Built, DesignVariable
from mesh.settings import MeshSettings


@dataclasses.dataclass(frozen=True)
class JenkinsParams:
    """The element's stiffnesses [N/mm] and slip force [N]."""

    k0_n_per_mm: float = 2000.0
    k1_n_per_mm: float = 6000.0
    slip_force_n: float = 60.0

    def __post_init__(self) -> None:
        check_range("k0_n_per_mm", self.k0_n_per_mm, 0.0, 1e9, lo_open=True)
        check_range("k1_n_per_mm", self.k1_n_per_mm, 0.0, 1e9, lo_open=True)
        check_range("slip_force_n", self.slip_force_n, 0.0, 1e6)


SLIP = DesignVariable(
    name="slip_force_n",
    column="slip_force_N",
    symbol="F_s",
    word="slip force",
    unit="N",
    lo=0.0,
    hi=1e6,
    tag="s",
    structural=False,
    study_levels=(30.0, 60.0),
    synth_levels=(30.0, 60.0, 90.0),
    case_tag="fs",
)


def loop_area(params: JenkinsParams, amplitude_n: float) -> float:
    """The closed-form loop area of the cycle ±Fg [N·mm] (0 below the slip onset)."""
    k0, k1, fs = params.k0_n_per_mm, params.k1_n_per_mm, params.slip_force_n
    onset = fs * (k0 + k1) / k1  # the force swing that takes the branch from -Fs to +Fs is 2·onset
    return max(0.0, 4.0 * fs * (amplitude_n - onset) / k0)


def _solve(p: JenkinsParams, force: float, s: float) -> tuple[float, float, float]:
    """(δ, q, s) at ``force`` from slider position ``s``: stick if |q| ≤ Fs, else slip."""
    k0, k1, fs = p.k0_n_per_mm, p.k1_n_per_mm, p.slip_force_n
    d = (force + k1 * s) / (k0 + k1)
    q = k1 * (d - s)
    if abs(q) <= fs:
        return d, q, s
    q = float(np.sign(q)) * fs
    d = (force - q) / k0
    return d, q, d - q / k1


def _kink(p: JenkinsParams, f_from: float, f_to: float, q: float) -> float | None:
    """The force inside (f_from, f_to) where a sticking branch reaches ±Fs, if any."""
    if f_to == f_from or abs(q) >= p.slip_force_n:
        return None
    ratio = p.k1_n_per_mm / (p.k0_n_per_mm + p.k1_n_per_mm)
    limit = np.sign(f_to - f_from) * p.slip_force_n
    f = f_from + (limit - q) / ratio
    return float(f) if min(f_from, f_to) < f < max(f_from, f_to) else None


def run_jenkins_cycle(p: JenkinsParams, settings: CycleSettings) -> CycleResult:
    """The load cycle 0 → +Fg → −Fg → +Fg, solved exactly."""
    incs: list[Increment] = []
    d, q, s, f_prev = 0.0, 0.0, 0.0, 0.0
    for stage, (f_from, f_to, n) in enumerate(settings.stages()):
        for target in stage_targets(f_from, f_to, n, settings.grading):
            kink = _kink(p, f_prev, float(target), q)
            for f in [x for x in (kink, float(target)) if x is not None]:
                d, q, s_new = _solve(p, f, s)
                work = abs(q) * abs(s_new - s)
                s = s_new
                energy = 0.5 * p.k0_n_per_mm * d**2 + 0.5 * p.k1_n_per_mm * (d - s) ** 2
                slip = int(abs(q) >= p.slip_force_n and work > 0)
                incs.append(Increment(stage, f, d, 1, 1, 0, 1 - slip, slip, work, 0.0, energy))
                f_prev = f
    return CycleResult(settings, 0.0, tuple(incs), 0.0, (), {}, {})


class JenkinsPin:
    """The hinge kind: a rigid pin on a Jenkins element, no mesh, no CAD."""

    name = "jenkins_pin"
    title = "Jenkins pin"
    params_type = JenkinsParams
    design_variables = (SLIP,)

    def mesh_settings(
        self, *, cycle: bool = True, coarse: bool = False, **overrides: Any
    ) -> MeshSettings:
        return MeshSettings(**overrides)

    def check(self, params: Any, effects: Mapping[str, Mapping[str, float]]) -> None:
        pass

    def resolve(
        self, params: Any, cycle: CycleSettings, effects: Any
    ) -> tuple[Any, CycleSettings, Any]:
        return params, cycle, effects

    def structure(self, params: Any) -> Any:
        return dataclasses.replace(params, slip_force_n=0.0)

    def build(
        self, params: Any, mesh: MeshSettings, out: Path | None, cache_dir: Path | None
    ) -> Built:
        return Built(system=None, meshed=None)

    def run(
        self, built: Built, params: Any, settings: CycleSettings, effects: Any, progress: Any
    ) -> CycleResult:
        result = run_jenkins_cycle(params, settings)
        if effects:
            from fe.effects.registry import post_increments, validate_effects

            result = post_increments(result, validate_effects(effects))
        if progress is not None:
            progress(len(result.increments), len(result.increments))
        return result

    def summary(self, built: Built, params: Any, result: CycleResult) -> dict[str, Any]:
        return {"hinge": self.name, "n_dof": 1, "slip_force_N": params.slip_force_n}

    def headline(self, summary: Mapping[str, Any]) -> str:
        return f"η = {summary['eta']:.5f}   W_cycle = {summary['W_cycle_Nmm']:.5g} N·mm   (Jenkins pin)"

    def write_fields(
        self, built: Built, result: CycleResult, folder: Path, every: int
    ) -> Path | None:
        return None

    def cad(self, params: Any) -> Any:
        raise ParameterError("the Jenkins pin has no CAD model")


JENKINS_PIN = JenkinsPin()
