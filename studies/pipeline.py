"""Build → mesh → files: the steps every command and study shares."""

from __future__ import annotations

import json
from typing import Any

from cad.errors import ParameterError
from cad.model import HingeModel
from fe.service.geometry import MeshedHinge, build_and_mesh

__all__ = ["HINGES", "MeshedHinge", "build_and_mesh", "dumps", "make_model", "mesh_summary"]

HINGES = ("general", "bearing")


def make_model(
    hinge: str, *, clearance_mm: float | None = None, preload_n: float | None = None
) -> HingeModel:
    """Build a hinge model from the command-line parameters.

    Raises:
        ParameterError: For an unknown hinge or a parameter the hinge does not take.
    """
    if hinge == "general":
        from cad.general import GeneralHingeParams, make_general_hinge

        if preload_n is not None:
            raise ParameterError(
                f"preload applies to the bearing hinge only, got --preload {preload_n} with --hinge general"
            )
        return make_general_hinge(
            GeneralHingeParams(clearance_mm=0.0 if clearance_mm is None else clearance_mm)
        )
    if hinge == "bearing":
        from cad.bearing import BearingHingeParams, make_bearing_hinge

        if clearance_mm is not None:
            raise ParameterError(
                f"the bearing hinge has no clearance, got --clearance {clearance_mm} with --hinge bearing"
            )
        kwargs: dict[str, Any] = {} if preload_n is None else {"preload_n": preload_n}
        return make_bearing_hinge(BearingHingeParams(**kwargs))
    raise ParameterError(f"hinge must be one of {HINGES}, got {hinge!r}")


def mesh_summary(m: MeshedHinge, total_wall_s: float) -> dict[str, Any]:
    """Return the JSON summary the ``mesh`` command prints."""
    r = m.report
    return {
        "hinge": m.model.kind,
        "params": {
            k: v for k, v in vars(m.model.params).items() if isinstance(v, int | float | type(None))
        },
        "parts": {
            name: {
                "volume_mm3": p["volume_mm3"],
                "mesh_volume_mm3": p["mesh_volume_mm3"],
                "n_hex": int(p["n_hex"]),
            }
            for name, p in r.parts.items()
        },
        "n_nodes": r.n_nodes,
        "n_hex": r.n_hex,
        "hex_fraction": r.hex_fraction,
        "min_scaled_jacobian": r.min_scaled_jacobian,
        "sets": r.sets,
        "files": {k: str(v) for k, v in m.files.items()},
        "wall_s": total_wall_s,
    }


def dumps(obj: Any) -> str:
    """JSON with paths and numpy scalars turned into plain values."""
    return json.dumps(obj, default=lambda o: o.item() if hasattr(o, "item") else str(o), indent=2)
