"""A 6-case diagnosis of the general hinge at the default mesh, in process and on 2 workers.

Issue 35, item 2: the wall time of a default-mesh diagnosis and its 1 → 2 worker speed-up.
The data: ``hingelab synth`` from the coarse example model (its own, finer data mesh; so
the default-mesh model is judged on loops of another mesh), Δr 0 and 0.1 mm × Fg 100, 250,
400 N, a hidden frame compliance of 2e-5 mm/N, seed 5. The model: the same hinge on the
default mesh. Each run starts from an empty result store (``--out`` of its own) in a fresh
process; the verdict, fitted value and χ² of the two runs must agree (the cluster path runs
the same code).

Run: .venv/bin/python benchmarks/bench_diagnose_workers.py [WORKDIR]
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, run_isolated

ROOT = Path(__file__).resolve().parents[1]
CASES = "0:100,250,400;0.1:100,250,400"
HIDDEN = "frame_compliance:compliance_mm_per_n=2e-5"


def _synth(work: str) -> dict[str, Any]:
    from studies.cli.main import main

    argv = ["synth", str(ROOT / "studies/examples/MODEL.toml"), "--effect", HIDDEN]
    assert main([*argv, "--cases", CASES, "--seed", "5", "--out", f"{work}/data"]) == 0
    return {}


def _diagnose(work: str, model: str, workers: int) -> dict[str, Any]:
    import contextlib
    import io

    from studies.cli.main import main

    out = f"{work}/diag_w{workers}"
    buf = io.StringIO()
    argv = ["diagnose", model, f"{work}/data", "--json", "--out", out]
    with contextlib.redirect_stdout(buf):
        assert main([*argv, "--workers", str(workers)]) == 0
    d = json.loads(buf.getvalue())
    best = d["candidates"][0] if d["candidates"] else {}
    return {
        "workers": workers,
        "verdict": d["verdict"],
        "best": best.get("name", ""),
        "value": best.get("value", float("nan")),
        "chi2": best.get("chi2", float("nan")),
        "cycles": d["stats"].get("n_cycles", d["stats"].get("n_computed", "")),
    }


def main() -> None:
    work = sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp(prefix="bench_diag_w_")
    os.makedirs(work, exist_ok=True)
    if not Path(work, "data", "cases.csv").is_file():
        run_isolated(_synth, work)
    # the model: the example hinge on the default mesh ([mesh] left out), its other settings
    text = (ROOT / "studies/examples/MODEL.toml").read_text()
    head, _, tail = text.partition("[mesh]")
    tail = tail[tail.index("[friction]") :]
    model = Path(work, "MODEL_default_mesh.toml")
    model.write_text(head + tail)
    rows = [run_isolated(_diagnose, work, str(model), w) for w in (1, 2)]
    print_table(rows, ["workers", "wall_s", "peak_MB", "cycles", "verdict", "best", "value", "chi2"])
    print(f"speed-up 1 → 2 workers: {rows[0]['wall_s'] / rows[1]['wall_s']:.2f}×")
    same = all(rows[0][k] == rows[1][k] for k in ("verdict", "best"))
    rel = max(abs(rows[1][k] / rows[0][k] - 1.0) for k in ("value", "chi2"))
    print(f"same verdict and effect: {same}; fitted value and χ² agree to {rel:.1e} relative")


if __name__ == "__main__":
    main()
