"""The paper's general-hinge 5 × 5 study: a private LocalCluster, its cached rerun, and an
existing cluster (``dask scheduler`` + two ``dask worker`` on 127.0.0.1), in one run.

Usage: python benchmarks/bench_study.py [STUDY.toml] [--skip-cluster]
(default: studies/examples/paper_general_5x5.toml; the coarse example takes about a minute).
Targets (issue: design studies as files): 5 × 5 at the default mesh ≤ 15 min, cached rerun
≤ 10 s, the existing cluster within 1.3× of the LocalCluster.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DASK = str(Path(sys.executable).parent / "dask")


def _study(study: Path, out: Path, *extra: str) -> float:
    t0 = time.perf_counter()
    cmd = [
        sys.executable,
        "-m",
        "studies.cli.main",
        "study",
        str(study),
        "--out",
        str(out),
        "--no-plots",
    ]
    subprocess.run([*cmd, *extra], check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cluster_run(study: Path, out: Path) -> float:
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    log = (out.parent / "dask.log").open("w")
    sched = [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"]
    procs = [subprocess.Popen(sched, stdout=log, stderr=subprocess.STDOUT)]
    try:
        time.sleep(2.0)
        worker = [
            DASK,
            "worker",
            address,
            "--nthreads",
            "1",
            "--host",
            "127.0.0.1",
            "--no-dashboard",
        ]
        procs += [subprocess.Popen(worker, stdout=log, stderr=subprocess.STDOUT) for _ in range(2)]
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        return _study(study, out, "--scheduler", address)
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            p.wait(timeout=30)


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    study = Path(args[0]) if args else ROOT / "studies" / "examples" / "paper_general_5x5.toml"
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        rows = [("LocalCluster, 2 workers", _study(study, base / "local", "--workers", "2"))]
        rows.append(("cached rerun", _study(study, base / "local", "--workers", "2")))
        if "--skip-cluster" not in sys.argv:
            rows.append(("existing cluster, 2 workers", _cluster_run(study, base / "cluster")))
    print(f"study: {study.name}")
    print(f"{'run':<30} {'wall s':>8} {'ratio':>7}")
    for name, wall in rows:
        print(f"{name:<30} {wall:8.1f} {wall / rows[0][1]:7.2f}")
