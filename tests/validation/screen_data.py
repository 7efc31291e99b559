"""Data of the coarse-to-fine tests (``diagnose`` and ``calibrate`` with a screen).

Loops of the general hinge on its coarse preset with a hidden roughness softening, and the
model judged on them: the same hinge, finer than the coarse preset at the contacts, so
its grids run on the coarse mesh (``validation.candidates.screen_mesh``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from cad.general_params import GeneralHingeParams
from fe.cycle.protocol import CycleSettings
from mesh.settings import MeshSettings
from model.spec import ModelSpec
from validation.candidate_fit import DiagnoseSettings
from validation.measurements import MeasurementSet, read_measurement_set
from validation.synth import SynthSettings, design_cases, synthesize

HIDDEN = {"roughness_softening": {"compliance_mm3_per_n": 2e-4}}
"""The effect the data hold and the model does not."""


def search_settings(**extra: Any) -> DiagnoseSettings:
    """Both tests' search: a small grid, few refinement runs, the data's increments."""
    return DiagnoseSettings(
        grid_points=5,
        grid_decades=2.5,
        refine_iter=4,
        increments_per_stage=6,
        clearance_increments=12,
        **extra,
    )


def coarse_data_and_finer_model(
    out: Path, amplitudes_n: Sequence[float], seed: int
) -> tuple[ModelSpec, MeasurementSet]:
    """Synthesise the data at Δr = 0 into ``out``; return (the model judged, the data)."""
    cycle = CycleSettings(mu=0.2, increments_per_stage=6, clearance_increments=12)
    coarse = ModelSpec("general", GeneralHingeParams(), MeshSettings.coarse(), cycle)
    cases = design_cases(((0.0, tuple(amplitudes_n)),))
    synthesize(coarse, HIDDEN, cases, SynthSettings(seed=seed), out)
    model = dataclasses.replace(coarse, mesh=MeshSettings.coarse(contact_size_mm=1.5))
    return model, read_measurement_set(out)
