"""Sections of the HTML report for a load cycle, and what every report body is made of.

Each ``*_report`` function reads one kind of result folder and returns a
:class:`ReportBody`: what was run (name → value pairs) and the page's sections.
Nothing here writes files; the page is assembled by ``studies.report.page``; a sweep's
sections are in ``studies.report.sweep``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cad.errors import DataError
from studies.report.parts import (
    Html,
    Section,
    cards,
    figure,
    fmt,
    join,
    kv_table,
    link,
    scroll,
    table,
    tag,
)


@dataclass(frozen=True)
class ReportBody:
    """What a result folder holds, ready for the page.

    Attributes:
        title: Heading of the page.
        run: What was run, as (name, value) pairs.
        sections: The page's sections in order.
    """

    title: str
    run: list[tuple[str, object]]
    sections: list[Section]


def read_json(path: Path) -> Any:
    """Read a JSON file (NaN allowed, as older result files hold it).

    Raises:
        DataError: Naming the file, if it is not valid JSON.
    """
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as err:
        raise DataError(f"{path}: not valid JSON ({err})") from err


def _um(mm: object) -> str:
    return f"{mm * 1e3:.4g} µm" if isinstance(mm, int | float) else "—"


def _float(d: Mapping[str, Any], key: str) -> float | None:
    v = d.get(key)
    return float(v) if isinstance(v, int | float) else None


def _energy(r: Mapping[str, Any]) -> Html:
    """The energy balance of the reported loop: loop area = friction work + ΔU_elastic."""
    w, fric, du = (
        _float(r, k) for k in ("W_cycle_Nmm", "friction_work_Nmm", "elastic_energy_change_Nmm")
    )
    rest = None if w is None or fric is None or du is None else w - fric - du
    return table(
        ["quantity", "value [N·mm]"],
        [
            ["loop area W_cycle = ∮F dδ", w],
            ["friction work (sum over all contact points)", fric],
            ["change of elastic energy over the loop", du],
            ["W_cycle − friction work − ΔU", rest],
            [Html("relative error |W − W<sub>f</sub> − ΔU| / W"), r.get("energy_balance_rel_err")],
        ],
        caption="Energy balance of the reported loop",
    )


def cycle_headline(r: Mapping[str, Any]) -> Html:
    """Headline numbers of one cycle: η, W, U, δ(+Fg), stiffness, free play."""
    k = r.get("secant_stiffness_N_per_mm")
    return cards(
        [
            ("loss factor η = W/(2π U_max)", fmt(r.get("eta"))),
            ("W_cycle [N·mm]", fmt(r.get("W_cycle_Nmm"))),
            ("U_max [N·mm]", fmt(r.get("U_max_Nmm"))),
            ("δ(+Fg)", _um(r.get("disp_at_peak_mm"))),
            ("δ(−Fg)", _um(r.get("disp_at_minus_peak_mm"))),
            ("secant stiffness [N/mm]", fmt(k)),
            ("free play (removed)", _um(r.get("free_play_mm"))),
        ]
    )


def _increments(incs: list[Mapping[str, Any]]) -> Html:
    rows = [
        [
            n,
            i.get("stage"),
            i.get("force_N"),
            i.get("disp_mm"),
            i.get("iterations"),
            i.get("open"),
            i.get("stick"),
            i.get("slip"),
        ]
        for n, i in enumerate(incs, start=1)
    ]
    heads = ["increment", "stage", "force [N]", "δ [mm]", "Newton it.", "open", "stick", "slip"]
    return scroll(table(heads, rows))


def cycle_report(folder: Path, report_dir: Path) -> ReportBody:
    """Read a ``hingelab cycle`` folder (result.json, loop.png, mesh files)."""
    r = read_json(folder / "result.json")
    incs = r.get("increments") or []
    run: list[tuple[str, object]] = [
        ("command", "hingelab cycle (load cycle 0 → +Fg → −Fg → +Fg)"),
        ("hinge", "general hinge"),
        ("radial clearance Δr [mm]", r.get("clearance_mm")),
        ("force amplitude Fg [N]", r.get("amplitude_N")),
        ("friction coefficient μ", r.get("mu")),
        ("increments (all stages)", len(incs)),
        ("mesh", f"{fmt(r.get('n_hex'))} hexahedra, {fmt(r.get('n_dof'))} DOF"),
        (
            "contact points / surface pairs",
            f"{fmt(r.get('n_contact_pairs'))} / {fmt(r.get('n_surface_pairs'))}",
        ),
        ("Newton iterations (total)", r.get("total_iterations")),
        ("wall time [s]", r.get("wall_s")),
    ]
    files = [
        ("STEP geometry", folder / "hinge.step"),
        ("mesh (VTU)", folder / "mesh.vtu"),
        ("mesh (gmsh .msh)", folder / "mesh.msh"),
        ("loop (CSV)", folder / "loop.csv"),
        ("loop (PNG)", folder / "loop.png"),
        ("fields (ParaView .pvd)", folder / "fields" / "cycle.pvd"),
        ("result.json", folder / "result.json"),
    ]
    timings = r.get("timings_s") or {}
    sections = [
        Section(
            "results",
            "Loss factor and loop",
            join(
                [
                    cycle_headline(r),
                    tag("p", r.get("delta_definition", ""), cls="note"),
                    figure(folder / "loop.png", "Force–displacement loop (loop.png)", wide=True),
                ]
            ),
        ),
        Section("energy", "Energy balance", _energy(r)),
        Section(
            "mesh", "Geometry and mesh", figure(folder / "mesh.png", "Mesh (mesh.png)", wide=True)
        ),
        Section(
            "increments",
            "Contact state per increment",
            join(
                [
                    tag(
                        "p",
                        "Contact points open, sticking and slipping after each increment.",
                        cls="note",
                    ),
                    _increments(incs),
                ]
            ),
        ),
        Section(
            "files",
            "Files",
            join(
                [
                    table(["file", "link"], [[lbl, link(p, report_dir)] for lbl, p in files]),
                    kv_table((f"time: {k} [s]", v) for k, v in timings.items()),
                ]
            ),
        ),
    ]
    return ReportBody("Load cycle", run, sections)
