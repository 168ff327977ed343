"""The one pairing rule (issue 14 #1, issue 16 #6, #12-#14): frequency window, MAC floor, unobservable and
rigid-body modes, reasons for unpaired modes, determinism, frequency-only sets, frequency covariance.

The pairing is judged on an analytic model (simply supported Euler-Bernoulli beam, closed-form modes),
not on the FE code: sin(nπx/L) sampled at 7 equally spaced sensors aliases mode n with mode 16 - n
(identical |shape|, MAC = 1), which MAC alone cannot resolve.
"""
import numpy as np
import pytest

from modalab.core.errors import ModalabValueError
from modalab.core.modes import ModeSet
from updating.correlation.metrics import correlate, observability, pair_modes

L = 1.0
X_SENS = np.arange(1, 8) / 8 * L


def beam(n_modes, f1, x=X_SENS):
    """Simply supported beam: f_n = n² f1, φ_n(x) = sin(nπx/L)."""
    n = np.arange(1, n_modes + 1)
    return n ** 2 * f1, np.sin(np.outer(x, n) * np.pi / L)


def beam_sets(n_test=6, n_fe=15, stiff=1.1, seed=0):
    fa, A = beam(n_fe, 10.0)
    fx, X = beam(n_test, 10.0 * np.sqrt(stiff))
    X = X + 0.02 * np.random.default_rng(seed).normal(size=X.shape)
    dofs = [f"{k + 1}+Z" for k in range(len(X_SENS))]
    return ModeSet(freq_hz=fa, shapes=A, dofs=dofs), ModeSet(freq_hz=fx, shapes=X, dofs=dofs)


class TestAliasingAndWindow:
    def test_aliased_modes_are_paired_by_frequency(self):
        an, te = beam_sets()
        M = correlate(an, te, max_freq_error=None, freq_weight=0.0).mac
        # mode 1 and mode 15 look the same at the 7 sensors: MAC alone cannot choose
        assert M[14, 0] > 0.99 and M[0, 0] > 0.99
        r = correlate(an, te)
        assert r.pairs == [(k, k) for k in range(6)]
        assert np.all(np.abs(r.freq_error_pct - (np.sqrt(1 / 1.1) - 1) * 100) < 1e-9)

    def test_far_pair_is_refused_and_the_reason_given(self):
        # the case: a test mode whose best MAC (0.58) is with a mode 78 % lower is unpaired
        M = np.array([[0.99, 0.10], [0.10, 0.58]])
        p = pair_modes(M, [15.68, 69.59], [15.68, 311.5])
        assert p.pairs == [(0, 0)] and p.unpaired_test == [1]
        assert "outside the ±35 % frequency window" in p.unpaired_reason[1]
        # by MAC alone (no window, no frequency term) the same MAC would have paired it
        assert pair_modes(M, [15.68, 69.59], [15.68, 311.5], max_freq_error=None,
                          freq_weight=0.0).pairs == [(0, 0), (1, 1)]

    def test_table_says_when_the_best_mac_partner_is_taken(self):
        # test 2 has its best MAC with FE 1, which test 1 takes with a better pair
        fa = [10.0, 30.0]
        A = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
        X = np.array([[1.0, 1.0], [0.0, 0.2], [0.0, 0.6]])
        an = ModeSet(freq_hz=fa, shapes=A, dofs=["1+Z", "2+Z", "3+Z"])
        te = ModeSet(freq_hz=[10.0, 10.5], shapes=X, dofs=["1+Z", "2+Z", "3+Z"])
        r = correlate(an, te)
        assert r.pairs == [(0, 0)]
        line = [ln for ln in r.table().splitlines() if ln.strip().startswith("2 ")][0]
        assert "FE 1 is paired with test 1" in line
        assert "pairing: Hungarian assignment" in r.table()

    def test_leaving_a_mode_unpaired_can_be_better_than_a_forced_pair(self):
        # A pairs with FE1 (0.99) or FE2 (0.55); B only with FE1 (0.55): A-FE1 and B unpaired costs less
        # than A-FE2 + B-FE1, so the bad pair B-FE1 is not forced
        M = np.array([[0.99, 0.55], [0.55, 0.0]])
        p = pair_modes(M, mac_min=0.5)
        assert p.pairs == [(0, 0)] and p.unpaired_test == [1]


class TestExclusions:
    def test_unobservable_mode_is_excluded_despite_a_roundoff_mac(self):
        an, te = beam_sets(n_test=3, n_fe=4)
        # an FE mode the sensors cannot see: 1e-13 at the sensors (round-off) but of unit size elsewhere
        full = np.vstack([an.shapes, np.eye(4)[:1] * 0 + 1.0])
        ghost = te.shapes[:, 1] * 1e-13
        shapes = np.column_stack([full, np.r_[ghost, 1.0]])
        dofs = list(an.dofs) + ["99+Z"]
        an2 = ModeSet(freq_hz=list(an.freq_hz) + [te.freq_hz[1] * 1.001], shapes=shapes, dofs=dofs)
        r = correlate(an2, te)
        assert r.observability[4] < 1e-10
        assert 4 in r.pairing.excluded_analysis and "not observable" in r.pairing.excluded_analysis[4]
        assert (1, 1) in r.pairs and all(a != 4 for a, _ in r.pairs)
        # without the exclusion the round-off MAC of the ghost would have won on frequency
        p = pair_modes(r.mac, r.analysis.freq_hz, te.freq_hz, observability=None)
        assert (4, 1) in p.pairs

    def test_table_lists_only_unpaired_model_modes_inside_the_test_band(self):
        # FE modes at 3 Hz (below the lowest test mode, 10 Hz) and 30 Hz (inside) have no test partner
        fa = [3.0, 10.0, 30.0, 50.0]
        A = np.eye(4)
        an = ModeSet(freq_hz=fa, shapes=A, dofs=["1+Z", "2+Z", "3+Z", "4+Z"])
        te = ModeSet(freq_hz=[10.0, 50.0], shapes=A[:, [1, 3]], dofs=an.dofs)
        r = correlate(an, te)
        line = [ln for ln in r.table().splitlines() if "in the test band without a test partner" in ln][0]
        assert "3 (30 Hz)" in line and "1 (3 Hz)" not in line

    def test_rigid_body_modes_excluded_or_paired_on_purpose(self):
        rb = np.ones((7, 1))
        _, B = beam(3, 10.0)
        an = ModeSet(freq_hz=[0.0, 10.0, 40.0, 90.0], shapes=np.column_stack([rb, B]),
                     dofs=[f"{k + 1}+Z" for k in range(7)])
        te = ModeSet(freq_hz=[1.5, 10.1, 40.3], shapes=np.column_stack([rb + 0.01, B[:, :2]]), dofs=an.dofs)
        r = correlate(an, te)
        assert r.pairs == [(1, 1), (2, 2)] and r.pairing.unpaired_test == [0]
        assert "rigid-body" in r.pairing.excluded_analysis[0]
        rp = correlate(an, te, rigid="pair")
        assert rp.pairing.rigid_pairs == [(0, 0)] and rp.pairs == [(1, 1), (2, 2)]
        assert "rigid-body pair (not in any objective)" in rp.table()
        with pytest.raises(ModalabValueError, match="rigid"):
            pair_modes(np.eye(2), rigid="keep")


class TestDeterminism:
    def test_same_input_same_pairs_and_order_invariance(self):
        an, te = beam_sets(n_test=8, n_fe=15, stiff=1.0)
        ref = correlate(an, te)
        for _ in range(5):
            assert correlate(an, te).pairs == ref.pairs
        perm = np.random.default_rng(3).permutation(an.n_modes)
        r2 = correlate(an.select_modes(perm), te)
        assert sorted((int(perm[a]), x) for a, x in r2.pairs) == sorted(ref.pairs)


class TestFrequencyOnly:
    def test_modeset_without_shapes(self):
        ms = ModeSet(freq_hz=[1.0, 2.0, 3.0, 4.0])
        assert not ms.has_shapes and ms.shapes.shape == (0, 4)
        with pytest.raises(Exception, match="frequency-only"):
            ModeSet(freq_hz=[1.0, 2.0], shapes=np.zeros((0, 1)), dofs=["1+Z"])
        rt = ModeSet.from_dict(ms.to_dict())
        assert not rt.has_shapes and rt.n_modes == 4

    def test_uff_round_trip_of_a_frequency_only_set(self, tmp_path):
        ms = ModeSet(freq_hz=[1.0, 2.5], damping=[0.01, 0.02])
        ms.to_uff(tmp_path / "f.uff")
        back = ModeSet.from_uff(tmp_path / "f.uff")
        assert not back.has_shapes
        np.testing.assert_array_equal(back.freq_hz, ms.freq_hz)

    def test_pairing_by_order_inside_the_window(self):
        an = ModeSet(freq_hz=[0.0, 9.0, 21.0, 29.0, 60.0], shapes=np.eye(5), dofs=[f"{k}+Z" for k in range(1, 6)])
        te = ModeSet(freq_hz=[10.0, 20.0, 30.0, 40.0])
        r = correlate(an, te)
        assert r.pairs == [(1, 0), (2, 1), (3, 2)] and r.pairing.unpaired_test == [3]
        assert "pairing by frequency order" in r.table() and "no mode shapes" in r.table()
        assert r.pairing.unpaired_reason[3] == "nearest FE 4 (-27.5 %) is paired with test 3 (frequency order)"
        assert r.to_dict()["mac"] is None

    def test_covariance_from_repeats(self):
        rng = np.random.default_rng(1)
        C = np.array([[1.0, 0.8], [0.8, 1.0]]) * 0.01 ** 2
        F = np.array([5.0, 12.0]) + rng.multivariate_normal([0, 0], C, size=400)
        ms = ModeSet.from_repeats(F)
        np.testing.assert_allclose(ms.freq_cov * 400, C, rtol=0.2)
        assert ms.freq_std_hz.shape == (2,) and ms.metadata["n_repeats"] == 400
        rt = ModeSet.from_dict(ms.to_dict())
        np.testing.assert_allclose(rt.freq_cov, ms.freq_cov)
