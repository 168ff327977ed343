"""The per-line factorisation of the dynamic stiffness above the dense limit: LAPACK's banded LU in the reverse
Cuthill-McKee order for narrow bands, SuperLU for wide ones (updating.correlation.condensation).  Both must give
the same receptances and the same condensed residual: the choice changes time, never an answer."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import modalab.core.dense as dense
import updating.correlation.condensation as cond
from updating.correlation.condensation import condensed_residual, solve_columns
from updating.fe.models.garteur import garteur_model


@pytest.fixture
def limits():
    """Restores the dense and band limits a test changes."""
    old = dense.SOLVE_LIMIT, cond.BAND_LIMIT
    yield
    dense.SOLVE_LIMIT, cond.BAND_LIMIT = old


def _garteur():
    st_ = garteur_model().structure()
    n = st_.K.shape[0]
    D = 0.01 * st_.K                                    # a structural loss, so that no line is singular
    return st_.K, st_.M, None, D, n


def _both(fn, band_limit: int):
    """``fn()`` through the banded LU (band limit ``band_limit``) and through SuperLU (band limit −1)."""
    cond.BAND_LIMIT = band_limit
    a = fn()
    cond.BAND_LIMIT = -1
    b = fn()
    return a, b


def test_garteur_receptance_columns_are_the_same_banded_and_by_superlu(limits):
    """The GARTEUR-like frame (396 DOFs, half band 40 after the reordering) with its band limit raised: the same
    receptance columns as SuperLU gives, at lines through its resonances."""
    K, M, C, D, n = _garteur()
    s = 2j * np.pi * np.linspace(2.0, 80.0, 60)
    cols = [0, n // 3, n - 1]
    a, b = _both(lambda: solve_columns(K, M, C, D, s, cols), 1000)
    cond.BAND_LIMIT = 1000
    assert cond._Pattern(K, M, C, D)._banded()[1] == 40      # what the band limit is raised over
    np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-10 * np.abs(b).max())
    # and the columns are the receptance: Z x = e at one line, checked on the matrices themselves
    Z = (K + s[7] ** 2 * M + 1j * D).toarray()
    np.testing.assert_allclose(Z @ a[:, 1, 7], np.eye(n)[:, cols[1]], atol=1e-8)


def test_garteur_condensed_residual_is_the_same_banded_and_by_superlu(limits):
    """The dynamic expansion of measured columns (the MCI's residual, its expansion matrices and weights):
    the same through either factorisation of Z_ss."""
    K, M, C, D, n = _garteur()
    rng = np.random.default_rng(3)
    s = 2j * np.pi * np.linspace(3.0, 60.0, 25)
    meas = np.sort(rng.choice(n, 12, replace=False))
    x = rng.standard_normal((12, 2, s.size)) + 1j * rng.standard_normal((12, 2, s.size))
    F = np.zeros((n, 2))
    F[meas[0], 0] = F[meas[5], 1] = 1.0
    a, b = _both(lambda: condensed_residual(K, M, C, D, s, meas, x, F), 1000)
    for u, v in zip(a, b):
        np.testing.assert_allclose(u, v, rtol=1e-8, atol=1e-10 * np.abs(v).max())


def test_wide_band_is_left_to_superlu():
    """A pattern whose half band after the reordering exceeds the limit is not banded (SuperLU factors it)."""
    K, M, C, D, n = _garteur()
    pat = cond._Pattern(K, M, C, D)
    assert cond.BAND_LIMIT < 40 and pat._banded() is None
    assert type(pat.factor(2j * np.pi * 10.0)).__name__ == "SuperLU"


def test_an_exactly_singular_line_fails_as_superlu_says():
    """Z exactly singular at a line (two equal rows): the banded LU finds the zero pivot and leaves the line to
    SuperLU, which raises as it did before there was a banded path."""
    K = sp.csr_matrix(np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 2.0]]))     # rows 0 and 1 equal
    pat = cond._Pattern(K, sp.csr_matrix((3, 3)), None, None)
    assert pat._banded() is not None
    with pytest.raises(RuntimeError, match="singular"):
        pat.factor(0.0)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(n=st.integers(3, 60), half_band=st.integers(0, 6), seed=st.integers(0, 2 ** 16))
def test_banded_solve_of_a_shuffled_banded_matrix_is_the_dense_solve(n, half_band, seed):
    """A diagonally dominant complex matrix with a band of ``half_band``, its DOFs shuffled (as a mesh numbers
    them): the reordering finds a band, and the banded LU solves it as a dense solve does."""
    rng = np.random.default_rng(seed)
    A = np.zeros((n, n), complex)
    half_band = min(half_band, n - 1)
    for d in range(-half_band, half_band + 1):
        A += np.diag(rng.standard_normal(n - abs(d)) + 1j * rng.standard_normal(n - abs(d)), d)
    A += np.diag(2.0 * (2 * half_band + 1) * (1.0 + np.abs(np.diag(A))))
    p = rng.permutation(n)
    A = A[np.ix_(p, p)]
    K = sp.csr_matrix(A.real)
    D = sp.csr_matrix(A.imag)
    pat = cond._Pattern(K, sp.csr_matrix((n, n)), None, D)
    band = pat._banded()
    assert band is not None                            # a shuffled band is found again, narrow
    B = rng.standard_normal((n, 2)) + 1j * rng.standard_normal((n, 2))
    np.testing.assert_allclose(pat.factor(0.0).solve(B), np.linalg.solve(A, B), rtol=1e-9, atol=1e-12)
