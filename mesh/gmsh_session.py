"""One context manager around a gmsh session, so a failure always finalises it."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any


@contextmanager
def gmsh_session(name: str = "hingelab") -> Iterator[Any]:
    """Initialise gmsh quietly, yield the module, and always finalise it.

    Yields:
        The ``gmsh`` module with a fresh model called ``name``.
    """
    import gmsh  # imported here: the core library works without gmsh installed

    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.Verbosity", 1)
        gmsh.model.add(name)
        yield gmsh
    finally:
        gmsh.finalize()
