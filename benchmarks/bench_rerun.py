"""How much faster a rerun with nothing changed is than the first run (issue 35, item 3).

Runs ``hingelab paper --quick`` twice into a fresh folder (first run, then the rerun that
reads every point back), then profiles a third run and prints where its seconds go:
imports, the sweeps' bookkeeping (plan, trace, table), the response-surface fits and
figures, the threshold map. Prints a table; not a timed test.

    python benchmarks/bench_rerun.py [--out DIR]
"""

from __future__ import annotations

import argparse
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PARTS = {
    "build the parser (imports of every command)": "build_parser",
    "load the hinge kinds (no build123d since this branch)": "kinds/__init__.py:.*(_load)",
    "all imports (importlib, cumulative)": "_bootstrap>:.*\\(_find_and_load\\)",
    "sweeps: plan, trace, table, convergence": "sweep.py:.*(run_sweep)",
    "surface fits and figures": "study.py:.*(_hinge_report)",
    "threshold map (read back from its stamp)": "checks.py:.*(current_threshold)",
}


def _run(out: Path) -> float:
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "studies.cli.main", "paper", "--quick", "--out", str(out)]
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    """Print first run, rerun, ratio and the rerun's profile."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    out = args.out or Path(tempfile.mkdtemp()) / "paper"
    first = _run(out)
    _run(out)  # the figures' stamps are written by the first run; this one is like any rerun
    rerun = _run(out)
    prof = out.parent / "rerun.prof"
    cmd = ["-m", "cProfile", "-o", str(prof), "-m", "studies.cli.main", "paper", "--quick"]
    subprocess.run([sys.executable, *cmd, "--out", str(out)], check=True, capture_output=True)
    stats = pstats.Stats(str(prof))
    total = max(v[3] for v in stats.stats.values())  # type: ignore[attr-defined]
    print(f"{'run':<46}{'wall s':>8}")
    print(f"{'paper --quick, first run':<46}{first:8.1f}")
    print(f"{'paper --quick, rerun (nothing changed)':<46}{rerun:8.1f}")
    print(f"{'ratio':<46}{first / rerun:8.1f}")
    print(f"\nwhere the rerun's {total:.1f} s (profiled, in process) go:")
    for label, pattern in PARTS.items():
        import re

        cum = sum(
            v[3] for k, v in stats.stats.items() if re.search(pattern, f"{k[0]}:{k[1]}({k[2]})")
        )  # type: ignore[attr-defined]
        print(f"  {label:<50}{cum:6.2f}")


if __name__ == "__main__":
    main()
