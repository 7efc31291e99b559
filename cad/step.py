"""STEP export and import of hinge assemblies, with part names."""

from __future__ import annotations

import copy
import re
from pathlib import Path

import build123d as bd

from cad.errors import GeometryError
from cad.model import HingeModel

_FILE_NAME_TIME = re.compile(rb"(FILE_NAME\s*\(\s*'(?:[^']|'')*'\s*,\s*')[^']*(')")
"""The time stamp of a STEP header, ``FILE_NAME('name','2026-11-27T08:12:45',...)``."""

_USAGE_ID = re.compile(rb"(NEXT_ASSEMBLY_USAGE_OCCURRENCE\s*\(\s*')\d+(')")
"""The id of a part's place in the assembly: a counter of the writing process."""


def step_body(data: bytes) -> bytes:
    """Return a STEP file's bytes without what differs between two exports of one geometry.

    OpenCASCADE writes the time of writing into the header and numbers the assembly's
    part occurrences with a counter that runs on within a process; both are blanked.

    >>> step_body(b"FILE_NAME('hinge','2026-11-27T08:12:45',('A'));"
    ...           b"#474 = NEXT_ASSEMBLY_USAGE_OCCURRENCE('4','tang','',#5,#35,$);")
    b"FILE_NAME('hinge','',('A'));#474 = NEXT_ASSEMBLY_USAGE_OCCURRENCE('','tang','',#5,#35,$);"
    """
    return _USAGE_ID.sub(rb"\1\2", _FILE_NAME_TIME.sub(rb"\1\2", data, count=1))


def write_step(model: HingeModel, path: Path) -> Path:
    """Write the assembly as a STEP file whose products are named after the parts.

    The file is written whole (to a temporary file, then renamed). A file already at
    ``path`` that differs from the new one only in its header's time stamp is kept as it
    is, so a rerun leaves the same bytes (and the same SHA-256 in a trace) for an unchanged
    geometry.

    Args:
        model: The hinge.
        path: Output file (``.step``); its folder must exist.

    Returns:
        The path written.

    Raises:
        GeometryError: If the STEP writer fails.
    """
    children = []
    for part in model.parts:
        solid = copy.copy(part.solid)  # labels are set on a copy: never modify the model
        solid.label = part.name
        children.append(solid)
    assembly = bd.Compound(children=children, label=f"{model.kind}_hinge")
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    try:
        ok = bd.export_step(assembly, str(tmp))
    except Exception as err:  # OCP raises bare Standard_Failure subclasses
        tmp.unlink(missing_ok=True)
        raise GeometryError(f"STEP export to {path} failed: {err}") from err
    if not ok or not tmp.is_file():
        tmp.unlink(missing_ok=True)
        raise GeometryError(f"STEP export to {path} failed")
    if path.is_file() and step_body(path.read_bytes()) == step_body(tmp.read_bytes()):
        tmp.unlink()
    else:
        tmp.replace(path)
    return path


def read_step_parts(path: Path) -> dict[str, float]:
    """Read a STEP assembly back; return part name → volume [mm³].

    Raises:
        GeometryError: If the file cannot be read.
    """
    try:
        shape = bd.import_step(str(path))
    except Exception as err:
        raise GeometryError(f"cannot read STEP file {path}: {err}") from err
    leaves = [s for s in shape.leaves] if hasattr(shape, "leaves") else list(shape.solids())
    return {leaf.label: float(leaf.volume) for leaf in leaves}
