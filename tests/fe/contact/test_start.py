"""A starting iterate moves where Newton begins, never the solution or the works."""

from __future__ import annotations

import numpy as np
import pytest

from cad.errors import ParameterError
from fe.contact.solve import solve_increment
from fe.contact.state import ContactSettings, ContactState


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


def test_frictionless_start_changes_nothing_but_the_path(monkeypatch):
    """From rest, the frictionless pre-solve moves the start only; both solves are counted.

    A floating body (the hinge's situation: rigid amplitudes) pressed onto a ring of points
    in its plane (the frictionless problem has an equilibrium).
    """
    from fe.contact import solve as contact_solve
    from tests.fe.contact.test_working import pin_in_hole

    W, G, w_free = pin_in_hole()
    e = np.array([10.0, 3.0, 0.0])
    rest = ContactState.initial(len(w_free), 3)
    plain = solve_increment(W, w_free, rest, ContactSettings(mu=0.3), G=G, e=e)
    mus, inner = [], []
    solve = contact_solve.solve_increment

    def spy(*args, **kwargs):
        mus.append(np.max(args[3].mu))
        inner.append(solve(*args, **kwargs))
        return inner[-1]

    monkeypatch.setattr(contact_solve, "solve_increment", spy)
    started = solve(W, w_free, rest, ContactSettings(mu=0.3, frictionless_start=True), G=G, e=e)
    assert mus == [0.0, 0.3]  # frictionless first, then the frictional solve from there
    scale = np.max(np.abs(plain.state.p))
    np.testing.assert_allclose(started.state.p, plain.state.p, atol=1e-9 * scale)
    np.testing.assert_array_equal(started.state.status, plain.state.status)
    np.testing.assert_allclose(started.friction_work, plain.friction_work, atol=1e-9 * scale)
    assert plain.n_slip > 0
    assert started.residuals[-1] <= ContactSettings().tol
    assert started.iterations == inner[0].iterations + inner[1].iterations
    assert started.residuals == (*inner[0].residuals, *inner[1].residuals)


def test_frictionless_start_only_from_rest_and_with_friction(monkeypatch):
    """Not from a loaded state, not with a given start, not without friction."""
    from fe.contact import solve as contact_solve

    W, w_free = problem()
    calls = []
    solve = contact_solve.solve_increment

    def spy(*args, **kwargs):
        calls.append(np.max(args[3].mu))
        return solve(*args, **kwargs)

    monkeypatch.setattr(contact_solve, "solve_increment", spy)
    on = ContactSettings(mu=0.3, frictionless_start=True)
    rest = ContactState.initial(len(w_free))
    loaded = solve(W, w_free, rest, ContactSettings(mu=0.3)).state
    solve(W, w_free, loaded, on)
    solve(W, w_free, rest, on, start=(loaded.p, np.zeros(0)))
    solve(W, w_free, rest, ContactSettings(mu=0.0, frictionless_start=True))
    assert calls == []  # none of them took the pre-solve


def test_a_frictionless_start_that_fails_falls_back_to_rest():
    """A load only friction can carry (along the ring's axis): no frictionless equilibrium.

    The pre-solve runs out of its budget, its iterations are counted, and the increment is
    solved from rest, to the same answer as without the option.
    """
    from fe.contact import solve as contact_solve
    from tests.fe.contact.test_working import pin_in_hole

    W, G, w_free = pin_in_hole()
    e = np.array([10.0, 3.0, 2.0])
    rest = ContactState.initial(len(w_free), 3)
    plain = solve_increment(W, w_free, rest, ContactSettings(mu=0.3), G=G, e=e)
    res = solve_increment(
        W, w_free, rest, ContactSettings(mu=0.3, frictionless_start=True), G=G, e=e
    )
    np.testing.assert_array_equal(res.state.p, plain.state.p)
    budget = contact_solve.FRICTIONLESS_START_MAX_ITER
    assert res.iterations == plain.iterations + budget
