import itertools

import numpy as np
import pytest

from cad.errors import ParameterError
from fe.quadrature import exact_degree, gauss_hex, gauss_quad

ORDERS = [1, 2, 3, 4]
RULES = [(gauss_hex, 3, 8.0), (gauss_quad, 2, 4.0)]
RULE_IDS = ["hex", "quad"]


def _exact_monomial(powers):
    """∫_{[-1,1]^d} Π x_k^p_k: each factor is 0 for odd p, 2/(p+1) for even p."""
    return np.prod([0.0 if p % 2 else 2.0 / (p + 1) for p in powers])


@pytest.mark.parametrize(("rule", "dim", "measure"), RULES, ids=RULE_IDS)
@pytest.mark.parametrize("order", ORDERS, ids=[f"order{n}" for n in ORDERS])
def test_weights_sum_to_reference_measure(rule, dim, measure, order):
    points, weights = rule(order)
    assert points.shape == (order**dim, dim)
    assert weights.shape == (order**dim,)
    assert weights.sum() == pytest.approx(measure, rel=1e-14)
    assert np.all(np.abs(points) < 1.0)


@pytest.mark.parametrize(("rule", "dim", "measure"), RULES, ids=RULE_IDS)
@pytest.mark.parametrize("order", ORDERS, ids=[f"order{n}" for n in ORDERS])
def test_monomials_exact_up_to_claimed_degree(rule, dim, measure, order):
    points, weights = rule(order)
    deg = exact_degree(order)
    for powers in itertools.product(range(deg + 1), repeat=dim):
        value = weights @ np.prod(points ** np.array(powers), axis=1)
        assert value == pytest.approx(_exact_monomial(powers), abs=1e-13), powers


@pytest.mark.parametrize(("rule", "dim", "measure"), RULES, ids=RULE_IDS)
@pytest.mark.parametrize("order", ORDERS, ids=[f"order{n}" for n in ORDERS])
def test_claimed_degree_is_tight(rule, dim, measure, order):
    points, weights = rule(order)
    powers = (exact_degree(order) + 1,) + (0,) * (dim - 1)  # even degree 2n is not exact
    value = weights @ np.prod(points ** np.array(powers), axis=1)
    assert abs(value - _exact_monomial(powers)) > 1e-6


def test_first_coordinate_varies_fastest():
    points, _ = gauss_hex(2)
    assert np.all(np.sign(points[:4, 0]) == [-1, 1, -1, 1])
    assert np.all(points[:4, 2] < 0)
    assert np.all(points[4:, 2] > 0)


@pytest.mark.parametrize(
    "order", [0, -1, 11, 2.0, True], ids=["zero", "negative", "too-big", "float", "bool"]
)
def test_bad_order_is_rejected_with_its_value(order):
    with pytest.raises(ParameterError, match="order"):
        gauss_hex(order)
