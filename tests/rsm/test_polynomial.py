import itertools
import math

import numpy as np
import pytest

from cad.errors import DataError, ParameterError
from rsm.design import full_factorial, latin_hypercube
from rsm.polynomial import (
    design_matrix,
    fit_response_surface,
    format_polynomial,
    gradient,
    monomial_exponents,
    physical_from_scaled,
    predict,
    term_names,
)


def test_term_order_matches_paper_eq3_for_two_variables():
    names = term_names(monomial_exponents(2, 4))
    assert names == (
        "1",
        "x1",
        "x2",
        "x1^2",
        "x1*x2",
        "x2^2",
        "x1^3",
        "x1^2*x2",
        "x1*x2^2",
        "x2^3",
        "x1^4",
        "x1^3*x2",
        "x1^2*x2^2",
        "x1*x2^3",
        "x2^4",
    )


@pytest.mark.parametrize(("n_vars", "degree"), [(1, 1), (2, 2), (3, 4), (5, 3)], ids=str)
def test_term_count_is_binomial(n_vars, degree):
    exps = monomial_exponents(n_vars, degree)
    assert len(exps) == math.comb(n_vars + degree, degree)
    assert len(set(exps)) == len(exps)
    assert all(sum(e) <= degree for e in exps)


def test_three_variable_degree_two_order():
    assert term_names(monomial_exponents(3, 2))[4:] == (
        "x1^2",
        "x1*x2",
        "x1*x3",
        "x2^2",
        "x2*x3",
        "x3^2",
    )


def test_degree_out_of_range_is_named():
    with pytest.raises(ParameterError, match="degree must be in"):
        monomial_exponents(2, 5)


def test_exact_quadratic_recovered_to_round_off():
    x = full_factorial([[0.0, 0.1, 0.2, 0.3, 0.4], [100.0, 200.0, 300.0, 400.0, 500.0]])
    beta = np.array([0.02, -0.3, 4e-4, 0.5, 2e-5, -6e-7])
    y = design_matrix(x, monomial_exponents(2, 2)) @ beta
    s = fit_response_surface(x, y, 2)
    np.testing.assert_allclose(s.coefficients, beta, rtol=1e-9, atol=0)
    np.testing.assert_allclose(predict(s, x), y, rtol=0, atol=1e-14)


def test_exact_quartic_in_three_variables_recovered():
    exps = monomial_exponents(3, 4)
    rng = np.random.default_rng(3)
    beta = rng.uniform(-1.0, 1.0, len(exps))
    # physical ranges of different size, as in a real study: mm, N, MPa
    x = latin_hypercube([(0.0, 0.4), (100.0, 500.0), (1.0, 3.0)], 120, seed=5)
    scale = np.array([0.4, 500.0, 3.0])
    beta_phys = beta / np.prod(scale ** np.asarray(exps), axis=1)
    y = design_matrix(x, exps) @ beta_phys
    s = fit_response_surface(x, y, 4)
    np.testing.assert_allclose(s.coefficients, beta_phys, rtol=1e-7)
    np.testing.assert_allclose(predict(s, x), y, rtol=1e-11, atol=1e-13)


def test_gradient_matches_central_differences():
    x = latin_hypercube([(0.0, 0.4), (100.0, 500.0)], 30, seed=1)
    y = np.sin(5 * x[:, 0]) + np.cos(x[:, 1] / 200.0) + x[:, 0] * x[:, 1] / 100
    s = fit_response_surface(x, y, 4)
    p = np.array([[0.13, 270.0], [0.31, 410.0]])
    g = gradient(s, p)
    h = np.array([1e-6, 1e-3])
    for i in range(2):
        e = np.zeros(2)
        e[i] = h[i]
        fd = (predict(s, p + e) - predict(s, p - e)) / (2 * h[i])
        np.testing.assert_allclose(g[:, i], fd, rtol=1e-6)


def test_physical_from_scaled_round_trip():
    exps = monomial_exponents(2, 3)
    b = np.arange(1.0, len(exps) + 1)
    c, h = np.array([0.2, 300.0]), np.array([0.2, 200.0])
    phys = physical_from_scaled(b, exps, c, h)
    pts = np.array([[0.05, 150.0], [0.33, 480.0]])
    np.testing.assert_allclose(
        design_matrix(pts, exps) @ phys, design_matrix((pts - c) / h, exps) @ b, rtol=1e-10
    )


def test_fit_does_not_modify_inputs():
    x = full_factorial([[0.0, 1.0, 2.0], [0.0, 1.0, 2.0]])
    y = x[:, 0] ** 2 + x[:, 1]
    x0, y0 = x.copy(), y.copy()
    s = fit_response_surface(x, y, 2)
    predict(s, x)
    gradient(s, x)
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_array_equal(y, y0)
    assert not s.coefficients.flags.writeable


def test_too_few_points_raises_with_counts():
    x = full_factorial([[0.0, 1.0, 2.0], [0.0, 1.0]])
    with pytest.raises(DataError, match="15 coefficients but only 6 points"):
        fit_response_surface(x, np.ones(6), 4)


def test_rank_deficient_design_names_the_variable():
    x = full_factorial([[0.0, 1.0, 2.0], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0]])
    with pytest.raises(DataError, match="x1 has 3 distinct values"):
        fit_response_surface(x, np.arange(21.0), 4)


def test_constant_variable_raises():
    x = np.column_stack([np.linspace(0, 1, 10), np.full(10, 3.0)])
    with pytest.raises(DataError, match="'b' is constant"):
        fit_response_surface(x, np.arange(10.0), 1, x_names=("a", "b"))


def test_format_polynomial_uses_names_and_signs():
    x = np.array([[0.0], [1.0], [2.0]])
    s = fit_response_surface(x, [1.0, 0.0, 1.0], 2, x_names=("c_mm",), y_name="eta")
    assert format_polynomial(s) == "eta = 1 - 2*c_mm + 1*c_mm^2"


def test_term_names_every_monomial_once():
    exps = monomial_exponents(3, 3)
    names = term_names(exps, ("a", "b", "c"))
    assert "a*b*c" in names
    assert "a^2*b" in names
    for combo in itertools.combinations(names, 2):
        assert combo[0] != combo[1]
