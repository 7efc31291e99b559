import math

import numpy as np
import pytest

from rsm.metrics import OverfitWarning, fit_metrics, r2_adjusted, rmse_paper
from rsm.polynomial import design_matrix, fit_response_surface, predict


def test_metrics_by_hand_on_a_line():
    # y = (1, 3, 2, 5) at x = 0..3; least-squares line ŷ = 1 + 1.1 x (by hand:
    # x̄ = 1.5, ȳ = 2.75, Sxy = 5.5, Sxx = 5 → slope 1.1, intercept 1.1).
    x = np.array([[0.0], [1.0], [2.0], [3.0]])
    y = np.array([1.0, 3.0, 2.0, 5.0])
    s = fit_response_surface(x, y, 1)
    np.testing.assert_allclose(s.coefficients, [1.1, 1.1], rtol=1e-12)
    m = fit_metrics(s, warn=False)
    fit = np.array([1.1, 2.2, 3.3, 4.4])
    sse = float(np.sum((y - fit) ** 2))  # 0.01 + 0.64 + 1.69 + 0.36 = 2.7
    sst = 8.75
    assert m.sse == pytest.approx(2.7, rel=1e-12)
    assert m.sst == pytest.approx(sst)
    assert m.r2 == pytest.approx(1 - 2.7 / 8.75, rel=1e-12)
    assert m.r2_adj == pytest.approx(1 - (4 - 1) / (4 - 2) * (2.7 / 8.75), rel=1e-12)
    assert m.rmse == pytest.approx(math.sqrt(2.7 / (4 - 2 - 1)), rel=1e-12)  # paper Eq. 10
    np.testing.assert_allclose(m.relative_error, (fit - y) / y, rtol=1e-12)
    assert m.max_abs_re_percent == pytest.approx(65.0, rel=1e-12)  # (3.3 - 2) / 2
    assert sse == pytest.approx(m.sse)


def test_rmse_uses_m_minus_n_minus_one():
    assert rmse_paper(9.0, 25, 15) == pytest.approx(1.0)
    assert math.isnan(rmse_paper(1.0, 16, 15))
    assert math.isnan(r2_adjusted(0.9, 15, 15))


def test_loo_press_equals_explicit_refits():
    rng = np.random.default_rng(0)
    x = rng.uniform([0.0, 100.0], [0.4, 500.0], size=(18, 2))
    y = 0.05 + 0.1 * x[:, 0] - 2e-4 * x[:, 1] + 3e-7 * x[:, 1] ** 2 + rng.normal(0, 1e-3, 18)
    s = fit_response_surface(x, y, 2)
    m = fit_metrics(s, warn=False)
    explicit = np.empty(len(y))
    for i in range(len(y)):
        keep = np.arange(len(y)) != i
        si = fit_response_surface(x[keep], y[keep], 2)
        explicit[i] = y[i] - predict(si, x[i])[0]
    np.testing.assert_allclose(m.loo_residuals, explicit, rtol=1e-9, atol=1e-15)
    assert m.press == pytest.approx(float(explicit @ explicit), rel=1e-9)
    assert m.q2 == pytest.approx(1 - m.press / m.sst, rel=1e-12)


def test_overfit_warning_when_points_per_coefficient_too_few():
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 1, size=(16, 2))
    y = rng.normal(size=16)
    s = fit_response_surface(x, y, 4)
    with pytest.warns(OverfitWarning, match="16 points for 15 coefficients"):
        m = fit_metrics(s)
    assert m.overfit_reasons


def test_overfit_warning_when_q2_far_below_r2():
    rng = np.random.default_rng(2)
    x = rng.uniform(0, 1, size=(30, 2))
    y = rng.normal(size=30)  # pure noise: a quadratic fits some of it, predicts none
    s = fit_response_surface(x, y, 2)
    with pytest.warns(OverfitWarning, match="Q2"):
        fit_metrics(s)


def test_leverage_is_hat_diagonal():
    x = np.linspace(0, 1, 7)[:, None]
    s = fit_response_surface(x, np.arange(7.0), 2)
    phi = design_matrix(x, s.exponents)
    hat = phi @ np.linalg.solve(phi.T @ phi, phi.T)
    np.testing.assert_allclose(s.leverage, np.diag(hat), rtol=1e-10)
