"""The bearing hinge as a registered kind: the pin in a preloaded pair of angular-contact bearings.

Registered as ``bearing`` (``fe.kinds``). Its structure is one geometry for every preload
(the preload is a load step on it); its balls are Hertz lines between meshed rings
(``hertz``) or the one-ball rig's law (``full``); its fits are bonded or frictional
contacts (``interfaces``), and the ``interface_friction`` effect turns bonded fits into
frictional ones.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from cad.bearing_geometry import MAX_PRELOAD_N, BallModel, BearingHingeParams, Interfaces
from cad.errors import ParameterError
from fe.cycle.protocol import CycleSettings
from fe.cycle.result import CycleResult
from fe.kinds import Built, DesignVariable, Effects, Progress
from mesh.meshed import build_and_mesh
from mesh.settings import MeshSettings

PRELOAD = DesignVariable(
    name="preload_n",
    column="preload_N",
    symbol="F_p",
    word="preload",
    unit="N",
    lo=0.0,
    hi=MAX_PRELOAD_N,
    tag="p",
    fmt="g",
    structural=False,
    study_levels=(0.0, 50.0, 100.0, 150.0, 200.0),
    synth_levels=(0.0, 100.0, 200.0),
    case_tag="fp",
)
"""The axial preload F_p: a load on an unchanged structure (one mesh for every value)."""

INTERFACE_FRICTION = "interface_friction"
"""The effect that swaps the structure: bonded fits become Coulomb contacts."""

MESH_DEFAULTS: Mapping[str, Any] = {
    "size_mm": 2.5,
    "contact_size_mm": 0.4,
    "slave_ratio": 1.5,
    "part_sizes_mm": (("ball", 0.6), ("ring", 0.8), ("pin", 1.2), ("preload_plate", 1.2)),
}
"""Mesh of the structure a cycle runs on: 4 mm balls need their own sizes and thin rings;
without meshed balls the raceway patches only average the ring's displacement, so 0.4 mm
there suffices (a 62k-node structure)."""

COARSE: Mapping[str, Any] = {
    "size_mm": 4.0,
    "contact_size_mm": 0.8,
    "part_sizes_mm": (("ring", 1.2),),
}
"""The coarse preset of the structure without balls (4 mm / 0.8 mm, rings 1.2 mm)."""

BALL_CONTACT_SIZE_MM = 0.15
"""Contact size where the balls are meshed (``hingelab mesh``): the ball–raceway Hertz
radius is about 0.15 mm at 200 N preload."""


class BearingHinge:
    """The paper's modified hinge (``cad.bearing``, ``fe.bearing``)."""

    name = "bearing"
    title = "bearing hinge"
    params_type = BearingHingeParams
    design_variables = (PRELOAD,)

    def mesh_settings(
        self, *, cycle: bool = True, coarse: bool = False, **overrides: Any
    ) -> MeshSettings:
        """The bearing hinge's mesh defaults, with fields overridden.

        Args:
            cycle: The structure a cycle runs on (no meshed balls); False: the whole CAD
                model with its balls, at the finer contact size their patches need.
            coarse: The coarse preset of the structure (``COARSE``: a cycle in seconds).
            **overrides: MeshSettings fields.
        """
        base = dict(MESH_DEFAULTS)
        if not cycle:
            base["contact_size_mm"] = BALL_CONTACT_SIZE_MM
        if coarse:
            base |= COARSE
        return MeshSettings(**{**base, **overrides})

    def check(self, params: Any, effects: Effects) -> None:
        """Refuse model choices whose cycle is not implemented, naming them.

        Raises:
            ParameterError: ``ball_model = "full"`` with frictional fits (``interfaces =
                "contact"`` or ``interface_friction``), or ``interface_friction`` on fits
                that are contacts already.
        """
        full = params.ball_model is BallModel.FULL
        if full and params.interfaces is Interfaces.CONTACT:
            raise ParameterError(
                "ball_model = 'full' runs with interfaces = 'bonded' only (the frictional fits' "
                "cycle takes hertz balls), got ball_model = 'full' with interfaces = 'contact'"
            )
        if full and INTERFACE_FRICTION in effects:
            raise ParameterError(
                f"ball_model = 'full' runs with bonded interfaces only, got ball_model = 'full' "
                f"with effects.{INTERFACE_FRICTION} (frictional fits take hertz balls)"
            )
        if INTERFACE_FRICTION in effects and params.interfaces is Interfaces.CONTACT:
            raise ParameterError(
                f"effects.{INTERFACE_FRICTION} makes bonded interfaces frictional, but "
                "interfaces = 'contact' already: their friction coefficient is the model's mu"
            )

    def resolve(
        self, params: Any, cycle: CycleSettings, effects: Effects
    ) -> tuple[Any, CycleSettings, Effects]:
        """``interface_friction`` written as the structure it makes.

        On bonded fits with ``mu_interface > 0`` it becomes ``interfaces = "contact"`` with
        ``cycle.mu = mu_interface`` (the hertz balls carry no friction, so the model's μ acts
        on nothing else); at 0 the effect is off and only dropped. So keys and stored results
        are those of the model the cycle really runs.
        """
        values = effects.get(INTERFACE_FRICTION)
        if values is None or params.interfaces is not Interfaces.BONDED:
            return params, cycle, effects
        rest = {k: v for k, v in effects.items() if k != INTERFACE_FRICTION}
        mu = float(values.get("mu_interface", 0.0))
        if mu == 0.0:
            return params, cycle, rest
        return (
            dataclasses.replace(params, interfaces=Interfaces.CONTACT),
            dataclasses.replace(cycle, mu=mu),
            rest,
        )

    def structure(self, params: Any) -> Any:
        """The parameters at zero preload: every preload shares one geometry."""
        return dataclasses.replace(params, preload_n=0.0)

    def build(
        self, params: Any, mesh: MeshSettings, out: Path | None, cache_dir: Path | None
    ) -> Built:
        """Mesh the structure without balls and build the Hertz-ball or frictional-fit system."""
        from cad.bearing import make_bearing_hinge, without_balls  # build123d: only to build

        model = without_balls(make_bearing_hinge(params))
        if params.interfaces is Interfaces.CONTACT:
            from fe.bearing.fits import build_fit_system, with_frictional_fits

            meshed = build_and_mesh(with_frictional_fits(model), mesh, out)
            return Built(build_fit_system(meshed.mesh, params), meshed)
        from fe.bearing.system import build_bearing_system

        meshed = build_and_mesh(model, mesh, out)
        return Built(build_bearing_system(meshed.mesh, params), meshed)

    def run(
        self,
        built: Built,
        params: Any,
        settings: CycleSettings,
        effects: Effects,
        progress: Progress | None,
    ) -> CycleResult:
        """Preload, then cycle; effects (applied to the loop) post-process δ."""
        if params.interfaces is Interfaces.CONTACT:
            from fe.bearing.fit_cycle import run_fit_cycle

            result = run_fit_cycle(built.system, settings, params.preload_n, progress=progress)[0]
        else:
            from fe.bearing.cycle import run_bearing_cycle

            result = run_bearing_cycle(
                built.system, settings, params.preload_n, progress=progress
            ).result
        return _post_only(result, effects)

    def summary(self, built: Built, params: Any, result: CycleResult) -> dict[str, Any]:
        """Preload, ball loads, model choices; the energy-balance note of bonded fits."""
        from fe.bearing.summary import bearing_summary, fit_summary

        if params.interfaces is Interfaces.CONTACT:
            return fit_summary(result, built.system, params)
        return bearing_summary(result, built.system, params)

    def headline(self, summary: Mapping[str, Any]) -> str:
        """η, W_cycle and δ(+Fg); the preload step for Hertz balls."""
        if summary["interfaces"] == Interfaces.CONTACT.value:
            return (
                f"η = {summary['eta']:.5f}   W_cycle = {summary['W_cycle_Nmm']:.5g} N·mm   "
                f"δ(+Fg) = {summary['disp_at_peak_mm'] * 1e3:.3f} µm   energy balance "
                f"{summary['energy_balance_rel_err']:.1e}   (bearing hinge, frictional fits)"
            )
        pre = summary["preload_step"]
        what = (
            "meshed balls: ball-patch micro-slip only"
            if "ball_friction_work_loop_Nmm" in summary
            else "nothing dissipates in this model"
        )
        return (
            f"η = {summary['eta']:.2e}   W_cycle = {summary['W_cycle_Nmm']:.3g} N·mm "
            f"(U_max {summary['U_max_Nmm']:.4g} N·mm; {what})   "
            f"δ(+Fg) = {summary['disp_at_peak_mm'] * 1e3:.3f} µm   preload: plate travel "
            f"{pre['plate_travel_mm'] * 1e3:.2f} µm, contact angle "
            f"{pre['contact_angle_mean_deg']:.2f}°"
        )

    def write_fields(
        self, built: Built, result: CycleResult, folder: Path, every: int
    ) -> Path | None:
        """Displacements and ball loads on the raceway patches as a ParaView series."""
        from fe.bearing.fits import FitSystem
        from fe.bearing.report import write_bearing_series, write_fit_series

        if isinstance(built.system, FitSystem):
            return write_fit_series(built.system, result, folder, every=every)
        return write_bearing_series(built.system, result, folder, every=every)

    def cad(self, params: Any) -> Any:
        """The CAD model with its balls (``cad.bearing.make_bearing_hinge``)."""
        from cad.bearing import make_bearing_hinge

        return make_bearing_hinge(params)


def _post_only(result: CycleResult, effects: Effects) -> CycleResult:
    """The cycle with its (loop-only) effects applied to δ.

    The tangent stiffness kept for the Hermite loop rule no longer holds once δ changes, so
    it is dropped (the trapezoid is used).
    """
    if not effects:
        return result
    from fe.effects.registry import post_increments, validate_effects

    out = post_increments(result, validate_effects(effects))
    incs = tuple(dataclasses.replace(i, stiffness_n_per_mm=math.nan) for i in out.increments)
    return dataclasses.replace(out, increments=incs)


BEARING = BearingHinge()
"""The registered bearing hinge (entry point ``bearing``)."""
