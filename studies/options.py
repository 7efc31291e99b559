"""Hinge parameters from command-line options, for any registered kind.

An option sets a field of the kind's parameter dataclass (``--clearance`` →
``clearance_mm``); an option whose field the kind does not have is refused naming the
option and the kind, and a text value of an enum field (``--interfaces contact``) is
converted by the field's type. No kind is named here: the kind's dataclass decides.
"""

from __future__ import annotations

import dataclasses
import enum
import typing
from collections.abc import Mapping
from typing import Any

from cad.errors import ParameterError
from fe.kinds import HingeKind, hinge_kind, kind_names


def field_types(kind: HingeKind) -> dict[str, Any]:
    """Field name → resolved type of the kind's parameter dataclass."""
    hints = typing.get_type_hints(kind.params_type)
    return {f.name: hints[f.name] for f in dataclasses.fields(kind.params_type)}


def params_with(
    kind: HingeKind, values: Mapping[str, Any], options: Mapping[str, str] | None = None
) -> Any:
    """The kind's default parameters with ``values`` set (None values are left out).

    Args:
        kind: The hinge kind.
        values: Field → value; a string for an enum field is its value (``"contact"``).
        options: Field → the option that gave it (``--interfaces``), for messages.

    Raises:
        ParameterError: A field the kind does not have (naming the option and the kind),
            an enum value not allowed (listing the allowed ones), or a value out of range.
    """
    options = options or {}
    types = field_types(kind)
    given = {k: v for k, v in values.items() if v is not None}
    kw: dict[str, Any] = {}
    for name, value in given.items():
        what = options.get(name, name)
        if name not in types:
            owners = [
                hinge_kind(k).title for k in kind_names() if name in field_types(hinge_kind(k))
            ]
            where = f"; it is a parameter of the {' and the '.join(owners)}" if owners else ""
            raise ParameterError(
                f"{what} does not apply to the {kind.title} (got {what} {value}){where}"
            )
        kw[name] = _converted(types[name], value, what)
    try:
        return kind.params_type(**kw)
    except ParameterError as err:  # in the option's name when the option gave that field
        if err.parameter in kw and err.parameter in options:
            raise err.renamed(options[err.parameter]) from err
        raise


def _converted(hint: Any, value: Any, what: str) -> Any:
    if isinstance(hint, type) and issubclass(hint, enum.Enum) and not isinstance(value, hint):
        try:
            return hint(value)
        except ValueError as err:
            allowed = [m.value for m in hint]
            raise ParameterError(f"{what} must be one of {allowed}, got {value!r}") from err
    return value
