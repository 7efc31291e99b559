"""``hingelab cycle --hinge bearing --interfaces contact`` writes its ParaView series."""

from __future__ import annotations

import json
import re
from pathlib import Path

import meshio
import numpy as np
import pytest

from cad.bearing_geometry import BearingHingeParams, Interfaces
from fe.cycle.protocol import CycleSettings
from fe.kinds import hinge_kind
from model.file import write_model
from model.spec import ModelSpec
from studies.cli.main import main

COARSE = {"size_mm": 4.0, "contact_size_mm": 0.8, "part_sizes_mm": (("ring", 1.2),)}


def _model(tmp_path: Path) -> Path:
    """The coarse bearing hinge with frictional fits (a model file: the ring size too)."""
    spec = ModelSpec(
        "bearing",
        BearingHingeParams(preload_n=100.0, interfaces=Interfaces.CONTACT),
        hinge_kind("bearing").mesh_settings(**COARSE),
        CycleSettings(amplitude_n=400.0, increments_per_stage=4, mu=0.2),
    )
    return write_model(spec, tmp_path / "MODEL.toml")


@pytest.mark.slow
def test_fits_cycle_writes_a_field_series(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    argv = ["cycle", "--model", str(_model(tmp_path)), "--frames", "3", "--out", str(out)]
    assert main([*argv, "--json", "--no-progress"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["interfaces"] == "contact"
    pvd = out / "fields" / "cycle.pvd"
    assert summary["files"]["pvd"] == str(pvd)
    names = re.findall(r'file="([^"]+)"', pvd.read_text())
    n_inc = len(summary["increments"])
    # every third increment and the last one
    assert names == [f"step_{k:04d}.vtu" for k in range(n_inc) if k % 3 == 0 or k == n_inc - 1]
    forces = [i["force_N"] for i in summary["increments"]]
    for name in names:
        frame = meshio.read(out / "fields" / name)
        k = int(name[5:9])
        for key in ("displacement", "ball_load", "fit_pressure", "fit_slip"):
            assert key in frame.point_data, key
        u = np.asarray(frame.point_data["displacement"])
        assert u.shape == (len(frame.points), 3)
        assert 1e-3 < np.linalg.norm(u, axis=1).max() < 0.05  # µm scale [mm]
        load = np.asarray(frame.point_data["ball_load"])
        pressure = np.asarray(frame.point_data["fit_pressure"])
        slip = np.asarray(frame.point_data["fit_slip"])
        assert load.max() > 1.0
        assert load.min() >= 0.0
        assert pressure.max() > 1.0
        assert pressure.min() >= 0.0
        # a ball patch is not a fit: both are nonzero on separate nodes
        assert not np.any((load > 0) & (pressure > 0))
        assert slip.min() >= 0.0
        if abs(forces[k]) > 100.0:  # away from the preload state the fits have slipped
            assert slip.max() > 1e-6
        assert "stress" in frame.cell_data
        assert "von_mises" in frame.cell_data
    # the loaded frames carry the clevis force through the fits: the pin–clevis pressure
    last = meshio.read(out / "fields" / names[-1])
    assert abs(forces[-1]) == pytest.approx(400.0)
    assert np.asarray(last.point_data["fit_pressure"]).max() > 10.0
