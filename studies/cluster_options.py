"""Where a command's model runs go: the ``--workers`` / ``--scheduler`` options and the service.

Shared by the subcommands (``studies.cli``) and ``python -m studies.paper.validation``,
which is why it is not under ``studies.cli``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any


def add_cluster_arguments(p: argparse.ArgumentParser) -> None:
    """Add where the points run (``sweep``, ``study``, ``compare``, ``diagnose``, ``calibrate``)."""
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        metavar="N",
        help="local Dask worker processes (default 1: in this process)",
    )
    p.add_argument(
        "--scheduler",
        default=os.environ.get("DASK_SCHEDULER_ADDRESS"),
        metavar="ADDRESS",
        help="run on an existing Dask cluster, e.g. tcp://host:8786 "
        "(default: $DASK_SCHEDULER_ADDRESS, else no cluster)",
    )


CLUSTER_OPTIONS: Mapping[str, tuple[str, ...]] = {
    "workers": ("--workers",),
}
"""The checked field ``add_cluster_arguments`` sets (``model.cluster.Cluster``); a scheduler
address is not range-checked, and a failed connection already names ``--scheduler``."""


@contextlib.contextmanager
def model_service(args: argparse.Namespace, results: Path | None) -> Iterator[Any]:
    """The ``ModelService`` a validation command runs its cycles through.

    In this process by default; on a private ``LocalCluster`` with ``--workers N`` (N > 1)
    or on the cluster at ``--scheduler`` (``model.cluster``), closed on exit.

    Args:
        args: The options (``--workers``, ``--scheduler``).
        results: Folder of the result store (a rerun reads back what is there), or None.
    """
    from model.cluster import Cluster, ClusterRunner
    from model.service import ModelService
    from model.store import ResultStore

    cluster = Cluster(workers=args.workers, scheduler=args.scheduler)
    store = None if results is None else ResultStore(results)
    if cluster.in_process:
        yield ModelService(store=store)
        return
    with ClusterRunner(cluster) as runner:
        yield ModelService(store=store, runner=runner)
