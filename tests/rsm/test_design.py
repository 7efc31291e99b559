import numpy as np
import pytest

from cad.errors import ParameterError
from rsm.design import (
    CompositeFace,
    box_behnken,
    central_composite,
    full_factorial,
    latin_hypercube,
)
from rsm.paper_printed import GENERAL, paper_table_path
from rsm.tables import read_xy


def test_full_factorial_matches_paper_table_order():
    x = full_factorial([[0.0, 0.1, 0.2, 0.3, 0.4], [100.0, 200.0, 300.0, 400.0, 500.0]])
    with paper_table_path(GENERAL.csv_name) as p:
        xy = read_xy(p, GENERAL.x_names, "eta_fe")
    np.testing.assert_array_equal(x, xy.x)


def test_full_factorial_rejects_repeated_level():
    with pytest.raises(ParameterError, match=r"levels\[1\]"):
        full_factorial([[0.0, 1.0], [2.0, 2.0]])


def test_latin_hypercube_one_point_per_stratum_and_repeatable():
    x = latin_hypercube([(0.0, 0.4), (100.0, 500.0)], 10, seed=7)
    assert x.shape == (10, 2)
    for i, (lo, hi) in enumerate([(0.0, 0.4), (100.0, 500.0)]):
        strata = np.floor((x[:, i] - lo) / (hi - lo) * 10).astype(int)
        assert sorted(strata) == list(range(10))
    np.testing.assert_array_equal(x, latin_hypercube([(0.0, 0.4), (100.0, 500.0)], 10, seed=7))


def test_central_composite_faced_stays_in_box():
    x = central_composite([(0.0, 0.4), (100.0, 500.0)], face=CompositeFace.FACED)
    assert x.shape == (9, 2)
    assert x.min(axis=0).tolist() == [0.0, 100.0]
    assert x.max(axis=0).tolist() == [0.4, 500.0]
    assert [0.2, 300.0] in x.tolist()


def test_central_composite_circumscribed_leaves_box():
    x = central_composite([(0.0, 1.0), (0.0, 1.0)], face=CompositeFace.CIRCUMSCRIBED)
    assert x.min() < 0.0
    assert x.max() > 1.0


def test_box_behnken_three_variables():
    x = box_behnken([(0.0, 0.4), (100.0, 500.0), (0.0, 200.0)], n_center=2)
    assert x.shape == (14, 3)
    with pytest.raises(ParameterError, match="at least 3 variables"):
        box_behnken([(0.0, 1.0), (0.0, 1.0)])
