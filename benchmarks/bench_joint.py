"""Speed of the reduced-order joint: a 10 000-sample history, a step, and a `reduce` fit.

python benchmarks/bench_joint.py [SWEEP_FOLDER]   # prints a table (CPU and wall time)
"""

from __future__ import annotations

import sys
import time

import numpy as np

from fe.joint.element import JointParams, initial_state
from fe.joint.history import displacement_history, force_history
from fe.joint.step import step


def timed(fn, repeat: int) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    fn()
    w0, c0 = time.perf_counter(), time.process_time()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - w0) / repeat, (time.process_time() - c0) / repeat


def main() -> None:
    p = JointParams(
        k_slip_n_per_mm=5e4,
        slip_ratio=0.3,
        slip_force_n=20.0,
        free_play_mm=0.01,
        k_tension_n_per_mm=1e5,
        k_compression_n_per_mm=2e5,
    )
    u = 0.02 * np.sin(2 * np.pi * np.linspace(0, 10, 10_000))
    f = displacement_history(p, u).force_n
    rows = [
        (
            "displacement history, 10 000 samples, 10 cycles",
            *timed(lambda: displacement_history(p, u), 50),
        ),
        ("force history, 10 000 samples, 10 cycles", *timed(lambda: force_history(p, f), 50)),
        (
            "one step (increment by increment)",
            *timed(lambda: step(p, initial_state(p), 0.01), 2000),
        ),
    ]
    if len(sys.argv) > 1:
        from validation.reduce import fit_design, group_by_design, read_points

        for design, pts in group_by_design(read_points(sys.argv[1])).items():
            rows.append(
                (
                    f"reduce fit, {design}, {len(pts)} points",
                    *timed(lambda d=design, g=pts: fit_design(d, g), 1),
                )
            )
    print(f"{'what':<55s} {'wall [ms]':>10s} {'CPU [ms]':>10s}")
    for name, wall, cpu in rows:
        print(f"{name:<55s} {wall * 1e3:10.3f} {cpu * 1e3:10.3f}")


if __name__ == "__main__":
    main()
