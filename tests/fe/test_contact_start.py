"""A starting iterate moves where Newton begins, never the solution or the works."""

from __future__ import annotations

import numpy as np
import pytest

from cad.errors import ParameterError
from fe.contact import ContactSettings, ContactState, solve_increment


def problem(m=12, seed=3):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3 * m, 3 * m))
    W = A @ A.T / (3 * m) + np.eye(3 * m)
    w_free = np.column_stack([rng.normal(-0.5, 0.5, m), rng.normal(0, 0.5, (m, 2))])
    return W, w_free


@pytest.mark.parametrize("seed", [0, 1, 2], ids=lambda s: f"start-seed={s}")
def test_start_changes_nothing_but_the_path(seed):
    W, w_free = problem()
    settings = ContactSettings(mu=0.3)
    prev = solve_increment(W, 0.5 * w_free, ContactState.initial(len(w_free)), settings).state
    plain = solve_increment(W, w_free, prev, settings)
    rng = np.random.default_rng(seed)
    guess = np.abs(rng.normal(size=(len(w_free), 3)))
    started = solve_increment(W, w_free, prev, settings, start=(guess, np.zeros(0)))
    assert np.allclose(started.state.p, plain.state.p, atol=1e-9)
    assert np.allclose(started.friction_work, plain.friction_work, atol=1e-9)
    assert np.array_equal(started.state.status, plain.state.status)


def test_start_with_wrong_shape_is_refused():
    W, w_free = problem()
    with pytest.raises(ParameterError, match="start"):
        solve_increment(
            W,
            w_free,
            ContactState.initial(len(w_free)),
            ContactSettings(mu=0.3),
            start=(np.zeros((2, 3)), np.zeros(0)),
        )


def test_a_symmetric_hint_skips_only_the_check():
    """``symmetric=True`` (a condensed W known symmetric) gives the checked answer bit for
    bit; the hint reaches the problem the solver builds (False takes the other path)."""
    from fe.contact.state import validate_problem

    W, w_free = problem()
    settings = ContactSettings(mu=0.3)
    prev = ContactState.initial(len(w_free))
    checked = solve_increment(W, w_free, prev, settings)
    hinted = solve_increment(W, w_free, prev, settings, symmetric=True)
    assert np.array_equal(hinted.state.p, checked.state.p)
    assert validate_problem(W, w_free, prev, None, None).symmetric
    assert not validate_problem(W, w_free, prev, None, None, symmetric=False).symmetric
    asym = W + np.triu(np.full_like(W, 1e-3), 1)
    assert not validate_problem(asym, w_free, prev, None, None).symmetric
