"""Property-based checks of the correlation criteria, pairing and reduction."""
import numpy as np
import scipy.linalg as sla
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from updating.correlation.metrics import automac, comac, ecomac, mac, macx, msf, pair_modes
from updating.correlation.reduction import guyan, serep

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
scales = st.floats(1e-3, 1e3).flatmap(lambda m: st.sampled_from([m, -m]))


def shapes(n_dof=st.integers(2, 10), n_modes=st.integers(1, 5)):
    return st.tuples(n_dof, n_modes).flatmap(lambda s: arrays(float, s, elements=finite))


def nonzero_cols(A):
    return np.all(np.linalg.norm(A, axis=0) > 1e-6)


@settings(max_examples=60, deadline=None)
@given(shapes(), st.data())
def test_mac_bounded_and_transposes(A, data):
    X = data.draw(arrays(float, (A.shape[0], data.draw(st.integers(1, 4))), elements=finite))
    M = mac(A, X)
    assert M.shape == (A.shape[1], X.shape[1])
    assert np.all((M >= 0) & (M <= 1))
    np.testing.assert_allclose(M, mac(X, A).T, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(shapes(), st.data())
def test_mac_invariant_to_scaling(A, data):
    assume(nonzero_cols(A))
    X = data.draw(arrays(float, A.shape, elements=finite))
    assume(nonzero_cols(X))
    sa = np.array([data.draw(scales) for _ in range(A.shape[1])])
    phase = np.exp(1j * data.draw(st.floats(0, 2 * np.pi)))
    sx = data.draw(scales) * phase
    np.testing.assert_allclose(mac(A * sa, X * sx), mac(A, X), atol=1e-9)
    np.testing.assert_allclose(macx(A * sa, X * sx), macx(A, X), atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(shapes())
def test_identical_vectors_have_mac_one(A):
    assume(nonzero_cols(A))
    np.testing.assert_allclose(np.diag(mac(A, A)), 1.0, rtol=1e-12)
    Am = automac(A)
    np.testing.assert_allclose(Am, Am.T)
    np.testing.assert_allclose(np.diag(Am), 1.0, rtol=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 9))
def test_orthogonal_vectors_have_mac_zero(seed, n):
    # a Gaussian matrix is non-singular with probability one: no filtering needed (hypothesis' own
    # float matrices are mostly singular, which tripped its filter health check)
    R = np.random.default_rng(seed).normal(size=(n, n))
    Q, _ = np.linalg.qr(R)
    np.testing.assert_allclose(automac(Q), np.eye(n), atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(shapes(), st.data())
def test_msf_recovers_scale(A, data):
    assume(nonzero_cols(A))
    s = np.array([data.draw(scales) for _ in range(A.shape[1])])
    np.testing.assert_allclose(msf(A * s, A), s, rtol=1e-9)
    np.testing.assert_allclose(comac(A, A * s), 1.0, rtol=1e-9)
    assert np.all(ecomac(A, A * s) < 1e-9)


@settings(max_examples=40, deadline=None)
@given(shapes(n_dof=st.integers(2, 8), n_modes=st.integers(1, 4)), st.data())
def test_comac_bounded(A, data):
    X = data.draw(arrays(float, A.shape, elements=finite))
    c = comac(A, X)
    assert np.all((c >= 0) & (c <= 1 + 1e-12))


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 8), st.integers(0, 3), st.randoms(use_true_random=False))
def test_pairing_recovers_permutation(n, extra, rnd):
    perm = list(range(n + extra))
    rnd.shuffle(perm)
    perm = perm[:n]                       # test mode j is analysis mode perm[j]; `extra` analysis modes unmeasured
    rng = np.random.default_rng(rnd.randint(0, 2 ** 31))
    Q, _ = np.linalg.qr(rng.normal(size=(n + extra + 4, n + extra)))
    X = Q[:, perm] * rng.uniform(0.5, 2.0, n) + 0.02 * rng.normal(size=(Q.shape[0], n))
    p = pair_modes(mac(Q, X), mac_min=0.5)
    assert p.pairs == [(perm[j], j) for j in range(n)]
    assert sorted(p.unpaired_analysis) == sorted(set(range(n + extra)) - set(perm))


@settings(max_examples=25, deadline=None)
@given(st.integers(4, 9), st.integers(1, 3), st.integers(0, 2 ** 31 - 1))
def test_reduction_bounds_and_serep_exactness(n, m, seed):
    rng = np.random.default_rng(seed)
    k = rng.uniform(0.5, 2.0, n)
    K = np.diag(np.r_[k[1:], 0] + k) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    M = np.diag(rng.uniform(0.5, 2.0, n))
    masters = sorted(rng.choice(n, size=m, replace=False).tolist())
    full = sla.eigvalsh(K, M)[:m]
    g = guyan(K, M, masters)
    lg = sla.eigvalsh(g.K, g.M)
    assert np.all(lg >= full * (1 - 1e-9))                        # Guyan: Rayleigh–Ritz upper bounds
    s = serep(K, M, masters)
    np.testing.assert_allclose(sla.eigvalsh(s.K, s.M), full, rtol=1e-8)
