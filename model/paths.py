"""Names from data as file names: a case id is data, never a path.

Case ids, point ids and study names come from users' files. Before one names a file it
goes through :func:`file_stem`, which keeps letters, digits, ``.``, ``-`` and ``_``, and
makes everything else (separators, ``..``, drive letters, control characters, Windows'
reserved device names) harmless. A name that had to change gets a short hash of the
original, so two different ids never share a file.

>>> file_stem("c300_bad")
'c300_bad'
>>> file_stem("../../evil")
'evil-0fbfd372'
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

from cad.errors import DataError

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")
_RESERVED = {
    "con",
    "prn",
    "aux",
    "nul",
    *(f"com{i}" for i in range(10)),
    *(f"lpt{i}" for i in range(10)),
}
"""Device names Windows refuses as file names (with any extension)."""

MAX_STEM = 80
"""Longest stem kept from a name (file systems allow 255 bytes; room for suffixes)."""


def file_stem(name: str) -> str:
    """A file-name stem for ``name``: itself when safe, else a cleaned form plus a hash."""
    stem = _UNSAFE.sub("_", name).strip("._-")[:MAX_STEM]
    if stem.split(".")[0].lower() in _RESERVED:
        stem = f"case_{stem}"
    elif stem and stem == name:
        return stem
    digest = hashlib.sha256(name.encode("utf-8")).hexdigest()[:8]
    return f"{stem or 'case'}-{digest}"


def inside(folder: Path, path: Path) -> Path:
    """Return ``path`` after checking it lies inside ``folder``.

    Raises:
        DataError: Naming both, if ``path`` resolves outside ``folder``.
    """
    root = Path(folder).resolve()
    target = Path(path).resolve()
    if target != root and root not in target.parents:
        raise DataError(f"refusing to write {path}: it is outside the output folder {folder}")
    return path
