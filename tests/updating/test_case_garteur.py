"""Thesis section 5.3 (Tables 10 and 11): inverse eigensensitivity updating of a GARTEUR SM-AG19-like model.

Case (``updating.fe.models.garteur_cases``, choices documented there): nominal = ``garteur_model()`` with
torsion springs, fin 5 % too thick, wing torsion springs almost absent (25 N·m/rad), fin spring
1000 N·m/rad; pseudo-experimental truth = wing springs 100 N·m/rad, fin spring 1500 N·m/rad, fin
thickness × 0.95, plus wing E + 0.3 % and fuselage ρ − 0.3 % that are not updated.  Test data: the
first ten elastic modes of the truth at 28 accelerometer DOFs (Z along the wing, drums, fuselage and
tail plane; Y at the fuselage ends and on the fin; X at drum and tail-plane ends and the fin tip).
Updating parameters: the thesis' wing-tip torsion springs (one value for both), fin torsion spring
and fin thickness.

Achieved (asserted with these tolerances):

* Initially the modes are out of order with the Table 10 pattern for modes 3–5: test mode 3 pairs
  with nominal mode 5, test modes 4 and 5 with nominal modes 3 and 4 (MAC ≥ 0.7 at the test DOFs).
  The Table 10 swap of modes 9 and 10 is not reproduced by this model (see garteur_cases).
* Sensitivity ranking puts the fin thickness first; the three parameters are identifiable (rank 3).
* Frequency residuals only (as the thesis, whose SOL 200 iterations matched frequencies), MAC
  re-pairing every iteration, springs bounded ≥ 0: converges in ≤ 8 iterations; every test mode pairs
  with the analysis mode of the same number (MAC diagonal, ≥ 0.9); every frequency error is within the
  Table 11 error of that mode (achieved ≤ 0.17 %, e.g. 0.10 % against 0.95 % for mode 3 and < 0.01 %
  against 0.01 % for mode 10); parameters within 5 % of the truth (achieved 2.7 %, 1.5 %, 0.3 %; the
  residue comes from the nuisance errors).
* Frequencies and shapes (default weighting, tol 1e-5): parameters within 1 % (achieved 0.2 %, 0.3 %, 0.1 %),
  order restored, all frequency errors below the largest Table 11 error of the well-correlated modes
  (1.28 %; achieved ≤ 0.19 %).
* Bulk data path: the nominal written with ``write_bdf(to_bulk(model))`` and rebuilt with
  ``build_model(read_bdf(...))`` has the same frequencies (1e-9); updated there, the exported deck
  (``to_bulk(updated, template=...)``) re-imports with the updated frequencies (1e-7; achieved 9e-9,
  the rounding of the written fields).

BLAS threads are limited to one (set before numpy is first imported): on this shared two-core machine
a threaded dense eigensolution of the 426-DOF model is ~80× slower than a single-threaded one.
Runtime about 10 s.
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from updating.fe.bulk import build_model, read_bdf, to_bulk, write_bdf  # noqa: E402
from updating.correlation.metrics import mac, pair_modes  # noqa: E402
from updating.methods.eigensensitivity import InverseEigensensitivity, identifiability, sensitivity_ranking  # noqa: E402
from updating.fe.models.garteur import THESIS_REPLICA_HZ  # noqa: E402
from updating.fe.models.garteur_cases import (TRUE_VALUES, UPDATING_PARAMETERS, modal_test, nominal_model,  # noqa: E402
                                           truth_model, updating_model)

#: Table 11 absolute frequency errors (%) of the thesis' updated model, per mode
TABLE11_ERR_PCT = np.array([0.18, 7.3, 0.95, 0.08, 0.05, 1.28, 0.97, 0.44, 0.21, 0.01])
BOUNDS = ([0.0, 0.0, 0.5], [1e5, 1e5, 2.0])
P_TRUE = np.array([TRUE_VALUES[n] for n in UPDATING_PARAMETERS])
DIAG = [(6 + i, i) for i in range(10)]          # (analysis mode index incl. 6 rigid, test mode)


@pytest.fixture(scope="module")
def case():
    nom = nominal_model()
    test = modal_test(truth_model())
    return nom, test, updating_model(nom)


@pytest.fixture(scope="module")
def freq_fit(case):
    _, test, pm = case
    return InverseEigensensitivity(use_shapes=False, bounds=BOUNDS).fit(pm, test)


def err_pct(u, test):
    return 100 * np.abs(u.freq_a_hz_ - test.freq_hz) / test.freq_hz


class TestInitialCorrelation:
    def test_table10_pattern_modes_3_to_5(self, case):
        nom, test, _ = case
        a = nom.modes(16).select_modes(np.arange(6, 16)).select_dofs(test.dofs)
        M = mac(a.shapes, test.shapes)                            # (analysis, test)
        pairs = dict((int(x), int(ai)) for ai, x in pair_modes(M, mac_min=0.5).pairs)
        assert pairs[2] == 4                                     # test 3 <-> nominal 5
        assert {pairs[3], pairs[4]} == {2, 3}                    # test 4, 5 <-> nominal 3, 4
        for k in (0, 1, 5, 6, 7, 8, 9):
            assert pairs[k] == k
        assert min(M[pairs[k], k] for k in range(10)) >= 0.7
        # nominal 3-4 (wing torsion pair) below nominal 5, but above it in the test
        assert a.freq_hz[2] < a.freq_hz[4] and test.freq_hz[2] < test.freq_hz[3]

    def test_frequencies_resemble_the_replica(self, case):
        _, test, _ = case
        # first seven modes within 8 % of the thesis' measured replica (Table 10), same grouping
        np.testing.assert_allclose(test.freq_hz[:7], THESIS_REPLICA_HZ[:7], rtol=0.08)


class TestParameterSelection:
    def test_ranking_and_identifiability(self, case):
        _, test, pm = case
        rank = sensitivity_ranking(pm, test, use_shapes=False)
        assert rank[0][0] == "t_fin"
        idf = identifiability(pm, test, use_shapes=False)
        assert idf["rank"] == 3 and idf["condition"] < 1e3


class TestUpdating:
    def test_frequency_residuals_restore_order_and_meet_table11(self, case, freq_fit):
        _, test, _ = case
        u = freq_fit
        assert u.converged_ and u.n_iter_ <= 8
        assert u.initial_pairs_ != DIAG
        assert sorted(u.pairs_, key=lambda t: t[1]) == DIAG
        assert np.all(err_pct(u, test) <= TABLE11_ERR_PCT)
        np.testing.assert_allclose(u.p_, P_TRUE, rtol=0.05)
        assert np.all(u.std_ > 0)

    def test_updated_mac_is_diagonal(self, case, freq_fit):
        _, test, pm = case
        a = pm.model_at(freq_fit.p_).modes(16).select_modes(np.arange(6, 16)).select_dofs(test.dofs)
        M = mac(a.shapes, test.shapes)
        assert np.all(np.argmax(M, axis=0) == np.arange(10))
        assert np.diag(M).min() >= 0.9

    def test_frequencies_and_shapes(self, case):
        _, test, pm = case
        # tol 1e-5: at 1e-6 the last steps are at the round-off of the shape residuals of the close
        # wing-torsion pair (39.44/39.51 Hz), and whether a line search still finds a decrease there
        # depends on the BLAS threading; the parameters agree to 1e-6 either way
        u = InverseEigensensitivity(bounds=BOUNDS, tol=1e-5).fit(pm, test)
        assert u.converged_
        assert sorted(u.pairs_, key=lambda t: t[1]) == DIAG
        np.testing.assert_allclose(u.p_, P_TRUE, rtol=0.01)
        assert err_pct(u, test).max() <= 1.28


class TestBulkDataPath:
    def test_nominal_deck_update_export_reimport(self, case, tmp_path):
        nom, test, _ = case
        deck = tmp_path / "nominal.bdf"
        write_bdf(to_bulk(nom), deck)
        rebuilt = build_model(read_bdf(deck))
        np.testing.assert_allclose(rebuilt.modes(16).freq_hz[6:], nom.modes(16).freq_hz[6:], rtol=1e-9)
        pm = updating_model(rebuilt)
        assert pm.parameter_names == list(UPDATING_PARAMETERS)
        np.testing.assert_allclose(pm.p0, [25.0, 1000.0, 1.0])
        u = InverseEigensensitivity(use_shapes=False, bounds=BOUNDS).fit(pm, test)
        assert sorted(u.pairs_, key=lambda t: t[1]) == DIAG
        out = tmp_path / "updated.bdf"
        write_bdf(to_bulk(pm.model_at(u.p_), template=read_bdf(deck)), out)
        again = build_model(read_bdf(out))
        np.testing.assert_allclose(again.modes(16).freq_hz[6:], u.freq_a_hz_, rtol=1e-7)
        assert np.all(err_pct(u, test) <= TABLE11_ERR_PCT)
