"""An external Dask cluster for tests: ``dask scheduler`` and ``dask worker`` processes."""

from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping
from pathlib import Path


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def external_cluster(
    folder: Path, workers: int = 2, env: Mapping[str, str] | None = None, *, nanny: bool = True
) -> Iterator[str]:
    """Start a scheduler and ``workers`` one-thread workers; yield the scheduler's address.

    The workers run in ``folder`` (so they find the package installed, not through the cwd)
    with ``env``, as does the scheduler (it unpickles the tasks); their logs go to
    ``folder/dask.log``. Without ``nanny`` a worker that dies stays dead. Every process is
    stopped on exit.
    """
    from distributed import Client

    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = str(Path(sys.executable).parent / "dask")
    with (folder / "dask.log").open("w") as logs:
        procs = [
            subprocess.Popen(
                [dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                stdout=logs,
                stderr=subprocess.STDOUT,
                env=None if env is None else dict(env),  # it unpickles the tasks too
            )
        ]
        try:
            time.sleep(2.0)
            worker = [dask, "worker", address, "--nthreads", "1", "--host", "127.0.0.1"]
            worker += [] if nanny else ["--no-nanny"]
            for _ in range(workers):
                procs.append(
                    subprocess.Popen(
                        [*worker, "--no-dashboard"],
                        stdout=logs,
                        stderr=subprocess.STDOUT,
                        cwd=folder,
                        env=None if env is None else dict(env),
                    )
                )
            with Client(address, timeout="30s") as client:
                client.wait_for_workers(workers, timeout=60)
            yield address
        finally:
            for p in reversed(procs):
                p.terminate()
            for p in procs:
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    p.kill()
