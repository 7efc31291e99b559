"""Strict JSON: the one writer of every JSON file and line the project produces.

Strict parsers (and SQLite's JSON functions) reject the ``NaN`` and ``Infinity`` that
``json.dumps`` writes by default, so non-finite floats become ``null``. Paths, enums,
numpy arrays and scalars and dataclasses become plain JSON values.

>>> import math
>>> dumps({"eta": math.nan, "n": 3}, indent=None)
'{"eta": null, "n": 3}'
"""

from __future__ import annotations

import dataclasses
import enum
import json
import math
from collections.abc import Mapping
from pathlib import PurePath
from typing import Any


def strict_json(obj: Any) -> Any:
    """Return ``obj`` as plain JSON values, every non-finite float replaced by None.

    Raises:
        TypeError: For an object JSON cannot hold (naming its type).
    """
    if isinstance(obj, Mapping):
        return {str(k): strict_json(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [strict_json(v) for v in obj]
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: strict_json(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if hasattr(obj, "tolist"):  # numpy arrays and scalars
        return strict_json(obj.tolist())
    if isinstance(obj, enum.Enum):
        return strict_json(obj.value)
    if isinstance(obj, PurePath):
        return str(obj)
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if obj is None or isinstance(obj, bool | int | str):
        return obj
    raise TypeError(f"cannot write {type(obj).__name__} {obj!r} as JSON")


def dumps(obj: Any, *, indent: int | None = 2, sort_keys: bool = False) -> str:
    """Strict JSON text of ``obj`` (``strict_json``), UTF-8 characters kept as they are."""
    return json.dumps(
        strict_json(obj), indent=indent, allow_nan=False, ensure_ascii=False, sort_keys=sort_keys
    )
