"""Names and numbers in a deck: labels, numbers as CalculiX reads them, the sets by role.

Shared by the deck's model blocks (:mod:`fe.interop.inp`) and its steps
(:mod:`fe.interop.inp_steps`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from cad.errors import ParameterError

GRIP_REF_SET = "grip_ref"
"""NSET holding the one node that carries the grip force (and whose x is the grip's)."""

_NAME_RE = re.compile(r"[^A-Za-z0-9_]")


def inp_name(name: str) -> str:
    """Return ``name`` as a deck label: letters, digits and ``_``, starting with a letter.

    Raises:
        ParameterError: If ``name`` is empty.
    """
    if not name:
        raise ParameterError("a set, part or material name must not be empty")
    out = _NAME_RE.sub("_", name)
    return out if out[0].isalpha() else "N_" + out


def num(x: float) -> str:
    """Format a number in at most 20 characters, always with a point or an exponent.

    CalculiX reads fields of 20 characters at most, and took a spring constant written
    as ``50`` for a missing data line (``50.`` is read).
    """
    out = f"{float(x):.13g}"
    return out if any(c in out for c in ".en") else out + "."


@dataclass(frozen=True)
class Roles:
    """Facet sets by role: FIXED ones, the one LOAD set (the grip), floating parts."""

    fixed: tuple[str, ...]
    load: str
    floating: tuple[str, ...]
