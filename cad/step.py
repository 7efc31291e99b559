"""STEP export and import of hinge assemblies, with part names."""

from __future__ import annotations

import copy
from pathlib import Path

import build123d as bd

from cad.errors import GeometryError
from cad.model import HingeModel


def write_step(model: HingeModel, path: Path) -> Path:
    """Write the assembly as a STEP file whose products are named after the parts.

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
    try:
        ok = bd.export_step(assembly, str(path))
    except Exception as err:  # OCP raises bare Standard_Failure subclasses
        raise GeometryError(f"STEP export to {path} failed: {err}") from err
    if not ok:
        raise GeometryError(f"STEP export to {path} failed")
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
