"""The model service: content keys, the atomic result store, one preparation per geometry."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cad.errors import ConvergenceError, ParameterError
from cad.general_params import GeneralHingeParams
from fe.cycle.protocol import CycleSettings
from fe.kinds import hinge_kind
from mesh.settings import MeshSettings
from model.service import ModelService
from model.spec import DesignPoint, ModelSpec, point_label, result_key
from model.store import ResultStore


def _spec(**cycle):
    return ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(**{"increments_per_stage": 6, "clearance_increments": 6, **cycle}),
    )


def test_result_key_changes_with_every_input_and_only_then():
    spec, p = _spec(), DesignPoint(300.0, {"clearance_mm": 0.0})
    key = result_key(spec, p)
    assert (
        result_key(_spec(), DesignPoint(300, {"clearance_mm": -0.0})) == key
    )  # same point, other spelling
    changed = [
        result_key(_spec(mu=0.1), p),
        result_key(_spec(increments_per_stage=8), p),
        result_key(dataclasses.replace(spec, mesh=MeshSettings.coarse(refinement=1)), p),
        result_key(
            dataclasses.replace(spec, effects={"frame_compliance": {"compliance_mm_per_n": 1e-5}}),
            p,
        ),
        result_key(spec, DesignPoint(301.0, {"clearance_mm": 0.0})),
        result_key(spec, DesignPoint(300.0, {"clearance_mm": 0.1})),
    ]
    assert len({key, *changed}) == len(changed) + 1


def test_store_round_trip_and_one_preparation_per_geometry(tmp_path):
    store = ResultStore(tmp_path / "results")
    service = ModelService(store=store)
    spec = _spec()
    runs = service.run(spec, [DesignPoint(200.0), DesignPoint(400.0), DesignPoint(200.0)])
    assert [r.point.amplitude_n for r in runs] == [200.0, 400.0]  # the duplicate ran once
    assert service.n_computed == 2
    assert len(service._prepared) == 1  # one mesh + factorisation for both amplitudes
    again = ModelService(store=store).run(spec, [DesignPoint(400.0)])[0]
    assert again.cached
    fresh = runs[1].result.metrics()
    for k, v in again.result.metrics().items():
        assert v == pytest.approx(fresh[k], rel=1e-15, nan_ok=True), k
    np.testing.assert_array_equal(again.result.states[-1].p, runs[1].result.states[-1].p)
    # a half-written file (a temporary that never got renamed) is not a result
    (tmp_path / "results" / ".abc-partial.npz").write_bytes(b"PK\x03")
    assert store.get("abc") is None


def test_a_failing_point_is_recorded_and_the_others_go_on(tmp_path, monkeypatch):
    from cad.errors import ConvergenceError

    service = ModelService()
    real = ModelService._compute

    def flaky(self, spec, point, prepared, progress):
        if point.amplitude_n == 300.0:
            raise ConvergenceError("refused", increment=2, iteration=60, residual=1e-3)
        return real(self, spec, point, prepared, progress)

    monkeypatch.setattr(ModelService, "_compute", flaky)
    runs = service.run(_spec(), [DesignPoint(300.0), DesignPoint(100.0)])
    assert [r.ok for r in runs] == [False, True]
    assert "increment 2, iteration 60" in runs[0].error


def test_run_cycle_refuses_a_clearance_the_mesh_does_not_have():
    from fe.general.cycle import run_cycle

    service = ModelService()
    prepared = service.prepare(_spec(), DesignPoint(300.0, {"clearance_mm": 0.1}))
    assert prepared.built.structure["clearance_mm"] == pytest.approx(0.1, abs=1e-12)
    with pytest.raises(ParameterError, match="does not match the mesh"):
        run_cycle(prepared.system, 0.2, CycleSettings())


def test_design_point_range_is_checked():
    with pytest.raises(ParameterError, match="amplitude_n"):
        DesignPoint(-5.0)


def _bearing_spec():
    from cad.bearing_geometry import BearingHingeParams

    mesh = hinge_kind("bearing").mesh_settings(
        size_mm=4.0, contact_size_mm=0.8, part_sizes_mm=(("ring", 1.2),)
    )
    return ModelSpec("bearing", BearingHingeParams(), mesh, CycleSettings(increments_per_stage=8))


def test_bearing_preloads_share_one_geometry_and_round_trip_the_store(tmp_path):
    spec = _bearing_spec()
    points = [DesignPoint(200.0, {"preload_n": fp}) for fp in (0.0, 100.0)]
    assert result_key(spec, points[0]) != result_key(spec, points[1])
    service = ModelService(store=ResultStore(tmp_path))
    runs = service.run(spec, points)
    assert all(r.ok for r in runs)
    assert len(service._prepared) == 1  # the preload is a load: one mesh, one factorisation
    assert [point_label(spec, r.point) for r in runs] == ["p0_F200", "p100_F200"]
    again = ModelService(store=ResultStore(tmp_path)).run(spec, points)
    assert all(r.cached for r in again)
    for first, second in zip(runs, again, strict=True):
        a, b = first.result, second.result
        assert b.metrics()["disp_at_peak_mm"] == a.metrics()["disp_at_peak_mm"]
        assert b.preload_state is not None
        np.testing.assert_array_equal(b.preload_state.p, a.preload_state.p)
    # the preload stiffens the hinge
    d = [r.result.metrics()["delta_max_mm"] for r in runs]
    assert d[1] < d[0]


def test_bearing_point_and_spec_mistakes_are_named():
    from cad.bearing_geometry import BallModel, BearingHingeParams, Interfaces

    spec = _bearing_spec()
    with pytest.raises(
        ParameterError, match="clearance_mm is not a design variable of the bearing"
    ):
        result_key(spec, DesignPoint(200.0, {"clearance_mm": 0.1}))
    with pytest.raises(ParameterError, match="preload_n is not a design variable of the general"):
        result_key(_spec(), DesignPoint(200.0, {"preload_n": 50.0}))
    with pytest.raises(ParameterError, match=r"preload_n must be in \[0, 500\], got -5"):
        result_key(spec, DesignPoint(200.0, {"preload_n": -5.0}))
    full = dataclasses.replace(
        spec, hinge=BearingHingeParams(ball_model=BallModel.FULL, interfaces=Interfaces.CONTACT)
    )
    with pytest.raises(ParameterError, match="runs with interfaces = 'bonded' only"):
        ModelService().run(full, [DesignPoint(200.0)])


def test_a_result_of_an_older_store_format_is_recomputed_not_an_error(tmp_path):
    """A sweep interrupted before an upgrade resumes: the old file is a miss, not a DataError."""
    import json as _json

    store = ResultStore(tmp_path)
    key = "a" * 64
    store.root.mkdir(parents=True, exist_ok=True)
    v1 = np.zeros((3, 11))  # format 1: eleven increment columns (no tangent stiffness)
    np.savez(store.path(key), meta=np.array(_json.dumps({"format": 1, "key": key})), increments=v1)
    assert store.get(key) is None
    other = np.array(_json.dumps({"format": 2, "key": "b" * 64}))
    np.savez(store.path(key), meta=other, increments=np.zeros((3, 12)))
    with pytest.raises(Exception, match="stored key does not match"):
        store.get(key)


@pytest.mark.slow  # 13 s (two bearing systems)
def test_a_loop_effect_applies_to_the_bearing_hinge_and_a_contact_effect_is_refused():
    spec = _bearing_spec()
    point = DesignPoint(300.0, {"preload_n": 100.0})
    bare = ModelService().run_point(spec, point)
    framed_spec = dataclasses.replace(
        spec, effects={"frame_compliance": {"compliance_mm_per_n": 2e-5}}
    )
    framed = ModelService().run_point(framed_spec, point)
    d0, d1 = bare.metrics()["disp_at_peak_mm"], framed.metrics()["disp_at_peak_mm"]
    assert d1 - d0 == pytest.approx(2e-5 * 300.0, rel=1e-9)
    assert all(np.isnan(i.stiffness_n_per_mm) for i in framed.increments)  # δ changed
    contact = dataclasses.replace(spec, effects={"face_friction": {"clamp_force_n": 100.0}})
    with pytest.raises(
        ParameterError, match=r"\['face_friction'\] do not act on the bearing hinge"
    ):
        ModelService().run(contact, [point])


class _StandInRunner:
    """A cluster runner that hands back the given (result, error) per job, in order."""

    def __init__(self, outcomes):  # type: ignore[no-untyped-def]
        self.outcomes = outcomes

    def run(self, jobs, arrived, summarize=False):  # type: ignore[no-untyped-def]
        for j, _ in enumerate(jobs):
            arrived(j, *self.outcomes[j])


def _no_convergence() -> ConvergenceError:
    return ConvergenceError("increment failed", increment=3, iteration=60, residual=1.0)


def test_a_cycle_that_does_not_converge_counts_as_computed_here_and_on_a_cluster(monkeypatch):
    """n_computed counts the same cycles in process and on a cluster (issue 35: a failed
    candidate value counted here and not there, 540 against 539)."""
    spec = _spec()

    def fails(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        raise _no_convergence()

    monkeypatch.setattr(type(spec.hinge_kind), "run", fails)
    here = ModelService()
    (outcome,) = here.run_jobs([(spec, DesignPoint(200.0))])
    there = ModelService(
        runner=_StandInRunner([(None, _no_convergence()), (None, ParameterError("refused"))])
    )
    outcomes = there.run_jobs([(spec, DesignPoint(200.0)), (spec, DesignPoint(300.0))])

    assert isinstance(outcome, ConvergenceError)
    assert [type(o) for o in outcomes] == [ConvergenceError, ParameterError]
    assert here.n_computed == there.n_computed == 1  # the refused job ran no cycle
