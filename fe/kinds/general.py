"""The general hinge as a registered kind: tang, clevis and a steel pin with radial clearance.

Registered as ``general`` (``fe.kinds``); everything kind-specific that the service, the
command line and the validation ask about the general hinge is answered here.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from cad.general_params import MAX_CLEARANCE_MM, GeneralHingeParams
from fe.cycle.protocol import CycleSettings
from fe.cycle.result import CycleResult
from fe.kinds import Built, DesignVariable, Effects, Progress
from mesh.meshed import build_and_mesh
from mesh.settings import MeshSettings

CLEARANCE = DesignVariable(
    name="clearance_mm",
    column="clearance_mm",
    symbol="Δr",
    word="clearance",
    unit="mm",
    lo=0.0,
    hi=MAX_CLEARANCE_MM,
    tag="c",
    fmt=".3f",
    structural=True,
    study_levels=(0.0, 0.1, 0.2, 0.3, 0.4),
    synth_levels=(0.0, 0.1, 0.2),
    case_tag="dr",
    limit="max_clearance_mm",
)
"""The radial clearance Δr: it changes the holes, so every value is its own mesh."""


class GeneralHinge:
    """The paper's general hinge (``cad.general``, ``fe.general``)."""

    name = "general"
    title = "general hinge"
    params_type = GeneralHingeParams
    design_variables = (CLEARANCE,)

    def mesh_settings(
        self, *, cycle: bool = True, coarse: bool = False, **overrides: Any
    ) -> MeshSettings:
        """``MeshSettings``'s own defaults (one mesh for cycles and CAD), or its coarse preset."""
        return MeshSettings.coarse(**overrides) if coarse else MeshSettings(**overrides)

    def check(self, params: Any, effects: Effects) -> None:
        """Nothing beyond the parameters' and effects' own checks."""

    def resolve(
        self, params: Any, cycle: CycleSettings, effects: Effects
    ) -> tuple[Any, CycleSettings, Effects]:
        """No effect changes the general hinge's structure: returned as given."""
        return params, cycle, effects

    def structure(self, params: Any) -> Any:
        """All parameters shape the mesh (the clearance included)."""
        return params

    def build(
        self, params: Any, mesh: MeshSettings, out: Path | None, cache_dir: Path | None
    ) -> Built:
        """Build, mesh and factorise; ``structure`` holds the exact clearance of the mesh."""
        from cad.general import make_general_hinge  # build123d loads only to build a solid
        from fe.general.system import build_system

        meshed = build_and_mesh(make_general_hinge(params), mesh, out)
        system = build_system(meshed.mesh, cache_dir=cache_dir)
        return Built(system, meshed, {"clearance_mm": system.clearance_mm})

    def run(
        self,
        built: Built,
        params: Any,
        settings: CycleSettings,
        effects: Effects,
        progress: Progress | None,
    ) -> CycleResult:
        """Run the cycle, with effects on the condensed system when any are on.

        The condensed configurations are kept in ``built.cache`` (by contact window for
        plain cycles, one set without window for effects) and reused by every later cycle.
        """
        clearance = built.structure["clearance_mm"]
        if effects:
            from fe.effects.cycle import run_cycle_with_effects

            with_effects = run_cycle_with_effects(
                built.system,
                clearance,
                settings,
                effects,
                configs=built.cache.get("effect_configs"),
            )
            built.cache["effect_configs"] = with_effects.base_configs
            return with_effects.result
        from fe.general.cycle import run_cycle

        windows: dict[float, Any] = built.cache.setdefault("configs", {})
        result = run_cycle(
            built.system,
            clearance,
            settings,
            configs=windows.get(settings.contact_window),
            progress=progress,
        )
        windows[settings.contact_window] = result.configs
        return result

    def summary(self, built: Built, params: Any, result: CycleResult) -> dict[str, Any]:
        """Clearance, model size and contact points of the cycle."""
        system = built.system
        return {
            "hinge": self.name,
            "clearance_mm": result.clearance_mm,
            "n_dof": system.n_dof,
            "n_contact_pairs": len(result.configs[1].geo.slave)
            if result.configs
            else len(result.states[-1].p),
            "n_contact_points": len(result.configs[1].geo.slave)
            if result.configs
            else len(result.states[-1].p),
            "n_surface_pairs": len(system.mesh.pairs),
            "timings_s": dict(system.timings_s),
        }

    def headline(self, summary: Mapping[str, Any]) -> str:
        """η, W_cycle, δ(+Fg), the free play removed and the energy balance."""
        return (
            f"η = {summary['eta']:.5f}   W_cycle = {summary['W_cycle_Nmm']:.5g} N·mm   "
            f"δ(+Fg) = {summary['disp_at_peak_mm'] * 1e3:.3f} µm   free play = "
            f"{summary['free_play_mm'] * 1e3:.0f} µm (removed)   energy balance "
            f"{summary['energy_balance_rel_err']:.1e}"
        )

    def write_fields(
        self, built: Built, result: CycleResult, folder: Path, every: int
    ) -> Path | None:
        """Displacement, stress, contact pressure and slip as a ParaView series."""
        from fe.general.report import write_time_series

        return write_time_series(built.system, result, folder, every=every)

    def cad(self, params: Any) -> Any:
        """The CAD model (``cad.general.make_general_hinge``)."""
        from cad.general import make_general_hinge

        return make_general_hinge(params)


GENERAL = GeneralHinge()
"""The registered general hinge (entry point ``general``)."""
