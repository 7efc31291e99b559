"""``hingelab export-inp``: write a model file's hinge as an ABAQUS/CalculiX input deck."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cad.errors import ParameterError
from model.jsonio import dumps

if TYPE_CHECKING:
    from mesh.settings import MeshSettings

FIELD_OPTIONS = {
    "amplitude_n": ("--amplitude",),
    "clearance_mm": ("--clearance",),
    "mu": ("--mu",),
    "penalty_mpa_per_mm": ("--penalty",),
    "stick_slope_mpa_per_mm": ("--stick-slope",),
}
"""Field → the options that set it: ``main`` words a refusal in the option the user typed."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``export-inp`` subcommand."""
    p = sub.add_parser(
        "export-inp",
        help="write MODEL.toml's hinge as an ABAQUS/CalculiX .inp deck (mesh, sets, contact, load steps)",
    )
    p.add_argument("model", type=Path, metavar="MODEL.toml", help="the model file")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.inp", help="deck to write")
    p.add_argument(
        "--amplitude",
        type=float,
        default=None,
        metavar="FG",
        help="force amplitude [N] (default: the model file's [cycle] amplitude_n)",
    )
    p.add_argument(
        "--clearance",
        type=float,
        default=None,
        metavar="MM",
        help="radial clearance [mm] (default: the model file's)",
    )
    p.add_argument(
        "--mu",
        type=float,
        default=None,
        metavar="X",
        help="friction coefficient (default: the model file's [friction] mu)",
    )
    p.add_argument(
        "--contact",
        choices=("mortar", "node", "surface"),
        default="mortar",
        help="CalculiX contact: mortar with hard contact and exact stick (default: our "
        "solver's counterpart, completes in ccx on the conforming mesh), node-to-surface or "
        "surface-to-surface penalty contact (docs/calculix_crosscheck.md)",
    )
    p.add_argument(
        "--mesh",
        choices=("conforming", "model"),
        default="conforming",
        help="conforming (default): the model file's mesh sizes with pin and hole nodes at "
        "the same angles (slave_ratio 1, arc_grading 1), which mortar contact needs without "
        "ADJUST; model: the model file's own [mesh] as it is",
    )
    p.add_argument(
        "--penalty",
        type=float,
        default=None,
        metavar="MPA_PER_MM",
        help="normal penalty slope [MPa/mm] (default 1e6)",
    )
    p.add_argument(
        "--stick-slope",
        type=float,
        default=None,
        metavar="MPA_PER_MM",
        help="friction stick slope [MPa/mm] (default 1e6)",
    )
    p.add_argument(
        "--steps",
        type=int,
        choices=(1, 2, 3),
        default=3,
        help="write the first N steps of 0 → +Fg → −Fg → +Fg (default 3, the cycle)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab export-inp``."""
    from fe.effects.registry import REGISTRY
    from fe.interop.deck_settings import CYCLE, ContactType, DeckSettings
    from fe.interop.inp import write_deck
    from mesh.build import mesh_hinge
    from model.file import read_model
    from model.spec import DesignPoint, hinge_at

    spec = read_model(args.model, REGISTRY)
    if args.out.suffix.lower() != ".inp":
        raise ParameterError(f"out must end in .inp, got {args.out}")
    values = {} if args.clearance is None else {"clearance_mm": args.clearance}
    params = hinge_at(spec, DesignPoint(spec.cycle.amplitude_n, values))
    model = spec.hinge_kind.cad(params)
    clearance = float(getattr(params, "clearance_mm", 0.0))  # the deck's contact gap
    overrides = {
        k: v
        for k, v in {
            "amplitude_n": args.amplitude,
            "mu": args.mu,
            "penalty_mpa_per_mm": args.penalty,
            "stick_slope_mpa_per_mm": args.stick_slope,
        }.items()
        if v is not None
    }
    common: dict[str, object] = {
        "amplitude_n": spec.cycle.amplitude_n,
        "mu": spec.cycle.mu,
        "clearance_mm": clearance,
        "increments_per_stage": spec.cycle.increments_per_stage,
        "load_factors": CYCLE[: args.steps],
    }
    if args.contact == "mortar":
        base = DeckSettings.exact_mortar(**common)
    else:
        kind = (
            ContactType.NODE_TO_SURFACE
            if args.contact == "node"
            else ContactType.SURFACE_TO_SURFACE
        )
        base = DeckSettings(contact=kind, **common)  # type: ignore[arg-type]
    settings = dataclasses.replace(base, **overrides)
    mesh_settings = spec.mesh
    if args.mesh == "conforming":
        mesh_settings = dataclasses.replace(spec.mesh, **CONFORMING)
    mesh, _ = mesh_hinge(model, mesh_settings)
    title = f"hingelab {spec.kind} hinge from {args.model.name}"
    path = write_deck(mesh, model.faces, settings, args.out, title=title)
    summary = {
        "deck": str(path),
        "n_nodes": mesh.n_nodes,
        "n_elem": mesh.n_elem,
        "parts": list(mesh.part_names),
        "sets": sorted(mesh.facet_sets),
        "pairs": [p.name for p in mesh.pairs],
        "amplitude_N": settings.amplitude_n,
        "mu": settings.mu,
        "clearance_mm": settings.clearance_mm,
        "contact": settings.contact.value,
        "mesh": args.mesh,
        "effects_not_exported": sorted(spec.effects),
    }
    caution = deck_caution(args.contact, mesh_settings)
    if caution:
        summary["caution"] = caution
    if args.json:
        print(dumps(summary))
    else:
        print(
            f"{path}: {mesh.n_elem} C3D8I elements, {mesh.n_nodes} nodes, "
            f"{len(mesh.pairs)} contact pairs; run it with: ccx -i {path.with_suffix('').name}"
        )
        if spec.effects:
            print(f"note: effects {sorted(spec.effects)} are not in the deck")
        if caution:
            print(f"caution: {caution}", file=sys.stderr)
    return 0


CONFORMING: dict[str, Any] = {"slave_ratio": 1.0, "arc_grading": 1.0}
"""The ``MeshSettings`` overrides of ``--mesh conforming``: 16 equal facets around pin and holes
at the coarse size, every pin node at a hole node's angle (docs/calculix_crosscheck.md)."""


def deck_caution(contact: str, mesh: MeshSettings) -> str | None:
    """Why CalculiX may not finish this deck, with the options that make one it finishes."""
    conforming = all(getattr(mesh, k) == v for k, v in CONFORMING.items())
    if contact == "mortar" and not conforming:
        return (
            "mortar contact without ADJUST needs pin and hole nodes at the same angles; on this "
            "mesh (slave_ratio "
            f"{mesh.slave_ratio:g}, arc_grading {mesh.arc_grading:g}) ccx starts overclosed: "
            "use --mesh conforming (the default)"
        )
    if contact != "mortar":
        return (
            f"--contact {contact} is penalty contact: on the coarse mesh ccx ran over 20 min "
            "without finishing the frictional cycle; --contact mortar --mesh conforming (the "
            "defaults) completes"
        )
    return None
