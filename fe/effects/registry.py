"""The registry of physical effects, and their two hooks applied in order.

Effects extend the baseline hinge model (elasticity + Coulomb contact). They come from
this package (``BUILTIN``), from installed packages (entry-point group
``hingelab.effects``, ``name = "module:attr"``), and from a user's own files named in
MODEL.toml (``[effects.NAME] from = "file.py:Class"``, ``register_source``); ``REGISTRY``
is a live read-only view of all of them, in the order they are applied.

An effect acts in one (or both) of two places, so that none of them needs a new mesh or a
new factorisation:

* ``apply(configs, values, ctx)`` on the condensed system ``w = W p + G α + w0`` of each
  touching configuration (``fe.structure.condensed.Condensed``): it returns new ``Condensed``
  objects (``dataclasses.replace``), never modifies its input. Interface compliances add
  to the diagonal blocks of ``W``; an interference shifts the normal gap ``w0``; face
  friction appends contact points (condensed with the factorised hinge ``ctx.system``,
  calibrated with the cycle's μ ``ctx.settings``).
* ``post(history, values)`` on the computed loop (``fe.effects.base.History``: force,
  displacement and time): a displacement in series with the hinge; it must map the
  unloaded start to 0. A rate-independent one is a function of the force (all its work
  is stored); a time-dependent one may say what it stores (``PostResult``) and the rest
  is booked as dissipated (``post_increments``).

The general hinge's cycle with effects is ``fe.effects.cycle.run_cycle_with_effects``.

Fingerprints: each effect's docstring gives a table measured on the coarse test mesh
(``MeshSettings.coarse()``: size 4, contact 2 mm; μ = 0.2),
baseline vs effect, η and δ(+Fg) [µm] at Fg = 100 and 400 N and Δr = 0 and 0.1 mm
(``tests/fe/effects/test_effects.py::fingerprint_table`` regenerates it; the slow test
``test_docstring_fingerprints_are_measured`` checks every row to 2 %), each effect at its
parameter's default strength, 40 increments per stage (with clearance, fewer increments
leave a first-order open/close work in the loop area: at 6 per stage η at Δr = 0.1 mm
is off by a factor 2). Baseline: Δr = 0: η = 0.01458 at both amplitudes (positively
homogeneous); Δr = 0.1 mm: η = 0.00094 / 0.00126 at 100 / 400 N.

Effects that only make sense without clearance say so in ``zero_clearance_reason``;
they raise a ``ParameterError`` naming their parameter when applied with Δr > 0, and
``validation.diagnose`` skips them for data with clearance.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import math
import sys
import types
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from cad.errors import ParameterError
from fe.cycle.protocol import DEFAULT_FORCE_RATE
from fe.cycle.result import CycleResult, Increment
from fe.effects.base import Effect, EffectContext, FloatArray, History
from fe.effects.history import protocol_time
from fe.effects.interfaces import InterfaceFriction
from fe.effects.models import (
    FaceFriction,
    FrameCompliance,
    Interference,
    RoughnessSoftening,
    TangentialCompliance,
)
from fe.effects.plugins import (
    ENTRY_POINT_GROUP,
    EffectSource,
    call_apply,
    call_post,
    check_effect,
    load_entry_point,
    load_source,
    named,
    origin_hash,
)
from fe.structure.condensed import Condensed

__all__ = [
    "BUILTIN",
    "REGISTRY",
    "Entry",
    "PostChain",
    "apply_effects",
    "effect_entry",
    "effect_names",
    "effect_ranges",
    "post_chain",
    "post_increments",
    "post_process",
    "register_effect",
    "register_source",
    "unregister_effect",
    "validate_effects",
]


BUILTIN: tuple[Effect, ...] = (
    FrameCompliance(),
    RoughnessSoftening(),
    TangentialCompliance(),
    Interference(),
    FaceFriction(),  # last of the general hinge's: the effects before it act on the pin–hole points
    InterfaceFriction(),  # the bearing hinge's: swaps its structure (fe.kinds.bearing)
)
"""The effects this package ships, in the order they are applied."""


@dataclass(frozen=True)
class Entry:
    """A registered effect and where it came from.

    Attributes:
        effect: The effect (its ``name`` is the registry name).
        origin: ``hingelab`` for a built-in; ``path:Class`` for a file; the entry point.
        source_hash: SHA-256 of the source that defines it ("" for a built-in, which
            hingelab's own source digest keys, ``model.code``): part of every result key
            that uses it.
        source: The file it was loaded from (None for a built-in or an entry point).
    """

    effect: Effect
    origin: str
    source_hash: str = ""
    source: EffectSource | None = None

    @property
    def builtin(self) -> bool:
        """True for an effect this package ships."""
        return self.origin == "hingelab"


_BUILTIN: dict[str, Entry] = {e.name: Entry(e, "hingelab") for e in BUILTIN}
_REGISTERED: dict[str, Entry] = {}  # files and objects, in registration order
_ENTRY_POINTS: dict[str, Entry] = {}  # loaded entry points


_POINTS_CACHE: dict[tuple[str, ...], dict[str, str]] = {}


def _entry_point_values() -> dict[str, str]:
    """Effect name → ``module:attr`` of the installed entry points (not loaded).

    Read once per ``sys.path`` (the registry is asked on every validation).
    """
    key = tuple(sys.path)
    if key not in _POINTS_CACHE:
        _POINTS_CACHE.clear()
        _POINTS_CACHE[key] = {
            ep.name: ep.value for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)
        }
    return _POINTS_CACHE[key]


def effect_names() -> tuple[str, ...]:
    """Every effect that is known, in application order: built-ins, entry points, registered."""
    names = [*_BUILTIN, *_entry_point_values(), *_REGISTERED]
    return tuple(dict.fromkeys(names))


def effect_entry(name: str) -> Entry:
    """The registered effect ``name`` and its origin (an entry point is loaded on first use).

    Raises:
        ParameterError: For an unknown name (the known ones listed), or an entry point
            that does not load or is not an effect (naming it).
    """
    if name in _BUILTIN:
        return _BUILTIN[name]
    if name in _REGISTERED:
        return _REGISTERED[name]
    if name not in _ENTRY_POINTS:
        points = _entry_point_values()
        if name not in points:
            raise ParameterError(
                f"unknown effect {name!r}; known effects: {', '.join(effect_names())}"
            )
        where = f"entry point {name} = {points[name]!r} ({ENTRY_POINT_GROUP})"
        effect = named(load_entry_point(name, points[name]), name, where)
        _ENTRY_POINTS[name] = Entry(effect, where, origin_hash(effect))
    return _ENTRY_POINTS[name]


def register_effect(effect: Effect, origin: str = "registered object") -> Effect:
    """Register an effect object under its name (a script or a test); return it.

    Raises:
        ParameterError: For a built-in's name, or an object that is not an effect.
    """
    effect = check_effect(effect, origin)
    if effect.name in _BUILTIN:
        raise ParameterError(
            f"{origin}: {effect.name!r} is a built-in effect: name yours otherwise"
        )
    _REGISTERED[effect.name] = Entry(effect, origin, origin_hash(effect))
    return effect


def register_source(name: str, source: EffectSource) -> Effect:
    """Register the effect of a user's file under ``name`` (the MODEL.toml section).

    Idempotent for the same file content; a spec read before the file was edited
    registers its own version again (kept in memory by hash), so a result is always
    computed with the code its key names.

    Raises:
        ParameterError: For a built-in's name or an entry point's, a missing or changed
            file, or a file whose class is not an effect (``fe.effects.plugins``).
    """
    have = _REGISTERED.get(name)
    if have is not None and have.source == source:
        return have.effect
    if name in _BUILTIN or name in _entry_point_values():
        raise ParameterError(
            f"{source.origin}: {name!r} is already the name of a "
            f"{'built-in' if name in _BUILTIN else 'installed'} effect: name the section otherwise"
        )
    effect = named(load_source(source), name, source.origin)
    _REGISTERED[name] = Entry(effect, source.origin, source.sha256, source)
    return effect


def unregister_effect(name: str) -> None:
    """Forget a registered effect (a loaded entry point is loaded again on next use)."""
    _REGISTERED.pop(name, None)
    _ENTRY_POINTS.pop(name, None)


class _Registry(Mapping[str, Effect]):
    """Effect name → effect, read-only and live: what is registered now, in application order."""

    def __getitem__(self, name: str) -> Effect:
        if name not in effect_names():
            raise KeyError(name)
        return effect_entry(name).effect

    def __iter__(self) -> Iterator[str]:
        return iter(effect_names())

    def __len__(self) -> int:
        return len(effect_names())

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in effect_names()

    def __repr__(self) -> str:
        return f"REGISTRY({', '.join(effect_names())})"


REGISTRY: Mapping[str, Effect] = _Registry()
"""Effect name → effect, in the order they are applied: the built-ins, then entry points
(``hingelab.effects``), then effects registered from files (MODEL.toml ``from``) or
objects. A live read-only view: it always shows what is registered now."""


def effect_ranges() -> dict[str, dict[str, tuple[float, float]]]:
    """Return effect → parameter → (lo, hi): the shape ``model.file`` checks against."""
    return {n: {p.name: (p.lo, p.hi) for p in e.params} for n, e in REGISTRY.items()}


def validate_effects(
    effects: Mapping[str, Mapping[str, float]],
) -> Mapping[str, Mapping[str, float]]:
    """Check effect names, parameter names and ranges; fill absent parameters with defaults.

    Args:
        effects: Effect name → parameter → value.

    Returns:
        A read-only copy, effects in registry order, every parameter present.

    Raises:
        ParameterError: Unknown effect or parameter (the known ones listed), or a value
            outside its range (naming effect, parameter, value and range).
    """
    names = effect_names()
    unknown = [n for n in effects if n not in names]
    if unknown:
        raise ParameterError(f"unknown effect(s) {unknown}; known effects: {', '.join(names)}")
    out: dict[str, Mapping[str, float]] = {}
    for name in names:
        if name not in effects:
            continue
        effect = effect_entry(name).effect
        given = effects[name]
        specs = {p.name: p for p in effect.params}
        bad = [k for k in given if k not in specs]
        if bad:
            raise ParameterError(
                f"effect {name!r}: unknown parameter(s) {bad}; allowed: {', '.join(specs)}"
            )
        vals: dict[str, float] = {}
        for p in effect.params:
            v = float(given.get(p.name, p.default))
            if not (math.isfinite(v) and p.lo <= v <= p.hi):
                raise ParameterError(
                    f"effects.{name}.{p.name} must be in [{p.lo:g}, {p.hi:g}] {p.unit}, got {v:g}"
                )
            vals[p.name] = v
        out[name] = types.MappingProxyType(vals)
    return types.MappingProxyType(out)


def apply_effects(
    configs: Mapping[int, Condensed],
    effects: Mapping[str, Mapping[str, float]],
    ctx: EffectContext,
) -> dict[int, Condensed]:
    """Apply every enabled effect's ``apply`` hook, in registry order (inputs unchanged).

    A plug-in's hook is guarded (``fe.effects.plugins.call_apply``).
    """
    values = validate_effects(effects)
    out = dict(configs)
    for name, vals in values.items():
        entry = effect_entry(name)
        if entry.builtin:
            out = entry.effect.apply(out, vals, ctx)
        else:
            out = call_apply(entry.effect, out, vals, ctx, entry.origin)
    return out


@dataclass(frozen=True)
class PostChain:
    """The loop after every ``post`` hook.

    Attributes:
        disp_mm: Displacement at the grips, shape (n,) [mm].
        series_work_nmm: Work ``Σ ½(F_i + F_{i−1}) Δh`` done on the effects' elements
            from the start, shape (n,) [N·mm] (h = the displacement they add).
        dissipated_nmm: The part of it the elements dissipated, shape (n,) [N·mm] (0
            for a rate-independent element, which stores all of it).
    """

    disp_mm: FloatArray
    series_work_nmm: FloatArray
    dissipated_nmm: FloatArray


def post_chain(
    force_n: FloatArray,
    disp_mm: FloatArray,
    effects: Mapping[str, Mapping[str, float]],
    time_s: FloatArray | None = None,
    force_rate_n_per_s: float = DEFAULT_FORCE_RATE,
) -> PostChain:
    """Apply every enabled effect's ``post`` hook in registry order, keeping the energy books.

    Args:
        force_n: Force, shape (n,) [N], from the unloaded start.
        disp_mm: Displacement, shape (n,) [mm].
        effects: Effect name → parameter → value.
        time_s: Time of each sample, shape (n,) [s]; None: the force ramped at
            ``force_rate_n_per_s`` (``fe.effects.history.protocol_time``).
        force_rate_n_per_s: The protocol's force rate [N/s] (when ``time_s`` is None).

    Raises:
        ParameterError: An unknown effect or a value out of range.
        DataError: A plug-in's hook that fails (``fe.effects.plugins.call_post``).
    """
    values = validate_effects(effects)
    F = np.asarray(force_n, dtype=np.float64)
    t = protocol_time(F, force_rate_n_per_s) if time_s is None else np.asarray(time_s, float)
    d = np.array(disp_mm, dtype=np.float64, copy=True)
    work = np.zeros_like(d)
    lost = np.zeros_like(d)
    for name, vals in values.items():
        entry = effect_entry(name)
        d_new, stored = call_post(entry.effect, History(F, d, t), vals, entry.origin)
        step = np.concatenate([[0.0], np.cumsum(0.5 * (F[1:] + F[:-1]) * np.diff(d_new - d))])
        work += step
        if stored is not None:
            lost += step - (stored - stored[0])
        d = d_new
    return PostChain(d, work, lost)


def post_process(
    force_n: FloatArray,
    disp_mm: FloatArray,
    effects: Mapping[str, Mapping[str, float]],
    time_s: FloatArray | None = None,
    force_rate_n_per_s: float = DEFAULT_FORCE_RATE,
) -> FloatArray:
    """Apply every enabled effect's ``post`` hook, in registry order; shape (n,) [mm].

    ``time_s`` and ``force_rate_n_per_s`` as in ``post_chain``.
    """
    return post_chain(force_n, disp_mm, effects, time_s, force_rate_n_per_s).disp_mm


def post_increments(
    result: CycleResult,
    effects: Mapping[str, Mapping[str, float]],
    zero_mm: float = 0.0,
    time_s: FloatArray | None = None,
) -> CycleResult:
    """Return ``result`` with post-processed δ and the effects' energies booked.

    The work done on the effects' elements (``post_chain``) is added to the elastic
    energy as far as they store it, and the rest to ``Increment.effect_work`` (what a
    viscous element dissipates), so ``W_cycle = ΔE + friction work + effect work`` holds
    exactly as before: for a rate-independent effect (all stored) nothing changes.

    Args:
        result: The cycle without post effects.
        effects: Effect name → parameter → value.
        zero_mm: Subtracted from every increment first (the prestressed zero δ₀).
        time_s: Time of the start and of each increment, shape (n + 1,) [s]; None: the
            protocol's, at ``result.settings.force_rate_n_per_s``.

    Raises:
        ParameterError: A post effect that does not map F = 0 to δ = 0 at the start.
    """
    F = np.array([0.0] + [i.force_n for i in result.increments])
    d = np.array([0.0] + [i.disp_mm - zero_mm for i in result.increments])
    chain = post_chain(F, d, effects, time_s, result.settings.force_rate_n_per_s)
    if chain.disp_mm[0] != 0.0:
        raise ParameterError(f"a post effect must map F = 0 to δ = 0, got {chain.disp_mm[0]:g} mm")
    stored = chain.series_work_nmm - chain.dissipated_nmm
    lost = np.diff(chain.dissipated_nmm)
    incs: list[Increment] = [
        dataclasses.replace(
            inc,
            disp_mm=float(chain.disp_mm[k + 1]),
            elastic_energy=inc.elastic_energy + float(stored[k + 1]),
            effect_work=inc.effect_work + float(lost[k]),
        )
        for k, inc in enumerate(result.increments)
    ]
    return dataclasses.replace(result, increments=tuple(incs))
