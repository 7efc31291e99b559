"""``hingelab reduce``: fit the reduced-order joint element to a hinge design's FE loops.

``hingelab reduce FOLDER --out DIR [--pbush-amplitudes LIST] [--no-fmu]`` reads the FE
points of a sweep, study or cycle folder (``points/*/result.json`` and ``loop.csv``),
fits one element per design (``validation.reduce``), prints the validation table and
writes, per design, into ``DIR/<design>/``: ``reduced.toml`` (a model file that
``hingelab cycle --model`` runs), ``fit.json`` (parameters with 1σ uncertainties, fit
time), ``pbush.bdf`` (CBUSH/PBUSH per amplitude) and ``joint.fmu`` (FMI 2.0
co-simulation); and ``DIR/validation.csv`` for every point.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import re
from pathlib import Path
from typing import Any

from cad.errors import ParameterError
from model.jsonio import dumps
from studies.outputs import check_writable_dir


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``reduce`` subcommand."""
    p = sub.add_parser(
        "reduce",
        help="fit the reduced-order joint element to FE loops; write model, FMU, PBUSH cards",
    )
    p.add_argument("folder", type=Path, metavar="FOLDER", help="a sweep, study or cycle folder")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument(
        "--pbush-amplitudes",
        default=None,
        metavar="LIST",
        help="amplitudes [N] of the equivalent-linear PBUSH cards, e.g. 100,400 "
        "(default: the FE points' amplitudes)",
    )
    p.add_argument("--no-fmu", action="store_true", help="do not build the FMU")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def _amplitudes(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError as err:
        raise ParameterError(
            f"--pbush-amplitudes must be numbers [N] like 100,400, got {text!r}"
        ) from err
    if not values or any(not v > 0 for v in values):
        raise ParameterError(f"--pbush-amplitudes must be > 0 N, got {text!r}")
    return values


def _label(design: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", design)


def _write_text(path: Path, text: str) -> None:
    part = path.with_name(path.name + ".part")
    part.write_text(text, encoding="utf-8")
    part.replace(path)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab reduce``."""
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.file import write_model
    from model.spec import ModelSpec
    from validation.reduce import fit_design, group_by_design, read_points
    from validation.reduce_export import pbush_cards, write_fmu

    amps = _amplitudes(args.pbush_amplitudes)
    out = check_writable_dir(args.out, "--out")
    rows: list[dict[str, Any]] = []
    summary: dict[str, Any] = {}
    for design, pts in group_by_design(read_points(args.folder)).items():
        red = fit_design(design, pts)
        folder = out / _label(design)
        folder.mkdir(parents=True, exist_ok=True)
        f_max = max(p.amplitude_n for p in pts)
        spec = ModelSpec("joint", red.params, MeshSettings(), CycleSettings(amplitude_n=f_max))
        write_model(spec, folder / "reduced.toml.part").replace(folder / "reduced.toml")
        _write_text(
            folder / "pbush.bdf", pbush_cards(red.params, amps or [p.amplitude_n for p in pts])
        )
        files = ["reduced.toml", "fit.json", "pbush.bdf"]
        if not args.no_fmu:
            write_fmu(red.params, folder / "joint.fmu")
            files.append("joint.fmu")
        info = {
            "design": design,
            "params": dataclasses.asdict(red.params),
            "fitted": red.values,
            "sigma": red.sigma,
            "fit_s": red.fit_s,
            "cost": red.cost,
            "free_play_geometry_mm": pts[0].free_play_mm,
            "files": files,
        }
        _write_text(folder / "fit.json", dumps(info))
        summary[design] = info
        rows += red.table()
    _write_csv(out / "validation.csv", rows)
    if args.json:
        print(dumps({"designs": summary, "validation": rows}))
    else:
        _print(summary, rows, out)
    return 0


def _write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    part = path.with_name(path.name + ".part")
    with open(part, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    part.replace(path)


def _print(summary: dict[str, Any], rows: list[dict[str, Any]], out: Path) -> None:
    for design, info in summary.items():
        fit = ", ".join(
            f"{k} = {v:.5g} ± {info['sigma'][k]:.2g}" for k, v in info["fitted"].items()
        )
        print(
            f"{design}: {fit}; free play {info['params']['free_play_mm']:g} mm "
            f"(geometry {info['free_play_geometry_mm']:g}); fit {info['fit_s']:.1f} s"
        )
    print(
        f"{'design':<18s} {'Fg [N]':>7s} {'δ+ FE':>10s} {'δ+ el':>10s} {'err':>7s} "
        f"{'δ− FE':>10s} {'δ− el':>10s} {'err':>7s} {'W FE':>10s} {'W el':>10s} "
        f"{'η FE':>8s} {'η el':>8s} {'err':>7s}"
    )
    for r in rows:
        print(
            f"{r['design']:<18s} {r['amplitude_N']:7.0f} {r['d_plus_fe_mm']:10.4e} "
            f"{r['d_plus_el_mm']:10.4e} {r['d_plus_err']:+7.2%} {r['d_minus_fe_mm']:10.4e} "
            f"{r['d_minus_el_mm']:10.4e} {r['d_minus_err']:+7.2%} {r['W_fe_Nmm']:10.4e} "
            f"{r['W_el_Nmm']:10.4e} {r['eta_fe']:8.5f} {r['eta_el']:8.5f} {r['eta_err']:+7.2%}"
        )
    print(
        f"results in {out}/ (validation.csv; per design reduced.toml, fit.json, pbush.bdf, joint.fmu)"
    )
