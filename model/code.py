"""Which code computed a result: hingelab's version, a digest of its source, the libraries.

A stored result is read back when its key matches (``model.spec.result_key``), so the key
must change whenever the code that computes the cycle changes. The package version alone
does not: it is 0.1.0 in every commit of a checkout (an editable install), so a result
computed before a fix to the solver would have been read back after it. ``code_version``
adds the SHA-256 of the computing packages' source files as installed and the versions of
the libraries whose numbers enter a cycle (the mesher, the CAD kernel, the linear
algebra). A Dask worker reports its own, and a cluster whose workers run other code is
refused (``model.cluster.dispatch``): their cycles would be stored under this code's keys.

The digest and the library versions themselves are ``cad.provenance``'s (the solver's own
caches key with them too). Only the standard library is imported: ``hingelab --version``
and a rerun read it.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import sys
from dataclasses import dataclass
from pathlib import Path

from cad.errors import ParameterError
from cad.provenance import CYCLE_LIBRARIES, installed_version, library_versions, source_digest

CYCLE_PACKAGES = ("cad", "mesh", "fe", "model")
"""The packages whose code makes a geometry, a mesh, a condensation or a cycle: their
source keys every stored result and geometry. Editing ``rsm``, ``validation`` or
``studies`` (reports, fits, verdicts, which are recomputed from the stored cycles on
every run) does not throw the cycles away."""

ALL_PACKAGES = (*CYCLE_PACKAGES, "rsm", "validation", "studies")
"""Every package of the distribution: what a Dask worker must run the same of (a sweep's
worker also writes the point's files) and what keys the paper's drawn figures."""


@dataclass(frozen=True)
class CodeVersion:
    """The code a result was computed with.

    Attributes:
        version: hingelab's installed version ("unknown" from a bare source tree).
        source: SHA-256 of the packages' Python files (path within the package and bytes,
            in sorted order), hex.
        libraries: (distribution, version) pairs, sorted; "absent" where not installed.
    """

    version: str
    source: str
    libraries: tuple[tuple[str, str], ...]

    def short(self) -> str:
        """``0.1.0+src.1a2b3c4d5e6f``: the version and the first 12 digits of the source."""
        return f"{self.version}+src.{self.source[:12]}"

    def differences(self, other: CodeVersion) -> list[str]:
        """What differs from ``other``, one phrase each (empty when the same)."""
        out = []
        if self.version != other.version:
            out.append(f"hingelab {self.version} against {other.version}")
        if self.source != other.source:
            out.append(f"source {self.source[:12]} against {other.source[:12]}")
        mine, theirs = dict(self.libraries), dict(other.libraries)
        for name in sorted({*mine, *theirs}):
            if mine.get(name) != theirs.get(name):
                out.append(
                    f"{name} {mine.get(name, 'absent')} against {theirs.get(name, 'absent')}"
                )
        return out


def package_version() -> str:
    """The installed hingelab version ("unknown" when run from a bare source tree)."""
    return installed_version("hingelab", missing="unknown")


@functools.cache
def plugin_digest(module: str) -> str:
    """SHA-256 of the code of a plug-in's top-level package (or module) ``module`` belongs to.

    A hinge kind from another distribution (an entry point) is keyed by its own code, as
    ``code_version`` keys hingelab's: all files of its top-level package, or its one file.

    Raises:
        ParameterError: If the module's top level cannot be found.
    """
    top = module.partition(".")[0]
    try:
        spec = importlib.util.find_spec(top)
    except (ImportError, ValueError):  # __main__ of a script, a module without a spec
        spec = None
    if spec is not None and spec.submodule_search_locations:
        return source_digest((top,))
    origin = spec.origin if spec is not None else getattr(sys.modules.get(module), "__file__", None)
    if not origin or not Path(origin).is_file():
        raise ParameterError(f"plug-in module {module!r}: its source cannot be found")
    # fe.effects.plugins.file_hash, without its import (numpy: 0.4 s for --version)
    return hashlib.sha256(Path(origin).read_bytes()).hexdigest()


@functools.cache
def code_version(packages: tuple[str, ...] = CYCLE_PACKAGES) -> CodeVersion:
    """The version, the digest of ``packages``' source and the cycle libraries' versions."""
    return CodeVersion(
        package_version(), source_digest(packages), library_versions(CYCLE_LIBRARIES)
    )
