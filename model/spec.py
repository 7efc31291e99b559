"""What determines a result: the model specification, a design point, and their content hash.

A ``ModelSpec`` is everything a ``MODEL.toml`` holds (hinge kind and parameters with
their materials, mesh settings, load protocol and solver options with μ, effects). A
``DesignPoint`` is what a study varies (clearance, amplitude). ``result_key`` hashes
both, the package version and the contact-solver defaults into one SHA-256: two runs with
the same key give the same numbers, and any changed input gives another key.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import importlib.metadata
import json
import math
import types
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from cad.bearing import BearingHingeParams
from cad.errors import ParameterError, check_range
from cad.general import GeneralHingeParams
from fe.contact import ContactSettings
from fe.hinge.protocol import CycleSettings
from mesh.settings import MeshSettings

HingeParams = GeneralHingeParams | BearingHingeParams


class HingeKind(enum.StrEnum):
    """The hinges the project models."""

    GENERAL = "general"
    """Tang, clevis and a steel pin with radial clearance (the paper's general hinge)."""
    BEARING = "bearing"
    """The pin in a preloaded pair of angular-contact ball bearings (the modified hinge)."""


HINGE_PARAMS: dict[str, type[GeneralHingeParams] | type[BearingHingeParams]] = {
    HingeKind.GENERAL.value: GeneralHingeParams,
    HingeKind.BEARING.value: BearingHingeParams,
}
"""Hinge kind → its parameter dataclass."""


@dataclass(frozen=True)
class ModelSpec:
    """A complete hinge model.

    Attributes:
        kind: Hinge kind (``general`` or ``bearing``).
        hinge: Geometry and materials.
        mesh: Mesh settings.
        cycle: Load protocol and solver options, including the friction coefficient μ.
        effects: Enabled effect → its parameters (read-only mappings).
    """

    kind: str
    hinge: HingeParams
    mesh: MeshSettings = field(default_factory=MeshSettings)
    cycle: CycleSettings = field(default_factory=CycleSettings)
    effects: Mapping[str, Mapping[str, float]] = field(
        default_factory=lambda: types.MappingProxyType({})
    )

    def __post_init__(self) -> None:
        if self.kind not in HINGE_PARAMS:
            raise ParameterError(f"kind must be one of {tuple(HINGE_PARAMS)}, got {self.kind!r}")
        if not isinstance(self.hinge, HINGE_PARAMS[self.kind]):
            raise ParameterError(
                f"kind {self.kind!r} needs {HINGE_PARAMS[self.kind].__name__}, "
                f"got {type(self.hinge).__name__}"
            )
        frozen = {k: types.MappingProxyType(dict(v)) for k, v in self.effects.items()}
        object.__setattr__(self, "effects", types.MappingProxyType(frozen))


@dataclass(frozen=True)
class DesignPoint:
    """One point of a design study.

    Attributes:
        amplitude_n: Force amplitude Fg [N].
        clearance_mm: Radial clearance Δr of the general hinge [mm].
        preload_n: Axial preload F_p of the bearing hinge [N]; None: the model's own.
    """

    amplitude_n: float
    clearance_mm: float = 0.0
    preload_n: float | None = None

    def __post_init__(self) -> None:
        check_range("amplitude_n", self.amplitude_n, 0.0, 1e6, lo_open=True)
        check_range("clearance_mm", self.clearance_mm, 0.0, 10.0)
        # 0.0 and -0.0, 300 and 300.0 are one point (one key, one run)
        object.__setattr__(self, "amplitude_n", float(self.amplitude_n) + 0.0)
        object.__setattr__(self, "clearance_mm", float(self.clearance_mm) + 0.0)
        if self.preload_n is not None:
            check_range("preload_n", self.preload_n, 0.0, 500.0)
            object.__setattr__(self, "preload_n", float(self.preload_n) + 0.0)

    def label(self) -> str:
        """Folder name of the point, e.g. ``c0.100_F300`` or ``p100_F300``."""
        if self.preload_n is not None:
            return f"p{self.preload_n:g}_F{self.amplitude_n:g}"
        return f"c{self.clearance_mm:.3f}_F{self.amplitude_n:g}"

    def key_fields(self) -> dict[str, float]:
        """What identifies the point in a result key.

        No preload entry when it is None, so the general hinge's keys do not change.
        """
        out = {"amplitude_n": self.amplitude_n, "clearance_mm": self.clearance_mm}
        if self.preload_n is not None:
            out["preload_n"] = self.preload_n
        return out


def with_clearance(spec: ModelSpec, clearance_mm: float) -> HingeParams:
    """Return the spec's hinge parameters at another radial clearance (general hinge).

    The bearing hinge has no clearance: its parameters are returned as they are for 0.

    Raises:
        ParameterError: For a clearance on the bearing hinge, or an out-of-range value.
    """
    if not isinstance(spec.hinge, GeneralHingeParams):
        if clearance_mm != 0.0:
            raise ParameterError(
                f"clearance_mm must be 0 for the {spec.kind} hinge (it has none), "
                f"got {clearance_mm!r}"
            )
        return spec.hinge
    return dataclasses.replace(spec.hinge, clearance_mm=clearance_mm)


def hinge_at(spec: ModelSpec, point: DesignPoint) -> HingeParams:
    """The hinge parameters at a design point (its clearance, its preload if it has one).

    Raises:
        ParameterError: For a preload on the general hinge or a clearance on the bearing one.
    """
    hinge = with_clearance(spec, point.clearance_mm)
    if point.preload_n is None:
        return hinge
    if not isinstance(hinge, BearingHingeParams):
        raise ParameterError(
            f"preload_n applies to the bearing hinge only, got {point.preload_n!r} "
            f"for the {spec.kind} hinge"
        )
    return dataclasses.replace(hinge, preload_n=point.preload_n)


def structure_of(spec: ModelSpec, clearance_mm: float) -> HingeParams:
    """The hinge parameters that determine the mesh and its condensation.

    The bearing hinge's preload is a load on an unchanged structure, so every preload
    shares one geometry (one factorisation).
    """
    hinge = with_clearance(spec, clearance_mm)
    if isinstance(hinge, BearingHingeParams):
        return dataclasses.replace(hinge, preload_n=0.0)
    return hinge


INTERFACE_FRICTION = "interface_friction"
"""The effect that swaps the bearing hinge's structure (``fe.effects.interfaces``)."""


def resolve_structural(spec: ModelSpec) -> ModelSpec:
    """The model with its structure-changing effects written as the structure they make.

    ``interface_friction`` on a bonded bearing hinge (``mu_interface > 0``) becomes
    ``interfaces = "contact"`` with ``cycle.mu = mu_interface`` (the hertz balls carry no
    friction, so the model's μ acts on nothing else); at 0 the effect is off and only
    dropped. Every other spec is returned as it is, so keys and stored results are those
    of the model the cycle really runs.
    """
    values = spec.effects.get(INTERFACE_FRICTION)
    if values is None or not isinstance(spec.hinge, BearingHingeParams):
        return spec
    from cad.bearing import Interfaces

    if spec.hinge.interfaces is not Interfaces.BONDED:
        return spec  # refused by check_spec, with the reason
    rest = {k: v for k, v in spec.effects.items() if k != INTERFACE_FRICTION}
    mu = float(values.get("mu_interface", 0.0))
    if mu == 0.0:
        return dataclasses.replace(spec, effects=rest)
    return dataclasses.replace(
        spec,
        hinge=dataclasses.replace(spec.hinge, interfaces=Interfaces.CONTACT),
        cycle=dataclasses.replace(spec.cycle, mu=mu),
        effects=rest,
    )


def package_version() -> str:
    """The installed hingelab version ("unknown" when run from a bare source tree)."""
    try:
        return importlib.metadata.version("hingelab")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def plain(obj: Any) -> Any:
    """Turn dataclasses, enums, mappings and tuples into JSON values, recursively.

    Floats are kept exact (``repr`` round-trips); a non-finite float becomes its name
    as a string, so the canonical text is strict JSON.
    """
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, enum.Enum):
        return obj.value
    if isinstance(obj, Mapping):
        return {str(k): plain(v) for k, v in sorted(obj.items(), key=lambda kv: str(kv[0]))}
    if isinstance(obj, list | tuple):
        return [plain(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    if hasattr(obj, "tolist"):  # numpy arrays and scalars
        return plain(obj.tolist())
    return obj


def content_hash(obj: Any) -> str:
    """SHA-256 of the canonical JSON of ``obj`` (sorted keys, no whitespace)."""
    text = json.dumps(plain(obj), sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def geometry_key(spec: ModelSpec, clearance_mm: float) -> str:
    """Hash of what the mesh and its condensation depend on (not the load or μ)."""
    spec = resolve_structural(spec)
    return content_hash(
        {
            "kind": spec.kind,
            "hinge": structure_of(spec, clearance_mm),
            "mesh": spec.mesh,
            "version": package_version(),
        }
    )


def result_key(spec: ModelSpec, point: DesignPoint) -> str:
    """Hash of everything that determines the cycle at ``point``.

    The whole specification (its own amplitude replaced by the point's), the design
    point, the contact-solver defaults and the package version; a structure-changing
    effect is keyed as the structure it makes (``resolve_structural``).
    """
    spec = resolve_structural(spec)
    cycle = dataclasses.replace(spec.cycle, amplitude_n=point.amplitude_n)
    return content_hash(
        {
            "kind": spec.kind,
            "hinge": hinge_at(spec, point),
            "mesh": spec.mesh,
            "cycle": cycle,
            "effects": spec.effects,
            "point": point.key_fields(),
            "contact": ContactSettings(),
            "version": package_version(),
        }
    )
