"""Loop features for diagnosis: a few robust, nearly independent numbers per case.

A loop's residual (model − measured, sample by sample or on a force grid) is strongly
correlated along the loop, so a χ² over loop points would count one misfit many times
and make every test over-confident. Diagnosis therefore summarises each loop, measured
and computed alike (both through ``validation.loops.process_loop``), into three features
(``FEATURES``):

* ``delta_max_mm``: half the peak-to-peak displacement of the last loop, free play
  included [mm] (not δ(±Fg) from the initial zero: that zero depends on where the pin
  sat in its free play before loading);
* ``W_cycle_Nmm``: the loop area [N·mm];
* ``opening_mm``: the loop's width at F = +½F_max, descending minus ascending branch
  [mm] (at −½ … +½ F_max with clearance the free play crossing makes it ill-defined at 0).

Their uncertainty σ (``feature_sigma``) combines, in quadrature,

* the **noise** of the record: displacement noise σ_d and force noise σ_F (estimated
  from the record, ``validation.loops.noise_level``) propagate to δ(±Fg) as
  ``σ_d/√2`` plus ``δ_max/F_max · σ_F`` (the peaks are picked on a noisy force), to
  the opening as ``√2`` times ``σ_d`` and ``δ_max/F_max · σ_F`` in quadrature (one
  sample per branch), and to W by first-order propagation through the shoelace
  sum: ``var W = ¼ Σ σ_d² (F_{i+1} − F_{i−1})² + ¼ Σ σ_F² (δ_{i+1} − δ_{i−1})²``;
* the **model floor**: a coarse model mesh cannot reproduce a real (or finer) hinge
  exactly, so ``rel_floor · δ_max`` for δ_max, ``rel_floor · |W| + eta_floor · π F_max
  δ_max`` for W (an absolute η resolution: with clearance W is tiny and its
  discretisation error is first order in the increments) and ``rel_floor · opening +
  eta_floor · δ_max`` for the opening;
* the **replicate scatter**, when a design point was measured more than once (the
  sample standard deviation of the feature over the replicates).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cad.errors import check_range
from validation.loops import ProcessedLoop, area_noise_sigma, noise_level

FloatArray = npt.NDArray[np.float64]

FEATURES = ("delta_max_mm", "W_cycle_Nmm", "opening_mm")
"""Feature names, in column order."""


@dataclass(frozen=True)
class FeatureSettings:
    """The model floor of the feature uncertainty.

    Attributes:
        rel_floor: Relative model error of δ(±Fg) and W (default 2 %: the coarse model
            mesh against a finer one; at Δr = 0, η is 0.0146 / 0.0147 / 0.0149 on the
            coarse / default level-0 / level-1 meshes, benchmarks/bench_cycle.py).
        eta_floor: Absolute η resolution added to σ_W as ``eta_floor · π F_max δ_max``
            (default 0.001: with Δr = 0.1 mm η at 400 N is 0.00126 / 0.00114 / 0.00103 at
            levels 0 / 1 / 2, a discretisation error of ~0.0003 that the floor covers with
            room for the increment size).
        eta_rel_sigma: Relative uncertainty of a stated η (η-only tables carry none).
        max_rel_sigma: A feature whose σ exceeds this fraction of its own value carries
            no information about a relative model error below 100 % (e.g. the loop area
            with clearance, where the force noise during the free-play crossing gives W a
            σ tens of times the area): it is left out of χ² and of N, so that it neither
            hides an error nor raises the noise limit.
    """

    rel_floor: float = 0.02
    eta_floor: float = 0.001
    eta_rel_sigma: float = 0.05
    max_rel_sigma: float = 1.0

    def __post_init__(self) -> None:
        check_range("rel_floor", self.rel_floor, 0.0, 1.0)
        check_range("eta_floor", self.eta_floor, 0.0, 1.0)
        check_range("eta_rel_sigma", self.eta_rel_sigma, 0.0, 1.0)
        check_range("max_rel_sigma", self.max_rel_sigma, 0.0, float("inf"), lo_open=True)


def loop_features(loop: ProcessedLoop) -> FloatArray:
    """Return the features of a processed loop, shape (3,) in ``FEATURES`` order."""
    m = loop.metrics
    half = 0.5 * m.f_max_n
    (Fd, dd), (Fu, du) = loop.branches()
    opening = _at_force(Fd, dd, half) - _at_force(Fu, du, half)
    return np.array([m.delta_max_mm, m.W_cycle_Nmm, opening])


def _at_force(F: FloatArray, d: FloatArray, f: float) -> float:
    """δ of one branch at force f: the samples sorted by force (noise makes F non-monotone)."""
    order = np.argsort(F, kind="stable")
    return float(np.interp(f, F[order], d[order]))


def noise_sigma(loop: ProcessedLoop) -> FloatArray:
    """Return the noise part of the features' σ, shape (3,) (module docstring)."""
    F, d = loop.force_n, loop.displacement_mm
    s_F, s_d = noise_level(F), noise_level(d)
    m = loop.metrics
    slope = m.delta_max_mm / m.f_max_n * s_F
    s_delta = math.hypot(s_d / math.sqrt(2.0), slope)
    s_open = math.sqrt(2.0) * math.hypot(s_d, slope)
    return np.array([s_delta, area_noise_sigma(F, d, loop.stages), s_open])


def feature_sigma(
    loops: Sequence[ProcessedLoop], settings: FeatureSettings, replicate_std: FloatArray | None
) -> FloatArray:
    """Return σ of the features of one design point, shape (3,).

    Args:
        loops: The measured loops of the design point (replicates), at least one.
        settings: The model floor.
        replicate_std: The sample std of the features over the replicates, shape (3,),
            or None for a single measurement.
    """
    noise = np.mean([noise_sigma(p) for p in loops], axis=0)
    feats = np.mean([loop_features(p) for p in loops], axis=0)
    m = loops[0].metrics
    floor = np.array(
        [
            settings.rel_floor * m.delta_max_mm,
            settings.rel_floor * abs(feats[1])
            + settings.eta_floor * math.pi * m.f_max_n * m.delta_max_mm,
            settings.rel_floor * abs(feats[2]) + settings.eta_floor * m.delta_max_mm,
        ]
    )
    rep = np.zeros(3) if replicate_std is None else np.asarray(replicate_std, dtype=np.float64)
    return np.asarray(np.sqrt(noise**2 + floor**2 + rep**2), dtype=np.float64)


def derived(features: FloatArray, amplitude_n: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Return (δ_max [mm], η) from features, shape (n_cases, 3) → two (n_cases,) arrays."""
    f = np.asarray(features, dtype=np.float64)
    delta = f[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        eta = f[:, 1] / (math.pi * np.asarray(amplitude_n) * delta)
    return delta, eta
