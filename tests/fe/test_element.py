import numpy as np
import pytest

from cad.errors import MeshQualityError, ParameterError
from cad.materials import lame_from_young_poisson
from fe.element import (
    HEX8_NODE_COORDS,
    ElementType,
    bubble_gradients,
    element_stiffness,
    element_strain_stress,
    element_stress_at_points,
    elements_jacobian_det,
    hex8_shape_functions,
    hex8_shape_gradients,
    von_mises,
)
from fe.quadrature import gauss_hex

KINDS = list(ElementType)
KIND_IDS = [k.name.lower() for k in KINDS]
E, NU = 200_000.0, 0.3
LAM, MU = lame_from_young_poisson(E, NU)
RTOL = np.sqrt(np.finfo(float).eps)


def _distorted_elements(n, seed=0, amp=0.15):
    rng = np.random.default_rng(seed)
    base = 0.5 * (HEX8_NODE_COORDS + 1.0) * np.array([2.0, 1.0, 0.5])  # 2 × 1 × 0.5 mm box
    return base[None] + amp * rng.uniform(-0.5, 0.5, size=(n, 8, 3))


def _rigid_modes(coords):
    """Six rigid-body displacement fields of every element, shape (n_elem, 24, 6)."""
    modes = []
    for k in range(3):
        t = np.zeros(3)
        t[k] = 1.0
        modes.append(np.broadcast_to(t, coords.shape))
        modes.append(np.cross(t, coords - coords.mean(axis=1, keepdims=True)))
    return np.stack([m.reshape(len(coords), 24) for m in modes], axis=2)


def _random_points(n, seed=1):
    return np.random.default_rng(seed).uniform(-1.0, 1.0, size=(n, 3))


def test_kronecker_property():
    np.testing.assert_allclose(hex8_shape_functions(HEX8_NODE_COORDS), np.eye(8), atol=1e-15)


def test_partition_of_unity_and_zero_gradient_sum():
    xi = _random_points(50)
    np.testing.assert_allclose(hex8_shape_functions(xi).sum(axis=1), 1.0, rtol=1e-14)
    np.testing.assert_allclose(hex8_shape_gradients(xi).sum(axis=1), 0.0, atol=1e-15)


def test_shape_gradients_match_central_differences():
    xi, h = _random_points(20), 1e-6
    fd = np.stack(
        [
            (
                hex8_shape_functions(xi + h * np.eye(3)[j])
                - hex8_shape_functions(xi - h * np.eye(3)[j])
            )
            / (2 * h)
            for j in range(3)
        ],
        axis=2,
    )
    np.testing.assert_allclose(hex8_shape_gradients(xi), fd, atol=1e-9)


def test_bubble_gradients_match_central_differences():
    xi, h = _random_points(20), 1e-6

    def bubbles(p):
        return 1.0 - p**2  # (n, 3): P_k = 1 - ξ_k²

    fd = np.stack(
        [
            (bubbles(xi + h * np.eye(3)[j]) - bubbles(xi - h * np.eye(3)[j])) / (2 * h)
            for j in range(3)
        ],
        axis=2,
    )
    np.testing.assert_allclose(bubble_gradients(xi), fd, atol=1e-9)


def test_jacobian_of_affine_element_is_constant_and_integrates_volume():
    A = np.array([[2.0, 0.3, 0.0], [0.1, 1.0, 0.2], [0.0, -0.1, 0.5]])
    coords = (HEX8_NODE_COORDS @ A.T + [1.0, 2.0, 3.0])[None]
    points, weights = gauss_hex(2)
    det = elements_jacobian_det(coords, points)
    np.testing.assert_allclose(det, np.linalg.det(A), rtol=1e-14)
    assert weights @ det[0] == pytest.approx(8.0 * np.linalg.det(A), rel=1e-14)


@pytest.mark.parametrize("kind", KINDS, ids=KIND_IDS)
def test_stiffness_symmetric_psd_with_six_rigid_modes(kind):
    K = element_stiffness(_distorted_elements(5), LAM, MU, kind)
    assert K.shape == (5, 24, 24)
    np.testing.assert_allclose(K, K.transpose(0, 2, 1), rtol=0, atol=1e-12 * np.abs(K).max())
    for eig in np.linalg.eigvalsh(K):
        assert eig[0] > -1e-10 * eig[-1]
        assert np.sum(eig < 1e-10 * eig[-1]) == 6
        assert eig[6] > 1e-4 * eig[-1]


@pytest.mark.parametrize("kind", KINDS, ids=KIND_IDS)
def test_rigid_body_motion_has_zero_energy(kind):
    coords = _distorted_elements(4)
    K = element_stiffness(coords, LAM, MU, kind)
    R = _rigid_modes(coords)
    energy = 0.5 * np.einsum("eim,eij,ejm->em", R, K, R)  # (n_elem, 6)
    scale = np.abs(K).max() * np.abs(R).max() ** 2
    assert np.abs(energy).max() < 1e-12 * scale


@pytest.mark.parametrize("kind", KINDS, ids=KIND_IDS)
def test_stiffness_is_rotation_invariant(kind):
    coords = _distorted_elements(1)
    c, s = np.cos(0.7), np.sin(0.7)
    Q = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]]
    )
    T = np.kron(np.eye(8), Q)  # rotates all 8 nodal vectors
    K = element_stiffness(coords, LAM, MU, kind)[0]
    K_rot = element_stiffness(coords @ Q.T, LAM, MU, kind)[0]
    np.testing.assert_allclose(K_rot, T @ K @ T.T, atol=1e-10 * np.abs(K).max())


@pytest.mark.parametrize("kind", KINDS, ids=KIND_IDS)
def test_constant_strain_gives_exact_stress_everywhere_on_distorted_element(kind):
    coords = _distorted_elements(3, amp=0.3)
    grad_u = np.array([[1.0, 0.2, -0.3], [0.4, -0.5, 0.1], [0.0, 0.6, 0.8]]) * 1e-3
    u_e = (coords @ grad_u.T).reshape(3, 24)
    eps = 0.5 * (grad_u + grad_u.T)
    sigma = LAM * np.trace(eps) * np.eye(3) + 2 * MU * eps
    voigt = sigma[[0, 1, 2, 1, 0, 0], [0, 1, 2, 2, 2, 1]]
    # At the Gauss points the internal modes would show up if they were excited.
    at_gauss = element_stress_at_points(coords, u_e, LAM, MU, kind, gauss_hex(2).points)
    np.testing.assert_allclose(
        at_gauss, np.broadcast_to(voigt, at_gauss.shape), rtol=0, atol=RTOL * 300
    )
    np.testing.assert_allclose(
        element_strain_stress(coords, u_e, LAM, MU, kind), np.tile(voigt, (3, 1)), atol=1e-9
    )


def test_centroid_stress_skips_the_modes_without_changing_it():
    """The centroid shortcut (no mode recovery) equals the stress with the modes recovered.

    Evaluated together with a Gauss point, the centroid goes through the mode recovery
    (α = -K_αα⁻¹ K_αu u_e); alone, it skips it. On distorted elements under a random field
    the modes are excited (they change the Gauss-point stress) but not the centroid's.
    """
    coords = _distorted_elements(5, amp=0.3)
    u_e = np.random.default_rng(7).standard_normal((5, 24)) * 1e-3
    gauss = gauss_hex(2).points[:1]
    both = element_stress_at_points(
        coords, u_e, LAM, MU, ElementType.INCOMPATIBLE, np.vstack([np.zeros((1, 3)), gauss])
    )
    alone = element_strain_stress(coords, u_e, LAM, MU, ElementType.INCOMPATIBLE)
    np.testing.assert_allclose(alone, both[:, 0], rtol=0, atol=1e-12 * np.abs(both).max())
    without_modes = element_stress_at_points(coords, u_e, LAM, MU, ElementType.FULL, gauss)[:, 0]
    assert np.abs(both[:, 1] - without_modes).max() > 1e-3 * np.abs(both).max()


def _pure_bending(coords, kappa):
    """Exact 3D pure-bending field (σxx = E κ z, all else 0) and its stress at points x."""
    x, y, z = coords[..., 0], coords[..., 1], coords[..., 2]
    u = np.stack(
        [kappa * x * z, -NU * kappa * y * z, -0.5 * kappa * (x**2 + NU * (z**2 - y**2))], axis=-1
    )
    return u


def test_incompatible_element_bends_exactly_and_full_element_locks():
    a, b, c = 4.0, 1.0, 1.0  # slender element, centred on the neutral axis z = 0
    coords = (0.5 * HEX8_NODE_COORDS * [a, b, c])[None]
    kappa = 1e-3
    u_e = _pure_bending(coords, kappa).reshape(1, 24)
    points = gauss_hex(2).points
    z_gauss = 0.5 * c * points[:, 2]
    exact = np.zeros((len(points), 6))
    exact[:, 0] = E * kappa * z_gauss
    inc = element_stress_at_points(coords, u_e, LAM, MU, ElementType.INCOMPATIBLE, points)[0]
    np.testing.assert_allclose(inc, exact, atol=1e-9 * np.abs(exact).max())
    full = element_stress_at_points(coords, u_e, LAM, MU, ElementType.FULL, points)[0]
    assert np.abs(full[:, 4]).max() > 0.5 * np.abs(exact[:, 0]).max()  # parasitic shear σxz


def test_incompatible_element_has_lower_bending_energy():
    coords = (0.5 * HEX8_NODE_COORDS * [4.0, 1.0, 1.0])[None]
    u_e = _pure_bending(coords, 1e-3).reshape(24)
    energy = {k: 0.5 * u_e @ element_stiffness(coords, LAM, MU, k)[0] @ u_e for k in KINDS}
    exact = 0.5 * E * 1e-3**2 * (1.0 * 1.0**3 / 12.0) * 4.0  # ½ E I κ² L
    assert energy[ElementType.INCOMPATIBLE] == pytest.approx(exact, rel=1e-10)
    assert energy[ElementType.FULL] > 1.5 * exact


@pytest.mark.parametrize("kind", KINDS, ids=KIND_IDS)
def test_inputs_are_not_mutated(kind):
    coords = _distorted_elements(2)
    lam, mu = np.full(2, LAM), np.full(2, MU)
    u_e = np.random.default_rng(3).standard_normal((2, 24))
    before = [a.copy() for a in (coords, lam, mu, u_e)]
    element_stiffness(coords, lam, mu, kind)
    element_strain_stress(coords, u_e, lam, mu, kind)
    elements_jacobian_det(coords, gauss_hex(2).points)
    for a, b in zip((coords, lam, mu, u_e), before, strict=True):
        np.testing.assert_array_equal(a, b)


def test_von_mises_of_simple_states():
    s = np.array([[250.0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 10.0], [7.0, 7.0, 7.0, 0, 0, 0]])
    np.testing.assert_allclose(von_mises(s), [250.0, np.sqrt(3) * 10.0, 0.0], atol=1e-12)
    with pytest.raises(ParameterError, match="shape"):
        von_mises(np.zeros((2, 5)))


def test_inverted_element_names_element_and_value():
    coords = _distorted_elements(3)
    coords[1] = coords[1][[4, 5, 6, 7, 0, 1, 2, 3]]  # top and bottom swapped: inside out
    with pytest.raises(
        MeshQualityError, match=r"element 1 has non-positive Jacobian determinant -"
    ):
        element_stiffness(coords, LAM, MU)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((np.zeros((2, 8)), LAM, MU, ElementType.FULL), "coords must have shape"),
        ((None, LAM, -1.0, ElementType.FULL), "mu must be > 0"),
        ((None, -10 * MU, MU, ElementType.FULL), "bulk modulus"),
        ((None, LAM, MU, "full"), "ElementType"),
    ],
    ids=["bad-shape", "negative-mu", "negative-bulk", "string-kind"],
)
def test_bad_arguments_raise_parameter_error(args, match):
    coords = _distorted_elements(1) if args[0] is None else args[0]
    with pytest.raises(ParameterError, match=match):
        element_stiffness(coords, *args[1:])
