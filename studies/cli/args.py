"""Command-line options shared by several subcommands (geometry, mesh size)."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from typing import Any

from cad.errors import ParameterError
from fe.kinds import DEFAULT_KIND, hinge_kind, kind_names
from mesh.settings import MeshSettings


def add_geometry_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options that choose a hinge and its mesh (shared with ``cycle``)."""
    p.add_argument(
        "--hinge",
        choices=kind_names(),
        default=None,
        help=f"hinge kind, a registered one (default: {DEFAULT_KIND})",
    )
    p.add_argument(
        "--clearance",
        type=float,
        default=None,
        metavar="MM",
        help="radial pin-hole clearance of the general hinge [mm] (default 0)",
    )
    p.add_argument(
        "--preload",
        type=float,
        default=None,
        metavar="N",
        help="axial bearing preload of the bearing hinge [N] (default 100)",
    )
    add_mesh_arguments(p)


def add_mesh_arguments(p: argparse.ArgumentParser) -> None:
    """Add the mesh-size options (shared with ``cycle`` and ``sweep``)."""
    p.add_argument(
        "--refinement",
        type=int,
        default=0,
        metavar="K",
        help="mesh level; each halves sizes (0-4; default 0)",
    )
    p.add_argument(
        "--size",
        type=float,
        default=None,
        metavar="MM",
        help="global element size at level 0 [mm] (default 3 general, 2.5 bearing; 4 is a coarse, fast mesh)",
    )
    p.add_argument(
        "--contact-size",
        type=float,
        default=None,
        metavar="MM",
        help="master contact-surface element size at level 0 [mm] (default 1.2 general, 0.15 bearing; 2 is coarse)",
    )


def settings_from_args(args: argparse.Namespace, *, cycle: bool = True) -> MeshSettings:
    """Return mesh settings from the parsed options.

    Args:
        args: The options (``--hinge``, ``--refinement``, ``--size``, ``--contact-size``).
        cycle: The mesh a cycle runs on; False: the whole CAD model's (the ``mesh``
            command: the bearing hinge's balls too, ``HingeKind.mesh_settings``).
    """
    kw: dict[str, Any] = {"refinement": args.refinement}
    if args.size is not None:
        kw["size_mm"] = args.size
    if args.contact_size is not None:
        kw["contact_size_mm"] = args.contact_size
    return hinge_kind(args.hinge or DEFAULT_KIND).mesh_settings(cycle=cycle, **kw)


FieldOptions = Mapping[str, tuple[str, ...]]
"""A command's ``FIELD_OPTIONS``: parameter-dataclass field → the options that set it
(``increments_per_stage`` → ``("--increments",)``; the sweep's ``clearance_mm`` →
``("--levels", "--clearance")``)."""

GEOMETRY_OPTIONS: FieldOptions = {
    "clearance_mm": ("--clearance",),
    "preload_n": ("--preload",),
    "refinement": ("--refinement",),
    "size_mm": ("--size",),
    "contact_size_mm": ("--contact-size",),
}
"""The fields ``add_geometry_arguments`` sets (``add_mesh_arguments``: the last three)."""

FIT_OPTIONS: FieldOptions = {
    "rel_floor": ("--model-error",),
    "increments_per_stage": ("--increments",),
    "clearance_increments": ("--increments",),
}
"""The fields ``add_fit_arguments`` sets."""


def dest(option: str) -> str:
    """The attribute of the parsed options that holds an option (``--contact-size`` → ``contact_size``)."""
    return option.lstrip("-").replace("-", "_")


def in_user_terms(
    err: ParameterError, args: argparse.Namespace, options: FieldOptions
) -> ParameterError:
    """Return the error naming the option the user typed instead of the field it sets.

    The dataclasses check their fields by their own names (``check_range`` records the
    name in ``ParameterError.parameter``); ``main`` calls this with the command's
    ``FIELD_OPTIONS``, so "increments_per_stage must be in [2, 10000], got 1" reaches the
    user as "--increments must be in [2, 10000], got 1". An option not given (None)
    renames nothing: the value then came from a file or a default, named as it is there.

    Args:
        err: The error.
        args: The parsed options.
        options: Field → the options that set it.
    """
    for option in options.get(err.parameter or "", ()):
        if getattr(args, dest(option), None) is not None:
            return err.renamed(option)
    return err


def add_fit_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options ``diagnose`` and ``calibrate`` share: model floor and increments."""
    p.add_argument(
        "--model-error",
        type=float,
        default=0.02,
        metavar="REL",
        help="relative model error floor of the features (default 0.02)",
    )
    p.add_argument(
        "--increments",
        type=int,
        default=8,
        metavar="N",
        help="increments per stage (default 8; twice that with clearance)",
    )
