"""synth and the paper's validation on Dask: the same set as in process; the options reach the service.

The model is the plug-in kind ``jenkins_pin`` (``tests/plugins``, a cycle in milliseconds):
these check the dispatch, not the physics. The workers find the plug-in through
``PYTHONPATH``, as a user's workers would find an installed package.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

from studies.cli.main import main
from tests.conftest import PLUGINS

CASES = "30:200,400;60:200,400"
HIDDEN = "frame_compliance:compliance_mm_per_n=2e-5"


def _model(tmp_path: Path, slip_force_n: float = 60.0) -> Path:
    path = tmp_path / f"MODEL_{slip_force_n:g}.toml"
    path.write_text(
        '[hinge]\nkind = "jenkins_pin"\nk0_n_per_mm = 2000.0\nk1_n_per_mm = 6000.0\n'
        f"slip_force_n = {slip_force_n}\n[cycle]\nincrements_per_stage = 12\n"
    )
    return path


@pytest.mark.slow  # a LocalCluster of two processes takes ~8 s to start
def test_synth_on_a_local_cluster_writes_the_in_process_set(
    jenkins, tmp_path, capsys, monkeypatch
) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(PLUGINS), *sys.path]))
    model = _model(tmp_path)
    sets = {}
    for name, extra in (("here", []), ("dask", ["--workers", "2"])):
        out = tmp_path / name
        argv = ["synth", str(model), "--effect", HIDDEN, "--cases", CASES, "--seed", "4"]
        assert main([*argv, "--out", str(out), *extra]) == 0
        capsys.readouterr()
        manifest = json.loads((out / "manifest.json").read_text())
        manifest.pop("wall_s")
        loops = {p.name: p.read_bytes() for p in sorted((out / "loops").iterdir())}
        sets[name] = (manifest, loops, (out / "cases.csv").read_text())
    assert len(sets["here"][1]) == 4
    assert sets["dask"] == sets["here"]  # every sample, offset and FE metric, to the byte


@pytest.mark.slow
def test_run_summarized_on_a_local_cluster_summarises_where_the_cycle_ran(
    jenkins, tmp_path, monkeypatch
) -> None:  # type: ignore[no-untyped-def]
    import dataclasses

    from dask.distributed import get_task_stream

    from model.cluster import Cluster, ClusterRunner
    from model.file import read_model
    from model.service import ModelService
    from model.spec import DesignPoint

    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(PLUGINS), *sys.path]))
    spec = read_model(_model(tmp_path))
    jobs = [
        (dataclasses.replace(spec, hinge=dataclasses.replace(spec.hinge, slip_force_n=f)),
         DesignPoint(a))
        for f in (40.0, 70.0) for a in (100.0, 300.0)
    ]  # fmt: skip
    one = dataclasses.replace(spec, hinge=dataclasses.replace(spec.hinge, slip_force_n=55.0))
    alone = [(one, DesignPoint(a)) for a in (100.0, 150.0, 200.0, 250.0, 300.0, 350.0)]
    here = ModelService().run_summarized(jobs)
    with ClusterRunner(Cluster(workers=2)) as runner:
        service = ModelService(runner=runner)
        there = service.run_summarized(jobs)
        with get_task_stream(runner.client()) as stream:
            there_alone = service.run_summarized(alone)
    # one geometry's six jobs ran on both workers (not all on the one it was pinned to)
    assert len({t["worker"] for t in stream.data if t["key"].startswith("run_job")}) == 2
    assert [s for _, s in there_alone] == [s for _, s in ModelService().run_summarized(alone)]
    assert service.n_computed == 4 + 6
    assert [s["slip_force_N"] for _, s in there] == [40.0, 40.0, 70.0, 70.0]
    for (ra, sa), (rb, sb) in zip(here, there, strict=True):
        assert sa == sb
        assert rb.metrics() == pytest.approx(ra.metrics(), rel=1e-12, abs=1e-300, nan_ok=True)
        assert rb.configs == {}  # the condensed operators stay on the worker


def test_the_paper_validation_takes_the_cluster_options(tmp_path, monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    """--workers/--scheduler reach the service that runs the cycles, whose store is DIR/results."""
    import studies.paper.validation as validation

    seen = {}

    def fake_run(out: Path, quick: bool, service) -> dict:  # type: ignore[no-untyped-def]
        seen.update(service=service, quick=quick)
        (out / "report.md").parent.mkdir(parents=True, exist_ok=True)
        (out / "report.md").write_text("# report\n")
        return {"wall_s": 0.0}

    monkeypatch.setattr(validation, "run", fake_run)
    out = tmp_path / "v"
    assert validation.main(["--out", str(out), "--quick", "--workers", "2"]) == 0
    service = seen["service"]
    assert service.runner.cluster.workers == 2
    assert service.runner.cluster.scheduler is None
    assert service.store.root == out / "results"
    addr = "tcp://127.0.0.1:1"
    assert validation.main(["--out", str(out), "--scheduler", addr]) == 0
    assert seen["service"].runner.cluster.scheduler == addr
    assert validation.main(["--out", str(out)]) == 0
    assert seen["service"].runner is None  # the default: in this process
    capsys.readouterr()
