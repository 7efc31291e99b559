"""What code is running: a digest of packages' source files and the libraries' versions.

The lowest layer's, so that every stage can key what it keeps on disk by the code that
computed it: the result store (``model.code.code_version``, which builds on these) and the
one-ball rig's cache (``fe.bearing.ball_rig``). Only the standard library is imported.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import importlib.util
from pathlib import Path

from cad.errors import ParameterError

CYCLE_LIBRARIES = ("build123d", "gmsh", "numpy", "scipy", "pypardiso", "mkl")
"""Installed distributions whose numbers enter a cycle: the solids, the mesh, the dense
and sparse linear algebra (PARDISO from the ``mkl`` wheel). Their versions key results."""


def installed_version(name: str, missing: str = "absent") -> str:
    """The installed version of distribution ``name``, or ``missing``."""
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return missing


def library_versions(names: tuple[str, ...] = CYCLE_LIBRARIES) -> tuple[tuple[str, str], ...]:
    """(distribution, version) of each of ``names``, sorted by name ("absent" if not installed)."""
    return tuple(sorted((n, installed_version(n)) for n in names))


@functools.cache
def source_digest(packages: tuple[str, ...]) -> str:
    """SHA-256 of the Python source of ``packages`` where this process imports them from.

    Every ``.py`` file's path within its package and its bytes, in sorted order. Read once
    per process, when first asked (about 10 ms for ``cad``, ``mesh``, ``fe`` and ``model``,
    ~1 MB): the files as they were then. A file edited after a process imported it but
    before this read keys that process's results as the edited code; a cluster run is safe
    either way, since a worker that reads other files than its client is refused
    (``model.cluster``).

    Raises:
        ParameterError: For a name that is not an importable package.
    """
    h = hashlib.sha256()
    for name in packages:
        spec = importlib.util.find_spec(name)
        if spec is None or not spec.submodule_search_locations:
            raise ParameterError(f"packages: {name!r} is not an importable package")
        for root in sorted(Path(p) for p in spec.submodule_search_locations):
            for path in sorted(root.rglob("*.py")):
                rel = path.relative_to(root.parent).as_posix()
                h.update(rel.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()
