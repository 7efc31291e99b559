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
    """

    amplitude_n: float
    clearance_mm: float = 0.0

    def __post_init__(self) -> None:
        check_range("amplitude_n", self.amplitude_n, 0.0, 1e6, lo_open=True)
        check_range("clearance_mm", self.clearance_mm, 0.0, 10.0)
        # 0.0 and -0.0, 300 and 300.0 are one point (one key, one run)
        object.__setattr__(self, "amplitude_n", float(self.amplitude_n) + 0.0)
        object.__setattr__(self, "clearance_mm", float(self.clearance_mm) + 0.0)

    def label(self) -> str:
        """Folder name of the point, e.g. ``c0.100_F300``."""
        return f"c{self.clearance_mm:.3f}_F{self.amplitude_n:g}"


def with_clearance(spec: ModelSpec, clearance_mm: float) -> HingeParams:
    """Return the spec's hinge parameters at another radial clearance (general hinge).

    Raises:
        ParameterError: For a hinge kind without clearance, or an out-of-range value.
    """
    if not isinstance(spec.hinge, GeneralHingeParams):
        raise ParameterError(f"the {spec.kind} hinge has no clearance_mm")
    return dataclasses.replace(spec.hinge, clearance_mm=clearance_mm)


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
    return content_hash(
        {
            "kind": spec.kind,
            "hinge": with_clearance(spec, clearance_mm),
            "mesh": spec.mesh,
            "version": package_version(),
        }
    )


def result_key(spec: ModelSpec, point: DesignPoint) -> str:
    """Hash of everything that determines the cycle at ``point``.

    The whole specification (its own amplitude replaced by the point's), the design
    point, the contact-solver defaults and the package version.
    """
    cycle = dataclasses.replace(spec.cycle, amplitude_n=point.amplitude_n)
    return content_hash(
        {
            "kind": spec.kind,
            "hinge": with_clearance(spec, point.clearance_mm),
            "mesh": spec.mesh,
            "cycle": cycle,
            "effects": spec.effects,
            "point": point,
            "contact": ContactSettings(),
            "version": package_version(),
        }
    )
