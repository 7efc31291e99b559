"""``hingelab repeatability``: the repeatability θ of hinges from repeated position readings.

``hingelab repeatability READINGS.csv --length-mm 25 --out DIR [--json] [--eta ETA]
[--hinges TABLE.csv] [--label NAME] [--unit um|mm] [--confidence 0.95]`` reads the
readings (``validation.repeatability.read_readings``: a ``reading_um`` or
``reading_mm`` column, or one column in ``--unit``; an optional ``hinge`` column),
fits a normal law per hinge, tests normality (Shapiro–Wilk, Anderson–Darling), takes
θ = arcsin(6σ/L) [rad] with intervals, relates η to θ when η is given, and writes into
DIR: ``repeatability.json``, ``repeatability.csv`` (one row per hinge),
``histogram_<hinge>.png`` and, with η for two or more hinges, ``eta_theta.png``.

η comes from ``--eta`` (a number for a file with one hinge, or
``NAME=VALUE[,NAME=VALUE…]``) or from ``--hinges``, a CSV with columns ``hinge, eta``
(the paper's ``paper_table7_repeatability.csv`` is one).
"""

from __future__ import annotations

import argparse
import csv
import math
import re
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from cad.errors import DataError, ParameterError, check_range
from model.jsonio import dumps
from validation import repeatability as rp

UM_PER_MM = 1e3
EQ14_NOTE = (
    "Eq. 14 as printed, arcsin(6σ/L)/180·π, gives 57.3× smaller angles than Table 7 when arcsin "
    "is in radians; Table 7's numbers follow θ = arcsin(6σ/L) in radians (σ = 1.0942 µm, L = 25 mm "
    "→ 2.62608e-4 rad), which is what is computed here."
)


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``repeatability`` subcommand."""
    p = sub.add_parser(
        "repeatability",
        help="repeatability θ = arcsin(6σ/L) from repeated position readings; η–θ correlation",
        description=__doc__.splitlines()[0] if __doc__ else None,
    )
    p.add_argument("readings", type=Path, metavar="READINGS.csv", help="position readings l")
    p.add_argument(
        "--length-mm", type=float, required=True, metavar="L", help="axis-to-sensor distance [mm]"
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument("--json", action="store_true", help="print repeatability.json")
    p.add_argument(
        "--eta",
        default=None,
        metavar="ETA",
        help="loss factor: a number, or NAME=VALUE,... (default: none, no η correlation)",
    )
    p.add_argument(
        "--hinges",
        type=Path,
        default=None,
        metavar="TABLE.csv",
        help="a table of hinge, eta (default: none)",
    )
    p.add_argument(
        "--label",
        default=None,
        metavar="NAME",
        help="hinge name if the file has no hinge column (default: the file's stem)",
    )
    p.add_argument(
        "--unit",
        choices=[u.value for u in rp.ReadingUnit],
        default=None,
        help="unit of a reading column not named reading_um / reading_mm (default: from the column name)",
    )
    p.add_argument(
        "--confidence",
        type=float,
        default=0.95,
        metavar="C",
        help="interval coverage (default 0.95)",
    )
    p.set_defaults(func=run)


def parse_eta(text: str, hinges: list[str]) -> dict[str, float]:
    """Parse ``--eta``: a number (one hinge only) or ``NAME=VALUE[,NAME=VALUE…]``.

    Raises:
        ParameterError: Naming the bad item, an unknown hinge, or η outside [0, inf).
    """
    items = [t.strip() for t in text.split(",") if t.strip()]
    if len(items) == 1 and "=" not in items[0]:
        if len(hinges) != 1:
            raise ParameterError(
                f"--eta {text!r}: one number needs a file with one hinge, this one has "
                f"{len(hinges)} ({', '.join(hinges)}); give NAME=VALUE,..."
            )
        items = [f"{hinges[0]}={items[0]}"]
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = (s.strip() for s in item.partition("="))
        try:
            if not (sep and name):
                raise ValueError(item)
            out[name] = float(value)
        except ValueError:
            raise ParameterError(f"--eta: {item!r} is not NAME=NUMBER") from None
        check_range(f"--eta {name}", out[name], 0.0, math.inf, hi_open=True)
    return out


def read_eta_table(path: Path) -> dict[str, float]:
    """Read ``--hinges``: a CSV with columns ``hinge`` and ``eta`` (others are ignored).

    Raises:
        DataError: Missing file or column, a bad number or a repeated hinge (naming the line).
        ParameterError: η outside [0, inf).
    """
    rows = rp.read_csv_rows(path)
    header = rows[0][1]
    if "hinge" not in header or "eta" not in header:
        raise DataError(f"{path}: a hinge table needs columns hinge and eta; columns are {header}")
    out: dict[str, float] = {}
    for line, cells in rows[1:]:
        if len(cells) != len(header):
            raise DataError(
                f"{path}: line {line} has {len(cells)} fields, the header has {len(header)}"
            )
        name, text = cells[header.index("hinge")], cells[header.index("eta")]
        if name in out:
            raise DataError(f"{path}: line {line}, column hinge: {name!r} appears twice")
        try:
            out[name] = float(text)
        except ValueError:
            raise DataError(f"{path}: line {line}, column eta: not a number: {text!r}") from None
        check_range(
            f"eta of hinge {name!r} ({path}, line {line})", out[name], 0.0, math.inf, hi_open=True
        )
    return out


def safe_name(hinge: str) -> str:
    """Return ``hinge`` reduced to letters, digits, ``-``, ``_`` and ``.`` for a file name."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", hinge).strip("._") or "hinge"


def _scaled(value: float | None, factor: float) -> float | None:
    return None if value is None else value * factor


def _test_dict(t: rp.NormalityTest) -> dict[str, Any]:
    keys = ("statistic", "p_value", "critical_value", "alpha", "rejects_normal", "verdict")
    return {k: getattr(t, k) for k in keys}


def result_as_dict(r: rp.Repeatability) -> dict[str, Any]:
    """Return one hinge's result as JSON-ready values (σ in µm, L in mm, θ in rad; no NaN)."""
    res, um = r.resolution, UM_PER_MM
    coarse_note = (
        f"readings are rounded to {res.step_mm * um:.3g} µm = {res.step_mm / r.sigma_mm:.2f} σ: "
        "normality tests reject normal data rounded this coarsely, so a rejection says little"
    )
    return {
        "hinge": r.hinge,
        "n": r.n,
        "mean_um": r.mean_mm * um,
        "sigma_um": r.sigma_mm * um,
        "sigma_estimator": "maximum likelihood, scipy.stats.norm.fit (ddof = 0)",
        "sigma_ci_um": {"lo": r.sigma_ci_mm.lo * um, "hi": _scaled(r.sigma_ci_mm.hi, um)},
        "six_sigma_um": 6.0 * r.sigma_mm * um,
        "length_mm": r.length_mm,
        "theta_rad": r.theta_rad,
        "theta_ci_rad": {
            "lo": r.theta_ci_rad.lo,
            "hi": r.theta_ci_rad.hi,
            "hi_reason": r.theta_ci_rad.reason,
        },
        "shapiro_wilk": _test_dict(r.shapiro),
        "anderson_darling": _test_dict(r.anderson),
        "resolution": {
            "n_distinct": res.n_distinct,
            "step_um": res.step_mm * um,
            "step_over_sigma": res.step_mm / r.sigma_mm,
            "coarse": res.coarse,
            "note": coarse_note if res.coarse else None,
        },
        "eta": r.eta,
    }


def correlation_as_dict(c: rp.Correlation) -> dict[str, Any]:
    """Return the η–θ correlation as JSON-ready values (None where a number does not exist)."""
    change = c.relative_change
    return {
        "hinges": list(c.hinges),
        "eta": c.eta.tolist(),
        "theta_rad": c.theta_rad.tolist(),
        "n_points": len(c.hinges),
        "slope_rad": c.slope_rad,
        "slope_stderr_rad": c.slope_stderr_rad,
        "pearson_r": c.r,
        "p_value": c.p_value,
        "relative_change": None if change is None else {"eta": change[0], "theta": change[1]},
        "note": c.note,
    }


def summary_row(r: rp.Repeatability) -> dict[str, Any]:
    """Return one hinge's row of ``repeatability.csv`` (None for a missing value)."""
    d = result_as_dict(r)
    return {
        "hinge": r.hinge,
        "n": r.n,
        "mean_um": d["mean_um"],
        "sigma_um": d["sigma_um"],
        "sigma_lo_um": d["sigma_ci_um"]["lo"],
        "sigma_hi_um": d["sigma_ci_um"]["hi"],
        "six_sigma_um": d["six_sigma_um"],
        "length_mm": r.length_mm,
        "theta_rad": r.theta_rad,
        "theta_lo_rad": r.theta_ci_rad.lo,
        "theta_hi_rad": r.theta_ci_rad.hi,
        "confidence": r.sigma_ci_mm.confidence,
        "shapiro_w": r.shapiro.statistic,
        "shapiro_p": r.shapiro.p_value,
        "shapiro_rejects": r.shapiro.rejects_normal,
        "ad_a2": r.anderson.statistic,
        "ad_critical_5pct": r.anderson.critical_value,
        "ad_p": r.anderson.p_value,
        "ad_rejects": r.anderson.rejects_normal,
        "step_um": d["resolution"]["step_um"],
        "coarse_rounding": r.resolution.coarse,
        "eta": r.eta,
    }


def write_summary_csv(results: tuple[rp.Repeatability, ...], path: Path) -> Path:
    """Write one row per hinge; a missing value is an empty cell."""
    rows = [summary_row(r) for r in results]
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows({k: "" if v is None else v for k, v in row.items()} for row in rows)
    return path


def plot_histogram(readings: rp.Readings, r: rp.Repeatability, path: Path) -> Path:
    """Draw the readings' histogram [µm] with the fitted normal curve and μ ± 3σ into a PNG.

    Rounded readings get one bar per value, so that the bins do not alias the step.
    """
    from matplotlib.figure import Figure  # imported here: `hingelab --help` stays fast
    from scipy import stats

    x = readings.position_mm * UM_PER_MM
    mu, sigma = r.mean_mm * UM_PER_MM, r.sigma_mm * UM_PER_MM
    step = r.resolution.step_mm * UM_PER_MM
    edges = np.histogram_bin_edges(x, "auto")
    if r.resolution.coarse or r.resolution.n_distinct <= 100:
        width = step * max(1, round(float(edges[1] - edges[0]) / step))  # a multiple of the step
        edges = np.arange(x.min() - step / 2, x.max() + width, width)
    fig = Figure(figsize=(7.0, 4.8), layout="constrained")
    ax = fig.subplots()
    ax.hist(
        x, bins=list(edges), color="0.78", edgecolor="0.35", lw=0.6, label=f"readings, n = {r.n}"
    )
    grid = np.linspace(min(x.min(), mu - 4 * sigma), max(x.max(), mu + 4 * sigma), 400)
    width = float(np.mean(np.diff(edges)))
    pdf = r.n * width * stats.norm.pdf(grid, mu, sigma)  # counts per bin
    ax.plot(grid, pdf, color="C3", lw=2.0, label="fitted normal (scaled to counts)")
    for k in (-3, 3):
        label = "μ ± 3σ (6σ = position error)" if k < 0 else None
        ax.axvline(mu + k * sigma, color="C0", ls="--", lw=1.0, label=label)
    ci, th = r.sigma_ci_mm, r.theta_ci_rad
    sig_hi = "n/a" if ci.hi is None else f"{ci.hi * UM_PER_MM:.4g}"
    th_hi = "n/a" if th.hi is None else f"{th.hi:.4e}"
    lines = [
        f"μ = {mu:.4g} µm, σ = {sigma:.4g} µm, {100 * ci.confidence:g} % interval "
        f"[{ci.lo * UM_PER_MM:.4g}, {sig_hi}] µm",
        f"θ = arcsin(6σ/L) = {r.theta_rad:.4e} rad [{th.lo:.4e}, {th_hi}], L = {r.length_mm:g} mm",
        f"Shapiro–Wilk: {r.shapiro.verdict}",
        f"Anderson–Darling: {r.anderson.verdict}",
    ]
    if r.resolution.coarse:
        lines.append(
            f"rounded to {step:.3g} µm = {step / sigma:.2f} σ: the tests reject rounded normal data"
        )
    ax.text(
        0.01, 0.99, "\n".join(lines), transform=ax.transAxes, va="top", fontsize=7.5,
        bbox={"boxstyle": "round", "fc": "white", "ec": "0.7", "alpha": 0.9},
    )  # fmt: skip
    ax.set_ylim(0, ax.get_ylim()[1] * 1.6)  # room for the text above the bars
    ax.set_xlabel("reading l [µm]")
    ax.set_ylabel("number of readings")
    ax.set_title(f"hinge {r.hinge}: repeated position readings")
    ax.legend(loc="upper right", fontsize=7.5)
    fig.savefig(path, dpi=110)
    return path


def plot_eta_theta(results: tuple[rp.Repeatability, ...], c: rp.Correlation, path: Path) -> Path:
    """Draw θ (with its interval) against η per hinge, and the line through them, into a PNG."""
    from matplotlib.figure import Figure  # imported here: `hingelab --help` stays fast

    fig = Figure(figsize=(6.4, 4.8), layout="constrained")
    ax = fig.subplots()
    by_name = {r.hinge: r for r in results}
    for name, eta, theta in zip(c.hinges, c.eta, c.theta_rad, strict=True):
        ci = by_name[name].theta_ci_rad
        up = (ci.hi if ci.hi is not None else theta) - theta
        ax.errorbar([eta], [theta], yerr=[[theta - ci.lo], [up]], fmt="o", capsize=4, color="C0")
        ax.annotate(name, (eta, theta), textcoords="offset points", xytext=(6, 4), fontsize=9)
    if c.slope_rad is not None:
        e = np.linspace(float(c.eta.min()), float(c.eta.max()), 50)
        line = float(c.theta_rad.mean()) + c.slope_rad * (e - float(c.eta.mean()))
        label = (
            "line through the 2 points (exact by construction)"
            if c.r is None
            else f"least squares, r = {c.r:.3f}, p = {c.p_value:.3g}"
        )
        ax.plot(e, line, "--", color="C3", lw=1.0, label=label)
        ax.legend(loc="upper left", fontsize=8)
    ax.set_xlim(left=0.0)
    ax.set_ylim(bottom=0.0)
    ax.ticklabel_format(axis="y", style="sci", scilimits=(0, 0))
    ax.set_xlabel("loss factor η [-]")
    pct = 100 * results[0].theta_ci_rad.confidence
    ax.set_ylabel(f"repeatability θ [rad] (bars: {pct:g} % interval)")
    ax.set_title("\n".join(textwrap.wrap(c.note, 95)), fontsize=8)
    fig.savefig(path, dpi=110)
    return path


def _eta_for(args: argparse.Namespace, hinges: list[str]) -> dict[str, float]:
    if args.eta is not None and args.hinges is not None:
        raise ParameterError("give η by --eta or by --hinges, not both")
    if args.eta is not None:
        eta = parse_eta(args.eta, hinges)
        unknown = sorted(set(eta) - set(hinges))
        if unknown:
            raise ParameterError(
                f"--eta names hinge(s) {unknown} not in {args.readings} (hinges: {hinges})"
            )
        return eta
    return {} if args.hinges is None else read_eta_table(args.hinges)


def _text_report(doc: dict[str, Any]) -> str:
    out = []
    for h in doc["hinges"]:
        s, t = h["sigma_ci_um"], h["theta_ci_rad"]
        t_hi = "n/a" if t["hi"] is None else f"{t['hi']:.4e}"
        eta = "" if h["eta"] is None else f", η = {h['eta']:g}"
        out += [
            f"hinge {h['hinge']}: n = {h['n']}, σ = {h['sigma_um']:.4f} µm [{s['lo']:.4f}, "
            f"{s['hi']:.4f}], 6σ = {h['six_sigma_um']:.3f} µm, θ = {h['theta_rad']:.4e} rad "
            f"[{t['lo']:.4e}, {t_hi}] ({100 * doc['confidence']:g} %){eta}",
            f"  Shapiro–Wilk: {h['shapiro_wilk']['verdict']}",
            f"  Anderson–Darling: {h['anderson_darling']['verdict']}",
        ]
        if h["resolution"]["note"]:
            out.append(f"  note: {h['resolution']['note']}")
    corr = doc["correlation"]
    out.append(f"η–θ: {corr['note'] if corr else doc['correlation_reason']}")
    out.append(f"files: {', '.join(doc['files'].values())}")
    return "\n".join(out)


def run(args: argparse.Namespace) -> int:
    """Run ``hingelab repeatability``."""
    check_range("--length-mm", args.length_mm, 0.0, math.inf, lo_open=True, hi_open=True)
    check_range("--confidence", args.confidence, 0.0, 1.0, lo_open=True, hi_open=True)
    unit = None if args.unit is None else rp.ReadingUnit(args.unit)
    groups = rp.read_readings(args.readings, unit=unit, label=args.label)
    names = [g.hinge for g in groups]
    if len({safe_name(n) for n in names}) != len(names):
        raise DataError(f"{args.readings}: hinge names {names} collide as file names")
    eta = _eta_for(args, names)
    results = tuple(
        rp.analyse_readings(g, args.length_mm, confidence=args.confidence, eta=eta.get(g.hinge))
        for g in groups
    )
    corr = rp.correlate(results)
    args.out.mkdir(parents=True, exist_ok=True)
    files = {"json": args.out / "repeatability.json", "csv": args.out / "repeatability.csv"}
    for g, r in zip(groups, results, strict=True):
        files[f"histogram {r.hinge}"] = plot_histogram(
            g, r, args.out / f"histogram_{safe_name(r.hinge)}.png"
        )
    if corr is not None:
        files["eta_theta"] = plot_eta_theta(results, corr, args.out / "eta_theta.png")
    n_eta = sum(r.eta is not None for r in results)
    doc = {
        "label": args.label or args.readings.stem,
        "readings_file": str(args.readings),
        "length_mm": args.length_mm,
        "confidence": args.confidence,
        "normality_alpha": rp.NORMALITY_ALPHA,
        "formula": "theta_rad = arcsin(6 sigma / L); sigma from scipy.stats.norm.fit",
        "eq14_note": EQ14_NOTE,
        "hinges": [result_as_dict(r) for r in results],
        "correlation": None if corr is None else correlation_as_dict(corr),
        "correlation_reason": None if corr else f"needs η for at least 2 hinges, got {n_eta}",
        "files": {k: str(v) for k, v in files.items()},
    }
    text = dumps(doc)
    files["json"].write_text(text + "\n", encoding="utf-8")
    write_summary_csv(results, files["csv"])
    print(text if args.json else _text_report(doc))
    return 0
