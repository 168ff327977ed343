"""Reciprocity: roving-hammer sets re-ordered with the sensors as references, and the both-ways check."""
import numpy as np
import pytest

from acquisition.reciprocity import ReciprocityReport, reorder_by_reciprocity, reciprocity_check
from modalab.core.dof import Dof
from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF
from modalab.core.structure import Structure


def random_structure(n, seed=0, zeta_scale=2e-3):
    """Symmetric positive-definite M, K and proportional C on DOFs 1+Z..n+Z (a free-form test body)."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    K = A @ A.T + n * np.eye(n)
    K *= 1e5 / np.abs(K).max()
    M = np.diag(rng.uniform(0.5, 2.0, n))
    return Structure(M=M, K=K, C=zeta_scale * K / 100.0 + 0.5 * M, dofs=[f"{i + 1}+Z" for i in range(n)])


FREQ = np.linspace(1.0, 200.0, 300)


@pytest.fixture(scope="module")
def body():
    return random_structure(6, seed=1)


def roving_set(s, sensors, hits, coherence=True):
    frf = s.frf(FREQ, responses=sensors, references=hits)
    if coherence:
        frf.coherence = np.random.default_rng(2).uniform(0.5, 1.0, frf.shape)
    return frf


def test_sensors_become_references(body):
    sensors = ["2+Z", "5+Z"]
    hits = ["1+Z", "2+Z", "3-Z", "4+Z", "5+Z", "6-Z"]        # two points hit in -Z
    meas = roving_set(body, sensors, hits)
    rec = reorder_by_reciprocity(meas)
    assert rec.shape == (6, 2, FREQ.size)
    assert [str(d) for d in rec.responses] == hits and [str(d) for d in rec.references] == sensors
    np.testing.assert_allclose(rec.H, body.frf(FREQ, responses=hits, references=sensors).H, rtol=1e-9, atol=0)
    np.testing.assert_array_equal(rec.coherence, meas.coherence.transpose(1, 0, 2))
    assert rec.metadata["reciprocity"] is True
    assert rec.metadata["measured_references"] == hits
    # an opposite-sign label negates: the value at 3-Z equals minus the one at 3+Z
    np.testing.assert_allclose(rec.get("3+Z", "2+Z"), -rec.get("3-Z", "2+Z"))


def test_positive_directions_restate_signs(body):
    meas = roving_set(body, ["2+Z", "5-Z"], ["1+Z", "3-Z", "6-Z"])
    rec = reorder_by_reciprocity(meas, positive=True)
    assert all(d.direction > 0 for d in rec.responses + rec.references)
    np.testing.assert_allclose(rec.H, body.frf(FREQ, responses=["1+Z", "3+Z", "6+Z"], references=["2+Z", "5+Z"]).H,
                               rtol=1e-9)


def test_reference_subset_with_sign(body):
    meas = roving_set(body, ["2+Z", "5+Z"], ["1+Z", "3+Z"])
    rec = reorder_by_reciprocity(meas, references=["5-Z"])
    assert [str(d) for d in rec.references] == ["5-Z"]
    np.testing.assert_allclose(rec.H[:, 0], -meas.H[1])


def test_thesis_layout_36_points_12_sensors():
    # section 5.3: 12 accelerometers, 36 impact points, re-ordered to 36 responses x 12 references
    s = random_structure(36, seed=3)
    sensors = [f"{k}+Z" for k in (1, 3, 6, 10, 14, 18, 21, 23, 27, 31, 33, 35)]
    hits = [f"{k}+Z" for k in range(1, 37)]
    freq = np.linspace(5.0, 100.0, 40)
    meas = s.frf(freq, responses=sensors, references=hits)
    assert meas.shape[:2] == (12, 36)
    rec = reorder_by_reciprocity(meas)
    assert rec.shape[:2] == (36, 12)
    np.testing.assert_allclose(rec.H, s.frf(freq, responses=hits, references=sensors).H, rtol=1e-8)
    rep = reciprocity_check(meas)
    assert len(rep) == 12 * 11 // 2                       # every sensor pair is also hit both ways
    assert rep.max_rel_diff < 1e-8


class TestReciprocityCheck:
    def test_exact_symmetric_structure_has_no_difference(self, body):
        rep = reciprocity_check(body.frf(FREQ))
        assert isinstance(rep, ReciprocityReport) and len(rep) == 15
        assert rep.max_rel_diff < 1e-10
        assert all(p.n_lines == FREQ.size for p in rep)

    def test_worst_pair_first_and_sizes(self, body):
        frf = body.frf(FREQ, responses=["1+Z", "2+Z", "3+Z"], references=["1+Z", "2+Z", "3+Z"])
        frf.H[0, 2] *= 1.10                   # H(1,3) measured 10 % high
        frf.H[1, 0] *= np.exp(0.02j)          # H(2,1) with a small phase error
        rep = reciprocity_check(frf)
        assert [(str(p.dof_a), str(p.dof_b)) for p in rep] == [("1+Z", "3+Z"), ("1+Z", "2+Z"), ("2+Z", "3+Z")]
        # |1.1 - 1| / 1.05 on every line
        assert rep.worst.rel_diff == pytest.approx(0.1 / 1.05, rel=1e-9)
        assert rep.worst.norm_rel_diff == pytest.approx(0.1 / 1.05, rel=1e-9)
        assert rep.pairs[1].rel_diff == pytest.approx(abs(np.exp(0.02j) - 1), rel=1e-9)
        assert rep.pairs[2].rel_diff < 1e-10
        d = rep.to_dict()
        assert d["pairs"][0]["dof_a"] == "1+Z" and "1+Z <-> 3+Z" in rep.summary()

    def test_sign_mismatch_is_caught_and_labels_fix_it(self, body):
        frf = body.frf(FREQ, responses=["1+Z", "2+Z"], references=["1+Z", "2+Z"])
        frf.H[0, 1] *= -1                      # H(1,2) with an unrecorded sign flip
        assert reciprocity_check(frf).worst.rel_diff == pytest.approx(2.0)
        frf.references = [Dof.parse("1+Z"), Dof.parse("2-Z")]       # ... because the hammer hit 2 in -Z
        frf.H[1, 1] *= -1
        assert reciprocity_check(frf).max_rel_diff < 1e-10

    def test_band_and_coherence_masks(self, body):
        frf = body.frf(FREQ, responses=["1+Z", "2+Z"], references=["1+Z", "2+Z"])
        frf.coherence = np.ones(frf.shape)
        hi = FREQ > 100
        frf.H[0, 1, hi] *= 2.0
        frf.coherence[0, 1, hi] = 0.5
        assert reciprocity_check(frf).worst.rel_diff > 0.3
        assert reciprocity_check(frf, band_hz=(None, 100.0)).max_rel_diff < 1e-10
        rep = reciprocity_check(frf, min_coherence=0.9)
        assert rep.max_rel_diff < 1e-10 and rep.worst.n_lines == int((~hi).sum())

    def test_no_pairs_and_errors(self, body):
        rep = reciprocity_check(body.frf(FREQ, responses=["1+Z"], references=["2+Z"]))
        assert len(rep) == 0 and rep.worst is None and "cannot be checked" in rep.summary()
        with pytest.raises(ModalabValueError, match="coherence"):
            reciprocity_check(body.frf(FREQ, responses=["1+Z"], references=["1+Z"]), min_coherence=0.9)
        with pytest.raises(ModalabValueError, match="band_hz"):
            reciprocity_check(body.frf(FREQ), band_hz=(500.0, 600.0))
        with pytest.raises(ModalabValueError, match="FRF"):
            reciprocity_check(np.zeros((2, 2, 3)))
        with pytest.raises(ModalabValueError, match="FRF"):
            reorder_by_reciprocity(np.zeros((2, 2, 3)))
