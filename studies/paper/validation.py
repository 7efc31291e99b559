"""Apply the validation workflow to the paper's published values.

``python -m studies.paper.validation --out DIR [--quick]`` takes the paper's numbers as
they are printed (kept once, in ``rsm/data/``, ``rsm.paper_printed``): Table 1 (the paper's own FE loss
factors over clearance × amplitude, an η-only table) and the 400 N test point of its
Fig. 5 (η = 0.0933 measured; the paper does not state that specimen's clearance — its FE
value there, 0.0891, sits next to Table 1's Δr = 0 entry 0.0895, so Δr = 0 is assumed),
and runs on our default general-hinge model (``ModelSpec`` defaults, μ = 0.2):

1. ``compare`` of the model with Table 1 (η error per case) and with the test point;
2. ``diagnose`` on Table 1's Δr = 0 row (every candidate, the interference included, which
   needs Δr = 0) and on a 3 × 3 subset over clearance (Δr 0, 0.2, 0.4 mm × Fg 100, 300,
   500 N; the interference and other Δr = 0-only candidates are skipped there).

It writes ``DIR/report.json`` and ``DIR/report.md`` (the findings in words, with numbers)
and the comparison folders; the cycles are kept in ``DIR/results`` (a rerun reads them
back) and run on Dask with ``--workers N`` or ``--scheduler ADDRESS``. The paper's Table 1
is a *model* (ABAQUS) record, not a measurement: "diagnosing" it asks which of our
candidate effects would make our model behave like theirs. ``--quick`` uses the tests'
coarse mesh (minutes instead of ~an hour).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

from model.jsonio import dumps
from rsm.paper_printed import paper_table_path
from validation.measurements import Case, MeasurementSet, read_eta_table

TABLE1 = "paper_table1_general_hinge.csv"
"""The paper's Table 1 (η of its FE model, column ``eta_fe``), as ``rsm`` keeps it."""
VALIDATION_POINTS = "paper_validation_points.csv"
"""The paper's validation test at 400 N (η measured, row ``general, eta``), as ``rsm`` keeps it."""
SUBSET = ((0.0, 100.0), (0.0, 300.0), (0.0, 500.0), (0.2, 100.0), (0.2, 300.0), (0.2, 500.0),
          (0.4, 100.0), (0.4, 300.0), (0.4, 500.0))  # fmt: skip


def table1_set() -> MeasurementSet:
    """The paper's Table 1 as η-only cases of the general hinge (``row1`` … ``row25``)."""
    with paper_table_path(TABLE1) as path:
        return read_eta_table(path, hinge="general", eta_column="eta_fe")


def measured_point() -> MeasurementSet:
    """The paper's measured η of the general hinge at 400 N (Δr 0 assumed) as one case."""
    with paper_table_path(VALIDATION_POINTS) as path, path.open(newline="") as fh:
        row = next(
            r for r in csv.DictReader(fh) if (r["hinge"], r["quantity"]) == ("general", "eta")
        )
        case = Case(
            "test_point", "general", {"clearance_mm": 0.0}, float(row["amplitude_N"]),
            eta=float(row["test_value"]),
        )  # fmt: skip
        return MeasurementSet((case,), path)


def _spec(quick: bool) -> Any:
    from cad.general_params import GeneralHingeParams
    from mesh.settings import MeshSettings
    from model.spec import ModelSpec

    if quick:
        return ModelSpec("general", GeneralHingeParams(), MeshSettings.coarse())
    return ModelSpec("general", GeneralHingeParams())


def _subset(data: Any, points: tuple[tuple[float, float], ...]) -> Any:
    from validation.measurements import MeasurementSet

    keep = tuple(
        c for c in data.cases if (c.values.get("clearance_mm", 0.0), c.amplitude_n) in points
    )
    return MeasurementSet(keep, data.root)


def run(out: Path, quick: bool, service: Any = None) -> dict[str, Any]:
    """Run the comparison and the two diagnoses; write and return the report.

    Args:
        out: The output folder.
        quick: The coarse mesh.
        service: The ``model.service.ModelService`` the cycles run through (its store and
            Dask runner), or None (in this process, nothing stored).
    """
    from validation.compare import CompareSettings
    from validation.diagnose import diagnose
    from validation.workflow import compare_and_write

    t0 = time.perf_counter()
    spec = _spec(quick)
    table1, test = table1_set(), measured_point()
    out.mkdir(parents=True, exist_ok=True)
    report: dict[str, Any] = {"model": {"mesh": dataclasses.asdict(spec.mesh), "mu": spec.cycle.mu}}
    settings = CompareSettings()
    for label, data in (("table1", table1), ("test_point", test)):
        cmp, _ = compare_and_write(
            spec, data, out / f"compare_{label}", settings, plots=True, service=service
        )
        report[f"compare_{label}"] = {
            "n_pass": cmp.summary["n_pass"],
            "n_cases": cmp.summary["n_cases"],
            "cases": [
                {
                    "clearance_mm": c.case.values.get("clearance_mm", 0.0),
                    "amplitude_N": c.case.amplitude_n,
                    "eta_paper": c.case.eta,
                    "eta_model": c.model["eta"],
                    "eta_error": c.errors.get("eta"),
                }
                for c in cmp.cases
            ],
        }
    zero_row = tuple(
        p
        for p in {(c.values.get("clearance_mm", 0.0), c.amplitude_n) for c in table1.cases}
        if p[0] == 0
    )
    for label, points in (("diagnose_zero_clearance", zero_row), ("diagnose_3x3", SUBSET)):
        d = diagnose(spec, _subset(table1, points), service=service)
        report[label] = d.to_dict()
        (out / f"{label}.txt").write_text(d.text() + "\n")
    report["wall_s"] = time.perf_counter() - t0
    if service is not None:
        report["n_computed"] = service.n_computed
    (out / "report.json").write_text(dumps(report))
    (out / "report.md").write_text(_markdown(report))
    return report


def _markdown(r: dict[str, Any]) -> str:
    lines = ["# Our model against the paper's published values", ""]
    lines.append(f"Model mesh: {dumps(r['model']['mesh'], indent=None)}; μ = {r['model']['mu']:g}.")
    lines.append("")
    lines.append("| Δr mm | Fg N | η paper | η model | error |")
    lines.append("|---|---|---|---|---|")
    for c in r["compare_table1"]["cases"] + r["compare_test_point"]["cases"]:
        err = c["eta_error"]
        lines.append(
            f"| {c['clearance_mm']:g} | {c['amplitude_N']:g} | {c['eta_paper']:.4f} | "
            f"{c['eta_model']:.5f} | {'—' if err is None else f'{err:+.0%}'} |"
        )
    for label in ("diagnose_zero_clearance", "diagnose_3x3"):
        d = r[label]
        lines += ["", f"## {label}", "", f"verdict: **{d['verdict']}** — {d['message']}", ""]
        lines += [f"- {w}" for w in d["pattern"]]
        for c in d["candidates"]:
            lines.append(
                f"- {c['name']}: {c['param']} = {c['value']:.3g} {c['unit']}, χ² {c['chi2']:.1f} "
                f"(baseline {d['chi2_base']:.1f}, noise limit {d['chi2_noise_limit']:.1f})"
            )
    lines.append("")
    lines.append(f"wall time {r['wall_s']:.0f} s")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Command line entry: ``python -m studies.paper.validation --out DIR [--quick]``.

    ``--workers N`` / ``--scheduler ADDRESS`` run the cycles on Dask; every cycle is kept
    in ``DIR/results``, so a rerun reads them back.
    """
    from studies.cluster_options import add_cluster_arguments, model_service

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True, metavar="DIR")
    p.add_argument("--quick", action="store_true", help="coarse mesh (the tests' model)")
    add_cluster_arguments(p)
    typed = list(sys.argv[1:] if argv is None else argv)
    args = p.parse_args(typed)
    with model_service(args, args.out / "results") as service:
        report = run(args.out, args.quick, service)
    from studies.outputs import record_command

    record_command(args.out, typed, 0, ("python", "-m", "studies.paper.validation"))
    print((args.out / "report.md").read_text())
    print(f"report in {args.out}/report.json ({report['wall_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
