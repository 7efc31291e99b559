"""The general hinge's system: compliance cache, low-memory mode and the condensed operators."""

from __future__ import annotations

import numpy as np
import pytest

from cad.errors import ParameterError
from cad.general import make_general_hinge
from cad.general_params import GeneralHingeParams
from fe.surfaces.geometry import contact_geometry
from mesh.build import mesh_hinge
from mesh.settings import MeshSettings


def test_compliance_cache_is_keyed_by_mesh_content(tmp_path):
    from fe.general.system import build_system

    settings = MeshSettings.coarse()
    mesh, _ = mesh_hinge(make_general_hinge(GeneralHingeParams()), settings)
    first = build_system(mesh, cache_dir=tmp_path)
    s1, m1 = first.nodal_compliance()
    assert len(list(tmp_path.glob("compliance_*.npz"))) == 1
    second = build_system(mesh, cache_dir=tmp_path)  # another process would do the same
    s2, m2 = second.nodal_compliance()
    assert np.array_equal(s1, s2)
    assert np.array_equal(m1, m2)
    other, _ = mesh_hinge(make_general_hinge(GeneralHingeParams(clearance_mm=0.1)), settings)
    assert other.content_hash() != mesh.content_hash()
    build_system(other, cache_dir=tmp_path).nodal_compliance()
    assert len(list(tmp_path.glob("compliance_*.npz"))) == 2
    assert not list(tmp_path.glob(".*tmp*"))


def test_low_memory_mode_holds_one_factor_and_recovers_the_same_fields():
    # At refinement 2 both sparse factors plus the dense operators exceeded 24 GB; in
    # low-memory mode each factor is released after its solve. The fields must not change.
    import dataclasses

    from fe.cycle.protocol import CycleSettings
    from fe.general.cycle import run_cycle
    from fe.general.system import build_system, displacement, displacements

    settings = MeshSettings.coarse()
    mesh, _ = mesh_hinge(make_general_hinge(GeneralHingeParams()), settings)
    kept = build_system(mesh)
    assert not kept.low_memory  # the coarse mesh is far below LOW_MEMORY_DOF
    res = run_cycle(kept, 0.0, CycleSettings(amplitude_n=300.0, increments_per_stage=4))
    cond = res.configs[1]
    picks = [(cond, np.asarray(s.p), np.asarray(s.alpha)) for s in res.states[::3]]
    one_by_one = [displacement(kept, *pick) for pick in picks]
    assert set(kept._factors) == {"lug", "pin"}  # kept for reuse

    lean = dataclasses.replace(kept, _factors={}, low_memory=True, timings_s=dict(kept.timings_s))
    batch = displacements(lean, picks)
    assert lean._factors == {}  # both released
    assert lean.timings_s["factorisation"] > kept.timings_s["factorisation"]  # made again
    for a, b in zip(one_by_one, batch, strict=True):
        assert np.abs(a - b).max() <= 1e-12 * np.abs(a).max()
    assert np.abs(one_by_one[-1]).max() > 1e-4  # a real field, not zeros


def _contact_like(m, b, per_row, rng):
    """A (3m, b) sparse operator with ``per_row`` entries per row, as C's slave/master parts."""
    import scipy.sparse as sp

    rows = np.repeat(np.arange(3 * m), per_row)
    cols = rng.integers(0, b, size=rows.size)
    return sp.csr_matrix((rng.normal(size=rows.size), (rows, cols)), shape=(3 * m, b))


def test_delassus_by_row_blocks_is_the_whole_matrix_formula_and_allocates_one_w(monkeypatch):
    """W = ½(V + Vᵀ), V = C_s S_s C_sᵀ + C_m S_m C_mᵀ, equals the whole-matrix expression bit
    for bit, is exactly symmetric, and allocates W and row blocks only (the whole-matrix
    expression held about four W-sized arrays)."""
    import tracemalloc

    import fe.general.condensation as condensation

    rng = np.random.default_rng(5)
    m, b_s, b_m = 400, 1100, 700
    Cs, Cm = _contact_like(m, b_s, 3, rng), _contact_like(m, b_m, 12, rng)
    A, B = rng.normal(size=(b_s, b_s)), rng.normal(size=(b_m, b_m))
    S_s, S_m = A @ A.T, B @ B.T
    V = np.asarray(Cs @ (Cs @ S_s).T) + np.asarray(Cm @ (Cm @ S_m).T)
    expected = 0.5 * (V + V.T)
    monkeypatch.setattr(condensation, "CONDENSE_ROWS", 50)  # 24 blocks, a ragged last one
    tracemalloc.start()
    W = condensation.delassus(Cs, S_s, Cm, S_m)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    np.testing.assert_array_equal(W, expected)
    assert np.array_equal(W, W.T)
    assert peak < 1.25 * W.nbytes, f"peak {peak / W.nbytes:.2f} W"


@pytest.fixture(scope="module")
def coarse_zero_clearance():
    """The coarse general hinge and its zero-clearance contact points."""
    mesh, _ = mesh_hinge(make_general_hinge(GeneralHingeParams()), MeshSettings.coarse())
    geo = contact_geometry(mesh, {p.name: np.zeros(3) for p in mesh.pairs})
    sizes = (
        3 * len(np.unique(geo.slave)),
        3 * len(np.unique(geo.master_nodes)),
        3 * len(geo.slave),
    )
    return mesh, geo, sizes


def test_condensation_by_pin_solves_is_the_compliance_condensation(
    monkeypatch, coarse_zero_clearance
):
    """W with its pin part from block solves with the pin's factor equals W from the nodal
    compliance blocks to round-off, is exactly symmetric, and leaves no compliance block
    in the system (what lets a zero-clearance level 2 fit); the pin factor is released in
    low-memory mode."""
    import fe.general.condensation as condensation
    from fe.general.condensation import condense
    from fe.general.system import build_system

    mesh, geo, _ = coarse_zero_clearance
    reference = condense(build_system(mesh), geo).W
    monkeypatch.setenv("HINGELAB_CONDENSE", "solves")
    monkeypatch.setattr(condensation, "BLOCK_RHS", 100)  # several blocks, a ragged last one
    system = build_system(mesh)
    system.low_memory = True
    cond = condense(system, geo)
    assert np.abs(cond.W - reference).max() <= 1e-11 * np.abs(reference).max()
    assert np.array_equal(cond.W, cond.W.T)
    assert not system.has_compliance(np.unique(geo.slave), np.unique(geo.master_nodes))
    assert "pin" not in system._factors
    assert system.timings_s["compliance"] > 0.0
    monkeypatch.setenv("HINGELAB_CONDENSE", "schur")
    with pytest.raises(ParameterError, match=r"HINGELAB_CONDENSE = 'schur'.*'solves'"):
        condense(system, geo)


def test_condensation_takes_the_path_that_fits_or_refuses_before_allocating(
    monkeypatch, coarse_zero_clearance
):
    """The compliance blocks where they fit; the pin solves where only those fit; else a
    ResourceError naming the sizes and both estimates before the first dense solve (a
    zero-clearance level 2 would otherwise be killed minutes later). HINGELAB_MEMORY_CHECK=0
    lets it run; kept compliances are not counted."""
    import fe.general.memory as memory
    from cad.errors import ResourceError
    from fe.general.condensation import condense
    from fe.general.memory import (
        CondensePath,
        condense_path,
        dense_memory_bytes,
        solves_memory_bytes,
    )
    from fe.general.system import build_system

    mesh, geo, (b_s, b_m, n) = coarse_zero_clearance
    system = build_system(mesh)
    nodes = (np.unique(geo.slave), np.unique(geo.master_nodes), len(geo.slave))
    need, low = dense_memory_bytes(b_s, b_m, n), solves_memory_bytes(b_m, n)
    assert need >= 8 * (b_s**2 + b_m**2 + n**2)  # at least the blocks and W themselves
    assert 8 * n**2 <= low < need  # at zero clearance the slave block is W's size
    monkeypatch.setattr(memory, "available_memory_bytes", lambda: low - 1)
    with pytest.raises(
        ResourceError,
        match=rf"{n}² entries.*or {low / 1e6:.1f} MB by pin solves.*{(low - 1) / 1e6:.1f} MB are",
    ):
        condense(system, geo)
    assert "compliance" not in system.timings_s  # refused before the first dense solve
    monkeypatch.setattr(memory, "available_memory_bytes", lambda: need - 1)
    assert condense_path(system, *nodes) is CondensePath.SOLVES
    monkeypatch.setattr(memory, "available_memory_bytes", lambda: need)
    assert condense_path(system, *nodes) is CondensePath.COMPLIANCE
    monkeypatch.setattr(memory, "available_memory_bytes", lambda: low - 1)
    monkeypatch.setenv("HINGELAB_MEMORY_CHECK", "0")
    assert condense_path(system, *nodes) is CondensePath.COMPLIANCE
    cond = condense(system, geo)
    assert cond.W.shape == (n, n)
    monkeypatch.delenv("HINGELAB_MEMORY_CHECK")
    kept = dense_memory_bytes(b_s, b_m, n, compliance_kept=True)
    assert kept < need
    monkeypatch.setattr(memory, "available_memory_bytes", lambda: kept)
    assert condense_path(system, *nodes) is CondensePath.COMPLIANCE  # blocks kept: W only
    monkeypatch.setattr(memory, "available_memory_bytes", lambda: min(kept, low) - 1)
    with pytest.raises(ResourceError):
        condense(system, geo)
