"""The diagnosis on data made independently of ``synth``: false alarms, power, an effect outside
the registry.

Data: the project's default-mesh loops (level 0: 3 mm / 1.2 mm, not the model's coarse 4 mm /
2 mm and not synth's 0.75x rule), 20 / 60 increments, Δr 0 and 0.1 mm x Fg 150 and 350 N,
sampled here (not by ``validation.synth``) like a test machine: force ramps at 20 N/s with a
0.1 mm/s crosshead limit, 20 Hz, a 2 s dwell, random zero offsets, force noise 0.5 % of Fg and
displacement noise 0.2 µm. Effects are added to the sampled record, outside the registry code:

* ``null``: none (20 seeds): the false-alarm rate of "a misfit" (anything but no_missing_effect
  / cannot_tell) at the stated α;
* ``frame``: a frame compliance δ += c·F (in the registry), c = 2e-5 mm/N;
* ``viscous``: a rate-dependent lag δ −= g·dF/dt (outside the registry), g set so that the
  loop area at Δr 0, 150 N is 3x the elastic-frictional one.

The model is the tests' coarse one (8 / 16 increments), one ``ModelEvaluator`` shared by every
set (the candidate grids are computed once; each set refits its own parameters).

Run: .venv/bin/python benchmarks/bench_diagnose_independent.py [n_null_seeds]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

DESIGN = ((0.0, 150.0), (0.0, 350.0), (0.1, 150.0), (0.1, 350.0))
FORCE_RATE, DISP_RATE, HZ, DWELL = 20.0, 0.1, 20.0, 2.0
FORCE_NOISE_REL, DISP_NOISE_MM = 0.005, 2e-4


def _truth_paths() -> dict[tuple[float, float], tuple[np.ndarray, np.ndarray, float]]:
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.service import ModelService
    from model.spec import DesignPoint, ModelSpec

    spec = ModelSpec("general", GeneralHingeParams(), MeshSettings(), CycleSettings())
    service = ModelService()
    out = {}
    for c, a in DESIGN:
        r = service.run_point(spec, DesignPoint(a, {"clearance_mm": c}))
        F, d = r.machine_path()
        out[(c, a)] = (F, d, r.metrics()["W_cycle_Nmm"])
    return out


def _sample(F: np.ndarray, d: np.ndarray, amp: float, rng: np.random.Generator, g: float, c: float):
    dt = np.maximum(np.abs(np.diff(F)) / FORCE_RATE, np.abs(np.diff(d)) / DISP_RATE)
    t_path = DWELL + np.concatenate([[0.0], np.cumsum(dt)])
    t = np.arange(0.0, t_path[-1] + 0.5 / HZ, 1.0 / HZ)
    Ft = np.interp(t, t_path, F, left=0.0)
    dt_ = np.interp(t, t_path, d, left=0.0)
    rate = np.gradient(Ft, t)
    dt_ = dt_ - g * rate + c * Ft  # a lag (δ behind F) and a series compliance, before the noise
    Fm = Ft + rng.uniform(-1, 1) * 1.0 + rng.normal(0.0, FORCE_NOISE_REL * amp, t.size)
    dm = dt_ + rng.uniform(-1, 1) * 5e-3 + rng.normal(0.0, DISP_NOISE_MM, t.size)
    return t, Fm, dm


def _dataset(paths: dict[Any, Any], seed: int, g: float = 0.0, c: float = 0.0) -> Any:
    from validation.loop_files import Loop
    from validation.measurements import Case, MeasurementSet

    rng = np.random.default_rng([seed, 7])
    cases = []
    for i, ((clr, amp), (F, d, _)) in enumerate(paths.items()):
        t, Fm, dm = _sample(F, d, amp, rng, g, c)
        loop = Loop(Fm, dm, t, f"independent:{i}")
        cases.append(Case(f"c{i}", "general", clr, 0.0, amp, loop=loop))
    return MeasurementSet(tuple(cases), Path("."))


def main(n_null: int) -> None:
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.spec import ModelSpec
    from validation.candidate_fit import DiagnoseSettings, measured_features
    from validation.diagnose import diagnose
    from validation.evaluate import ModelEvaluator

    t0 = time.perf_counter()
    paths = _truth_paths()
    t_truth = time.perf_counter() - t0
    W0 = paths[(0.0, 150.0)][2]
    g = W0 / (2.0 * 150.0 * FORCE_RATE)  # branches 2gr apart over 2Fg: adds 4grFg = 2 W0
    spec = ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(mu=0.2, increments_per_stage=8, clearance_increments=16),
    )
    s = DiagnoseSettings()
    points = tuple((c, a) for c, a in DESIGN)
    ev = ModelEvaluator(spec, points, s.increments_per_stage, s.clearance_increments)
    sets = [("null", k, 0.0, 0.0) for k in range(100, 100 + n_null)]
    sets += [("frame 2e-5", k, 0.0, 2e-5) for k in (200, 201, 202)]
    sets += [("viscous (area 3x)", k, g, 0.0) for k in (300, 301, 302)]
    rows = []
    for label, seed, gg, cc in sets:
        data = _dataset(paths, seed, gg, cc)
        t1 = time.perf_counter()
        meas = measured_features(data, s.features)
        d = diagnose(spec, data, s, evaluator=ev)
        fitted = f"{d.candidates[0].value:.3g}" if d.effects else ""
        rows.append(
            (label, seed, d.verdict.value, (",".join(d.effects) or "-") + (f" {fitted}" if fitted else ""), d.chi2_base,
             d.chi2_noise_limit, meas.n_obs, d.sensitivity.get("loop_area_or_eta"),
             time.perf_counter() - t1)
        )  # fmt: skip
        print(*rows[-1], sep=" | ", flush=True)
    print(f"\ntruth loops {t_truth:.0f} s; viscous g = {g:.3g} mm·s/N; alpha = {s.alpha}")
    print("| set | seed | verdict | named | chi2 | limit | N | detectable area error | s |")
    print("|---|--:|---|---|--:|--:|--:|--:|--:|")
    for r in rows:
        sens = "—" if r[7] is None else f"{r[7]:.0%}"
        print(
            f"| {r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]:.1f} | {r[5]:.1f} | {r[6]} | {sens} | {r[8]:.0f} |"
        )
    nulls = [r for r in rows if r[0] == "null"]
    alarms = sum(r[2] not in ("no_missing_effect", "cannot_tell") for r in nulls)
    print(
        f"\nnull: {alarms} alarm(s) in {len(nulls)} seeds (false-alarm rate {alarms / max(1, len(nulls)):.0%}; "
        f"alpha {s.alpha}); verdicts: " + ", ".join(sorted({r[2] for r in nulls}))
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20)
