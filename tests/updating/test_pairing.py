"""Automatic mode pairing: swapped modes (thesis Table 10), missing and spurious modes."""
import numpy as np
import pytest

from modalab.core.errors import ModalabValueError, ShapeError
from modalab.core.modes import ModeSet
from updating.correlation.metrics import correlate, pair_modes

# Thesis Table 10 (scaled aircraft): experimental mode -> original FE mode, frequencies in Hz
TABLE10_TEST_HZ = [5.65, 15.73, 36.79, 37.51, 37.65, 43.73, 50.32, 55.00, 60.66, 68.23]
TABLE10_FE_MODE = [1, 2, 5, 3, 4, 6, 7, 8, 10, 9]
TABLE10_FE_HZ = {1: 5.66, 2: 16.54, 5: 37.05, 3: 34.57, 4: 34.67, 6: 43.17, 7: 50.35, 8: 54.75, 10: 74.43,
                 9: 72.16}


def table10_modes(noise=0.08, n_dof=40, extra_fe=2, seed=0):
    """FE modes in FE order; test modes are the FE shapes of Table 10's partners plus noise."""
    rng = np.random.default_rng(seed)
    n_fe = 10 + extra_fe
    Q, _ = np.linalg.qr(rng.normal(size=(n_dof, n_fe)))
    fe_hz = [TABLE10_FE_HZ[k] for k in range(1, 11)] + [90.0 + 10 * k for k in range(extra_fe)]
    X = Q[:, [m - 1 for m in TABLE10_FE_MODE]]
    X = X * rng.uniform(0.5, 3.0, 10) * rng.choice([-1, 1], 10) + noise * rng.normal(size=X.shape) / np.sqrt(n_dof)
    dofs = [f"{i + 1}+Z" for i in range(n_dof)]
    an = ModeSet(freq_hz=fe_hz, shapes=Q, dofs=dofs)
    te = ModeSet(freq_hz=TABLE10_TEST_HZ, shapes=X, dofs=dofs)
    return an, te


class TestTable10:
    def test_recovers_thesis_pairing(self):
        an, te = table10_modes()
        r = correlate(an, te, mac_min=0.8)
        got = [(ia + 1, jx + 1) for ia, jx in r.pairs]
        assert got == [(fe, j + 1) for j, fe in enumerate(TABLE10_FE_MODE)]
        # out-of-order pairs: test modes 3-5 and 9-10
        assert sorted(jx + 1 for _, jx in r.pairing.out_of_order) == [3, 4, 5, 9, 10]
        assert r.pairing.unpaired_analysis == [10, 11] and r.pairing.unpaired_test == []
        # Table 10's frequency errors follow from the pairing
        np.testing.assert_allclose(r.freq_error_pct[2], (37.05 - 36.79) / 36.79 * 100)
        np.testing.assert_allclose(r.freq_error_pct[8], (74.43 - 60.66) / 60.66 * 100)
        assert r.pairing.mac.min() > 0.8
        assert "out of order" in r.table()

    def test_frequency_order_would_be_wrong(self):
        # pairing by order (the naive choice) would pair test 3 with FE 3: its MAC is ~0
        an, te = table10_modes()
        r = correlate(an, te)
        assert r.mac[2, 2] < 0.1


class TestMissingModes:
    def test_missing_test_mode_is_reported(self):
        an, te = table10_modes()
        te = te.select_modes([0, 1, 2, 3, 5, 6, 7, 8, 9])            # test mode 5 (FE 4) not measured
        r = correlate(an, te)
        assert (3, 4) not in r.pairs and 3 in r.pairing.unpaired_analysis
        assert r.pairing.unpaired_test == []
        assert "FE" in r.table() and "4 (34.67 Hz)" in r.table()

    def test_spurious_test_mode_is_unpaired(self):
        an, te = table10_modes()
        rng = np.random.default_rng(9)
        Q = an.shapes
        v = rng.normal(size=Q.shape[0])
        v -= Q @ (Q.T @ v)                                           # orthogonal to every FE mode
        shapes = np.column_stack([te.shapes, v])
        te2 = ModeSet(freq_hz=list(te.freq_hz) + [80.0], shapes=shapes, dofs=te.dofs)
        r = correlate(an, te2)
        assert r.pairing.unpaired_test == [10]
        assert len(r.pairs) == 10
        d = r.to_dict()
        assert d["unpaired_test_modes"] == [11]
        assert "unpaired" in r.table()


class TestPairModes:
    def test_hungarian_beats_greedy(self):
        # greedy (largest MAC first) takes (0,0)=0.9 then is left with (1,1)=0.0;
        # the optimal assignment takes (0,1)+(1,0) = 0.85 + 0.8
        M = np.array([[0.9, 0.85], [0.8, 0.0]])
        p = pair_modes(M, mac_min=0.5)
        assert p.pairs == [(1, 0), (0, 1)]
        assert p.out_of_order == [(1, 0), (0, 1)]

    def test_threshold(self):
        M = np.array([[0.95, 0.1], [0.1, 0.45]])
        p = pair_modes(M, mac_min=0.5)
        assert p.pairs == [(0, 0)] and p.unpaired_test == [1] and p.unpaired_analysis == [1]
        np.testing.assert_allclose(p.mac, [0.95])

    def test_frequency_weight_breaks_ties(self):
        # two analysis modes with the same MAC to one test mode (repeated/aliased): choose the closer frequency
        M = np.array([[0.9], [0.9]])
        assert pair_modes(M, [10.0, 20.0], [19.0], freq_weight=1.0).pairs == [(1, 0)]
        assert pair_modes(M, [10.0, 20.0], [11.0], freq_weight=1.0).pairs == [(0, 0)]

    def test_max_freq_error(self):
        M = np.array([[0.99]])
        assert pair_modes(M, [10.0], [15.0], max_freq_error=0.2).pairs == []
        assert pair_modes(M, [10.0], [11.0], max_freq_error=0.2).pairs == [(0, 0)]

    def test_more_test_than_analysis_modes(self):
        M = np.array([[0.2, 0.9, 0.3]])
        p = pair_modes(M)
        assert p.pairs == [(0, 1)] and p.unpaired_test == [0, 2]

    def test_empty(self):
        p = pair_modes(np.zeros((0, 3)))
        assert p.pairs == [] and p.unpaired_test == [0, 1, 2]

    def test_errors(self):
        with pytest.raises(ModalabValueError, match="mac_min"):
            pair_modes(np.eye(2), mac_min=1.5)
        with pytest.raises(ModalabValueError, match="freq_a_hz"):
            pair_modes(np.eye(2), freq_weight=1.0)
        with pytest.raises(ShapeError):
            pair_modes(np.ones(3))
        with pytest.raises(ShapeError):
            pair_modes(np.eye(2), [1.0], [1.0, 2.0], freq_weight=1.0)
