"""Fit the reduced-order joint (``fe.joint``) to the FE loops of one hinge design.

Input: a sweep, study or cycle folder whose ``points/*/`` hold ``result.json`` and
``loop.csv`` (``studies.sweep_points``), or one cycle folder (``result.json`` and
``loop.csv`` side by side). Points are grouped by their design values other than the
amplitude (a group = one design: one clearance of the general hinge, one preload of the
bearing hinge); each group gets one element, fitted over its amplitudes.

The fit (``scipy.optimize.least_squares``) drives the element through each FE loop's
force history (force control, the virgin loading included) and minimises, over the
points, the loop's displacement misfit (per sample, scaled by δ_max) together with the
relative misfits of the measures the targets name: δ(+Fg), δ(−Fg) and W_cycle. The
parameters are k₊, k₋, the bank's stiffness k_b (split evenly between its elastic path
and its branches: k∞ = k_slip = k_b/2, which keeps the bank's tangent positive and the
fit free of a direction the loops cannot resolve), the load-proportional slip ratio λ
and the fixed slip force F_s. The free play is not fitted: it is the geometry's, the FE's
``free_play_mm`` (4Δr for the general hinge), which the FE's loops have removed.
Uncertainties are 1σ from the Jacobian at the optimum, cov = s²(JᵀJ)⁻¹ with
s² = ‖r‖²/(m − n) (a misfit-scaled standard error, not a prior).
"""

from __future__ import annotations

import csv
import json
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from cad.errors import DataError
from fe.joint.element import JointParams
from fe.joint.history import force_history

FloatArray = npt.NDArray[np.float64]

FIT_NAMES = (
    "k_tension_n_per_mm",
    "k_compression_n_per_mm",
    "k_bank_n_per_mm",
    "slip_ratio",
    "slip_force_n",
)
"""The fitted parameters, in the order of the fit vector."""

N_BRANCHES = 20
"""Branches of the fitted bank (η converges to 0.1 % of its N → ∞ value by N = 20 for
the uniform bank; more only costs time)."""


@dataclass(frozen=True, eq=False)
class FePoint:
    """One FE point: its design values, amplitude, loop and measures.

    Attributes:
        label: The point's folder name.
        design: Design values other than the amplitude (column → value).
        amplitude_n: Fg [N].
        force_n: Loop forces, shape (n,) [N], from the unloaded start.
        disp_mm: Loop displacements, free play removed, shape (n,) [mm].
        stage: Stage of each sample, shape (n,).
        free_play_mm: The FE's free play (4Δr) [mm].
        eta: η. w_cycle_nmm: W_cycle [N·mm]. d_plus_mm / d_minus_mm: δ(±Fg) [mm].
    """

    label: str
    design: Mapping[str, float]
    amplitude_n: float
    force_n: FloatArray
    disp_mm: FloatArray
    stage: npt.NDArray[np.int64]
    free_play_mm: float
    eta: float
    w_cycle_nmm: float
    d_plus_mm: float
    d_minus_mm: float


def _read_loop(path: Path) -> tuple[FloatArray, FloatArray, npt.NDArray[np.int64]]:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    try:
        f = np.array([float(r["force_N"]) for r in rows])
        d = np.array([float(r["displacement_mm"]) for r in rows])
        s = np.array([int(r["stage"]) for r in rows], dtype=np.int64)
    except (KeyError, ValueError) as err:
        raise DataError(
            f"{path}: not a loop.csv of hingelab (force_N, displacement_mm, stage): {err}"
        ) from err
    return f, d, s


def read_points(folder: Path | str) -> list[FePoint]:
    """Read every finished point of a sweep/study/cycle folder.

    Raises:
        DataError: If the folder holds no finished point, naming the folder.
    """
    folder = Path(folder)
    dirs = sorted(p.parent for p in folder.glob("points/*/result.json"))
    if not dirs and (folder / "result.json").is_file():
        dirs = [folder]
    out = []
    for d in dirs:
        rec = json.loads((d / "result.json").read_text())
        res = rec.get("results", rec)
        if rec.get("status", "ok") != "ok" or not (d / "loop.csv").is_file():
            continue
        params = dict(rec.get("params", {}))
        amp = float(params.pop("amplitude_N", res.get("amplitude_N", math.nan)))
        f, disp, stage = _read_loop(d / "loop.csv")
        out.append(
            FePoint(
                d.name,
                params,
                amp,
                f,
                disp,
                stage,
                float(res.get("free_play_mm", 0.0)),
                float(res["eta"]),
                float(res["W_cycle_Nmm"]),
                float(res["disp_at_peak_mm"]),
                float(res["disp_at_minus_peak_mm"]),
            )
        )
    if not out:
        raise DataError(f"{folder}: no finished FE point (points/*/result.json with loop.csv)")
    return out


def group_by_design(points: Sequence[FePoint]) -> dict[str, list[FePoint]]:
    """Points by design (``clearance_mm=0.1``; ``all`` for a folder of one design)."""
    groups: dict[str, list[FePoint]] = {}
    for p in points:
        key = ",".join(f"{k}={v:g}" for k, v in sorted(p.design.items())) or "all"
        groups.setdefault(key, []).append(p)
    return {k: sorted(v, key=lambda p: p.amplitude_n) for k, v in groups.items()}


def params_from_vector(theta: FloatArray, free_play_mm: float) -> JointParams:
    """The element of a fit vector (k₊, k₋, k_b, λ, F_s)."""
    kt, kc, kb, lam, fs = (float(v) for v in theta)
    return JointParams(
        k_tension_n_per_mm=kt,
        k_compression_n_per_mm=kc,
        k_elastic_n_per_mm=kb / 2,
        k_slip_n_per_mm=kb / 2,
        slip_ratio=lam,
        slip_force_n=fs,
        free_play_mm=free_play_mm,
        n_branches=N_BRANCHES,
    )


@dataclass(frozen=True)
class Measures:
    """An element's loop at one FE point.

    δ(±Fg) [mm] (free play removed), W [N·mm], η, and its displacements at the FE's
    forces, shape (n,) [mm].
    """

    d_plus_mm: float
    d_minus_mm: float
    w_cycle_nmm: float
    eta: float
    disp_mm: FloatArray = field(repr=False)


def element_measures(params: JointParams, pt: FePoint) -> Measures:
    """Run the element through the point's force history; its measures on the last loop.

    W is the friction work of the last loop (exact: the element's own bookkeeping).
    """
    h = force_history(params, pt.force_n)
    disp = h.disp_mm - h.play_mm
    n_stage = int(pt.stage.max()) + 1
    first = int(np.flatnonzero(pt.stage == n_stage - 2)[0]) - 1
    i_min = first + int(np.argmin(pt.force_n[first:]))
    w = float(h.dissipation_nmm[-1] - h.dissipation_nmm[first])
    dp, dm = float(disp[-1]), float(disp[i_min])
    u_max = 0.5 * pt.amplitude_n * 0.5 * (dp - dm)
    return Measures(dp, dm, w, w / (2 * math.pi * u_max) if u_max > 0 else math.nan, disp)


def residuals(theta: FloatArray, pts: Sequence[FePoint]) -> FloatArray:
    """The fit's residual vector: loop misfits /δ_max/√n, then the relative δ(±Fg), W misfits."""
    p = params_from_vector(theta, pts[0].free_play_mm)
    out = []
    for pt in pts:
        m = element_measures(p, pt)
        scale = 0.5 * (pt.d_plus_mm - pt.d_minus_mm)
        out.append((m.disp_mm - pt.disp_mm) / scale / math.sqrt(pt.force_n.size))
        out.append(
            np.array(
                [
                    m.d_plus_mm / pt.d_plus_mm - 1,
                    m.d_minus_mm / pt.d_minus_mm - 1,
                    m.w_cycle_nmm / pt.w_cycle_nmm - 1,
                ]
            )
        )
    return np.concatenate(out)


@dataclass(frozen=True)
class Reduced:
    """A fitted element and how well it reproduces its FE points.

    Attributes:
        design: The group's key (``clearance_mm=0.1``).
        params: The element.
        values: Fitted values by ``FIT_NAMES``. sigma: Their 1σ uncertainties.
        points: The FE points. measures: The element's measures at each.
        fit_s: Wall time of the fit [s]. cost: ½‖r‖² at the optimum.
    """

    design: str
    params: JointParams
    values: Mapping[str, float]
    sigma: Mapping[str, float]
    points: tuple[FePoint, ...]
    measures: tuple[Measures, ...]
    fit_s: float
    cost: float

    def table(self) -> list[dict[str, Any]]:
        """The validation table: per point δ(±Fg), W, η, FE vs element and their errors."""
        rows = []
        for pt, m in zip(self.points, self.measures, strict=True):
            rows.append(
                {
                    "design": self.design,
                    "point": pt.label,
                    "amplitude_N": pt.amplitude_n,
                    "d_plus_fe_mm": pt.d_plus_mm,
                    "d_plus_el_mm": m.d_plus_mm,
                    "d_plus_err": m.d_plus_mm / pt.d_plus_mm - 1,
                    "d_minus_fe_mm": pt.d_minus_mm,
                    "d_minus_el_mm": m.d_minus_mm,
                    "d_minus_err": m.d_minus_mm / pt.d_minus_mm - 1,
                    "W_fe_Nmm": pt.w_cycle_nmm,
                    "W_el_Nmm": m.w_cycle_nmm,
                    "W_err": m.w_cycle_nmm / pt.w_cycle_nmm - 1,
                    "eta_fe": pt.eta,
                    "eta_el": m.eta,
                    "eta_err": m.eta / pt.eta - 1,
                    "free_play_fe_mm": pt.free_play_mm,
                    "free_play_el_mm": self.params.free_play_mm,
                }
            )
        return rows


def _start(pts: Sequence[FePoint]) -> FloatArray:
    """A first guess from the secant stiffnesses and η of the points."""
    kt = float(np.median([p.amplitude_n / p.d_plus_mm for p in pts]))
    kc = float(np.median([-p.amplitude_n / p.d_minus_mm for p in pts]))
    eta = float(np.median([p.eta for p in pts]))
    return np.array([2 * kt, 2 * kc, 2 * min(kt, kc), min(0.9, max(4 * eta, 1e-3)), 0.0])


def fit_design(design: str, pts: Sequence[FePoint]) -> Reduced:
    """Fit one element to the points of one design (see the module docstring)."""
    from scipy.optimize import least_squares

    t0 = time.perf_counter()
    x0 = _start(pts)
    f_max = max(p.amplitude_n for p in pts)
    lo = np.array([x0[0] / 100, x0[1] / 100, x0[2] / 100, 0.0, 0.0])
    hi = np.array([x0[0] * 100, x0[1] * 100, x0[2] * 100, 0.95, 0.5 * f_max])
    scale = np.array([x0[0], x0[1], x0[2], 0.01, 0.01 * f_max])
    sol = None
    for fs0 in (0.0, 0.05 * f_max):  # without and with fixed friction: microslip is a local optimum
        start = np.array([*x0[:4], fs0])
        trial = least_squares(
            residuals,
            start,
            args=(pts,),
            bounds=(lo, hi),
            x_scale=scale,
            method="trf",
            diff_step=1e-6,
        )
        if sol is None or trial.cost < sol.cost:
            sol = trial
    assert sol is not None
    m, n = sol.fun.size, sol.x.size
    s2 = 2 * sol.cost / max(m - n, 1)
    try:
        cov = np.linalg.pinv(sol.jac.T @ sol.jac) * s2
        sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        sig = np.full(n, math.nan)
    params = params_from_vector(sol.x, pts[0].free_play_mm)
    meas = tuple(element_measures(params, p) for p in pts)
    return Reduced(
        design,
        params,
        dict(zip(FIT_NAMES, map(float, sol.x), strict=True)),
        dict(zip(FIT_NAMES, map(float, sig), strict=True)),
        tuple(pts),
        meas,
        time.perf_counter() - t0,
        float(sol.cost),
    )
