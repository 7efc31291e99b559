import numpy as np
import pytest
import scipy.sparse as sp

from cad.errors import ParameterError, SolverError
from cad.materials import Material, lame_from_young_poisson
from fe.assembly import (
    assemble_body_force,
    assemble_stiffness,
    dofs_of,
    element_dofs,
    nodal_average,
    solve_dirichlet,
    strain_energy,
    stress_field,
)
from fe.element import ElementType, element_stiffness
from fe.linalg.sparse import Factorization, LinearSolverBackend, inverse_block
from mesh.hexmesh import HexMesh
from tests.helpers import TEST_MATERIAL, box_mesh, merge_meshes

KINDS = list(ElementType)
KIND_IDS = [k.name.lower() for k in KINDS]
BACKENDS = [LinearSolverBackend.PARDISO, LinearSolverBackend.SCIPY]
BACKEND_IDS = ["pardiso", "scipy"]
SQRT_EPS = np.sqrt(np.finfo(float).eps)
GRAD_U = np.array([[1.0, 0.2, -0.3], [0.4, -0.5, 0.1], [0.0, 0.6, 0.8]]) * 1e-3
OFFSET = np.array([0.01, -0.02, 0.03])


def _boundary_nodes(mesh):
    return np.unique(np.concatenate([f.ravel() for f in mesh.facet_sets.values()]))


def _linear_field(nodes):
    return nodes @ GRAD_U.T + OFFSET


@pytest.fixture(scope="module")
def distorted():
    return box_mesh(3.0, 2.0, 1.5, 4, 3, 3, distort=0.3, seed=7)


@pytest.mark.parametrize("kind", KINDS, ids=KIND_IDS)
def test_patch_test_reproduces_linear_field_on_distorted_mesh(distorted, kind):
    mesh = distorted
    K = assemble_stiffness(mesh, kind)
    exact = _linear_field(mesh.nodes)
    bnd = _boundary_nodes(mesh)
    interior = np.setdiff1d(np.arange(mesh.n_nodes), bnd)
    assert len(interior) == 12  # the distorted nodes are the unknowns
    fixed = dofs_of(bnd)
    u = solve_dirichlet(K, np.zeros(K.shape[0]), fixed, exact.ravel()[fixed]).reshape(-1, 3)
    err = np.abs(u - exact).max() / np.abs(exact).max()
    assert err < SQRT_EPS
    eps = 0.5 * (GRAD_U + GRAD_U.T)
    lam, mu = lame_from_young_poisson(TEST_MATERIAL.young_mpa, TEST_MATERIAL.poisson)
    sigma = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
    voigt = sigma[[0, 1, 2, 1, 0, 0], [0, 1, 2, 2, 2, 1]]
    stress = stress_field(mesh, u, kind)
    assert np.abs(stress - voigt).max() < SQRT_EPS * np.abs(voigt).max()


@pytest.mark.parametrize("kind", KINDS, ids=KIND_IDS)
def test_global_stiffness_symmetric_with_zero_rigid_body_energy(distorted, kind):
    K = assemble_stiffness(distorted, kind)
    assert isinstance(K, sp.csr_matrix)
    assert K.shape == (3 * distorted.n_nodes,) * 2
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()
    x = distorted.nodes - distorted.nodes.mean(axis=0)
    for axis in np.eye(3):
        for u in (np.broadcast_to(axis, x.shape), np.cross(axis, x)):
            scale = abs(K).max() * np.abs(u).max() ** 2 * distorted.n_nodes
            assert abs(strain_energy(K, u)) < 1e-13 * scale


def test_assembly_matches_element_by_element_reference():
    mesh = box_mesh(2.0, 1.0, 1.0, 2, 2, 1, distort=0.2)
    K = assemble_stiffness(mesh).toarray()
    lam, mu = lame_from_young_poisson(TEST_MATERIAL.young_mpa, TEST_MATERIAL.poisson)
    Ke = element_stiffness(mesh.nodes[mesh.hexes], lam, mu)
    ref = np.zeros_like(K)
    for e, d in enumerate(element_dofs(mesh.hexes)):  # a loop is fine in a reference
        ref[np.ix_(d, d)] += Ke[e]
    np.testing.assert_allclose(K, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_chunk_size_does_not_change_result(distorted):
    K1 = assemble_stiffness(distorted)
    K2 = assemble_stiffness(distorted, chunk_size=7)
    assert abs(K1 - K2).max() <= 1e-12 * abs(K1).max()


def test_each_part_uses_its_own_material():
    soft = Material("soft", 1000.0, 0.2)
    a = box_mesh(1.0, 1.0, 1.0, 2, 1, 1, part="stiff")
    b = box_mesh(1.0, 1.0, 1.0, 1, 2, 1, part="soft", material=soft, set_prefix="b_")
    merged = merge_meshes(a, b)
    K = assemble_stiffness(merged).toarray()
    n_a = 3 * a.n_nodes
    np.testing.assert_allclose(K[:n_a, :n_a], assemble_stiffness(a).toarray(), atol=1e-9)
    np.testing.assert_allclose(K[n_a:, n_a:], assemble_stiffness(b).toarray(), atol=1e-12)
    assert not K[:n_a, n_a:].any()


def test_dofs_of_is_node_major():
    np.testing.assert_array_equal(dofs_of([2, 5], [0, 2]), [6, 8, 15, 17])
    np.testing.assert_array_equal(dofs_of([1]), [3, 4, 5])
    assert dofs_of([1], [1]).dtype == np.int64
    with pytest.raises(ParameterError, match=r"comps must be in \{0, 1, 2\}, got \[3\]"):
        dofs_of([0], [3])


def test_nodal_average_of_constant_and_orphan_node():
    mesh = box_mesh(2.0, 1.0, 1.0, 2, 1, 1)
    np.testing.assert_allclose(nodal_average(mesh, np.full((2, 6), 4.5)), 4.5)
    avg = nodal_average(mesh, np.array([1.0, 3.0]))
    shared = np.intersect1d(mesh.hexes[0], mesh.hexes[1])
    np.testing.assert_allclose(avg[shared], 2.0)
    np.testing.assert_allclose(avg[mesh.hexes[0, 0]], 1.0)
    orphan = HexMesh(
        np.vstack([mesh.nodes, [9.0, 9.0, 9.0]]), mesh.hexes, mesh.elem_part,
        mesh.part_names, mesh.materials, {},
    )  # fmt: skip
    assert np.isnan(nodal_average(orphan, np.ones(2))[-1])
    with pytest.raises(ParameterError, match="elem_values"):
        nodal_average(mesh, np.ones(3))


def test_body_force_integrates_total_load():
    mesh = box_mesh(2.0, 1.0, 0.5, 3, 2, 2, distort=0.2)
    f = assemble_body_force(mesh, lambda x: np.tile([0.0, 0.0, -7.0], (len(x), 1)))
    np.testing.assert_allclose(
        f.reshape(-1, 3).sum(axis=0), [0.0, 0.0, -7.0], rtol=1e-13, atol=1e-13
    )
    g = assemble_body_force(mesh, lambda x: np.stack([x[:, 0], 0 * x[:, 0], 0 * x[:, 0]], axis=1))
    assert g.reshape(-1, 3)[:, 0].sum() == pytest.approx(2.0 * 1.0 * 0.5 * 1.0, rel=1e-13)  # ∫x dV


def _tension_problem():
    mesh = box_mesh(4.0, 1.0, 1.0, 4, 1, 1)
    K = assemble_stiffness(mesh)
    x0 = mesh.set_nodes("xmin")
    origin = x0[np.argmin(np.linalg.norm(mesh.nodes[x0], axis=1))]
    fixed = np.unique(np.concatenate([dofs_of(x0, [0]), dofs_of([origin], [1, 2]),
                                      dofs_of([x0[1]], [2]), dofs_of([x0[2]], [1])]))  # fmt: skip
    f = np.zeros(K.shape[0])
    f[dofs_of(mesh.set_nodes("xmax"), [0])] = 25.0  # 100 N on a 1 mm² section
    return mesh, K, f, fixed


@pytest.mark.parametrize("backend", BACKENDS, ids=BACKEND_IDS)
def test_uniaxial_tension_is_exact(backend):
    mesh, K, f, fixed = _tension_problem()
    u = solve_dirichlet(K, f, fixed, 0.0, backend=backend).reshape(-1, 3)
    tip = u[mesh.set_nodes("xmax")]
    np.testing.assert_allclose(tip[:, 0], 100.0 * 4.0 / TEST_MATERIAL.young_mpa, rtol=1e-12)
    reaction = (K @ u.ravel() - f).reshape(-1, 3)
    assert reaction[:, 0].sum() == pytest.approx(-100.0, rel=1e-12)


def test_solve_dirichlet_does_not_mutate_inputs():
    _, K, f, fixed = _tension_problem()
    values = np.zeros(len(fixed))
    before = [K.data.copy(), K.indices.copy(), f.copy(), fixed.copy(), values.copy()]
    solve_dirichlet(K, f, fixed, values)
    for a, b in zip([K.data, K.indices, f, fixed, values], before, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    ("fixed", "match"),
    [
        (np.array([0, 0, 1]), "repeats"),
        (np.array([-1]), "must lie in"),
        (np.array([10**6]), "must lie in"),
    ],
    ids=["repeated", "negative", "too-large"],
)
def test_solve_dirichlet_rejects_bad_fixed_dofs(fixed, match):
    _, K, f, _ = _tension_problem()
    with pytest.raises(ParameterError, match=match):
        solve_dirichlet(K, f, fixed)


def _free_block():
    _, K, _, fixed = _tension_problem()
    free = np.setdiff1d(np.arange(K.shape[0]), fixed)
    return K[free][:, free]


@pytest.mark.parametrize("backend", BACKENDS, ids=BACKEND_IDS)
def test_factorization_block_and_single_solves_agree(backend):
    K_ff = _free_block()
    data = K_ff.data.copy()
    B = np.random.default_rng(0).standard_normal((K_ff.shape[0], 7))
    fac = Factorization(K_ff, backend=backend)
    assert fac.backend is backend
    X = fac.solve(B)
    assert X.shape == B.shape
    np.testing.assert_allclose(K_ff @ X, B, atol=1e-9 * np.abs(B).max())
    for k in range(B.shape[1]):
        np.testing.assert_allclose(fac.solve(B[:, k]), X[:, k], rtol=1e-10, atol=1e-14)
    np.testing.assert_array_equal(K_ff.data, data)


@pytest.mark.parametrize("backend", BACKENDS, ids=BACKEND_IDS)
def test_factorization_rows_of_a_column_major_block_are_the_full_solve_s(backend):
    """``solve(B, rows=r)`` is ``solve(B)[r]`` bit for bit, for a column-major block too."""
    K_ff = _free_block()
    fac = Factorization(K_ff, backend=backend)
    B = np.random.default_rng(1).standard_normal((5, K_ff.shape[0]))
    rows = np.array([7, 0, K_ff.shape[0] - 1, 3])  # any order
    full = fac.solve(B.T.copy())
    for block in (B.T, B.T.copy()):  # column-major (no copy made) and row-major
        part = fac.solve(block, rows=rows)
        assert part.shape == (4, 5)
        assert part.flags.c_contiguous
        np.testing.assert_array_equal(part, full[rows])
    np.testing.assert_array_equal(fac.solve(B[0], rows=rows), fac.solve(B[0])[rows])
    assert fac.solve(np.zeros((K_ff.shape[0], 0)), rows=rows).shape == (4, 0)


def test_factorization_backends_agree():
    K_ff = _free_block()
    b = np.linspace(-1.0, 1.0, K_ff.shape[0])
    x = [Factorization(K_ff, backend=bk).solve(b) for bk in BACKENDS]
    np.testing.assert_allclose(x[0], x[1], rtol=1e-9, atol=1e-12 * np.abs(x[1]).max())


def test_factorization_rejects_unsymmetric_and_bad_rhs():
    K_ff = _free_block().tolil()
    K_ff[0, 1] += 1.0
    with pytest.raises(ParameterError, match="not symmetric"):
        Factorization(K_ff.tocsr())
    fac = Factorization(_free_block())
    with pytest.raises(ParameterError, match="B must have shape"):
        fac.solve(np.zeros(3))


def test_pardiso_reports_indefinite_matrix():
    with pytest.raises(SolverError, match="PARDISO"):
        Factorization(sp.csr_matrix(np.diag([1.0, -1.0, 2.0])), backend=LinearSolverBackend.PARDISO)


@pytest.mark.parametrize("backend", BACKENDS, ids=BACKEND_IDS)
@pytest.mark.parametrize("sort", [False, True], ids=["unsorted", "sorted"])
@pytest.mark.parametrize("sym_block", [512, 7], ids=["one-block", "blocks-of-7"])
def test_inverse_block_matches_dense_inverse_in_given_order(backend, sort, sym_block, monkeypatch):
    import fe.linalg.sparse as linalg_sparse

    monkeypatch.setattr(linalg_sparse, "SYMMETRISE_BLOCK", sym_block)  # ragged last block
    K_ff = _free_block()
    idx = np.random.default_rng(3).choice(K_ff.shape[0], 40, replace=False)
    idx = np.sort(idx) if sort else idx
    dense = np.linalg.inv(K_ff.toarray())[np.ix_(idx, idx)]
    block = inverse_block(K_ff, idx, backend=backend, block_rhs=16)
    np.testing.assert_allclose(block, dense, rtol=1e-9, atol=1e-12 * np.abs(dense).max())
    np.testing.assert_array_equal(block, block.T)
    assert block.flags.c_contiguous


def test_inverse_block_rejects_repeats_and_indefinite():
    K_ff = _free_block()
    with pytest.raises(ParameterError, match="repeated"):
        inverse_block(K_ff, [0, 1, 1])
    with pytest.raises(ParameterError, match=r"idx must lie in \[0, "):
        inverse_block(K_ff, [K_ff.shape[0]])
    with pytest.raises(SolverError, match="positive definite"):
        inverse_block(sp.csr_matrix(np.diag([1.0, -1.0, 2.0, 3.0])), [0, 1])
