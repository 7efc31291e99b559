"""η-only rows with clearance: the free play is taken off δ_max only where the model crossed it."""

from __future__ import annotations

import math

import numpy as np
import pytest


def test_free_play_taken_off_only_where_the_model_crossed_it(tmp_path):
    """Clamped faces that hold the clevis below their slip force never cross the free play
    (``fe.general.freeplay``): their δ_max is elastic and must not lose 2Δr."""
    from validation.candidate_fit import eta_without_free_play, measured_features
    from validation.features import FeatureSettings
    from validation.measurements import read_eta_table

    path = tmp_path / "eta.csv"
    path.write_text("clearance_mm,amplitude_N,eta\n0.1,100,0.05\n0.1,400,0.08\n")
    meas = measured_features(read_eta_table(path), FeatureSettings())
    # δ_max [mm], W [N·mm], opening: 100 N held by the faces, 400 N slid across the play
    model = np.array([[0.0013, 0.025, 0.0], [0.2081, 9.0, 0.0]])
    eta = eta_without_free_play(model, meas)
    assert eta[0] == pytest.approx(0.025 / (math.pi * 100.0 * 0.0013))
    assert eta[1] == pytest.approx(9.0 / (math.pi * 400.0 * 0.0081))
    failed = eta_without_free_play(np.full((2, 3), np.nan), meas)
    assert np.all(np.isnan(failed))
