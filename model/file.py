"""``MODEL.toml``: everything that defines a hinge model, in one file.

Sections (every key optional except ``[hinge] kind``; an absent key keeps the
dataclass default)::

    [hinge]            kind = a registered hinge kind ("general", "bearing", or one from
                       an installed package, ``fe.kinds``), then the fields of its
                       parameter dataclass (GeneralHingeParams, BearingHingeParams; mm)
    [materials.lug]    name, young_mpa, poisson   (one table per *_material field:
    [materials.pin]     lug, pin, and bearing for the bearing hinge)
    [mesh]             the fields of MeshSettings; [mesh.part_sizes_mm] "fragment" = size
    [friction]         mu
    [cycle]            the fields of CycleSettings except mu (amplitude_n is the default
                       amplitude; ``compare`` runs each case at its own)
    [effects.NAME]     parameters of a switched-on physical effect, checked against a
                       registry of known effects and their parameter ranges; a user's
                       own effect adds ``from = "effects/damper.py:Damper"`` (the file
                       relative to this one, and the Effect class in it). With ``from``
                       and no parameters the effect is only declared: off, but known to
                       ``diagnose``, ``calibrate`` and ``synth``.
    [laws.PARAM]       a hinge parameter as a straight line in the cases' test conditions:
                       read and checked by ``validation.joint_laws`` (left alone here)

Unknown sections and keys are refused by name with the allowed ones listed; a wrong
type is refused naming the key; out-of-range values are refused by the dataclasses'
own checks (``ParameterError`` naming the field, its value and the range), prefixed
with the file and section. ``write_model`` writes the same layout back (TOML by hand:
flat tables of numbers and strings), and ``read_model(write_model(spec))`` returns an
equal spec.
"""

from __future__ import annotations

import enum
import json
import math
import os
import tomllib
import types
import typing
from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any

from cad.errors import DataError, ParameterError, check_range
from cad.materials import Material
from fe.cycle.protocol import CycleSettings
from fe.effects.plugins import EffectSource
from fe.kinds import hinge_kind
from mesh.settings import MeshSettings
from model.spec import ModelSpec

__all__ = ["NO_EFFECTS", "read_model", "write_model"]


class _Param(typing.Protocol):
    @property
    def name(self) -> str: ...
    @property
    def lo(self) -> float: ...
    @property
    def hi(self) -> float: ...


class _Effect(typing.Protocol):
    @property
    def params(self) -> tuple[_Param, ...]: ...


EffectRegistry = Mapping[str, Mapping[str, tuple[float, float]]] | Mapping[str, _Effect]
"""Effect name → parameter name → (lowest, highest) allowed value; or effect name → an
object with ``params`` (``fe.effects.registry.REGISTRY``: each ParamSpec gives name, lo, hi)."""


def _ranges(registry: EffectRegistry, name: str) -> Mapping[str, tuple[float, float]] | None:
    """Return parameter → (lo, hi) of one effect from either registry shape (None: unknown).

    Only that effect is looked up (a broken plug-in elsewhere does not stop the file).
    """
    if name not in registry:
        return None
    entry = registry[name]
    params = getattr(entry, "params", None)
    if params is None:
        return typing.cast(Mapping[str, tuple[float, float]], entry)
    return {p.name: (p.lo, p.hi) for p in params}


NO_EFFECTS: EffectRegistry = types.MappingProxyType({})
"""A registry that refuses every [effects.*] section (for files that must have none)."""

SECTIONS = ("hinge", "materials", "mesh", "friction", "cycle", "effects", "laws")
_MATERIAL_SUFFIX = "_material"


def _where(path: Path, section: str) -> str:
    return f"{path}: [{section}]"


def _check_keys(table: Mapping[str, Any], allowed: list[str], where: str) -> None:
    unknown = [k for k in table if k not in allowed]
    if unknown:
        raise ParameterError(
            f"{where}: unknown key(s) {unknown}; allowed: {', '.join(allowed) or '(none)'}"
        )


def _convert(value: Any, hint: Any, key: str, where: str) -> Any:
    """Check a TOML value against a dataclass field's type; return it in that type."""
    args = typing.get_args(hint)
    if hint is float or (type(None) in args and float in args):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ParameterError(f"{where}: {key} must be a number, got {value!r}")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ParameterError(f"{where}: {key} must be an integer, got {value!r}")
        return value
    if isinstance(hint, type) and issubclass(hint, enum.Enum):
        names = [m.name for m in hint]
        if value not in names:
            raise ParameterError(f"{where}: {key} must be one of {names}, got {value!r}")
        return hint[value]
    if typing.get_origin(hint) is tuple:  # MeshSettings.part_sizes_mm: fragment → size
        if not isinstance(value, dict):
            raise ParameterError(f"{where}: {key} must be a table of name = size, got {value!r}")
        return tuple((str(k), _convert(v, float, f"{key}.{k}", where)) for k, v in value.items())
    raise ParameterError(f"{where}: {key} has a type this file format cannot hold ({hint})")


def _build(cls: Any, values: Mapping[str, Any], where: str, **extra: Any) -> Any:
    """Construct a parameter dataclass, prefixing its ParameterError with the file and section."""
    try:
        return cls(**values, **extra)
    except ParameterError as err:
        raise ParameterError(f"{where}: {err}") from err


def _plain_fields(cls: Any, skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """Field name → resolved type of a dataclass, without materials and ``skip``."""
    hints = typing.get_type_hints(cls)
    return {
        f.name: hints[f.name]
        for f in fields(cls)
        if not f.name.endswith(_MATERIAL_SUFFIX) and f.name not in skip
    }


def _table(doc: Mapping[str, Any], name: str, where: str) -> dict[str, Any]:
    value = doc.get(name, {})
    if not isinstance(value, dict):
        raise ParameterError(f"{where}: {name} must be a table, got {value!r}")
    return value


def _read_section(
    cls: Any, table: Mapping[str, Any], where: str, skip: tuple[str, ...] = ()
) -> dict[str, Any]:
    hints = _plain_fields(cls, skip)
    _check_keys(table, list(hints), where)
    return {k: _convert(v, hints[k], k, where) for k, v in table.items()}


def _read_materials(cls: Any, table: Mapping[str, Any], path: Path) -> dict[str, Material]:
    defaults: dict[str, Material] = {
        f.name.removesuffix(_MATERIAL_SUFFIX): typing.cast(Material, f.default)
        for f in fields(cls)
        if f.name.endswith(_MATERIAL_SUFFIX)
    }
    _check_keys(table, list(defaults), _where(path, "materials"))
    out = {}
    for role, values in table.items():
        where = _where(path, f"materials.{role}")
        if not isinstance(values, dict):
            raise ParameterError(f"{where}: must be a table of name, young_mpa, poisson")
        _check_keys(values, ["name", "young_mpa", "poisson"], where)
        base = defaults[role]
        name = values.get("name", base.name)
        if not isinstance(name, str):
            raise ParameterError(f"{where}: name must be a string, got {name!r}")
        young = _convert(values.get("young_mpa", base.young_mpa), float, "young_mpa", where)
        poisson = _convert(values.get("poisson", base.poisson), float, "poisson", where)
        out[role + _MATERIAL_SUFFIX] = _build(
            Material, {}, where, name=name, young_mpa=young, poisson=poisson
        )
    return out


def _user_effect(name: str, text: Any, path: Path, where: str) -> tuple[EffectSource, Any]:
    """The source a ``from`` value names, registered; and the effect."""
    from fe.effects.plugins import source_of
    from fe.effects.registry import register_source

    if not isinstance(text, str):
        raise ParameterError(f"{where}: from must be a string 'file.py:ClassName', got {text!r}")
    try:
        source = source_of(text, path.parent)
        return source, register_source(name, source)
    except ParameterError as err:
        raise ParameterError(f"{where}: {err}") from err


def _read_effects(
    table: Mapping[str, Any], registry: EffectRegistry, path: Path
) -> tuple[dict[str, dict[str, float]], dict[str, EffectSource]]:
    out = {}
    sources = {}
    for name, params in table.items():
        where = _where(path, f"effects.{name}")
        if not isinstance(params, dict):
            raise ParameterError(f"{where}: must be a table of parameters")
        params = dict(params)
        ranges: Mapping[str, tuple[float, float]]
        if "from" in params and registry is not NO_EFFECTS:
            sources[name], effect = _user_effect(name, params.pop("from"), path, where)
            ranges = {p.name: (p.lo, p.hi) for p in effect.params}
            if not params:
                continue  # declared, not switched on
        else:
            try:
                found = _ranges(registry, name)
            except ParameterError as err:  # a plug-in that does not load
                raise ParameterError(f"{where}: {err}") from err
            if found is None:
                known = ", ".join(registry) or "(none yet)"
                raise ParameterError(f"{where}: unknown effect {name!r}; known effects: {known}")
            ranges = found
        _check_keys(params, list(ranges), where)
        missing = [p for p in ranges if p not in params]
        if missing:
            raise ParameterError(f"{where}: missing parameter(s) {missing}")
        checked = {}
        for p, v in params.items():
            checked[p] = _convert(v, float, p, where)
            try:
                check_range(f"effects.{name}.{p}", checked[p], *ranges[p])
            except ParameterError as err:
                raise ParameterError(f"{path}: {err}") from err
        out[name] = checked
    return out, sources


def read_model(path: Path | str, registry: EffectRegistry | None = None) -> ModelSpec:
    """Read and validate a MODEL.toml.

    Args:
        path: The file.
        registry: Known effects and their parameter ranges (effect → parameter → (lo, hi),
            or objects with ``params``); None: ``fe.effects.registry.REGISTRY``, every
            physical effect the solver knows (what ``hingelab calibrate`` writes). A
            table with ``from`` is the user's own effect, whatever the registry (except
            ``NO_EFFECTS``): its ranges are its class's.

    Returns:
        The model.

    Raises:
        DataError: If the file is missing or not valid TOML.
        ParameterError: Unknown section or key (the allowed ones listed), wrong type,
            or a value outside its range (named with the file and section).
    """
    if registry is None:
        from fe.effects.registry import REGISTRY

        registry = REGISTRY
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: model file not found")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise DataError(f"{path}: not valid TOML: {err}") from err
    _check_keys(doc, list(SECTIONS), str(path))
    hinge = _table(doc, "hinge", str(path))
    try:
        if not isinstance(hinge.get("kind"), str):
            raise ParameterError(
                f"kind must be the name of a hinge kind, got {hinge.get('kind')!r}"
            )
        kind = hinge_kind(hinge["kind"]).name
    except ParameterError as err:
        raise ParameterError(f"{_where(path, 'hinge')}: {err}") from err
    cls = hinge_kind(kind).params_type
    geometry = _read_section(
        cls, {k: v for k, v in hinge.items() if k != "kind"}, _where(path, "hinge")
    )
    materials = _read_materials(cls, _table(doc, "materials", str(path)), path)
    params = _build(cls, {**geometry, **materials}, _where(path, "hinge"))
    mesh = _build(
        MeshSettings,
        _read_section(MeshSettings, _table(doc, "mesh", str(path)), _where(path, "mesh")),
        _where(path, "mesh"),
    )
    friction = _table(doc, "friction", str(path))
    _check_keys(friction, ["mu"], _where(path, "friction"))
    cycle_values = _read_section(
        CycleSettings, _table(doc, "cycle", str(path)), _where(path, "cycle"), skip=("mu",)
    )
    if "mu" in friction:
        cycle_values["mu"] = _convert(friction["mu"], float, "mu", _where(path, "friction"))
    try:
        cycle = CycleSettings(**cycle_values)
    except ParameterError as err:  # μ is written in [friction], the rest in [cycle]
        section = "friction" if err.parameter == "mu" else "cycle"
        raise ParameterError(f"{_where(path, section)}: {err}") from err
    effects, sources = _read_effects(_table(doc, "effects", str(path)), registry, path)
    return ModelSpec(kind, params, mesh, cycle, effects, sources)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, enum.Enum):
        return json.dumps(value.name)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # JSON strings are valid TOML basic strings
    raise ParameterError(f"cannot write {value!r} to TOML")


def _lines(values: Mapping[str, Any]) -> list[str]:
    return [f"{k} = {_toml_value(v)}" for k, v in values.items() if v is not None]


def _all_parameters(name: str, given: Mapping[str, float]) -> dict[str, float]:
    """An enabled registered effect's parameters, absent ones at their defaults.

    So the file reads back (``read_model`` asks for every one); ``given`` as it is otherwise.
    """
    from fe.effects.registry import REGISTRY

    if not given or name not in REGISTRY:
        return dict(given)
    params = REGISTRY[name].params
    if not set(given) <= {p.name for p in params}:  # checked against another registry
        return dict(given)
    return {p.name: float(given.get(p.name, p.default)) for p in params}


def _from_text(source: EffectSource, model_path: Path) -> str:
    """A source as a ``from`` value: its file relative to the model file's folder."""
    folder = model_path.resolve().parent
    try:
        rel = os.path.relpath(source.path, folder)
    except ValueError:  # another drive (Windows): keep the absolute path
        rel = source.path
    return f"{Path(rel).as_posix()}:{source.attr}"


def write_model(spec: ModelSpec, path: Path | str) -> Path:
    """Write a model as MODEL.toml (the layout ``read_model`` reads).

    Args:
        spec: The model.
        path: Where to write.

    Returns:
        ``path``.
    """
    path = Path(path)
    h = spec.hinge
    out = ["# hingelab model file (read by model.file.read_model)", "", "[hinge]"]
    out += [f"kind = {_toml_value(spec.kind)}"]
    out += _lines({k: getattr(h, k) for k in _plain_fields(type(h))})
    for f in fields(h):
        if f.name.endswith(_MATERIAL_SUFFIX):
            m = getattr(h, f.name)
            out += ["", f"[materials.{f.name.removesuffix(_MATERIAL_SUFFIX)}]"]
            out += _lines({"name": m.name, "young_mpa": m.young_mpa, "poisson": m.poisson})
    mesh = {k: getattr(spec.mesh, k) for k in _plain_fields(MeshSettings)}
    parts = mesh.pop("part_sizes_mm")
    out += ["", "[mesh]", *_lines(mesh)]
    if parts:
        out += ["", "[mesh.part_sizes_mm]"]
        out += [
            f"{json.dumps(name, ensure_ascii=False)} = {_toml_value(size)}" for name, size in parts
        ]
    out += ["", "[friction]", f"mu = {_toml_value(spec.cycle.mu)}"]
    cycle = {k: getattr(spec.cycle, k) for k in _plain_fields(CycleSettings, skip=("mu",))}
    out += ["", "[cycle]", *_lines(cycle)]
    for name in dict.fromkeys([*spec.effects, *spec.effect_sources]):
        out += ["", f"[effects.{json.dumps(name, ensure_ascii=False)}]"]
        if name in spec.effect_sources:
            out += [f"from = {_toml_value(_from_text(spec.effect_sources[name], path))}"]
        out += _lines(_all_parameters(name, spec.effects.get(name, {})))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path
