"""A job's numbers do not depend on the threads of the process that runs it (issue 35).

In process a cycle has the machine's cores; as a Dask task it has one. A diagnosis must
give the same verdict, fitted values and χ² on both, to the bit: the differences thread
counts make in the last bits (PARDISO's factor, OpenBLAS's kernels) can change a contact
Newton path (session 21: the paper's validation in process and on 2 workers, a held-out
χ² 3e-4 apart). The job runs
OpenBLAS on one thread and PARDISO factorises on one (``fe.linalg.threads``,
``fe.linalg.sparse``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from threadpoolctl import threadpool_limits

from cad.general_params import GeneralHingeParams
from fe.cycle.protocol import CycleSettings
from mesh.settings import MeshSettings
from model.service import ModelService
from model.spec import DesignPoint, ModelSpec


def _run(threads: int):  # type: ignore[no-untyped-def]
    spec = ModelSpec(
        "general",
        GeneralHingeParams(),
        MeshSettings.coarse(),
        CycleSettings(increments_per_stage=6, clearance_increments=6),
    )
    with threadpool_limits(limits=threads):  # every pool of the process: MKL, OpenBLAS
        return ModelService().run_point(spec, DesignPoint(300.0, {"clearance_mm": 0.1}))


def _signature(result):  # type: ignore[no-untyped-def]
    return (
        [dataclasses.astuple(i) for i in result.increments],
        [s.p.tobytes() + s.w.tobytes() for s in result.states],
    )


def test_a_cycle_gives_the_same_bits_on_one_and_two_process_threads():
    one, two = _run(1), _run(2)

    np.testing.assert_equal(_signature(one), _signature(two))  # NaN where both are NaN
    np.testing.assert_equal(one.metrics(), two.metrics())


def test_a_cycle_does_not_depend_on_the_cycles_run_before_it_on_its_geometry():
    """A diagnosis runs many cycles on one prepared geometry, in another order in process
    than on each worker: the contact solver must not carry what it learnt of ``W`` (its
    Krylov base, its working set) from one cycle into the next (``start_afresh``)."""
    cycle = CycleSettings(increments_per_stage=8, clearance_increments=16)  # a diagnosis' screen
    spec = ModelSpec("general", GeneralHingeParams(), MeshSettings.coarse(), cycle)
    point = DesignPoint(200.0, {"clearance_mm": 0.0})

    fresh = ModelService().run_point(spec, point)
    service = ModelService()
    service.run_point(spec, DesignPoint(100.0, {"clearance_mm": 0.0}))  # same geometry, W
    after = service.run_point(spec, point)

    np.testing.assert_equal(_signature(after), _signature(fresh))
