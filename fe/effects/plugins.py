"""A user's own effects: loaded from a Python file or an installed package, checked, guarded.

An effect that is not built in comes from

* a file named in MODEL.toml (``[effects.my_damper] from = "effects/damper.py:Damper"``,
  the path relative to the model file): ``EffectSource`` holds its absolute path, the
  class and the SHA-256 of the file's bytes; ``load_source`` runs exactly the bytes it
  hashed (a file edited later is another source, with another hash and result key);
* an entry point in the group ``hingelab.effects`` (``name = "module:attr"``), as hinge
  kinds register (``fe.kinds``): ``load_entry_point``.

Either may name an ``fe.effects.base.Effect`` subclass (instantiated without arguments)
or an instance. ``check_effect`` refuses anything else, and parameters without finite
bounds, with one line naming the file (or entry point), the class and what is wrong.

A plug-in's hooks are called through ``call_apply`` and ``call_post``: an exception
other than a project error, an output of the wrong type or shape, a NaN or an infinity,
or a call longer than ``CALL_LIMIT_S`` becomes an ``EffectError`` (a ``DataError``) naming
the origin, the class and the hook.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import importlib.util
import inspect
import re
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from cad.errors import EffectError, HingelabError, ParameterError
from fe.effects.base import (
    Effect,
    EffectContext,
    FloatArray,
    History,
    ParamSpec,
    PostResult,
    Values,
)
from fe.structure.condensed import Condensed

ENTRY_POINT_GROUP = "hingelab.effects"
"""The entry-point group effects register in."""

CALL_LIMIT_S = 60.0
"""Wall time one call of a plug-in's ``apply`` or ``post`` may take [s]. Python cannot
stop a running call safely, so a slower call is refused when it returns (EffectError): a
pathological effect fails at its first call, not after a night of diagnosis."""

T = TypeVar("T")


@dataclass(frozen=True)
class EffectSource:
    """Where a user's effect class lives: a file and a class in it.

    Attributes:
        path: Absolute path of the Python file.
        attr: The class (or instance) in it.
        sha256: SHA-256 of the file's bytes when it was read (keys the results).
    """

    path: str
    attr: str
    sha256: str

    @property
    def origin(self) -> str:
        """``path:attr``, as in messages."""
        return f"{self.path}:{self.attr}"


def file_hash(path: Path) -> str:
    """SHA-256 of a file's bytes (hex)."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def source_of(text: str, base: Path) -> EffectSource:
    """Parse a ``from`` value (``path.py:Class``, the path relative to ``base``) and hash the file.

    Raises:
        ParameterError: For a value that is not ``file.py:Class``, or a missing file.
    """
    path_text, sep, attr = text.rpartition(":")
    if not sep or not path_text or not attr.isidentifier():
        raise ParameterError(f"from must be 'file.py:ClassName', got {text!r}")
    path = (base / path_text).resolve()
    if not path.is_file():
        raise ParameterError(f"from = {text!r}: effect file {path} not found")
    return EffectSource(str(path), attr, file_hash(path))


_LOADED: dict[tuple[str, str, str], Effect] = {}
"""(path, attr, sha256) → the loaded effect (before it is given its registry name)."""


def load_source(source: EffectSource) -> Effect:
    """Load and check the effect a source names (memoised by path, class and hash).

    The bytes read are hashed and must match ``source.sha256``; those same bytes are run,
    as a module of their own (one per file content).

    Raises:
        ParameterError: A missing file, a file changed since it was read (the hash), an
            error while running it, a missing class, or not an effect (``check_effect``).
    """
    key = (source.path, source.attr, source.sha256)
    if key in _LOADED:
        return _LOADED[key]
    path = Path(source.path)
    if not path.is_file():
        raise ParameterError(f"{source.origin}: effect file not found")
    data = path.read_bytes()
    if hashlib.sha256(data).hexdigest() != source.sha256:
        raise ParameterError(
            f"{source.origin}: the file changed since the model was read (its SHA-256 "
            "differs): read the model file again"
        )
    stem = re.sub(r"\W", "_", path.stem)
    name = f"_hingelab_effect_{stem}_{source.sha256[:12]}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None:
        raise ParameterError(f"{source.origin}: not a Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the class is made
    try:
        exec(compile(data, str(path), "exec"), module.__dict__)  # the bytes that were hashed
    except Exception as err:
        sys.modules.pop(name, None)
        raise ParameterError(f"{source.origin}: {_error_text(err)}") from err
    if not hasattr(module, source.attr):
        sys.modules.pop(name, None)
        raise ParameterError(f"{source.origin}: the file has no {source.attr!r}")
    effect = check_effect(getattr(module, source.attr), source.origin)
    _LOADED[key] = effect
    return effect


def load_entry_point(name: str, value: str) -> Effect:
    """Load and check the effect of an entry point ``name = "module:attr"``.

    Raises:
        ParameterError: An import error, a missing attribute, or not an effect.
    """
    where = f"entry point {name} = {value!r} ({ENTRY_POINT_GROUP})"
    module, _, attr = value.partition(":")
    try:
        obj = getattr(importlib.import_module(module), attr)
    except Exception as err:
        raise ParameterError(f"{where}: {_error_text(err)}") from err
    return check_effect(obj, where)


def origin_hash(effect: Effect) -> str:
    """SHA-256 of the source file that defines an effect's class ("" if it has none)."""
    try:
        path = inspect.getsourcefile(type(effect))
    except TypeError:
        return ""
    return file_hash(Path(path)) if path and Path(path).is_file() else ""


def _error_text(err: BaseException) -> str:
    line = str(err).strip().splitlines()
    return f"{type(err).__name__}: {line[0] if line else ''}".rstrip(": ")


def check_effect(obj: Any, where: str) -> Effect:
    """Return the effect ``obj`` is (an instance, or made from a class), after checks.

    Raises:
        ParameterError: If ``obj`` is not an ``Effect`` subclass or instance, cannot be
            made without arguments, or its parameters are not ``ParamSpec`` objects with
            unique names and finite bounds (at least one).
    """
    what = getattr(obj, "__name__", type(obj).__name__)
    if isinstance(obj, type):
        if not issubclass(obj, Effect):
            raise ParameterError(
                f"{where}: class {what} is not a subclass of fe.effects.base.Effect"
            )
        try:
            obj = obj()  # type: ignore[call-arg]  # a subclass gives its fields defaults
        except Exception as err:
            raise ParameterError(f"{where}: {what}() failed: {_error_text(err)}") from err
    elif not isinstance(obj, Effect):
        raise ParameterError(
            f"{where}: {what} is a {type(obj).__name__}, not an fe.effects.base.Effect"
        )
    cls = type(obj).__name__
    params = obj.params
    if not isinstance(params, tuple) or not params:
        raise ParameterError(f"{where}: {cls}.params must be a non-empty tuple of ParamSpec")
    for p in params:
        if not isinstance(p, ParamSpec):
            raise ParameterError(f"{where}: {cls}.params holds {p!r}, not a ParamSpec")
        try:  # a ParamSpec made around its own checks (dataclasses.replace, object.__new__)
            ParamSpec(p.name, p.lo, p.hi, p.default, p.unit, p.doc)
        except (ParameterError, TypeError) as err:
            raise ParameterError(f"{where}: {cls} parameter {err}") from err
    names = [p.name for p in params]
    if len(set(names)) != len(names) or not all(isinstance(n, str) and n for n in names):
        raise ParameterError(f"{where}: {cls}.params must have unique names, got {names}")
    effect: Effect = obj
    return effect


def named(effect: Effect, name: str, where: str) -> Effect:
    """The effect under its registry name (a copy with ``name`` set if it differs)."""
    if effect.name == name:
        return effect
    try:
        return dataclasses.replace(effect, name=name)
    except Exception as err:
        raise ParameterError(
            f"{where}: cannot name {type(effect).__name__} {name!r}: {_error_text(err)}"
        ) from err


def _guarded(call: Callable[[], T], where: str, hook: str) -> T:
    t0 = time.perf_counter()
    try:
        out = call()
    except HingelabError:
        raise
    except Exception as err:
        raise EffectError(f"{where}: {hook} raised {_error_text(err)}") from err
    took = time.perf_counter() - t0
    if took > CALL_LIMIT_S:
        raise EffectError(
            f"{where}: {hook} took {took:.3g} s, more than the {CALL_LIMIT_S:g} s a call may take"
        )
    return out


def _finite_vector(a: Any, n: int, where: str, what: str) -> FloatArray:
    try:
        v = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise EffectError(
            f"{where}: {what} is not an array of numbers ({_error_text(err)})"
        ) from err
    if v.shape != (n,):
        raise EffectError(f"{where}: {what} has shape {v.shape}, expected ({n},)")
    bad = np.flatnonzero(~np.isfinite(v))
    if bad.size:
        raise EffectError(
            f"{where}: {what} is not finite at {bad.size} of {n} samples (first: index "
            f"{bad[0]}, {v[bad[0]]})"
        )
    return v


def call_post(
    effect: Effect, history: History, values: Values, where: str
) -> tuple[FloatArray, FloatArray | None]:
    """Run ``effect.post`` and check its output.

    Returns:
        (displacement (n,) [mm], stored energy (n,) [N·mm] or None).

    Raises:
        EffectError: An exception, a wrong shape, a non-finite value or a slow call, naming
            ``where`` (file or entry point and class) and the hook.
    """
    hook = f"{type(effect).__name__}.post"
    out = _guarded(lambda: effect.post(history, values), where, hook)
    stored = None
    if isinstance(out, PostResult):
        if out.stored_energy_nmm is not None:
            stored = _finite_vector(
                out.stored_energy_nmm, history.n, where, f"{hook} stored energy"
            )
        out = out.disp_mm
    return _finite_vector(out, history.n, where, f"{hook} displacement"), stored


def call_apply(
    effect: Effect, configs: Mapping[int, Condensed], values: Values, ctx: EffectContext, where: str
) -> dict[int, Condensed]:
    """Run ``effect.apply`` and check it returns a configuration for each side, finite.

    Raises:
        EffectError: As ``call_post``.
    """
    hook = f"{type(effect).__name__}.apply"
    out = _guarded(lambda: effect.apply(configs, values, ctx), where, hook)
    if not isinstance(out, Mapping) or set(out) != set(configs):
        raise EffectError(
            f"{where}: {hook} must return a dict side → Condensed with the sides "
            f"{sorted(configs)}, got {type(out).__name__}"
        )
    for side, cond in out.items():
        if not isinstance(cond, Condensed):
            raise EffectError(f"{where}: {hook} gave side {side} a {type(cond).__name__}")
        for name in ("W", "w0"):
            a = np.asarray(getattr(cond, name))
            if not np.all(np.isfinite(a)):
                raise EffectError(f"{where}: {hook} gave side {side} a non-finite {name}")
    return dict(out)
