"""Root tracking of the scalar pLSCF denominator (Aberth–Ehrlich, certified, eigenvalue fallback)."""
import numpy as np
import pytest

pytest.importorskip("mpmath")
from hypothesis import given, settings
from hypothesis import strategies as st

from identification import PolyMAX, frequency_weights, modal_system, reduced_normal_matrix
from identification.polymax import (_cholesky, _companion_roots, _roots_at_order, aberth_roots,
                                    denominator_roots)


def _separated_roots(rng, n_pairs, n_real, min_sep):
    """Conjugate pairs near the unit circle (like pLSCF poles) and real roots, pairwise >= min_sep apart."""
    roots = []
    while len(roots) < 2 * n_pairs:
        z = rng.uniform(0.5, 1.3) * np.exp(1j * rng.uniform(0.02, np.pi - 0.02))
        if all(abs(z - r) >= min_sep for r in roots) and abs(z - z.conjugate()) >= min_sep:
            roots += [z, z.conjugate()]
    while len(roots) < 2 * n_pairs + n_real:
        z = complex(rng.uniform(-1.2, 1.2))
        if all(abs(z - r) >= min_sep for r in roots):
            roots.append(z)
    return np.array(roots)


def _match_error(a, b):
    """Largest distance from a root in ``a`` to its partner in ``b`` (one-to-one, greedy by distance)."""
    a, b = list(a), list(b)
    assert len(a) == len(b)
    err = 0.0
    for x in a:
        j = int(np.argmin([abs(x - y) for y in b]))
        err = max(err, abs(x - b.pop(j)))
    return err


def _exact_roots(a):
    """The roots of the (rounded) coefficients ``a`` to ~30 digits: np.roots polished by Newton in mpmath."""
    import mpmath

    mpmath.mp.dps = 40
    c = [mpmath.mpf(float(x)) for x in a[::-1]]
    out = []
    for z0 in np.roots(a[::-1]):
        z = mpmath.mpc(z0)
        for _ in range(6):
            p, dp = mpmath.mpf(0), mpmath.mpf(0)
            for ck in c:                           # Horner for p and p' (descending c), in 40 digits
                dp = dp * z + p
                p = p * z + ck
            z -= p / dp
        out.append(complex(z))
    return np.array(out)


def _coeffs(roots):
    return np.real(np.poly(roots))[::-1]            # ascending, monic


@pytest.fixture(scope="class")
def track_from_degree_24():
    """In production tracking starts at degree 76 (cheaper eigenvalues below); the tests use smaller polynomials."""
    from identification import polymax_roots

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(polymax_roots, "_TRACK_MIN_DEGREE", 24)
        yield


@pytest.mark.usefixtures("track_from_degree_24")
class TestAberth:
    @settings(max_examples=30, deadline=None)
    @given(seed=st.integers(0, 2 ** 31 - 1), n_pairs=st.integers(12, 30), n_real=st.integers(0, 4),
           n_new=st.integers(0, 3))
    def test_tracked_roots_match_eigenvalues(self, seed, n_pairs, n_real, n_new):
        """From perturbed roots (a nearby polynomial) plus a few missing ones, tracking finds them all."""
        rng = np.random.default_rng(seed)
        true = _separated_roots(rng, n_pairs, n_real, min_sep=0.05)
        a = _coeffs(true)
        start = true + 0.004 * (rng.normal(size=true.size) + 1j * rng.normal(size=true.size))
        start = start[rng.permutation(true.size)][n_new:]         # a lower order has fewer roots
        z, method = denominator_roots(a, start)
        # badly scaled coefficients (pLSCF's are O(1)), or roots outside the unit circle where the polynomial's
        # evaluation loses digits (seed 211, 24 pairs, 3 real: |a| sums to 7.6e3, and the roots near -1.21 have
        # inclusion discs of radius 0.048 at the rounding level, wider than half their distance): the discs can
        # be too wide to certify even from the exact roots; then the eigenvalues must have been taken
        if method == "eigvals" and (np.abs(a).sum() > 1e4 or aberth_roots(a, true * np.exp(1e-4j)) is None):
            np.testing.assert_allclose(np.sort_complex(z), np.sort_complex(_companion_roots(a)))
            return
        assert method == "tracked"
        exact = _exact_roots(a)
        err_eig = _match_error(np.roots(a[::-1]), exact)
        assert _match_error(z, exact) <= max(10 * err_eig, 1e-12)   # as accurate as the eigenvalues

    @settings(max_examples=20, deadline=None)
    @given(seed=st.integers(0, 2 ** 31 - 1), n=st.integers(5, 60))
    def test_from_a_circle_on_random_polynomials(self, seed, n):
        """Global convergence from the classical circle start, certified by disjoint inclusion discs."""
        rng = np.random.default_rng(seed)
        a = np.append(rng.normal(size=n), 1.0)
        start = 1.1 * np.exp(1j * (2 * np.pi * np.arange(n) / n + 0.3))
        out = aberth_roots(a, start, max_iter=200)
        if out is None:                                             # may fail to certify: must not lie
            return
        z, rad = out
        exact = _exact_roots(a)
        d = np.abs(z[:, None] - exact[None, :])
        assert np.all(d.min(axis=1) <= rad) and sorted(d.argmin(axis=1)) == list(range(n))
        assert _match_error(z, exact) <= max(10 * _match_error(np.roots(a[::-1]), exact), 1e-12)

    def test_real_start_stays_real_unless_rotated(self):
        """Real starting points of a real polynomial stay real: z² + 1 is never solved from them."""
        a = np.array([1.0, 0.0, 1.0])
        assert aberth_roots(a, [0.3, -0.4], max_iter=100) is None
        z, rad = aberth_roots(a, np.array([0.3, -0.4]) * np.exp(1e-4j))
        assert _match_error(z, [1j, -1j]) <= 1e-14 and np.all(rad < 1e-8)

    def test_real_roots_come_out_exactly_real(self):
        true = np.r_[np.exp(1j * np.linspace(0.2, 3.0, 13)), np.exp(-1j * np.linspace(0.2, 3.0, 13)), 0.4, -0.6]
        z, method = denominator_roots(_coeffs(true), true * 1.001)
        assert method == "tracked"
        assert np.sum(z.imag == 0) == 2 and _match_error(z, np.roots(_coeffs(true)[::-1])) <= 1e-9

    @pytest.mark.parametrize("seed", [119, 239, 7])
    def test_certified_discs_hold_the_exact_roots(self, seed):
        """Every exact root (30 digits) lies in the inclusion disc of its tracked approximation."""
        rng = np.random.default_rng(seed)
        true = _separated_roots(rng, 20, 2, min_sep=0.05)
        a = _coeffs(true)
        z, rad = aberth_roots(a, true * np.exp(1e-4j) + 0.003)
        exact = _exact_roots(a)
        d = np.abs(z[:, None] - exact[None, :])
        assert np.all(d.min(axis=1) <= rad)
        assert sorted(d.argmin(axis=1)) == list(range(z.size))        # one exact root per disc
        err_eig = _match_error(np.roots(a[::-1]), exact)
        assert _match_error(z, exact) <= max(10 * err_eig, 1e-12)   # as accurate as the eigenvalues

    def test_multiple_root_falls_back_to_eigenvalues(self):
        true = np.r_[np.exp(1j * np.linspace(0.2, 3.0, 13)), np.exp(-1j * np.linspace(0.2, 3.0, 13)), 0.5, 0.5]
        a = _coeffs(true)
        assert aberth_roots(a, true + 0.01j) is None                 # discs of a double root overlap
        z, method = denominator_roots(a, true * 1.001)
        assert method == "eigvals"
        np.testing.assert_allclose(np.sort_complex(z), np.sort_complex(_companion_roots(a)))

    @pytest.mark.parametrize("case", ["too_many_new", "short_iteration", "nonfinite", "low_degree"])
    def test_fallback_cases(self, case):
        rng = np.random.default_rng(5)
        true = _separated_roots(rng, 15, 2, 0.05)
        a = _coeffs(true)
        if case == "too_many_new":
            z, method = denominator_roots(a, true[:10])
        elif case == "short_iteration":
            assert aberth_roots(a, true * 1.01, max_iter=1) is None
            z, method = denominator_roots(a, true * 1.01)
            assert method == "tracked"
            return
        elif case == "nonfinite":
            assert aberth_roots(np.r_[a[:-1], np.nan, 1.0][: a.size], true) is None
            z, method = denominator_roots(a, np.r_[true[:-1], np.nan])     # the nan start is dropped, one new
            assert method == "tracked"
            return
        else:
            a = _coeffs(true[:10])
            z, method = denominator_roots(a, true[:10])
        assert method == "eigvals"
        np.testing.assert_allclose(np.sort_complex(z), np.sort_complex(_companion_roots(a)))


class TestTrackingInPolyMAX:
    def test_tracked_poles_equal_eigenvalue_poles(self):
        """One reference, order sweep: every order's poles equal the companion-eigenvalue poles."""
        fn, zeta = np.array([42.0, 95.0, 151.0, 240.0, 247.0]), np.array([0.01, 0.008, 0.012, 0.006, 0.012])
        mm, _ = modal_system(fn, zeta, 6, rng=0)
        f = np.linspace(1.0, 400.0, 1200)
        frf = mm.frf(f, references=[mm.dofs[0]])
        rng = np.random.default_rng(3)
        frf = frf._replace(H=frf.H * (1 + 0.01 * (rng.normal(size=frf.H.shape) + 1j * rng.normal(size=frf.H.shape))))
        pm = PolyMAX(max_order=100, min_order=2, order_step=2, select=list(fn)).fit(frf)
        assert pm.root_methods_["tracked"] >= 10                     # orders 76..100 at least
        dt = pm.dt_
        M = reduced_normal_matrix(pm.frf_.H, frequency_weights(pm.frf_), 2 * np.pi * pm.frf_.freq_hz * dt, 100)
        chol = _cholesky(M)                                          # the fit's denominators, same rounding
        assert chol is not None
        for n, lam in zip(pm.orders_, pm.poles_):
            z, _, how = _roots_at_order(M, int(n), 1, start=None, chol=chol)   # no start: eigenvalues
            assert how == "eigvals"
            ref = np.log(z[z != 0]) / dt
            ref = ref[ref.imag > 0]
            assert lam.size == ref.size
            assert _match_error(np.exp(lam * dt), np.exp(ref * dt)) <= 1e-9
        np.testing.assert_allclose(pm.modes_.freq_hz, fn, rtol=2e-3)


class TestCholeskyDenominators:
    def test_equal_to_the_solve_of_each_order(self):
        from identification.polymax import _denominator

        mm, _ = modal_system([50.0, 120.0, 170.0], [0.02, 0.01, 0.015], 4, rng=0)
        f = np.linspace(1, 200, 400)
        frf = mm.frf(f, references=[mm.dofs[0], mm.dofs[1]])
        rng = np.random.default_rng(0)
        H = frf.H * (1 + 0.02 * rng.normal(size=frf.H.shape))
        dt = 1 / (2 * f[-1])
        M = reduced_normal_matrix(H, np.ones((4, f.size)), 2 * np.pi * f * dt, 20)
        chol = _cholesky(M)
        assert chol is not None
        for n in (1, 5, 12, 20):
            a_lu = _denominator(M, n, 2)
            # two solves of one ill-conditioned system agree to its conditioning, not to the last digit: the
            # smallest coefficients of order 20 differed by 1.8e-8 of the largest on an AMD EPYC's OpenBLAS
            np.testing.assert_allclose(_denominator(M, n, 2, chol), a_lu, rtol=1e-6, atol=1e-7 * np.abs(a_lu).max())

    def test_not_positive_definite_gives_none(self):
        assert _cholesky(np.diag([1.0, -1.0, 2.0])) is None
        assert _cholesky(np.diag([1.0, 1e-20, 2.0])) is None
