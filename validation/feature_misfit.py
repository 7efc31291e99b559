"""One error on every screen: the feature misfit that ``calibrate``'s ledger and ``compare`` share.

The ledger of ``validation.calibrate`` and the summary of ``validation.compare`` both judge
a model by :func:`feature_misfit`: the features of ``validation.features`` (δ_max, loop
area, opening — none depends on where the record's displacement zero lies), their σ
(noise ⊕ model floor ⊕ replicates) and the residuals of
``validation.candidate_fit.residuals``. It returns

* ``χ²`` over the informative features and ``error = sqrt(χ²/N)`` (≈ 1 at the noise);
* per design point, whether every informative feature lies within ``k σ`` (k = 2, as
  ``compare``'s coverage factor): the points the ledger calls **fitted**, with the case
  ids measured there (``group_case_ids``).

``calibrate`` evaluates it on the features of ``validation.evaluate.ModelEvaluator``,
``compare`` on the model loops it compares (``model_features_of_loops``): the same
function on the same features and uncertainties, so the error the ledger reports after a
calibration is the one ``compare`` prints for the written model.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cad.errors import DataError
from validation.candidate_fit import FloatArray, MeasuredFeatures, measured_features, residuals
from validation.evaluate import average_features
from validation.features import FeatureSettings, loop_features
from validation.loops import ProcessedLoop
from validation.measurements import MeasurementSet

K_FITTED = 2.0
"""A design point is fitted when every informative feature lies within this many σ."""


@dataclass(frozen=True)
class FeatureMisfit:
    """The misfit of model features to measured ones (module docstring).

    Attributes:
        chi2: Σ r² over the informative features.
        n_obs: Number of informative features N.
        error: sqrt(χ²/N) [σ].
        point_fitted: Per design point (``MeasuredFeatures.points`` order): every
            informative feature within ``k`` σ, shape (n_points,).
        k: The coverage factor used.
    """

    chi2: float
    n_obs: int
    error: float
    point_fitted: tuple[bool, ...]
    k: float

    @property
    def n_fitted(self) -> int:
        """Design points within k σ on every feature."""
        return sum(self.point_fitted)


def feature_misfit(model: FloatArray, meas: MeasuredFeatures, k: float = K_FITTED) -> FeatureMisfit:
    """Return χ², the error and the fitted design points of model features.

    Args:
        model: Model features, shape (n_points, 3) (NaN rows: a failed run, counted 1e3 σ).
        meas: The measured features.
        k: Coverage factor of "fitted".
    """
    r = residuals(model, meas)
    c = float(np.sum(r**2))
    n = max(meas.n_obs, 1)
    fitted = tuple(bool(np.all(np.abs(row) <= k)) for row in r)
    return FeatureMisfit(c, meas.n_obs, float(np.sqrt(c / n)), fitted, k)


def group_case_ids(data: MeasurementSet) -> list[tuple[str, ...]]:
    """Case ids per design point, in ``validation.candidate_fit.measured_features`` row order.

    A design point with neither a loop nor an η is no row there, and none here.
    """
    by_id = data.by_id()
    return [
        ids
        for ids in data.replicate_groups().values()
        if any(by_id[i].loop is not None or by_id[i].eta is not None for i in ids)
    ]


def fitted_cases(misfit: FeatureMisfit, data: MeasurementSet) -> list[str]:
    """Case ids of the design points the misfit calls fitted."""
    groups = group_case_ids(data)
    return [i for ids, ok in zip(groups, misfit.point_fitted, strict=True) if ok for i in ids]


def model_features_of_loops(
    data: MeasurementSet, model_loops: Mapping[str, ProcessedLoop]
) -> FloatArray:
    """Features of the model's loops per design point, shape (n_points, 3).

    Replicates share one design point; their model loops differ only when a loop effect
    depends on time (each at its record's clock): the features are then averaged over the
    point's records, as ``validation.evaluate.ModelEvaluator.features`` does (identical
    loops give the first's features exactly).

    Args:
        data: The measured cases.
        model_loops: case_id → the processed model loop of that case.
    """
    by_id = data.by_id()
    rows = []
    for ids in group_case_ids(data):
        looped = [i for i in ids if by_id[i].loop is not None] or list(ids[:1])
        rows.append(average_features([loop_features(model_loops[i]) for i in looped]))
    return np.array(rows, dtype=np.float64).reshape(len(rows), 3)


def feature_summary(
    data: MeasurementSet, model_loops: Mapping[str, ProcessedLoop], settings: FeatureSettings
) -> dict[str, Any]:
    """The ledger's error of the model loops ``compare`` judged (JSON-ready).

    Returns:
        ``{"chi2", "n_obs", "error", "n_points", "n_fitted", "fitted_cases", "k"}``; ``{}``
        without feature rows, ``{"not_available": why}`` for records the features do not
        describe (displacement-controlled).
    """
    try:
        meas = measured_features(data, settings)
    except DataError as err:  # records the features do not describe (displacement control)
        return {"not_available": str(err)}
    if len(meas.points) == 0:
        return {}
    m = feature_misfit(model_features_of_loops(data, model_loops), meas)
    return {
        "chi2": m.chi2,
        "n_obs": m.n_obs,
        "error": m.error,
        "n_points": len(m.point_fitted),
        "n_fitted": m.n_fitted,
        "fitted_cases": fitted_cases(m, data),
        "k": m.k,
    }
