"""Coarse to fine: a diagnosis whose grids run on the coarse mesh judges on the model's own.

Fast: which mesh screens which model. Slow: on one data set, the screened and the plain
diagnosis of a model finer than the coarse preset reach the same verdict and value, the
screened one with fewer model-mesh cycles, and every χ² it reports is the model mesh's.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fe.kinds import hinge_kind
from mesh.settings import MeshSettings
from validation.candidates import screen_mesh


def _spec(kind: str, mesh: MeshSettings | None = None):
    from model.spec import ModelSpec

    k = hinge_kind(kind)
    return ModelSpec(kind, k.params_type(), mesh or k.mesh_settings())


@pytest.mark.parametrize("kind", ["general", "bearing"])
def test_a_default_mesh_is_screened_on_its_kinds_coarse_preset(kind):
    coarse = hinge_kind(kind).mesh_settings(coarse=True)
    assert screen_mesh(_spec(kind)) == coarse
    assert screen_mesh(_spec(kind, coarse)) is None  # the coarse model itself: no screen
    finer = dataclasses.replace(coarse, refinement=1)
    assert screen_mesh(_spec(kind, finer)) == coarse
    coarser = dataclasses.replace(coarse, size_mm=coarse.size_mm * 1.5)
    assert screen_mesh(_spec(kind, coarser)) is None


@pytest.mark.slow
def test_screened_and_plain_diagnoses_agree_and_the_screen_saves_model_cycles(tmp_path):
    from validation.candidate_fit import chi2, measured_features
    from validation.diagnose import diagnose
    from validation.evaluate import ModelEvaluator

    from .screen_data import coarse_data_and_finer_model, search_settings

    model, data = coarse_data_and_finer_model(tmp_path, (100.0, 250.0, 400.0), seed=31)
    base = search_settings(candidates=("roughness_softening", "tangential_compliance"))
    plain = diagnose(model, data, dataclasses.replace(base, screen=False))
    screened = diagnose(model, data, base)
    assert screened.stats["screen_cycles"] > 0
    assert plain.stats["screen_cycles"] == 0
    assert screened.verdict == plain.verdict
    assert screened.effects == plain.effects
    assert screened.effects[:1] == ("roughness_softening",), screened.text()
    by_name = {c.name: c for c in plain.candidates}
    for c in screened.candidates:
        p = by_name[c.name]
        if p.value > 0 and c.value > 0:
            assert abs(np.log10(c.value / p.value)) < 0.05, (c.name, c.value, p.value)
        assert c.chi2 <= 1.05 * p.chi2 + 1.0, (c.name, c.chi2, p.chi2)
    assert screened.stats["n_cycles"] < plain.stats["n_cycles"]
    # every χ² the screened verdict used is the model mesh's own at the reported value
    meas = measured_features(data, base.features)
    ev = ModelEvaluator(model, meas.points, 6, 12)
    best = screened.candidates[0]
    again = chi2(ev.features({best.name: {best.param: best.value}}), meas)
    assert again == pytest.approx(best.chi2, rel=1e-9)


class _StandInRunnerService:
    """A service with a runner whose every run fails (no cycle is computed)."""

    runner = object()

    def run_jobs(self, jobs: list[object]) -> list[BaseException]:
        from cad.errors import DataError

        return [DataError("stand-in") for _ in jobs]


def test_batches_count_each_run_once_in_process_as_on_a_cluster() -> None:
    """``stats["batches"]``: in process a run announced by a batch is made later, when asked
    for; announcing it again (the grids' batch, then each candidate's) counted it twice."""
    from cad.general_params import GeneralHingeParams
    from model.spec import ModelSpec
    from validation.evaluate import ModelEvaluator, prefetch_together

    spec = ModelSpec("general", GeneralHingeParams())
    points = [(0.0, 100.0), (0.0, 250.0)]
    rough = {"roughness_softening": {"compliance_mm3_per_n": 1e-4}}
    soft = {"tangential_compliance": {"compliance_mm3_per_n": 1e-4}}
    widths = []
    for service in (None, _StandInRunnerService()):
        ev = ModelEvaluator(spec, points, service=service)
        coarse = ModelEvaluator(spec, points[:1], service=ev.service)
        prefetch_together([(ev, [({}, None), (rough, None)]), (coarse, [({}, None)])])
        ev.prefetch([(rough, None)])  # announced already: no batch
        ev.prefetch([(rough, None), (soft, None)])  # one new effect: its 2 runs
        widths.append((ev.batches, coarse.batches))
    assert widths[0] == widths[1] == ([5, 2], [5])
