"""Stated standard deviations of the diagnosis' FRF fits when the residual is correlated from line to line
(model-form error), and unchanged when it is white (measurement noise): ``fit.correlated_std`` (REML AR(1)
error along the lines, sandwich covariance).  Coverage over seeded trials of a linear model laid out as an FRF
fit's residual (real and imaginary parts of one FRF over the lines) whose regressors are smooth over the lines,
as FRF sensitivities are; fixed seeds; ±1σ coverage within 3.5 binomial standard deviations of 68.3 %.
"""
from __future__ import annotations

import numpy as np

from updating.diagnosis.fit import correlated_std, parameter_std, reml_ar1

N_LINES, N_TRIALS = 200, 300


def _regressors():
    x = np.linspace(0.0, 1.0, N_LINES)
    re = np.column_stack([np.sin(2 * np.pi * x) + 0.3, np.exp(-3 * x)])
    im = np.column_stack([np.cos(2 * np.pi * x), 0.5 * x])
    return np.vstack([re, im])                       # rows: real parts over the lines, then imaginary parts


def _ar1(rng, rho):
    e = np.empty((2, N_LINES))
    e[:, 0] = rng.standard_normal(2)
    for k in range(1, N_LINES):
        e[:, k] = rho * e[:, k - 1] + np.sqrt(1 - rho ** 2) * rng.standard_normal(2)
    return 0.05 * e.ravel()


def _coverage(rho, correlated=True):
    X = _regressors()
    beta = np.array([1.0, -0.5])
    inside = np.zeros(2)
    for t in range(N_TRIALS):
        rng = np.random.default_rng(1000 + t)
        y = X @ beta + _ar1(rng, rho)
        b, *_ = np.linalg.lstsq(X, y, rcond=None)
        r = y - X @ b
        if correlated:
            std = correlated_std(r, X, (1, 1, N_LINES))
        else:
            std = parameter_std(X, float(r @ r) / (r.size - 2))
        inside += np.abs(b - beta) <= std
    return inside / N_TRIALS


def _band(p=0.683):
    return 3.5 * np.sqrt(p * (1 - p) / N_TRIALS)


def test_white_residuals_stay_calibrated_and_give_back_the_least_squares_std():
    cov = _coverage(0.0)
    assert np.all(np.abs(cov - 0.683) <= _band()), cov
    rng = np.random.default_rng(5)
    X = _regressors()
    r = 0.05 * rng.standard_normal(2 * N_LINES)
    r -= X @ np.linalg.lstsq(X, r, rcond=None)[0]
    plain = parameter_std(X, float(r @ r) / (r.size - 2))
    np.testing.assert_allclose(correlated_std(r, X, (1, 1, N_LINES)), plain, rtol=0.25)


def test_correlated_residuals_are_covered_at_68_percent():
    # measured (300 seeded trials): ρ = 0.9 -> 0.70 / 0.68, ρ = 0.99 -> 0.67 / 0.64; without the correlation
    # (plain least squares) 0.20 / 0.15 and 0.14 / 0.06; with the former (1 + ρ̂)/(1 − ρ̂) inflation, ρ̂ from the
    # fitted residual, 0.68 / 0.66 and 0.79 / 0.57 here (0.59 / 0.64 and 0.60 / 0.49 on one 400-line series)
    for rho in (0.9, 0.99):
        cov = _coverage(rho)
        assert np.all(np.abs(cov - 0.683) <= _band()), (rho, cov)
        naive = _coverage(rho, correlated=False)
        assert np.all(naive < 0.3), (rho, naive)       # the plain least-squares std is far too small


def test_reml_recovers_the_correlation_the_fit_hides():
    """The lag-one correlation of the fitted residual is biased low (the fit absorbs the slow error); the
    REML estimate is not: median over 40 seeded series of 2 × 200 lines (measured at ρ = 0.99: REML 0.989,
    the fitted residual's 0.976; at ρ = 0.9: 0.895 and 0.882)."""
    X = _regressors()
    naive, reml = [], []
    for t in range(40):
        rng = np.random.default_rng(77 + t)
        e = _ar1(rng, 0.99)
        r = e - X @ np.linalg.lstsq(X, e, rcond=None)[0]
        rr = r.reshape(2, N_LINES)
        naive.append(np.sum(rr[:, 1:] * rr[:, :-1]) / np.sum(rr * rr))
        reml.append(reml_ar1(rr, X.reshape(2, N_LINES, 2))[1])
    assert abs(np.median(reml) - 0.99) < 0.004, np.median(reml)
    assert np.median(naive) < 0.99 - 0.01, np.median(naive)


def _map_coverage(rho, with_prior_term=True):
    """A MAP fit as the diagnosis makes it: the data rows weighted 1, prior rows ``scale (b − μ)/σ_p`` weighted as
    heavily as the data (the prior's own σ_p = 0.02, the data's noise 0.05: the weights do not match the
    variances), the truth drawn from the prior."""
    X = _regressors()
    mu, sp = np.array([1.0, -0.5]), np.array([0.02, 0.02])
    scale = np.sqrt(np.mean(np.diag(X.T @ X))) * 0.02
    P = (scale / sp) ** 2
    inside = np.zeros(2)
    for t in range(N_TRIALS):
        rng = np.random.default_rng(5000 + t)
        beta = mu + sp * rng.standard_normal(2)
        y = X @ beta + _ar1(rng, rho)
        b = np.linalg.solve(X.T @ X + np.diag(P), X.T @ y + P * mu)
        fun = np.concatenate([X @ b - y, scale * (b - mu) / sp])
        jac = np.vstack([X, np.diag(scale / sp)])
        std = correlated_std(fun, jac, (1, 1, N_LINES), prior_scale=scale if with_prior_term else 0.0)
        inside += np.abs(b - beta) <= std
    return inside / N_TRIALS


def test_a_map_fit_is_covered_with_the_prior_term():
    # measured (300 seeded trials): white 0.63 / 0.63, ρ = 0.9 0.62 / 0.65; without the prior rows' term in
    # the sandwich 0.18 / 0.09 and 0.47 / 0.31 (the shrinkage towards the prior mean is then not counted)
    for rho in (0.0, 0.9):
        cov = _map_coverage(rho)
        assert np.all(np.abs(cov - 0.683) <= _band()), (rho, cov)
    assert np.all(_map_coverage(0.0, with_prior_term=False) < 0.3)


def test_a_parameter_without_effect_leaves_the_reml_estimate_and_the_others_std_unchanged():
    """A Jacobian column that is zero (a parameter the FRFs do not feel) or repeats another made ``JᵀR⁻¹J``
    singular: its log-determinant −∞ turned the REML objective non-finite and the bounded search's ρ arbitrary
    (a clamped post's completed support release, seen as scipy's "invalid value encountered" warning).  REML
    depends on the regressors' column space only: the same ρ and σ² with or without such columns, no warning,
    and the std of the parameters the data do determine unchanged (the other ``inf``)."""
    import warnings
    X = _regressors()
    rng = np.random.default_rng(11)
    e = _ar1(rng, 0.9)
    r = e - X @ np.linalg.lstsq(X, e, rcond=None)[0]
    rr = r.reshape(2, N_LINES)
    base = reml_ar1(rr, X.reshape(2, N_LINES, 2))
    for extra in (np.zeros((2 * N_LINES, 1)), X[:, :1] * 3.0):
        Xe = np.hstack([X, extra])
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            got = reml_ar1(rr, Xe.reshape(2, N_LINES, 3))
        np.testing.assert_allclose(got, base, rtol=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        std = correlated_std(r, np.hstack([X, np.zeros((2 * N_LINES, 1))]), (1, 1, N_LINES))
    np.testing.assert_allclose(std[:2], correlated_std(r, X, (1, 1, N_LINES)), rtol=1e-6)
    assert std[2] == np.inf
