"""Frequency covariance propagated to parameter uncertainty (issue 16 #13-#14): coverage of the stated
±1σ / ±2σ on a 3-DOF chain with correlated frequency errors, and the identifiability warning."""
import logging

import numpy as np

from modalab.core.modes import ModeSet
from updating.methods.eigensensitivity import InverseEigensensitivity
from updating.fe.parametric import Derivative, MatrixModel
from updating.fe.sensitivity import solve_modes

N = 3


def chain(p):
    terms = []
    for j in range(N):
        K = np.zeros((N, N))
        K[j, j] += 1
        if j > 0:
            K[j - 1, j - 1] += 1
            K[j, j - 1] -= 1
            K[j - 1, j] -= 1
        terms.append((f"k{j + 1}", Derivative(dK=K)))
    terms += [(f"m{j + 1}", Derivative(dM=np.diag(np.eye(N)[j]))) for j in range(N)]
    return MatrixModel(dofs=[f"{j + 1}+Z" for j in range(N)], terms=terms, p0=p)


P_TRUE = np.r_[3e4, 2e4, 1e4, 1.0, 1.0, 1.0]


def test_stated_uncertainty_covers_the_truth():
    f_true = solve_modes(chain(P_TRUE)).freq_hz
    sd = 2e-3 * f_true
    R = np.array([[1.0, 0.8, 0.6], [0.8, 1.0, 0.8], [0.6, 0.8, 1.0]])
    cov = R * np.outer(sd, sd)
    rng = np.random.default_rng(11)
    inside1 = inside2 = total = 0
    for _ in range(150):
        f = f_true + rng.multivariate_normal(np.zeros(N), cov)
        ms = ModeSet(freq_hz=f, freq_cov=cov)
        up = InverseEigensensitivity(params=["k1", "k2"], regularisation=None).fit(chain(P_TRUE), ms)
        z = (up.p_[:2] - P_TRUE[:2]) / up.std_unregularised_
        inside1 += int(np.sum(np.abs(z) <= 1))
        inside2 += int(np.sum(np.abs(z) <= 2))
        total += 2
    assert 0.60 <= inside1 / total <= 0.76, inside1 / total
    assert 0.91 <= inside2 / total <= 0.98, inside2 / total


def test_ignoring_the_correlation_gives_a_different_uncertainty():
    f_true = solve_modes(chain(P_TRUE)).freq_hz
    sd = 2e-3 * f_true
    R = np.array([[1.0, 0.9, 0.9], [0.9, 1.0, 0.9], [0.9, 0.9, 1.0]])
    full = ModeSet(freq_hz=f_true, freq_cov=R * np.outer(sd, sd))
    diag = ModeSet(freq_hz=f_true, freq_cov=np.diag(sd ** 2))
    a = InverseEigensensitivity(params=["k1", "k2"], regularisation=None).fit(chain(P_TRUE), full)
    b = InverseEigensensitivity(params=["k1", "k2"], regularisation=None).fit(chain(P_TRUE), diag)
    assert a.identifiable_ and b.identifiable_
    assert not np.allclose(a.std_unregularised_, b.std_unregularised_, rtol=0.1)


def test_unidentifiable_set_is_reported(caplog):
    """The three frequencies of a unit-mass chain do not determine its three stiffnesses (the sensitivity
    matrix has rank 2): the condition number and the unregularised uncertainty say so."""
    f_true = solve_modes(chain(P_TRUE)).freq_hz
    ms = ModeSet(freq_hz=f_true, freq_cov=np.diag((1e-3 * f_true) ** 2))
    with caplog.at_level(logging.WARNING):
        up = InverseEigensensitivity(params=["k1", "k2", "k3"]).fit(chain(P_TRUE), ms)
    assert not up.identifiable_ and up.condition_ == np.inf
    assert np.all(np.isinf(up.std_unregularised_))
    assert "not identifiable" in caplog.text
