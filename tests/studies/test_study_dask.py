"""A study run on an existing Dask cluster (``dask scheduler`` + two ``dask worker``) equals the serial run."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from studies.cli.main import main
from tests.dask_cluster import external_cluster

STUDY = """
[study]
name = "dask_2x2"
[mesh]
preset = "coarse"
[solver]
increments = 6
[design]
type = "full_factorial"
[design.clearance_mm]
levels = [0.0, 0.1]
[design.amplitude_N]
levels = [200.0, 400.0]
[surface]
degree = 1
"""


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.slow
def test_study_on_an_existing_cluster_equals_the_serial_run(tmp_path, capsys):
    from model.store import ResultStore

    study = tmp_path / "study.toml"
    study.write_text(STUDY)
    with external_cluster(tmp_path) as address:
        assert (
            main(["study", str(study), "--out", str(tmp_path / "cluster"), "--scheduler", address])
            == 0
        )
        err = capsys.readouterr().err
        assert "INFO" not in err  # quiet by default: no Dask chatter
        assert "[4/4]" in err
    # the serial run with the threads dask's nanny gives its workers (MKL/OMP/OpenBLAS: 1)
    env = {
        **os.environ,
        **{k: "1" for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")},
    }
    serial_run = subprocess.run(
        [
            sys.executable,
            "-m",
            "studies.cli.main",
            "study",
            str(study),
            "--out",
            str(tmp_path / "serial"),
        ],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert serial_run.returncode == 0, serial_run.stderr
    serial, cluster = (ResultStore(tmp_path / name / "results") for name in ("serial", "cluster"))
    keys = sorted(p.stem for p in serial.root.glob("*.npz"))
    # the 4 points and the doubled-increment run of the clearance check (studies.convergence),
    # which the store keeps by its own key
    assert len(keys) == 5
    assert keys == sorted(p.stem for p in cluster.root.glob("*.npz"))
    points = {
        json.loads(f.read_text())["solver"]["result_key"]
        for f in (tmp_path / "cluster" / "points").glob("*/result.json")
    }
    assert len(points) == 4
    assert points < set(keys)
    (check,) = set(keys) - points  # run in the calling process, whose LU threads differ
    a, b = serial.get(check), cluster.get(check)
    assert a is not None
    assert b is not None
    assert b.metrics()["eta"] == pytest.approx(a.metrics()["eta"], rel=1e-12)
    for key in sorted(points):
        a, b = serial.get(key), cluster.get(key)
        assert a is not None
        assert b is not None
        # Bit for bit: the same code on the same inputs with the same thread counts. (With
        # MKL PARDISO on every core in the serial process instead, threaded sums add in
        # another order: ~1e-15 in the displacements, and a contact point exactly at its
        # stick/slip limit can then flip, which moved η by 8e-12 at Δr = 0.1 mm, 400 N.)
        for name in ("force_n", "disp_mm", "friction_work", "elastic_energy", "n_slip", "n_stick"):
            x = [getattr(i, name) for i in a.increments]
            y = [getattr(i, name) for i in b.increments]
            assert x == y, name
        assert a.metrics()["eta"] == b.metrics()["eta"]
    t_serial = {
        (r["clearance_mm"], r["amplitude_N"]): r["eta"]
        for r in _rows(tmp_path / "serial" / "table.csv")
    }
    t_cluster = {
        (r["clearance_mm"], r["amplitude_N"]): r["eta"]
        for r in _rows(tmp_path / "cluster" / "table.csv")
    }
    assert t_serial == t_cluster
