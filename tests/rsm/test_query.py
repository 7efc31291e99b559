import numpy as np
import pytest

from cad.errors import ParameterError
from rsm.design import full_factorial
from rsm.polynomial import fit_response_surface
from rsm.query import (
    ResponseLimit,
    Sense,
    best_design,
    extrema,
    threshold_region,
    value_and_gradient,
)


@pytest.fixture
def bowl():
    # y = (x1 - 0.1)^2 + ((x2 - 300) / 1000)^2 on [0, 0.4] x [100, 500]: minimum at (0.1, 300)
    x = full_factorial([np.linspace(0, 0.4, 5), np.linspace(100, 500, 5)])
    y = (x[:, 0] - 0.1) ** 2 + ((x[:, 1] - 300) / 1000) ** 2
    return fit_response_surface(x, y, 2, x_names=("c_mm", "f_N"), y_name="y")


def test_value_and_gradient(bowl):
    p = value_and_gradient(bowl, np.array([0.2, 400.0]))
    assert p.value == pytest.approx(0.01 + 0.01)
    np.testing.assert_allclose(p.gradient, [0.2, 2 * 100 / 1e6], rtol=1e-9)
    with pytest.raises(ParameterError, match=r"shape \(2,\)"):
        value_and_gradient(bowl, [1.0, 2.0, 3.0])


def test_extrema_of_bowl(bowl):
    e = extrema(bowl)
    np.testing.assert_allclose(e.minimum.x, [0.1, 300.0], atol=1e-6)
    assert e.minimum.value == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(e.maximum.x, [0.4, 100.0])  # farthest corner
    sub = extrema(bowl, bounds={"c_mm": (0.2, 0.3)})
    assert sub.minimum.x[0] == pytest.approx(0.2)


def test_threshold_region_is_a_disc(bowl):
    r = threshold_region(bowl, 0.01)  # (c - 0.1)^2 + ((f - 300)/1000)^2 < 0.01
    np.testing.assert_allclose(r.lower, [0.0, 200.0], atol=1e-6)
    np.testing.assert_allclose(r.upper, [0.2, 400.0], atol=1e-6)
    assert r.n_parts == 1
    above = threshold_region(bowl, 0.01, below=False)
    np.testing.assert_array_equal(above.mask, r.values > 0.01)
    np.testing.assert_array_equal(r.mask, r.values < 0.01)


def test_best_design_with_response_limit(bowl):
    b = best_design(
        bowl,
        objective="c_mm",
        sense=Sense.MAXIMIZE,
        fixed={"f_N": 300.0},
        response_limit=ResponseLimit(upper=0.01),
    )
    assert b.x[0] == pytest.approx(0.2, abs=1e-6)
    with pytest.raises(ParameterError, match="no point of the box"):
        best_design(bowl, response_limit=ResponseLimit(upper=-1.0))
    with pytest.raises(ParameterError, match="unknown variable 'nope'"):
        best_design(bowl, bounds={"nope": (0.0, 1.0)})
