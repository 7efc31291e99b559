"""Diagnosis on synthetic measurement sets (issue 5): speed, and a check of the decision rules.

Two modes:

* ``time`` (default): a 9-case set (Δr 0, 0.1, 0.2 mm × Fg 100, 250, 400 N) made by
  ``validation.synth`` with a hidden tangential compliance on a finer mesh, diagnosed
  against the whole registry with the default ``DiagnoseSettings``; the model is the
  tests' coarse one (``MeshSettings.coarse()``). Prints wall time (limit: 15 min), cycles
  run, set-up (mesh, factorisation, condensation) vs cycle time, peak memory, verdict and
  the fitted value against the hidden one.
* ``check``: the decision rules (Bonferroni F-test, held-out folds, the 90 % "explained"
  share) were adjusted while the slow tests were written; this mode re-runs the
  diagnosis on seeds, hidden strengths and designs that were *not* used then and prints
  truth vs verdict, so the rules are judged on data they were not tuned on.

Each case runs in a fresh process (``run_isolated``), so peak memory is the case's own.

Run: .venv/bin/python benchmarks/bench_diagnose.py [time|check] [case-index ...]
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, run_isolated

NINE = ((0.0, (100.0, 250.0, 400.0)), (0.1, (100.0, 250.0, 400.0)), (0.2, (100.0, 250.0, 400.0)))
FOUR = ((0.0, (100.0, 400.0)), (0.1, (100.0, 400.0)))
FOUR_B = ((0.0, (150.0, 350.0)), (0.15, (150.0, 350.0)))  # a design the tests never used

CHECKS: tuple[tuple[str, dict[str, dict[str, float]], Any, int], ...] = (
    ("none, seed 21", {}, FOUR, 21),
    ("none, seed 22, design B", {}, FOUR_B, 22),
    ("frame 3e-5", {"frame_compliance": {"compliance_mm_per_n": 3e-5}}, FOUR_B, 23),
    ("roughness 1e-4", {"roughness_softening": {"compliance_mm3_per_n": 1e-4}}, FOUR_B, 24),
    ("tangential 3e-4", {"tangential_compliance": {"compliance_mm3_per_n": 3e-4}}, FOUR, 25),
    ("roughness 5e-5 (weak)", {"roughness_softening": {"compliance_mm3_per_n": 5e-5}}, FOUR, 26),
)
"""(label, hidden effects, design, seed): none of these seeds or values is in the tests."""


def _spec() -> Any:
    from cad.general_params import GeneralHingeParams
    from fe.cycle.protocol import CycleSettings
    from mesh.settings import MeshSettings
    from model.spec import ModelSpec

    return ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(mu=0.2, increments_per_stage=8, clearance_increments=16),
    )


def case(label: str, hidden: dict[str, dict[str, float]], design: Any, seed: int) -> dict[str, Any]:
    import time

    from validation.candidate_fit import DiagnoseSettings
    from validation.diagnose import diagnose
    from validation.measurements import read_measurement_set
    from validation.synth import SynthSettings, design_cases, synthesize

    spec = _spec()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        synthesize(spec, hidden, design_cases(design), SynthSettings(seed=seed), Path(tmp))
        t_synth = time.perf_counter() - t0
        data = read_measurement_set(Path(tmp))
        t1 = time.perf_counter()
        d = diagnose(spec, data, DiagnoseSettings())
        t_diag = time.perf_counter() - t1
    truth = ",".join(hidden) or "-"
    named = ",".join(d.effects) or "-"
    fitted = ""
    if d.candidates and d.effects:
        best = d.candidates[0]
        fitted = f"{best.value:.3g}"
    expected = "no_missing_effect" if not hidden else "effect_missing"
    ok = d.verdict == expected and (not hidden or d.effects[0] in hidden)
    return {
        "case": label,
        "cases": len(data.cases),
        "truth": truth,
        "verdict": d.verdict,
        "named": named,
        "fitted": fitted,
        "chi2_base": d.chi2_base,
        "limit": d.chi2_noise_limit,
        "right": "yes" if ok else "NO",
        "cycles": int(d.stats["n_cycles"]),
        "setup_s": d.stats["setup_s"],
        "cycle_s": d.stats["cycle_s"],
        "synth_s": t_synth,
        "diagnose_s": t_diag,
    }


if __name__ == "__main__":
    mode = sys.argv[1] if len(sys.argv) > 1 else "time"
    if mode == "time":
        hidden = {"tangential_compliance": {"compliance_mm3_per_n": 1e-4}}
        rows = [run_isolated(case, "9 cases, tangential 1e-4", hidden, NINE, 31)]
    elif mode == "check":
        pick = [int(a) for a in sys.argv[2:]] or list(range(len(CHECKS)))
        rows = [run_isolated(case, *CHECKS[i]) for i in pick]
    else:
        raise SystemExit(f"mode must be 'time' or 'check', got {mode!r}")
    print("diagnosis on synthetic sets (finer truth mesh, default DiagnoseSettings)")
    print_table(
        rows,
        [
            "case",
            "cases",
            "truth",
            "verdict",
            "named",
            "fitted",
            "chi2_base",
            "limit",
            "right",
            "cycles",
            "setup_s",
            "cycle_s",
            "diagnose_s",
            "peak_MB",
        ],
    )
