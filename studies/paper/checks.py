"""The paper's checks beyond its tables: the η = 0.05 map, (η, θ), the 400 N validation points.

* ``threshold_comparison`` — the paper's Fig. 14 / Sec. V.A: where each hinge's surface
  lies below η = 0.05, ours beside the paper's own (its Tables 1 and 4 refitted at degree
  4, ``rsm.paper.fit_paper_table``, which reproduces its printed coefficients), the smallest
  clearance with η < 0.05 against the text's 0.2248 mm and its fit's 0.157 mm, and one
  figure with both hinges, the regions marked (``current_threshold``: read back on a
  rerun whose surfaces are the same).
* ``repeatability_pairs`` — Table 7: θ = arcsin(6σ/L) from the paper's measured σ
  (``validation.repeatability.theta_from_sigma``) beside the printed θ, the paper's η
  beside ours at the point Table 7's η stands for (``rsm.paper_printed.TABLE7_POINT``), and
  what two hinges can show about η against θ (a direction, no correlation).
* ``validation_points`` — the paper's FE and test values at 400 N (its Figs. 5 and 10:
  δ(+Fg) and η of each hinge) beside ours at the same point of our sweeps. The general
  hinge's specimen clearance is not printed; its FE η there (0.0891) sits next to Table 1's
  Δr = 0 entry (0.0895), so Δr = 0 is taken (as ``studies.paper.validation`` does); the
  modified hinge's is F_p = 0.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

ETA_LEVEL = 0.05
"""The paper's design target (``rsm.paper_printed.ETA_THRESHOLD``)."""


def _region_summary(region: Any, x_names: tuple[str, str]) -> dict[str, Any]:
    empty = not np.any(region.mask)
    return {
        "fraction_below": float(region.area_fraction),
        "n_parts": int(region.n_parts),
        "range": None
        if empty
        else {x_names[i]: [float(region.lower[i]), float(region.upper[i])] for i in range(2)},
    }


def threshold_comparison(
    surfaces: Mapping[str, Any], out: Path, figure: str = "figures/eta_0.05_both_hinges.png"
) -> dict[str, Any]:
    """Map η < 0.05 for both hinges, ours and the paper's, and draw them side by side.

    Args:
        surfaces: Hinge (``general``, ``modified``) → our fitted ``rsm`` surface, or None
            where a hinge has too few points for a surface.
        out: The study folder (the figure goes under it).
        figure: Path of the figure, relative to ``out``.

    Returns:
        Per hinge: ours and the paper's region (share of the design box below 0.05, number
        of pieces, variable ranges inside); for the general hinge the smallest clearance
        with η < 0.05 (ours, the paper's fit, the paper's text); and the figure's path.
    """
    from rsm.paper import fit_paper_table
    from rsm.paper_printed import GENERAL, MODIFIED, PRINTED_CLEARANCE_FOR_THRESHOLD_MM
    from rsm.query import threshold_region

    result: dict[str, Any] = {}
    regions: dict[str, tuple[Any, Any]] = {}
    for name, case in (("general", GENERAL), ("modified", MODIFIED)):
        paper_region = threshold_region(fit_paper_table(case), ETA_LEVEL)
        ours = surfaces.get(name)
        our_region = None if ours is None else threshold_region(ours, ETA_LEVEL)
        regions[name] = (our_region, paper_region)
        result[name] = {
            "ours": None if our_region is None else _region_summary(our_region, case.x_names),
            "paper_fit": _region_summary(paper_region, case.x_names),
        }
    ours_g, paper_g = regions["general"]
    result["general"]["smallest_clearance_mm"] = {
        "ours": None if ours_g is None or not np.any(ours_g.mask) else float(ours_g.lower[0]),
        "paper_fit": float(paper_g.lower[0]),
        "paper_text": PRINTED_CLEARANCE_FOR_THRESHOLD_MM,
    }
    path = out / figure
    _draw(regions, path)
    result["figure"] = figure
    return result


def current_threshold(
    surfaces: Mapping[str, Any], out: Path, figure: str = "figures/eta_0.05_both_hinges.png"
) -> dict[str, Any]:
    """``threshold_comparison``, read back from ``out/figures/.threshold.json`` on a rerun.

    The map costs about a second (the paper's fits, the regions, the figure) and depends
    only on the surfaces: their coefficients, scaling and names, the figure's path and the
    package version are hashed into the stamp, written after the figure, which a rerun with
    the same hash and the figure present returns as it is. Arguments as
    ``threshold_comparison``.
    """
    import json

    from model.code import ALL_PACKAGES, code_version
    from model.jsonio import dumps
    from model.spec import content_hash

    inputs = {
        name: None
        if s is None
        else [list(s.x_names), s.coefficients.tolist(), s.center.tolist(), s.half_range.tolist()]
        for name, s in sorted(surfaces.items())
    }
    digest = content_hash(
        {"surfaces": inputs, "figure": figure, "code": code_version(ALL_PACKAGES)}
    )
    stamp = out / "figures" / ".threshold.json"
    try:
        old = json.loads(stamp.read_text())
    except (OSError, ValueError):
        old = {}
    if old.get("inputs") == digest and (out / figure).is_file():
        return dict(old["result"])
    result = threshold_comparison(surfaces, out, figure)
    stamp.parent.mkdir(parents=True, exist_ok=True)
    tmp = stamp.with_suffix(".tmp")
    tmp.write_text(dumps({"inputs": digest, "result": result}))
    tmp.replace(stamp)
    back: dict[str, Any] = json.loads(dumps(result))  # as a rerun reads it (NaN: null)
    return back


def _draw(regions: Mapping[str, tuple[Any, Any]], path: Path) -> None:
    """Two panels (general, modified): our η map, the region below 0.05 hatched, both boundaries."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from rsm.plots import DPI, axis_label

    fig = Figure(figsize=(11.0, 4.6), dpi=DPI, layout="constrained")
    axes = fig.subplots(1, 2)
    titles = {"general": "general hinge (Δr × F_g)", "modified": "modified hinge (F_p × F_g)"}
    for ax, (name, (ours, paper)) in zip(axes, regions.items(), strict=True):
        shown = ours if ours is not None else paper
        X, Y = np.meshgrid(shown.grid_x, shown.grid_y)
        if ours is not None:
            im = ax.contourf(X, Y, ours.values, levels=14, cmap="viridis")
            fig.colorbar(im, ax=ax, label="η ours [–]")
            if np.any(ours.mask):
                ax.contourf(X, Y, ours.mask.astype(float), levels=[0.5, 1.5], colors="none",
                            hatches=["//"])  # fmt: skip
            if ours.values.min() < ETA_LEVEL < ours.values.max():
                ax.contour(X, Y, ours.values, levels=[ETA_LEVEL], colors="white", linewidths=2.0)
        Xp, Yp = np.meshgrid(paper.grid_x, paper.grid_y)
        ax.contour(Xp, Yp, paper.values, levels=[ETA_LEVEL], colors="crimson",
                   linestyles="--", linewidths=2.0)  # fmt: skip
        ax.contourf(Xp, Yp, paper.mask.astype(float), levels=[0.5, 1.5], colors="crimson",
                    alpha=0.18)  # fmt: skip
        frac_o = "–" if ours is None else f"{100 * ours.area_fraction:.0f} %"
        ax.set_title(
            f"{titles[name]}\nη < 0.05 on {frac_o} of the box (ours), "
            f"{100 * paper.area_fraction:.0f} % (paper's surface)",
            fontsize=10,
        )
        ax.set_xlabel(axis_label(shown.x_names[0]))
        ax.set_ylabel(axis_label(shown.x_names[1]))
    handles = [
        Patch(facecolor="none", hatch="//", edgecolor="black", label="η < 0.05, ours"),
        Line2D([], [], color="white", lw=2.0, label="η = 0.05, ours (where crossed)"),
        Patch(facecolor="crimson", alpha=0.18, label="η < 0.05, paper's surface"),
        Line2D([], [], color="crimson", ls="--", lw=2.0, label="η = 0.05, paper's surface"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncols=4, fontsize=9,
               facecolor="0.85")  # fmt: skip
    fig.suptitle("Where η < 0.05 (the paper's Fig. 14): our FE against the paper's surfaces")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)


def read_table7(path: Path) -> dict[str, dict[str, float]]:
    """Read Table 7 (hinge, eta, sigma_um, L_mm, theta_rad) as hinge → column → value."""
    with path.open(newline="", encoding="utf-8") as f:
        return {
            r["hinge"]: {k: float(v) for k, v in r.items() if k != "hinge"}
            for r in csv.DictReader(f)
        }


def repeatability_pairs(eta_ours: Mapping[str, float | None]) -> dict[str, Any]:
    """(η, θ) per hinge: the paper's Table 7 and ours, and what two points show.

    Args:
        eta_ours: Hinge → our η at ``rsm.paper_printed.TABLE7_POINT`` (None if not run).

    Returns:
        ``rows`` (per hinge: σ, L, θ recomputed and printed, η printed and ours),
        ``direction`` for the paper's and our η, and ``note``.
    """
    from rsm.paper_printed import TABLE7_POINT, paper_table_path
    from validation.repeatability import theta_from_sigma

    with paper_table_path("paper_table7_repeatability.csv") as p:
        table = read_table7(p)
    rows: list[dict[str, Any]] = []
    for hinge, t in table.items():
        theta = theta_from_sigma(t["sigma_um"] * 1e-3, t["L_mm"])
        rows.append(
            {
                "hinge": hinge,
                "sigma_um": t["sigma_um"],
                "L_mm": t["L_mm"],
                "theta_rad": theta,
                "theta_rad_table7": t["theta_rad"],
                "eta_table7": t["eta"],
                "eta_ours": eta_ours.get(hinge),
                "eta_ours_at": list(TABLE7_POINT[hinge]),
            }
        )
    by = {r["hinge"]: r for r in rows}
    g, m = by["general"], by["modified"]

    def direction(key: str) -> dict[str, Any] | None:
        eg, em = g[key], m[key]
        if eg is None or em is None or eg == em:
            return None
        return {
            "eta_change": 1.0 - em / eg,
            "theta_change": 1.0 - m["theta_rad"] / g["theta_rad"],
            "same_direction": bool((em < eg) == (m["theta_rad"] < g["theta_rad"])),
        }

    note = (
        "Two hinges are two points: a line through them always fits (|r| = 1 by construction), "
        "so they show a direction — the hinge with the smaller η has the smaller θ, or not — "
        "and no correlation, significance or slope uncertainty. θ is the paper's measurement "
        "(we have no readings of our own); only η is ours."
    )
    return {
        "rows": rows,
        "direction_paper": direction("eta_table7"),
        "direction_ours": direction("eta_ours"),
        "note": note,
    }


VALIDATED_AT = {"general": "Δr 0 (assumed)", "modified": "F_p 0"}
"""Where the paper's validation point of each case sits, in words."""

VALIDATION_AT = {"general": ("clearance_mm", 0.0, 400.0), "modified": ("preload_N", 0.0, 400.0)}
"""Hinge → (design variable, its value, amplitude [N]) of the paper's 400 N validation point."""


def validation_points(tables: Mapping[str, Path]) -> list[dict[str, Any]]:
    """The paper's 400 N validation values beside ours (None where our sweep lacks the point).

    Args:
        tables: Hinge → our sweep's ``table.csv``.
    """
    from rsm.paper_printed import paper_table_path

    with paper_table_path("paper_validation_points.csv") as p, p.open(newline="") as f:
        printed = list(csv.DictReader(f))
    out = []
    for hinge, (var, x, amp) in VALIDATION_AT.items():
        ours: dict[str, float] = {}
        table = tables.get(hinge)
        if table is not None and table.is_file():
            with table.open(newline="", encoding="utf-8") as f:
                for r in csv.DictReader(f):
                    if r.get("status", "ok") == "ok" and (
                        float(r[var]),
                        float(r["amplitude_N"]),
                    ) == (x, amp):
                        ours = {
                            "displacement_at_peak": float(r["disp_at_peak_mm"]),
                            "eta": float(r["eta"]),
                        }
        for row in printed:
            if row["hinge"] != hinge:
                continue
            q = row["quantity"]
            out.append(
                {
                    "hinge": hinge,
                    var: x,
                    "amplitude_N": amp,
                    "quantity": q,
                    "unit": row["unit"],
                    "paper_fe": float(row["fe_value"]),
                    "paper_test": float(row["test_value"]),
                    "ours": ours.get(q),
                }
            )
    return out


def markdown(
    threshold: Mapping[str, Any] | None,
    pairs: Mapping[str, Any] | None,
    points: list[dict[str, Any]] | None = None,
) -> list[str]:
    """The report's sections for the three checks."""
    lines: list[str] = []
    if points:
        lines += [
            "",
            "## The 400 N validation points (the paper's Figs. 5 and 10)",
            "",
            "| hinge | at | quantity | paper FE | paper test | ours | ours / test |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in points:
            at = VALIDATED_AT[r["hinge"]]
            ours = "not run" if r["ours"] is None else f"{r['ours']:.4g}"
            ratio = "–" if r["ours"] is None else f"{r['ours'] / r['paper_test']:.2f}"
            lines.append(
                f"| {r['hinge']} | {at}, {r['amplitude_N']:g} N | {r['quantity']} [{r['unit']}] "
                f"| {r['paper_fe']:g} | {r['paper_test']:g} | {ours} | {ratio} |"
            )
        lines += [
            "",
            "The general specimen's clearance is not printed (its FE η 0.0891 sits by Table 1's "
            "Δr = 0 value 0.0895, so Δr = 0 is taken). Our hinges are stiffer and dissipate less "
            "than the paper's specimens; the causes are those under “Why ours differs”.",
        ]
    if threshold:
        sc = threshold["general"]["smallest_clearance_mm"]
        ours_c = sc["ours"]
        ours_text = "nowhere in the box" if ours_c is None else f"{ours_c:.3f} mm"
        lines += [
            "",
            "## Where η < 0.05 (the paper's Fig. 14)",
            "",
            "| hinge | η < 0.05 on (ours) | pieces | η < 0.05 on (paper's surface) | pieces |",
            "|---|---|---|---|---|",
        ]
        for name in ("general", "modified"):
            o, p = threshold[name]["ours"], threshold[name]["paper_fit"]
            o_frac = "–" if o is None else f"{100 * o['fraction_below']:.0f} %"
            o_parts = "–" if o is None else str(o["n_parts"])
            lines.append(
                f"| {name} | {o_frac} | {o_parts} | {100 * p['fraction_below']:.0f} % | "
                f"{p['n_parts']} |"
            )
        ours_g = threshold["general"]["ours"]
        if ours_g is not None and ours_g["fraction_below"] == 1.0:
            why = (
                " Our general hinge's η stays below 0.05 in the whole box, because it lies far "
                "below Table 1 (above): there is no boundary to compare — a consequence of the "
                "dissipation our model lacks, not a finding about the design."
            )
        else:
            why = ""
        lines += [
            "",
            f"Smallest clearance with η < 0.05 (general hinge): ours {ours_text} (Δr = 0 means "
            f"everywhere in the box); the paper's surface {sc['paper_fit']:.3f} mm; the "
            f"paper's text {sc['paper_text']} mm.{why}",
            "",
            f"![η = 0.05 map]({threshold['figure']})",
        ]
    if pairs:
        lines += [
            "",
            "## Repeatability and η (Table 7)",
            "",
            "| hinge | σ µm | L mm | θ = arcsin(6σ/L) rad | θ Table 7 | η Table 7 | η ours (at) |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in pairs["rows"]:
            at = r["eta_ours_at"]
            eta = "–" if r["eta_ours"] is None else f"{r['eta_ours']:.4f}"
            lines.append(
                f"| {r['hinge']} | {r['sigma_um']:g} | {r['L_mm']:g} | {r['theta_rad']:.5e} | "
                f"{r['theta_rad_table7']:.4e} | {r['eta_table7']:.4f} | {eta} ({at[0]:g}, "
                f"{at[1]:g} N) |"
            )
        for who, key in (("the paper's η", "direction_paper"), ("our η", "direction_ours")):
            d = pairs[key]
            if d is None:
                continue
            lines.append(
                f"\nWith {who}: η falls by {100 * d['eta_change']:.1f} % and θ by "
                f"{100 * d['theta_change']:.1f} % from the general to the modified hinge — "
                f"{'the same' if d['same_direction'] else 'opposite'} direction."
            )
        lines += ["", pairs["note"]]
    return lines
