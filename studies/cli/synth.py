"""``hingelab synth``: a synthetic measurement set from a model with hidden effects.

``hingelab synth MODEL.toml --effect NAME[:PARAM=VALUE[,PARAM=VALUE]] [--effect …]
--noise-force N --noise-disp MM --seed S [--cases "0:100,400;0.1:100,400"] --out DIR``
writes ``cases.csv``, ``loops/<case>.csv`` and ``manifest.json`` (the hidden truth)
into DIR (``validation.synth``). Without ``--cases`` the design is 3 levels of the
model's design variable × 3 amplitudes (``validation.synth.default_design``: clearances
for the general hinge, preloads for the bearing hinge, whose ``--cases`` then reads
"preload:amp,amp;…" in N). The data come from a finer mesh than
the model file's (``validation.synth.MESH_RULE``). With ``--workers N`` or ``--scheduler
ADDRESS`` the cycles run on Dask (each worker the geometries it holds first); the sampling and noise are
drawn here, so the set is the same.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from cad.errors import ParameterError
from model.jsonio import dumps
from studies.cluster_options import CLUSTER_OPTIONS, add_cluster_arguments, model_service

FIELD_OPTIONS = {
    "noise_force_n": ("--noise-force",),
    "noise_disp_mm": ("--noise-disp",),
    "seed": ("--seed",),
    **CLUSTER_OPTIONS,
}
"""Field → the options that set it: ``main`` words a refusal in the option the user typed."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``synth`` subcommand."""
    p = sub.add_parser(
        "synth",
        help="write a synthetic measurement set from MODEL.toml with hidden effects",
    )
    p.add_argument("model", type=Path, metavar="MODEL.toml", help="the model file")
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME[:PARAM=VALUE,...]",
        help="a hidden effect (repeatable); absent parameters take their defaults",
    )
    p.add_argument(
        "--noise-force",
        type=float,
        default=0.2,
        metavar="N",
        help="force noise σ [N] (default 0.2)",
    )
    p.add_argument(
        "--noise-disp",
        type=float,
        default=5e-5,
        metavar="MM",
        help="displacement noise σ [mm] (default 5e-5)",
    )
    p.add_argument("--seed", type=int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument(
        "--cases",
        default=None,
        metavar="DESIGN",
        help='"clearance:amp,amp;clearance:amp,..." (mm, N), for a bearing-hinge model '
        '"preload:amp,amp;..." (N, N); default 3 × 3',
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument("--json", action="store_true", help="print the manifest as JSON")
    add_cluster_arguments(p)
    p.set_defaults(func=run)


def parse_effects(items: list[str]) -> dict[str, dict[str, float]]:
    """Parse ``NAME[:PARAM=VALUE[,PARAM=VALUE]]`` items; repeated names merge.

    Raises:
        ParameterError: Naming the item that is malformed.
    """
    out: dict[str, dict[str, float]] = {}
    for item in items:
        name, _, rest = item.partition(":")
        name = name.strip()
        if not name:
            raise ParameterError(f"--effect {item!r}: no effect name")
        params = out.setdefault(name, {})
        for assignment in filter(None, (a.strip() for a in rest.split(","))):
            key, sep, value = assignment.partition("=")
            try:
                if not sep:
                    raise ValueError
                params[key.strip()] = float(value)
            except ValueError:
                raise ParameterError(
                    f"--effect {item!r}: {assignment!r} is not PARAM=NUMBER"
                ) from None
    return out


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab synth``."""
    from fe.effects.registry import validate_effects
    from model.file import read_model
    from validation.synth import (
        SynthSettings,
        default_design,
        design_cases,
        parse_design,
        synthesize,
    )

    spec = read_model(args.model)
    hidden = validate_effects(parse_effects(args.effect))
    variables = spec.hinge_kind.design_variables
    variable = variables[0].column if variables else "level"
    design = default_design(spec.kind) if args.cases is None else parse_design(args.cases, variable)
    settings = SynthSettings(
        seed=args.seed, noise_force_n=args.noise_force, noise_disp_mm=args.noise_disp
    )
    try:
        cases = design_cases(design, spec.kind, spec.hinge)
    except ParameterError as err:
        if args.cases is None:
            raise
        raise ParameterError(f"--cases {args.cases!r}: {err}") from err  # err names the column
    with model_service(args, None) as service:  # the set is replaced whole: no result store
        report = synthesize(spec, hidden, cases, settings, args.out, service)
    if args.json:
        print(dumps(report.manifest))
    else:
        hidden_text = ", ".join(
            f"{n}({', '.join(f'{k}={v:g}' for k, v in p.items())})" for n, p in hidden.items()
        )
        print(
            f"{len(report.manifest['cases'])} cases written to {args.out}/ (cases.csv, loops/, "
            f"manifest.json); hidden: {hidden_text or 'none'}; seed {args.seed}; "
            f"{report.manifest['wall_s']:.1f} s"
        )
    return 0
