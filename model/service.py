"""The model service: a specification and design points in, one ``CycleResult`` per point out.

Every command that runs the model (``cycle``, ``sweep``, ``compare``, ``synth``,
``diagnose``, ``calibrate``, the paper validation) goes through ``ModelService``:

* each geometry (hinge parameters + mesh settings, i.e. one clearance) is built, meshed,
  assembled, factorised and condensed once (``prepare``; the nodal compliances are kept
  on disk by the mesh's content hash when ``cache_dir`` is given) and reused for every
  amplitude, μ and effect run on it;
* every point's result is keyed by ``model.spec.result_key``; with a ``ResultStore``
  a point whose key is stored is read back instead of computed (a rerun with identical
  inputs costs nothing; any changed input is another key and recomputes), and a newly
  computed point is stored atomically the moment it finishes, before ``on_result`` is
  called;
* duplicate points are run once;
* a failing point becomes a failed ``PointRun`` (with its error and partial loop) and the
  others go on (``keep_going``); a failing geometry fails its points the same way.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cad.errors import HingelabError, ParameterError
from fe.bearing.fits import FitSystem
from fe.bearing.system import BearingSystem, build_bearing_system
from fe.hinge.condensed import Condensed
from fe.hinge.cycle import run_cycle
from fe.hinge.result import CycleResult
from fe.hinge.system import HingeSystem, build_system
from mesh.meshed import MeshedHinge, build_and_mesh
from model.spec import (
    INTERFACE_FRICTION,
    DesignPoint,
    HingeKind,
    ModelSpec,
    geometry_key,
    hinge_at,
    resolve_structural,
    result_key,
    structure_of,
)
from model.store import ResultStore

logger = logging.getLogger(__name__)


@dataclass
class Prepared:
    """One geometry, meshed, factorised and ready to be condensed and cycled.

    Attributes:
        key: Its geometry key.
        clearance_mm: Its radial clearance [mm] (from the model's exact cylinders).
        meshed: The CAD model, mesh, quality report and the files written.
        system: The factorised hinge (``BearingSystem`` for the bearing hinge).
        configs: Condensed configurations of plain cycles by contact window
            (``CycleSettings.contact_window``), once a cycle has made them.
        effect_configs: Condensed configurations without window that effects start from
            (``fe.effects.run_cycle_with_effects``), once a cycle with effects has made them.
        setup_s: Wall time of building, meshing and factorising [s].
    """

    key: str
    clearance_mm: float
    meshed: MeshedHinge
    system: HingeSystem | BearingSystem | FitSystem
    configs: dict[float, dict[int, Condensed]] = field(default_factory=dict)
    effect_configs: dict[int, Condensed] | None = None
    setup_s: float = 0.0


@dataclass(frozen=True)
class PointRun:
    """What happened at one design point.

    Attributes:
        point: The design point.
        key: Its result key.
        result: The cycle (None if it failed).
        error: Why it failed (None if it did not).
        cached: True if the result was read from the store, not computed.
        prepared: The geometry it ran on (None if read from the store without one).
        partial: The increments that converged before a failure (or None).
        wall_s: Wall time of this point [s] (0 when cached).
    """

    point: DesignPoint
    key: str
    result: CycleResult | None
    error: str | None = None
    cached: bool = False
    prepared: Prepared | None = None
    partial: CycleResult | None = None
    wall_s: float = 0.0

    @property
    def ok(self) -> bool:
        """True if the point has a result."""
        return self.result is not None


def check_spec(spec: ModelSpec) -> None:
    """Refuse a specification the service cannot run, naming what is wrong.

    Raises:
        ParameterError: For a bearing-hinge model choice whose cycle is not implemented
            (``ball_model = "full"`` with frictional fits: ``interfaces = "contact"`` or
            the ``interface_friction`` effect), an effect that does not act on the model's
            hinge kind (``fe.effects.Effect.applies_to``), or ``interface_friction`` on
            fits that are contacts already.
    """
    from cad.bearing import BallModel, BearingHingeParams, Interfaces
    from fe.effects import REGISTRY

    other = sorted(
        n for n in spec.effects if n in REGISTRY and not REGISTRY[n].applies_to(spec.kind)
    )
    if other and spec.kind == HingeKind.BEARING:
        raise ParameterError(
            f"effects {other} act on the general hinge's pin contacts; the bearing hinge "
            "takes effects applied to its loop (e.g. frame_compliance) and interface_friction"
        )
    if other:
        raise ParameterError(
            f"effects {other} act on the bearing hinge's bonded interfaces; the {spec.kind} "
            "hinge has none (use kind = 'bearing')"
        )
    if spec.kind != HingeKind.BEARING or not isinstance(spec.hinge, BearingHingeParams):
        return
    if spec.hinge.ball_model is BallModel.FULL and spec.hinge.interfaces is Interfaces.CONTACT:
        raise ParameterError(
            "ball_model = 'full' runs with interfaces = 'bonded' only (the frictional fits' "
            "cycle takes hertz balls), got ball_model = 'full' with interfaces = 'contact'"
        )
    if spec.hinge.ball_model is BallModel.FULL and INTERFACE_FRICTION in spec.effects:
        raise ParameterError(
            f"ball_model = 'full' runs with bonded interfaces only, got ball_model = 'full' "
            f"with effects.{INTERFACE_FRICTION} (frictional fits take hertz balls)"
        )
    if INTERFACE_FRICTION in spec.effects and spec.hinge.interfaces is Interfaces.CONTACT:
        raise ParameterError(
            f"effects.{INTERFACE_FRICTION} makes bonded interfaces frictional, but interfaces = "
            "'contact' already: their friction coefficient is the model's mu"
        )


def _post_only(result: CycleResult, effects: Any) -> CycleResult:
    """The bearing hinge's cycle with its (loop-only) effects applied to δ.

    The tangent stiffness kept for the Hermite loop rule no longer holds once δ changes, so
    it is dropped (the trapezoid is used).
    """
    if not effects:
        return result
    from fe.effects.registry import post_increments, validate_effects

    out = post_increments(result, validate_effects(effects))
    incs = tuple(dataclasses.replace(i, stiffness_n_per_mm=math.nan) for i in out.increments)
    return dataclasses.replace(out, increments=incs)


class ModelService:
    """Run a model at design points, preparing each geometry once.

    Args:
        store: Where results are kept by key (None: nothing is kept between runs).
        cache_dir: Where nodal compliances are kept by mesh hash (None: in memory only).
        geometry_dir: Folder for a geometry's STEP, mesh and picture files, given its
            clearance [mm] (None: no files).
        max_geometries: Prepared geometries kept in memory (the least recently used is
            dropped); None keeps all (a diagnosis revisits every clearance).
    """

    def __init__(
        self,
        *,
        store: ResultStore | None = None,
        cache_dir: Path | None = None,
        geometry_dir: Callable[[float], Path] | None = None,
        max_geometries: int | None = None,
    ) -> None:
        self.store = store
        self.cache_dir = cache_dir
        self.geometry_dir = geometry_dir
        self.max_geometries = max_geometries
        self._prepared: OrderedDict[str, Prepared] = OrderedDict()
        self.n_computed = 0
        self.n_cached = 0
        self.setup_s = 0.0
        self.cycle_s = 0.0

    def prepare(self, spec: ModelSpec, clearance_mm: float) -> Prepared:
        """Build, mesh and factorise the geometry of ``spec`` at ``clearance_mm`` (memoised)."""
        from cad.general import GeneralHingeParams, make_general_hinge

        check_spec(spec)
        spec = resolve_structural(spec)
        key = geometry_key(spec, clearance_mm)
        if key in self._prepared:
            self._prepared.move_to_end(key)
            return self._prepared[key]
        t0 = time.perf_counter()
        hinge = structure_of(spec, clearance_mm)
        out = None if self.geometry_dir is None else self.geometry_dir(clearance_mm)
        system: HingeSystem | BearingSystem | FitSystem
        if isinstance(hinge, GeneralHingeParams):
            meshed = build_and_mesh(make_general_hinge(hinge), spec.mesh, out)
            system = build_system(meshed.mesh, cache_dir=self.cache_dir)
            clearance = system.clearance_mm
        else:
            from cad.bearing import Interfaces, make_bearing_hinge, without_balls

            model = without_balls(make_bearing_hinge(hinge))
            if hinge.interfaces is Interfaces.CONTACT:
                from fe.bearing.fits import build_fit_system, with_frictional_fits

                meshed = build_and_mesh(with_frictional_fits(model), spec.mesh, out)
                system = build_fit_system(meshed.mesh, hinge)
            else:
                meshed = build_and_mesh(model, spec.mesh, out)
                system = build_bearing_system(meshed.mesh, hinge)
            clearance = 0.0
        prepared = Prepared(key, clearance, meshed, system)
        prepared.setup_s = time.perf_counter() - t0
        self.setup_s += prepared.setup_s
        self._prepared[key] = prepared
        if self.max_geometries is not None:
            while len(self._prepared) > self.max_geometries:
                self._prepared.popitem(last=False)
        return prepared

    def cached(self, spec: ModelSpec, point: DesignPoint) -> CycleResult | None:
        """The stored result at ``point``, or None."""
        if self.store is None:
            return None
        return self.store.get(result_key(spec, point))

    def run_point(
        self,
        spec: ModelSpec,
        point: DesignPoint,
        *,
        progress: Callable[[int, int], None] | None = None,
    ) -> CycleResult:
        """Return the cycle at ``point`` (from the store, or computed and stored).

        Raises:
            ParameterError: A parameter out of range (named).
            ConvergenceError: As ``fe.hinge.cycle.run_cycle`` (its ``partial`` kept).
        """
        check_spec(spec)
        spec = resolve_structural(spec)
        key = result_key(spec, point)
        if self.store is not None:
            hit = self.store.get(key)
            if hit is not None:
                self.n_cached += 1
                return hit
        prepared = self.prepare(spec, point.clearance_mm)
        result = self._compute(spec, point, prepared, progress)
        if self.store is not None:
            self.store.put(key, result)
        return result

    def _compute(
        self,
        spec: ModelSpec,
        point: DesignPoint,
        prepared: Prepared,
        progress: Callable[[int, int], None] | None,
    ) -> CycleResult:
        settings = dataclasses.replace(spec.cycle, amplitude_n=point.amplitude_n)
        t0 = time.perf_counter()
        try:
            if isinstance(prepared.system, FitSystem):
                from fe.bearing.fit_cycle import run_fit_cycle

                hinge = hinge_at(spec, point)
                preload = float(getattr(hinge, "preload_n", 0.0))
                fit = run_fit_cycle(prepared.system, settings, preload, progress=progress)[0]
                return _post_only(fit, spec.effects)
            if isinstance(prepared.system, BearingSystem):
                from fe.bearing.cycle import run_bearing_cycle

                hinge = hinge_at(spec, point)
                preload = float(getattr(hinge, "preload_n", 0.0))
                result = run_bearing_cycle(
                    prepared.system, settings, preload, progress=progress
                ).result
                return _post_only(result, spec.effects)
            if spec.effects:
                from fe.effects import run_cycle_with_effects

                with_effects = run_cycle_with_effects(
                    prepared.system,
                    prepared.clearance_mm,
                    settings,
                    spec.effects,
                    configs=prepared.effect_configs,
                )
                prepared.effect_configs = with_effects.base_configs
                return with_effects.result
            result = run_cycle(
                prepared.system,
                prepared.clearance_mm,
                settings,
                configs=prepared.configs.get(settings.contact_window),
                progress=progress,
            )
            prepared.configs[settings.contact_window] = result.configs
            return result
        finally:
            self.n_computed += 1
            self.cycle_s += time.perf_counter() - t0

    def run(
        self,
        spec: ModelSpec,
        points: Iterable[DesignPoint],
        *,
        on_result: Callable[[PointRun], None] | None = None,
        keep_going: bool = True,
    ) -> list[PointRun]:
        """Run every distinct point, one geometry (clearance) at a time.

        Args:
            spec: The model.
            points: Design points; duplicates run once (the list returned has one entry each).
            on_result: Called with each point's outcome the moment it is known (after the
                result is stored).
            keep_going: Record a failing point and go on (else re-raise its error).

        Returns:
            One ``PointRun`` per distinct point, grouped by clearance in first-seen order.
        """
        check_spec(spec)
        spec = resolve_structural(spec)
        unique: dict[str, DesignPoint] = {}
        for p in points:
            unique.setdefault(result_key(spec, p), p)
        groups: dict[float, list[tuple[str, DesignPoint]]] = {}
        for key, p in unique.items():
            groups.setdefault(p.clearance_mm, []).append((key, p))
        out: list[PointRun] = []
        for clearance, members in groups.items():
            for key, p in members:
                run = self._one(spec, key, p, clearance, keep_going)
                out.append(run)
                if on_result is not None:
                    on_result(run)
        return out

    def _one(
        self, spec: ModelSpec, key: str, p: DesignPoint, clearance: float, keep_going: bool
    ) -> PointRun:
        hit = None if self.store is None else self.store.get(key)
        if hit is not None:
            self.n_cached += 1
            prepared = self._peek(spec, clearance)
            return PointRun(p, key, hit, cached=True, prepared=prepared)
        t0 = time.perf_counter()
        prepared = None
        try:
            prepared = self.prepare(spec, clearance)
            result = self._compute(spec, p, prepared, None)
            if self.store is not None:
                self.store.put(key, result)
            return PointRun(p, key, result, prepared=prepared, wall_s=time.perf_counter() - t0)
        except (HingelabError, ArithmeticError, RuntimeError, ValueError, MemoryError) as err:
            if not keep_going:
                raise
            partial = getattr(err, "partial", None)
            where = "geometry" if prepared is None else "point"
            msg = f"{where} failed: {type(err).__name__}: {err}"
            logger.error("%s: %s", p.label(), msg)
            return PointRun(
                p,
                key,
                None,
                error=msg,
                prepared=prepared,
                partial=partial if isinstance(partial, CycleResult) else None,
                wall_s=time.perf_counter() - t0,
            )

    def _peek(self, spec: ModelSpec, clearance: float) -> Prepared | None:
        return self._prepared.get(geometry_key(spec, clearance))


def design_points(
    clearances_mm: Iterable[float], amplitudes_n: Iterable[float]
) -> list[DesignPoint]:
    """The full factorial clearance × amplitude, duplicates removed, in order."""
    seen: dict[tuple[float, float], DesignPoint] = {}
    amps = list(amplitudes_n)
    for c in clearances_mm:
        for a in amps:
            p = DesignPoint(amplitude_n=a, clearance_mm=c)
            seen.setdefault((p.clearance_mm, p.amplitude_n), p)
    return list(seen.values())
