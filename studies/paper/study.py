"""The paper's study with our own FE: both hinges, their response surfaces, beside the paper.

``hingelab paper --out DIR [--quick]`` runs, as two sweeps (``studies.sweep``: traced,
resumable, every point stored by its content key) — at full size the two shipped study files
``studies/examples/paper_general_5x5.toml`` and ``paper_modified_5x5.toml`` (``STUDY_FILES``):

* the general hinge, clearance 0–0.4 mm × Fg 100–500 N (5 × 5; ``--quick``: 3 × 3 on the
  coarse mesh), and
* the modified hinge, preload 0–200 N × Fg 100–500 N (5 × 5; ``--quick``: 3 × 3, coarse), with
  the frictional fits of the paper's ABAQUS model (``--interfaces contact``, default) or tied
  interfaces (``bonded``);

fits each a response surface (degree 4 as the paper; degree 2 on a 3 × 3 grid, which cannot
carry 15 terms) with the paper's metrics and Q², draws the surfaces, slices and η = 0.05
maps (``rsm.plots``), and writes ``report.md`` and ``report.json`` with our η beside Tables 1
and 4 point by point, the extremes of each hinge and the reduction the bearing brings,
against the paper's printed 54.67 % / 32.57 % — each difference stated, nothing fitted.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from cad.errors import check_range
from fe.kinds import hinge_kind
from model.jsonio import dumps, strict_json
from studies.paper import checks as paper_checks

GRID = (100.0, 200.0, 300.0, 400.0, 500.0)
CLEARANCES = (0.0, 0.1, 0.2, 0.3, 0.4)
PRELOADS = (0.0, 50.0, 100.0, 150.0, 200.0)
QUICK = {"amplitudes": (100.0, 300.0, 500.0), "clearances": (0.0, 0.2, 0.4),
         "preloads": (0.0, 100.0, 200.0)}  # fmt: skip
QUICK_BEARING_MESH: dict[str, Any] = {
    "size_mm": 4.0,
    "contact_size_mm": 0.8,
    "part_sizes_mm": (("ring", 1.2),),
}
"""The bearing hinge's coarse mesh (40k nodes; the tests use it too)."""

STUDY_FILES = {"general": "paper_general_5x5.toml", "modified": "paper_modified_5x5.toml"}
"""The full run's two designs, shipped in ``studies/examples`` (a user can run either alone
with ``hingelab study``)."""

PRINTED_REDUCTION = {"min": 54.67, "max": 32.57}
"""The paper's reductions of η_min and η_max from the general to the modified hinge [%]."""


@dataclasses.dataclass(frozen=True)
class PaperStudy:
    """What ``hingelab paper`` runs.

    Attributes:
        quick: Coarse meshes and 3 × 3 grids.
        interfaces: The modified hinge's interfaces, ``contact`` (the paper's) or ``bonded``.
        mu: Friction coefficient of every frictional contact.
        workers: Dask worker processes per sweep.
        points: Restrict each hinge to its first ``points`` grid points (a smoke run), or 0.
    """

    quick: bool = False
    interfaces: str = "contact"
    mu: float = 0.2
    workers: int = 1
    points: int = 0

    def __post_init__(self) -> None:
        check_range("points", self.points, 0, 10_000)

    def sweeps(self) -> dict[str, Any]:
        """The two sweeps' settings, by hinge (``general``, ``modified``).

        The full run is the two shipped study files (``STUDY_FILES``) with this study's μ,
        interfaces and workers; ``--quick`` and ``--points`` run the same designs on the
        coarse meshes or fewer points.
        """
        if not self.quick and not self.points:
            return {name: self._from_file(name) for name in STUDY_FILES}
        from cad.bearing_geometry import Interfaces
        from mesh.settings import MeshSettings
        from studies.sweep import SweepSettings

        amps: tuple[float, ...] = QUICK["amplitudes"] if self.quick else GRID
        general_mesh = MeshSettings.coarse() if self.quick else MeshSettings()
        bearing_mesh = hinge_kind("bearing").mesh_settings()
        if self.quick:
            bearing_mesh = dataclasses.replace(bearing_mesh, **QUICK_BEARING_MESH)
        clearances: tuple[float, ...] = QUICK["clearances"] if self.quick else CLEARANCES
        preloads: tuple[float, ...] = QUICK["preloads"] if self.quick else PRELOADS
        if self.points:
            amps, clearances, preloads = amps[: self.points], clearances[:1], preloads[:1]
        return {
            "general": SweepSettings(
                levels=clearances, amplitudes_n=amps, mu=self.mu, mesh=general_mesh,
                workers=self.workers, study="paper_general",
            ),
            "modified": SweepSettings(
                hinge="bearing", levels=preloads, amplitudes_n=amps, mu=self.mu,
                mesh=bearing_mesh, workers=self.workers, study="paper_modified",
                hinge_options=(("interfaces", Interfaces(self.interfaces)),),
            ),
        }  # fmt: skip

    def _from_file(self, name: str) -> Any:
        """One shipped study file's sweep, with this study's μ, interfaces and workers."""
        from cad.bearing_geometry import Interfaces
        from studies.study_file import read_study

        study = read_study(Path(__file__).parents[1] / "examples" / STUDY_FILES[name])
        spec = study.spec
        spec = dataclasses.replace(spec, cycle=dataclasses.replace(spec.cycle, mu=self.mu))
        if name == "modified":  # the paper's modified hinge: the bearing kind's interfaces
            hinge = dataclasses.replace(spec.hinge, interfaces=Interfaces(self.interfaces))
            spec = dataclasses.replace(spec, hinge=hinge)
        settings = dataclasses.replace(study, spec=spec).sweep_settings(workers=self.workers)
        return dataclasses.replace(settings, study=f"paper_{name}")


def _paper_table(case: Any) -> dict[tuple[float, float], float]:
    from rsm.paper_printed import paper_table_path

    with paper_table_path(case.csv_name) as p, p.open() as fh:
        rows = list(csv.DictReader(fh))
    return {
        (float(r[case.x_names[0]]), float(r[case.x_names[1]])): float(r["eta_fe"]) for r in rows
    }


def _hinge_report(
    name: str, table: Path, x_names: tuple[str, str], case: Any, out: Path
) -> tuple[dict[str, Any], Any]:
    """Fit, plot and compare one hinge; return the report and its surface (None if too few points)."""
    from rsm.metrics import fit_metrics
    from rsm.polynomial import fit_response_surface
    from rsm.query import extrema, threshold_region
    from rsm.tables import read_xy

    xy = read_xy(table, x_names, "eta")
    x, eta = xy.x, xy.y
    paper = _paper_table(case)
    rows = [
        {
            x_names[0]: float(a),
            x_names[1]: float(b),
            "eta_ours": float(e),
            "eta_paper": paper.get((float(a), float(b)), math.nan),
        }
        for (a, b), e in zip(x, eta, strict=True)
    ]
    out_h: dict[str, Any] = {
        "points": rows,
        "n_points": len(rows),
        "eta_min_points": float(eta.min()),
        "eta_max_points": float(eta.max()),
    }
    n_levels = min(len(np.unique(x[:, 0])), len(np.unique(x[:, 1])))
    degree = 4 if n_levels >= 5 else 2 if n_levels >= 3 else 0
    if degree == 0:
        out_h["surface"] = None
        out_h["eta_min"], out_h["eta_max"] = float(eta.min()), float(eta.max())
        return out_h, None
    surface = fit_response_surface(x, eta, degree, x_names=x_names, y_name="eta")
    m = fit_metrics(surface, warn=False)

    def draw() -> dict[str, Path]:
        from rsm.plots import plot_all  # matplotlib (~0.8 s) only when a figure is drawn

        return plot_all(surface, m, out / "figures", threshold=0.05, prefix=f"{name}_")

    figures = current_figures(
        out / "figures" / f".{name}_surface.json",
        {"table": table.read_bytes().decode("utf-8"), "degree": degree, "x_names": x_names},
        draw,
    )
    ext = extrema(surface)
    region = threshold_region(surface, 0.05, below=True)
    out_h["surface"] = {
        "degree": degree,
        "max_abs_re_percent": m.max_abs_re_percent,
        "r2": m.r2,
        "r2_adj": m.r2_adj,
        "rmse": m.rmse,
        "q2": m.q2,
        "overfit": list(m.overfit_reasons),
        "figures": {k: str(v.relative_to(out)) for k, v in figures.items()},
    }
    out_h["eta_min"], out_h["eta_max"] = ext.minimum.value, ext.maximum.value
    out_h["eta_min_at"], out_h["eta_max_at"] = ext.minimum.x.tolist(), ext.maximum.x.tolist()
    out_h["below_0.05_fraction"] = region.area_fraction
    out_h["below_0.05_range"] = {
        x_names[i]: [float(region.lower[i]), float(region.upper[i])] for i in range(2)
    }
    return out_h, surface


def current_figures(
    stamp: Path, inputs: Any, draw: Callable[[], dict[str, Path]]
) -> dict[str, Path]:
    """The figures ``draw`` makes from ``inputs``, drawn again only when the inputs changed.

    A rerun with nothing changed spent most of its seconds redrawing the same surfaces
    (4 of 11 s, benchmarks/bench_rerun.txt). ``stamp`` records the inputs' content hash
    and the files, written after them: a figure missing, or a stamp from other inputs
    (another table, degree or code: ``model.code.code_version``), draws again.
    """
    import json

    from model.code import ALL_PACKAGES, code_version
    from model.spec import content_hash

    digest = content_hash({"inputs": inputs, "code": code_version(ALL_PACKAGES)})
    if stamp.is_file():
        try:
            old = json.loads(stamp.read_text())
        except ValueError:
            old = {}
        files = {k: stamp.parent / v for k, v in old.get("files", {}).items()}
        if old.get("inputs") == digest and files and all(f.is_file() for f in files.values()):
            return files
    files = draw()
    stamp.parent.mkdir(parents=True, exist_ok=True)
    tmp = stamp.with_suffix(".tmp")
    rel = {k: str(Path(v).relative_to(stamp.parent)) for k, v in files.items()}
    tmp.write_text(json.dumps({"inputs": digest, "files": rel}))
    tmp.replace(stamp)
    return files


def _eta_at(h: dict[str, Any] | None, x_names: tuple[str, str], at: tuple[float, float]) -> Any:
    """Our η at one design point of a hinge's report, or None if it was not run."""
    for p in (h or {}).get("points", []):
        if (p[x_names[0]], p[x_names[1]]) == at:
            return p["eta_ours"]
    return None


def _copy_loop(sweep_out: Path, folder: str, dest: Path) -> str | None:
    src = sweep_out / "points" / folder / "loop.png"
    if not src.is_file():
        return None
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dest)
    return str(dest.name)


def run_paper(study: PaperStudy, out: Path) -> dict[str, Any]:
    """Run both sweeps, fit, plot and compare; write ``report.json`` and ``report.md``."""
    from rsm.paper_printed import GENERAL, MODIFIED, TABLE7_POINT
    from studies.paper.checks import (
        current_threshold,
        repeatability_pairs,
        validation_points,
    )
    from studies.sweep import run_sweep

    hinges = (
        ("general", ("clearance_mm", "amplitude_N"), GENERAL),
        ("modified", ("preload_N", "amplitude_N"), MODIFIED),
    )
    t0 = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    sweeps = study.sweeps()
    outcomes = {name: run_sweep(s, out / name) for name, s in sweeps.items()}
    report: dict[str, Any] = {
        "study": dataclasses.asdict(study),
        "sweeps": {n: _outcome(o, out) for n, o in outcomes.items()},
    }
    surfaces: dict[str, Any] = {}
    for name, xs, case in hinges:
        table = outcomes[name].table
        report[name], surfaces[name] = (
            _hinge_report(name, table, xs, case, out) if table.is_file() else (None, None)
        )
    if any(v is not None for v in surfaces.values()):
        report["threshold"] = current_threshold(surfaces, out)
    report["validation_points"] = validation_points({n: outcomes[n].table for n, _, _ in hinges})
    report["repeatability"] = repeatability_pairs(
        {n: _eta_at(report[n], xs, TABLE7_POINT[n]) for n, xs, _ in hinges}
    )
    loops = {}
    for name in ("general", "modified"):
        label, folder = _label(sweeps[name], name)
        loops[name] = _copy_loop(out / name, folder, out / "figures" / f"{name}_loop_{label}.png")
    report["loops"] = loops
    g, mo = report.get("general"), report.get("modified")
    if g and mo:
        # the paper's reductions are between its surfaces' extremes; a fitted surface that
        # dips below zero (a low-degree fit over a 3 × 3 grid can) has no meaningful
        # minimum, and then the sampled points are used and the report says so
        on_surface = min(g["eta_min"], mo["eta_min"]) > 0
        basis = "" if on_surface else "_points"
        report["reduction_basis"] = "surface extremes" if on_surface else "sampled points"
        report["reduction_percent"] = {
            k: 100.0 * (g[f"eta_{k}{basis}"] - mo[f"eta_{k}{basis}"]) / g[f"eta_{k}{basis}"]
            if g[f"eta_{k}{basis}"] > 0
            else math.nan
            for k in ("min", "max")
        }
        report["reduction_percent_paper"] = PRINTED_REDUCTION
    report["wall_s"] = time.perf_counter() - t0
    (out / "report.json").write_text(dumps(strict_json(report)))
    (out / "report.md").write_text(report_markdown(report))
    return report


def _outcome(o: Any, out: Path) -> dict[str, Any]:
    return {
        "ok": o.ok,
        "failed": o.failed,
        "cached": o.cached,
        "skipped": o.skipped,
        "wall_s": o.wall_s,
        "compute_s": _compute_s(o.table),
        "table": str(o.table.relative_to(out)),
    }


def _compute_s(table: Path) -> float | None:
    """Sum of the points' own wall times as recorded when they were computed [s].

    Setup included; a rerun that reads the points back still reports what they cost.
    None if the table has no ``wall_s`` column.
    """
    if not table.is_file():
        return None
    with table.open(newline="", encoding="utf-8") as fh:
        walls = [r.get("wall_s") or "" for r in csv.DictReader(fh)]
    try:
        return float(sum(float(w) for w in walls if w))
    except ValueError:
        return None


LABEL_NEAR = {"general": 0.1, "modified": 0.0}
"""The design value near which each case's example loop is shown (Δr 0.1 mm, F_p 0 N)."""


def _label(settings: Any, name: str) -> tuple[str, str]:
    """The point closest to 400 N (and Δr 0.1 mm / F_p 0) of a sweep: its label and folder."""
    from model.spec import complete_point, point_folder, point_label

    spec = settings.spec()
    variable = spec.hinge_kind.design_variables[0].name

    def distance(p: Any) -> tuple[float, float]:
        value = complete_point(spec, p).values[variable]
        return (abs(p.amplitude_n - 400), abs(value - LABEL_NEAR[name]))

    point = min(settings.design_points(), key=distance)
    return point_label(spec, point), point_folder(spec, point)


def _fmt(v: Any, spec: str = ".4f") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return format(v, spec)


def report_markdown(r: dict[str, Any]) -> str:
    """The report a reader understands without the code."""
    s = r["study"]
    lines = [
        "# The paper's study with hingelab's FE",
        "",
        f"Run: `hingelab paper{' --quick' if s['quick'] else ''} --interfaces {s['interfaces']}"
        f" --mu {s['mu']:g}` ({r['wall_s']:.0f} s this run; computing the points took "
        + ", ".join(f"{n} {_fmt(o.get('compute_s'), '.0f')} s" for n, o in r["sweeps"].items())
        + " when they ran, setup included). The paper (ABAQUS) gives no dimensions and "
        "no friction coefficient: its tables are a record to compare with, not a target, and "
        "every difference below is reported as it is.",
        "",
        "| hinge | points ok | failed | table |",
        "|---|---|---|---|",
    ]
    for n, o in r["sweeps"].items():
        lines.append(
            f"| {n} | {o['ok'] + o['cached'] + o['skipped']} | {o['failed']} | `{o['table']}` |"
        )
    for name, label, xs, table in (
        ("general", "General hinge (Table 1)", ("clearance_mm", "amplitude_N"), "Table 1"),
        ("modified", "Modified hinge (Table 4)", ("preload_N", "amplitude_N"), "Table 4"),
    ):
        h = r.get(name)
        if not h:
            continue
        lines += ["", f"## {label}", "", f"| {xs[0]} | {xs[1]} | η ours | η {table} | ours / paper |",
                  "|---|---|---|---|---|"]  # fmt: skip
        for p in h["points"]:
            ratio = p["eta_ours"] / p["eta_paper"] if p["eta_paper"] else math.nan
            lines.append(
                f"| {p[xs[0]]:g} | {p[xs[1]]:g} | {_fmt(p['eta_ours'])} | {_fmt(p['eta_paper'])} "
                f"| {_fmt(ratio, '.2f')} |"
            )
        surf = h.get("surface")
        if surf:
            lines += [
                "",
                f"Response surface, degree {surf['degree']}: max |RE| {_fmt(surf['max_abs_re_percent'], '.2f')} %, "
                f"R² {_fmt(surf['r2'])}, R²adj {_fmt(surf['r2_adj'])}, RMSE {_fmt(surf['rmse'], '.2e')}, "
                f"Q² {_fmt(surf['q2'])}."
                + (f" Over-fit warnings: {'; '.join(surf['overfit'])}." if surf["overfit"] else ""),
                f"η on the surface: min {_fmt(h['eta_min'])} at {h['eta_min_at']}, max "
                f"{_fmt(h['eta_max'])} at {h['eta_max_at']} (sampled points: "
                f"{_fmt(h['eta_min_points'])} to {_fmt(h['eta_max_points'])}); η < 0.05 on "
                f"{100 * h['below_0.05_fraction']:.0f} % of the design box.",
                "",
                *[f"![{k}](figures/{Path(v).name})" for k, v in surf["figures"].items()],
            ]
    if "reduction_percent" in r:
        red, paper = r["reduction_percent"], r["reduction_percent_paper"]
        lines += [
            "",
            "## What the bearing brings",
            "",
            f"Reductions from the general to the modified hinge, between the {r['reduction_basis']} "
            "(the paper: between its surfaces' extremes). A negative reduction means the "
            "modified hinge dissipates more.",
            "",
            "| | ours | paper |",
            "|---|---|---|",
            f"| reduction of η_min | {_fmt(red['min'], '.1f')} % | {paper['min']} % |",
            f"| reduction of η_max | {_fmt(red['max'], '.1f')} % | {paper['max']} % |",
        ]
    lines += paper_checks.markdown(
        r.get("threshold"), r.get("repeatability"), r.get("validation_points")
    )
    loops = r.get("loops", {})
    lines += ["", "## Loops (the points nearest 400 N)", ""]
    lines += [f"![{k} loop](figures/{v})" for k, v in loops.items() if v]
    lines += [
        "",
        "## Why ours differs",
        "",
        "* Geometry: the paper gives no dimensions; ours are the defaults of `cad.general` and "
        "`cad.bearing` (a 708C pair).",
        "* Friction: the paper gives no μ; ours is the same μ on every contact.",
        "* The modified hinge: with tied interfaces our model dissipates nothing (free-rolling "
        "Hertz balls); with frictional fits it dissipates through the fits, and η rises with the "
        "preload as in Table 4 (docs/bearing_model.md §5).",
        "* The general hinge with clearance: our η is 0.001 where Table 1 has 0.035–0.084. Our "
        "default hinge has no axial clamp, so it crosses the free play with nothing rubbing. "
        "With a clamp (the `face_friction` effect, docs/face_friction_clearance.md) the faces "
        "hold the clevis until they slip and it slides across the free play: η 0.06–0.38 at "
        "300 N per face (coarse mesh). The paper states no clamp, so none is assumed here; "
        "`diagnose` on Table 1's clearance rows asks which one (docs/paper_validation.md). "
        "Until then a reduction computed against our general hinge with clearance says little.",
        "* The paper's own Table 1 fit puts its η = 0.05 boundary elsewhere than its text "
        "(0.157 vs 0.2248 mm: `hingelab rsm paper`).",
    ]
    return "\n".join(lines) + "\n"
