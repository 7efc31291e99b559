"""The same cycles in this process and on Dask workers: the per-task cost of a worker.

Issue 35, item 2: two local workers gave a 6-case general diagnosis only 1.16× (target
1.7×), although both workers were busy the whole run (benchmarks/bench_diagnose_workers.txt).
This isolates why: 12 coarse-mesh cycles (Δr 0.1 mm, 8/16 increments, each with its own
amplitude and roughness value, so no result is reused) run here through a ``ModelService``,
then on a private ``LocalCluster`` of 1 and of 2 workers (the geometry prepared on each
worker first, outside the timing). Prints the mean compute time per task (Dask's task
stream) against the time per cycle here, and the wall time of the batch.

Run: .venv/bin/python benchmarks/bench_worker_overhead.py
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    from dask.distributed import get_task_stream

    from model.cluster import Cluster, ClusterRunner
    from model.file import read_model
    from model.service import ModelService
    from model.spec import DesignPoint

    spec = read_model(ROOT / "studies/examples/MODEL.toml")  # the coarse mesh
    cycle = dataclasses.replace(spec.cycle, increments_per_stage=8, clearance_increments=16)
    spec = dataclasses.replace(spec, cycle=cycle)

    def jobs(mu: float) -> list[tuple[object, DesignPoint]]:
        out = []
        for k in range(12):
            amp = 100.0 + 10.0 * k
            c = dataclasses.replace(spec.cycle, amplitude_n=amp, mu=mu)
            e = {"roughness_softening": {"compliance_mm3_per_n": 1e-5 * (k + 1)}}
            out.append(
                (
                    dataclasses.replace(spec, cycle=c, effects=e),
                    DesignPoint(amp, {"clearance_mm": 0.1}),
                )
            )
        return out

    print(f"load average before: {os.getloadavg()}")
    here = ModelService()
    here.run_point(*jobs(0.2)[0])  # set-up and imports
    t0 = time.perf_counter()
    for j in jobs(0.21):
        here.run_point(*j)  # type: ignore[arg-type]
    t_here = (time.perf_counter() - t0) / 12
    print(f"in this process: {t_here:.3f} s per cycle")
    for n in (1, 2):
        with ClusterRunner(Cluster(workers=n)) as runner:
            client = runner.client()
            service = ModelService(runner=runner)
            service.run_jobs(jobs(0.2)[: 2 * n])  # type: ignore[arg-type]  # set-ups
            with get_task_stream(client) as ts:
                t0 = time.perf_counter()
                service.run_jobs(jobs(0.21))  # type: ignore[arg-type]
                wall = time.perf_counter() - t0
            comp = [
                s["stop"] - s["start"]
                for r in ts.data
                for s in r["startstops"]
                if s["action"] == "compute"
            ]
            mean = sum(comp) / len(comp)
            print(
                f"{n} worker(s): batch of 12 in {wall:.2f} s ({wall / 12:.3f} s per cycle); "
                f"task compute {mean:.3f} s = {mean / t_here:.2f}× a cycle here"
            )
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
