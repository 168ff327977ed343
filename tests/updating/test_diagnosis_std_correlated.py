"""Stated standard deviations of the diagnosis' FRF fits when the residual is correlated from line to line
(model-form error), and unchanged when it is white (measurement noise): ``fit.ar1_inflation`` with
``fit.parameter_std``.  Coverage over seeded trials of a linear model whose regressors are smooth over the
lines, as FRF sensitivities are; fixed seeds, bounds with margin (white: 3.5 binomial standard deviations).
"""
from __future__ import annotations

import numpy as np

from updating.diagnosis.fit import ar1_inflation, parameter_std

N_LINES, N_TRIALS = 400, 300


def _regressors():
    x = np.linspace(0.0, 1.0, N_LINES)
    return np.column_stack([np.sin(2 * np.pi * x) + 0.3, np.exp(-3 * x)])


def _ar1(rng, rho):
    e = np.empty(N_LINES)
    e[0] = rng.standard_normal()
    for k in range(1, N_LINES):
        e[k] = rho * e[k - 1] + np.sqrt(1 - rho ** 2) * rng.standard_normal()
    return 0.05 * e


def _coverage(rho, inflate):
    X = _regressors()
    beta = np.array([1.0, -0.5])
    inside = np.zeros(2)
    for t in range(N_TRIALS):
        rng = np.random.default_rng(1000 + t)
        y = X @ beta + _ar1(rng, rho)
        b, *_ = np.linalg.lstsq(X, y, rcond=None)
        r = y - X @ b
        s2 = float(r @ r) / (N_LINES - 2)
        f = ar1_inflation(r[None, :]) if inflate else 1.0
        inside += np.abs(b - beta) <= parameter_std(X, s2 * f)
    return inside / N_TRIALS


def _band(p=0.683):
    return 3.5 * np.sqrt(p * (1 - p) / N_TRIALS)


def test_white_residuals_are_not_inflated_and_stay_calibrated():
    cov = _coverage(0.0, inflate=True)
    assert np.all(np.abs(cov - 0.683) <= _band()), cov
    rng = np.random.default_rng(5)
    assert ar1_inflation(rng.standard_normal((2, 3, 2000))) < 1.1


def test_correlated_residuals_with_the_inflation_come_close_to_68_percent():
    # measured (300 seeded trials): ρ = 0.9 -> 0.59 / 0.64 with the inflation, 0.15 / 0.16 without;
    # ρ = 0.99 -> 0.60 / 0.49, without 0.08 / 0.06.  Still below 68 %: ρ estimated from the fitted residual is
    # biased low (the fit absorbs part of the slow error), which the inflation does not correct.
    for rho, floor in ((0.9, 0.55), (0.99, 0.45)):
        cov = _coverage(rho, inflate=True)
        assert np.all(cov >= floor) and np.all(cov <= 0.683 + _band()), (rho, cov)
        naive = _coverage(rho, inflate=False)
        assert np.all(naive < 0.25), (rho, naive)       # the plain least-squares std is far too small
