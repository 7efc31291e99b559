"""Hinge kinds as registered objects: what a kind is, and the registry that finds them.

A hinge kind (the general hinge, the bearing hinge, a user's own) is one object that
implements :class:`HingeKind`: its parameters, the quantities a study may vary
(:class:`DesignVariable`), its mesh defaults, how to build its system and run its cycle,
and what its result reports. The rest of the code asks the registry (:func:`hinge_kind`)
and the kind, never compares kind names.

Kinds register through the entry-point group ``hingelab.hinges`` (``name = "module:attr"``,
the attribute being the kind object), so a kind from an installed package plugs in
without edits here; the built-in kinds are listed in this project's own ``pyproject.toml``
the same way, and :data:`BUILTIN` keeps them available from a bare source tree.
:func:`register_hinge_kind` registers an object directly (a script or a test).

>>> kind = hinge_kind("general")
>>> kind.name, [v.name for v in kind.design_variables]
('general', ['clearance_mm'])
"""

from __future__ import annotations

import importlib
import importlib.metadata
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from cad.errors import ParameterError, check_range

if TYPE_CHECKING:
    from fe.cycle.protocol import CycleSettings
    from fe.cycle.result import CycleResult
    from mesh.meshed import MeshedHinge
    from mesh.settings import MeshSettings

ENTRY_POINT_GROUP = "hingelab.hinges"
"""The entry-point group hinge kinds register in."""

BUILTIN: Mapping[str, str] = {
    "general": "fe.kinds.general:GENERAL",
    "bearing": "fe.kinds.bearing:BEARING",
    "joint": "fe.kinds.joint:JOINT",
}
"""The kinds this package ships, by entry-point value (also listed in pyproject.toml)."""

DEFAULT_KIND = "general"
"""The kind a command or file runs when none is named (the paper's general hinge)."""

Effects = Mapping[str, Mapping[str, float]]
"""Effect name → parameter name → value."""

Progress = Callable[[int, int], None]
"""Called as ``progress(done, total)`` after each increment."""


@dataclass(frozen=True)
class DesignVariable:
    """A quantity of a hinge kind that a study may vary, besides the force amplitude.

    Attributes:
        name: The field of the kind's parameter dataclass it sets (``clearance_mm``).
        column: Its column in cases.csv, trace parameters and tables (``clearance_mm``,
            ``preload_N``).
        symbol: Its symbol in text and plots (``Δr``).
        word: Its name in words (``clearance``).
        unit: Its unit (``mm``).
        lo: Lowest allowed value.
        hi: Highest allowed value on any parameters.
        tag: Prefix of the point's folder label (``c`` → ``c0.100_F300``).
        fmt: Format of the value in the label (``.3f``).
        structural: True if it changes the mesh and its factorisation (a clearance), False
            if it is a load on an unchanged structure (a preload).
        study_levels: The levels a sweep takes when none are given.
        synth_levels: The levels of a synthetic data set's default design (``synth``).
        case_tag: Prefix of a synthetic case id (``dr`` → ``dr0.1mm_F300N``).
        limit: A property of the kind's parameters that bounds the variable on their
            geometry (``max_clearance_mm``), or None: the range at a model is then
            [lo, min(hi, that)], the range its parameters check, so every message states
            the same range (``bounds``).
    """

    name: str
    column: str
    symbol: str
    word: str
    unit: str
    lo: float
    hi: float
    tag: str
    fmt: str = "g"
    structural: bool = True
    study_levels: tuple[float, ...] = ()
    synth_levels: tuple[float, ...] = ()
    case_tag: str = "x"
    limit: str | None = None

    def bounds(self, params: Any = None) -> tuple[float, float]:
        """Return (lowest, highest) allowed value, on ``params``' geometry when given."""
        if params is None or self.limit is None:
            return self.lo, self.hi
        return self.lo, min(self.hi, float(getattr(params, self.limit)))

    def check(self, value: float, params: Any = None) -> float:
        """Return ``value`` as a float (−0 → 0) after checking its range (``bounds``).

        Args:
            value: The value.
            params: The kind's parameters the value is set on (their geometry bounds it),
                or None: the range on any parameters.

        Raises:
            ParameterError: Naming the variable, the value and the range.
        """
        check_range(self.name, value, *self.bounds(params))
        return float(value) + 0.0

    def text(self, value: float) -> str:
        """The value in words, e.g. ``Δr = 0.1 mm``."""
        return f"{self.symbol} = {value:g} {self.unit}"


@dataclass
class Built:
    """A kind's geometry, meshed and factorised: what its cycles run on.

    Attributes:
        system: The kind's own system object (opaque to everyone but the kind).
        meshed: The CAD model, mesh and files, or None for a kind without a mesh.
        structure: The exact values of the structural design variables of the built
            geometry (e.g. the clearance from the model's exact cylinders).
        cache: The kind's reusable data between cycles on this geometry (condensed
            configurations and the like), keyed as the kind likes.
    """

    system: Any
    meshed: MeshedHinge | None
    structure: Mapping[str, float] = field(default_factory=dict)
    cache: dict[str, Any] = field(default_factory=dict)


@runtime_checkable
class HingeKind(Protocol):
    """What a hinge kind provides (the general and bearing hinges; a user's own).

    Attributes:
        name: Registry name, the ``[hinge] kind`` of a MODEL.toml.
        title: In words (``general hinge``).
        params_type: Its frozen parameter dataclass (geometry, materials, options).
        design_variables: What a study may vary besides the amplitude.
    """

    name: str
    title: str
    params_type: type[Any]
    design_variables: tuple[DesignVariable, ...]

    def mesh_settings(
        self, *, cycle: bool = True, coarse: bool = False, **overrides: Any
    ) -> MeshSettings:
        """The kind's default mesh settings, with fields overridden.

        ``cycle``: the structure a cycle runs on; False: the whole CAD model (``hingelab
        mesh``; the bearing hinge's balls, at the finer size their patches need).
        ``coarse``: the kind's coarse preset (a cycle in seconds; study files' ``preset``).
        """
        ...

    def cad(self, params: Any) -> Any:
        """The CAD model (``cad.model.HingeModel``); ParameterError for a kind without one."""
        ...

    def check(self, params: Any, effects: Effects) -> None:
        """Refuse a parameter/effect combination the kind cannot run (ParameterError)."""
        ...

    def resolve(
        self, params: Any, cycle: CycleSettings, effects: Effects
    ) -> tuple[Any, CycleSettings, Effects]:
        """The model with its structure-changing effects written as the structure they make."""
        ...

    def structure(self, params: Any) -> Any:
        """The parameters that determine the mesh and its factorisation (loads dropped)."""
        ...

    def build(
        self, params: Any, mesh: MeshSettings, out: Path | None, cache_dir: Path | None
    ) -> Built:
        """Build, mesh and factorise a geometry (``params`` as from :meth:`structure`)."""
        ...

    def run(
        self,
        built: Built,
        params: Any,
        settings: CycleSettings,
        effects: Effects,
        progress: Progress | None,
    ) -> CycleResult:
        """Run the load cycle on a built geometry at the point's parameters."""
        ...

    def summary(self, built: Built, params: Any, result: CycleResult) -> dict[str, Any]:
        """What the kind adds to a cycle's JSON summary (``hingelab cycle``)."""
        ...

    def headline(self, summary: Mapping[str, Any]) -> str:
        """The one line ``hingelab cycle`` prints about the result."""
        ...

    def write_fields(
        self, built: Built, result: CycleResult, folder: Path, every: int
    ) -> Path | None:
        """Write the ParaView series of the cycle (None for a kind without fields)."""
        ...


_REGISTERED: dict[str, HingeKind] = {}


def register_hinge_kind(kind: HingeKind) -> HingeKind:
    """Register a kind object under its name (replacing one of that name); return it.

    Raises:
        ParameterError: If ``kind`` does not implement :class:`HingeKind`.
    """
    if not isinstance(kind, HingeKind):
        raise ParameterError(
            f"hinge kind {getattr(kind, 'name', kind)!r} ({type(kind).__name__}) does not "
            "implement fe.kinds.HingeKind"
        )
    _REGISTERED[kind.name] = kind
    return kind


def unregister_hinge_kind(name: str) -> None:
    """Forget a registered kind object (an entry point's kind is loaded again on next use)."""
    _REGISTERED.pop(name, None)


def _entry_points() -> dict[str, str]:
    """Kind name → ``module:attr`` from BUILTIN and the installed entry points."""
    out = dict(BUILTIN)
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        out[ep.name] = ep.value
    return out


def _load(name: str, value: str) -> HingeKind:
    module, _, attr = value.partition(":")
    try:
        obj = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as err:
        raise ParameterError(
            f"hinge kind {name!r}: cannot load {value!r} (entry point group "
            f"{ENTRY_POINT_GROUP}): {type(err).__name__}: {err}"
        ) from err
    if getattr(obj, "name", None) != name:
        raise ParameterError(
            f"hinge kind {name!r}: {value} names itself {getattr(obj, 'name', None)!r}"
        )
    return register_hinge_kind(obj)


def kind_names() -> tuple[str, ...]:
    """The names of every kind that can be loaded or is registered, in alphabetical order."""
    return tuple(sorted({*_REGISTERED, *_entry_points()}))


def hinge_kind(kind: str | HingeKind) -> HingeKind:
    """The registered kind of that name (a kind object is returned as it is).

    Raises:
        ParameterError: For an unknown name, listing the known ones.
    """
    if not isinstance(kind, str):
        return kind
    if kind in _REGISTERED:
        return _REGISTERED[kind]
    points = _entry_points()
    if kind not in points:
        raise ParameterError(f"hinge kind must be one of {list(kind_names())}, got {kind!r}")
    return _load(kind, points[kind])


def kind_of_params(params: Any) -> HingeKind:
    """The kind whose parameter dataclass ``params`` is.

    Raises:
        ParameterError: If no kind takes that type.
    """
    for name in kind_names():
        kind = hinge_kind(name)
        if isinstance(params, kind.params_type):
            return kind
    raise ParameterError(f"no hinge kind takes parameters of type {type(params).__name__}")
