"""What determines a result: the model specification, a design point, and their content hash.

A ``ModelSpec`` is everything a ``MODEL.toml`` holds (hinge kind and parameters with
their materials, mesh settings, load protocol and solver options with μ, effects). A
``DesignPoint`` is what a study varies (the amplitude and the kind's design variables, e.g.
the clearance). ``result_key`` hashes
both, the code (``model.code.code_version``) and the contact-solver defaults into one
SHA-256: two runs with the same key give the same numbers, and any changed input or code
gives another key.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
import math
import types
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from cad.errors import ParameterError, check_range
from fe.contact.state import ContactSettings
from fe.cycle.protocol import CycleSettings
from fe.effects.plugins import EffectSource
from fe.kinds import HingeKind, hinge_kind
from mesh.settings import MeshSettings
from model.code import CYCLE_PACKAGES, code_version, plugin_digest


@dataclass(frozen=True)
class ModelSpec:
    """A complete hinge model.

    Attributes:
        kind: Name of a registered hinge kind (``fe.kinds``: ``general``, ``bearing``, or a
            kind from an installed package); checked on construction.
        hinge: The kind's parameters (geometry, materials, options).
        mesh: Mesh settings.
        cycle: Load protocol and solver options, including the friction coefficient μ.
        effects: Enabled effect → its parameters (read-only mappings).
        effect_sources: A user's effect → the file and class it comes from (MODEL.toml
            ``from``), with the file's hash: enabled ones (in ``effects``) and ones only
            declared (diagnose and calibrate may try them). Each is registered
            (``fe.effects.registry.register_source``) when the spec is made, in this
            process or in a worker that receives the spec: the spec carries its effects.
    """

    kind: str
    hinge: Any
    mesh: MeshSettings = field(default_factory=MeshSettings)
    cycle: CycleSettings = field(default_factory=CycleSettings)
    effects: Mapping[str, Mapping[str, float]] = field(
        default_factory=lambda: types.MappingProxyType({})
    )
    effect_sources: Mapping[str, EffectSource] = field(
        default_factory=lambda: types.MappingProxyType({})
    )

    def __post_init__(self) -> None:
        kind = hinge_kind(self.kind)
        object.__setattr__(self, "kind", kind.name)
        if not isinstance(self.hinge, kind.params_type):
            raise ParameterError(
                f"kind {kind.name!r} needs {kind.params_type.__name__}, "
                f"got {type(self.hinge).__name__}"
            )
        frozen = {k: types.MappingProxyType(dict(v)) for k, v in self.effects.items()}
        object.__setattr__(self, "effects", types.MappingProxyType(frozen))
        object.__setattr__(
            self, "effect_sources", types.MappingProxyType(dict(self.effect_sources))
        )
        self.register_sources()

    def register_sources(self) -> None:
        """Register this spec's own effect files (the versions its hashes name).

        Raises:
            ParameterError: A missing or changed file, or one that holds no effect.
        """
        from fe.effects.registry import register_source

        for name, source in self.effect_sources.items():
            register_source(name, source)

    def __reduce__(self) -> tuple[Any, ...]:  # through __init__: a worker registers the files
        return (
            ModelSpec,
            (
                self.kind,
                self.hinge,
                self.mesh,
                self.cycle,
                {k: dict(v) for k, v in self.effects.items()},
                dict(self.effect_sources),
            ),
        )

    @property
    def hinge_kind(self) -> HingeKind:
        """The registered kind object."""
        return hinge_kind(self.kind)


@dataclass(frozen=True)
class DesignPoint:
    """One point of a design study: the force amplitude and the kind's design variables.

    Attributes:
        amplitude_n: Force amplitude Fg [N].
        values: Design variable name (``fe.kinds.DesignVariable.name``, e.g.
            ``clearance_mm``) → value; an absent variable keeps the model's own value.
    """

    amplitude_n: float
    values: Mapping[str, float] = field(default_factory=lambda: types.MappingProxyType({}))

    def __post_init__(self) -> None:
        check_range("amplitude_n", self.amplitude_n, 0.0, 1e6, lo_open=True)
        # 0.0 and -0.0, 300 and 300.0 are one point (one key, one run)
        object.__setattr__(self, "amplitude_n", float(self.amplitude_n) + 0.0)
        clean = {}
        for name, value in sorted(self.values.items()):
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not math.isfinite(value)
            ):
                raise ParameterError(f"{name} must be a finite number, got {value!r}")
            clean[str(name)] = float(value) + 0.0
        object.__setattr__(self, "values", types.MappingProxyType(clean))

    def __hash__(self) -> int:
        return hash((self.amplitude_n, tuple(self.values.items())))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, DesignPoint):
            return NotImplemented
        return self.amplitude_n == other.amplitude_n and dict(self.values) == dict(other.values)

    def __reduce__(self) -> tuple[Any, ...]:  # mappingproxy does not pickle (Dask sends points)
        return (DesignPoint, (self.amplitude_n, dict(self.values)))

    def key_fields(self) -> dict[str, float]:
        """What identifies the point in a result key: the amplitude and every value."""
        return {"amplitude_n": self.amplitude_n, **self.values}


def complete_point(spec: ModelSpec, point: DesignPoint) -> DesignPoint:
    """The point with every design variable of the spec's kind, checked against its range.

    An absent variable takes the model's own value, so a point names its geometry fully.

    Raises:
        ParameterError: For a variable the kind does not have, or a value out of range.
    """
    kind = spec.hinge_kind
    variables = {v.name: v for v in kind.design_variables}
    unknown = sorted(set(point.values) - set(variables))
    if unknown:
        allowed = ", ".join(variables) or "(none: only the amplitude)"
        raise ParameterError(
            f"{unknown[0]} is not a design variable of the {kind.title}, got "
            f"{unknown[0]} = {point.values[unknown[0]]!r}; it has: {allowed}"
        )
    values = {
        name: var.check(point.values.get(name, getattr(spec.hinge, name)), spec.hinge)
        for name, var in variables.items()
    }
    return DesignPoint(point.amplitude_n, values)


def point_label(spec: ModelSpec, point: DesignPoint) -> str:
    """Folder name of the point, e.g. ``c0.100_F300`` (general) or ``p100_F300`` (bearing)."""
    point = complete_point(spec, point)
    parts = [f"{v.tag}{point.values[v.name]:{v.fmt}}" for v in spec.hinge_kind.design_variables]
    return "_".join([*parts, f"F{point.amplitude_n:g}"])


def describe_point(spec: ModelSpec, point: DesignPoint) -> str:
    """The point in words, e.g. ``general hinge, Δr = 0.1 mm, Fg = 300 N, μ = 0.2``."""
    values = complete_point(spec, point).values
    kind = spec.hinge_kind
    what = [kind.title, *(v.text(values[v.name]) for v in kind.design_variables)]
    return ", ".join([*what, f"Fg = {point.amplitude_n:g} N", f"μ = {spec.cycle.mu:g}"])


def structure_label(spec: ModelSpec, point: DesignPoint) -> str:
    """Folder name of the point's geometry: its structural variables (``c0.100``), or ``base``."""
    point = complete_point(spec, point)
    parts = [
        f"{v.tag}{point.values[v.name]:{v.fmt}}"
        for v in spec.hinge_kind.design_variables
        if v.structural
    ]
    return "_".join(parts) or "base"


def hinge_at(spec: ModelSpec, point: DesignPoint) -> Any:
    """The hinge parameters at a design point (each design variable set to the point's value).

    Raises:
        ParameterError: For a variable the kind does not have, or a value out of range.
    """
    values = complete_point(spec, point).values
    return dataclasses.replace(spec.hinge, **values) if values else spec.hinge


def structure_at(spec: ModelSpec, point: DesignPoint) -> Any:
    """The hinge parameters that determine the mesh and its factorisation at ``point``.

    A load-like variable (the bearing hinge's preload) does not change the structure, so
    every value of it shares one geometry (one factorisation).
    """
    return spec.hinge_kind.structure(hinge_at(spec, point))


def resolve_structural(spec: ModelSpec) -> ModelSpec:
    """The model with its structure-changing effects written as the structure they make.

    The kind decides (``HingeKind.resolve``; e.g. the bearing hinge's
    ``interface_friction`` becomes frictional fits): keys and stored results are those of
    the model the cycle really runs.
    """
    hinge, cycle, effects = spec.hinge_kind.resolve(spec.hinge, spec.cycle, spec.effects)
    if hinge is spec.hinge and cycle is spec.cycle and effects is spec.effects:
        return spec
    return dataclasses.replace(spec, hinge=hinge, cycle=cycle, effects=effects)


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


def geometry_key(spec: ModelSpec, point: DesignPoint) -> str:
    """Hash of what the mesh and its condensation depend on at ``point`` (not the load or μ)."""
    spec = resolve_structural(spec)
    return content_hash(
        {
            "kind": spec.kind,
            "hinge": structure_at(spec, point),
            "mesh": spec.mesh,
            "code": code_version(),
            "kind_code": kind_code(spec),
        }
    )


def kind_code(spec: ModelSpec) -> str:
    """SHA-256 of the code of a hinge kind that is not hingelab's own ("" for a built-in).

    hingelab's kinds are keyed with the rest of its source (``model.code.code_version``); a
    kind from another package, by that package's files (``model.code.plugin_digest``), so
    editing a plug-in kind's mechanics recomputes its results too.
    """
    module = type(spec.hinge_kind).__module__
    return "" if module.partition(".")[0] in CYCLE_PACKAGES else plugin_digest(module)


def effect_code(spec: ModelSpec) -> dict[str, str]:
    """Enabled effect that is not built in → SHA-256 of the source that defines it.

    A user's file is keyed by the hash the spec holds (the version it was read as); an
    entry point's by its module's source file. Editing either gives another result key.
    """
    from fe.effects.registry import effect_entry

    out = {}
    for name in spec.effects:
        if name in spec.effect_sources:
            out[name] = spec.effect_sources[name].sha256
        else:
            entry = effect_entry(name)
            if not entry.builtin:
                out[name] = entry.source_hash
    return out


def result_key(spec: ModelSpec, point: DesignPoint) -> str:
    """Hash of everything that determines the cycle at ``point``.

    The whole specification (its own amplitude replaced by the point's), the design
    point, the contact-solver defaults (with the LU threads ``HINGELAB_LU_THREADS`` gives,
    which change a cycle's last bits) and the code (``model.code.code_version``:
    hingelab's version, its computing packages' source, the libraries' versions); a
    structure-changing effect is keyed as the structure it makes (``resolve_structural``);
    an effect or a hinge kind that is not built in, by the hash of its source
    (``effect_code``, ``kind_code``).
    """
    from fe.contact.dense import lu_threads  # scipy.linalg: not for a model file's reading

    spec = resolve_structural(spec)
    cycle = dataclasses.replace(spec.cycle, amplitude_n=point.amplitude_n)
    return content_hash(
        {
            "kind": spec.kind,
            "hinge": hinge_at(spec, point),
            "mesh": spec.mesh,
            "cycle": cycle,
            "effects": spec.effects,
            "effect_code": effect_code(spec),
            "kind_code": kind_code(spec),
            "point": complete_point(spec, point).key_fields(),
            # the LU threads as this process resolves them (they change the last bits)
            "contact": dataclasses.replace(ContactSettings(), lu_threads=lu_threads()),
            "code": code_version(),
        }
    )


KEY_CHARS = 10
"""Hex digits of a key in a folder name: 40 bits, so two keys of one folder share them by
chance once in about 10^12 pairs (a folder name is checked against the full key in its
``result.json`` before it is shown as a point's)."""


def point_folder(spec: ModelSpec, point: DesignPoint, key: str | None = None) -> str:
    """Folder name of a point's files: its label and its result key, ``c0.100_F300-1f2e3d4c5b``.

    The key makes the folder the point's own: a rerun with another μ, mesh, protocol or
    effect writes another folder instead of overwriting this one.

    Args:
        spec: The model.
        point: The design point.
        key: Its result key, when already known (``result_key(spec, point)`` otherwise).
    """
    return f"{point_label(spec, point)}-{(key or result_key(spec, point))[:KEY_CHARS]}"


def geometry_folder(spec: ModelSpec, point: DesignPoint) -> str:
    """Folder name of a point's geometry files: ``c0.100-5e6f7a8b9c`` (label and geometry key).

    Two meshes of one clearance (another mesh preset) get two folders.
    """
    return f"{structure_label(spec, point)}-{geometry_key(spec, point)[:KEY_CHARS]}"
