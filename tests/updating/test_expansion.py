"""Kidder, SEREP and analytical-mode expansion (thesis 2.1.2): exact when the test modes are model modes."""
import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from modalab.core.errors import DofError, ModalabValueError
from modalab.core.modes import ModeSet
from modalab.core.structure import Structure
from updating.correlation.dofmap import DofMap
from updating.correlation.expansion import kidder, modal_expand, serep_expand


def chain(n=12, seed=3):
    rng = np.random.default_rng(seed)
    k = rng.uniform(1.0, 2.0, n) * 1e4
    m = rng.uniform(1.0, 2.0, n)
    K = np.zeros((n, n))
    K[0, 0] = k[0]
    for i in range(1, n):
        K[np.ix_([i - 1, i], [i - 1, i])] += k[i] * np.array([[1, -1], [-1, 1]])
    return K, np.diag(m), [f"{i + 1}+Z" for i in range(n)]


@pytest.fixture(scope="module")
def model():
    K, M, dofs = chain()
    w2, phi = sla.eigh(K, M)
    an = ModeSet(freq_hz=np.sqrt(w2) / (2 * np.pi), shapes=phi, dofs=dofs, scaling="unit_modal_mass")
    return K, M, dofs, an


MEAS = ["2+Z", "5+Z", "8+Z", "12+Z"]


class TestKidder:
    def test_exact_for_model_modes(self, model):
        K, M, dofs, an = model
        test = an.select_modes([0, 2, 5]).select_dofs(MEAS)
        out = kidder(Structure(M=M, K=K, dofs=dofs), test)
        np.testing.assert_allclose(out.shapes, an.shapes[:, [0, 2, 5]], atol=1e-12)
        assert [str(d) for d in out.dofs] == dofs
        np.testing.assert_allclose(out.freq_hz, test.freq_hz)
        assert out.metadata["expansion"]["method"] == "kidder"

    def test_sparse_matrices_and_tuple_model(self, model):
        K, M, dofs, an = model
        test = an.select_modes([1, 3]).select_dofs(MEAS)
        out = kidder((sp.csr_matrix(K), sp.csr_matrix(M), dofs), test)
        np.testing.assert_allclose(out.shapes, an.shapes[:, [1, 3]], atol=1e-12)

    def test_sign_flipped_test_labels(self, model):
        K, M, dofs, an = model
        test = an.select_modes([0]).select_dofs(["2-Z", "5+Z", "8-Z", "12+Z"])   # negated rows
        out = kidder((K, M, dofs), test)
        np.testing.assert_allclose(out.shapes[:, 0], an.shapes[:, 0], atol=1e-12)

    def test_complex_shapes(self, model):
        K, M, dofs, an = model
        test = an.select_modes([2]).select_dofs(MEAS)
        test.shapes = test.shapes * np.exp(0.7j)
        out = kidder((K, M, dofs), test)
        np.testing.assert_allclose(out.shapes[:, 0], an.shapes[:, 2] * np.exp(0.7j), atol=1e-12)

    def test_static_is_inverse_guyan(self, model):
        from updating.correlation.reduction import guyan
        K, M, dofs, an = model
        test = an.select_modes([4]).select_dofs(MEAS)
        out = kidder((K, M, dofs), test, static=True)
        T = guyan(K, M, MEAS, dofs=dofs).T
        np.testing.assert_allclose(out.shapes[:, 0], T @ test.shapes[:, 0], atol=1e-12)

    def test_dynamic_beats_static_for_higher_mode(self, model):
        K, M, dofs, an = model
        test = an.select_modes([6]).select_dofs(MEAS)
        dyn = kidder((K, M, dofs), test).shapes[:, 0]
        sta = kidder((K, M, dofs), test, static=True).shapes[:, 0]
        ref = an.shapes[:, 6]
        assert np.linalg.norm(dyn - ref) < 1e-10 < np.linalg.norm(sta - ref)

    def test_oblique_sensor_rejected(self, model):
        K, M, dofs, an = model
        test = ModeSet(freq_hz=[1.0], shapes=np.ones((2, 1)), dofs=["2+Z", "5+Z"])
        dm = DofMap(dofs={"2+Z": {"2+Z": 0.5, "3+Z": 0.5}})
        with pytest.raises(ModalabValueError, match="oblique"):
            kidder((K, M, dofs), test, dofmap=dm)

    def test_unmapped_dof(self, model):
        K, M, dofs, an = model
        test = ModeSet(freq_hz=[1.0], shapes=np.ones((2, 1)), dofs=["2+Z", "77+Z"])
        with pytest.raises(DofError, match="77"):
            kidder((K, M, dofs), test)


class TestSerepExpansion:
    def test_exact_for_retained_model_modes(self, model):
        K, M, dofs, an = model
        test = an.select_modes([0, 1, 2]).select_dofs(MEAS)
        test.shapes = test.shapes * np.array([3.0, -0.5, 2.0])           # arbitrary test scaling
        out = serep_expand(an, test, modes=[0, 1, 2, 3])
        np.testing.assert_allclose(out.shapes, an.shapes[:, :3] * np.array([3.0, -0.5, 2.0]), atol=1e-12)

    def test_result_lies_in_span_of_used_modes(self, model):
        K, M, dofs, an = model
        rng = np.random.default_rng(0)
        test = an.select_modes([0]).select_dofs(MEAS)
        test.shapes = test.shapes + 1e-3 * rng.normal(size=test.shapes.shape)
        out = serep_expand(an, test, modes=[0, 1])
        # the result lies in the span of the two modes (eq. 2.60)
        coef = np.linalg.lstsq(an.shapes[:, :2], out.shapes[:, 0], rcond=None)[0]
        np.testing.assert_allclose(an.shapes[:, :2] @ coef, out.shapes[:, 0], atol=1e-13)

    def test_too_many_modes(self, model):
        K, M, dofs, an = model
        test = an.select_modes([0]).select_dofs(MEAS)
        with pytest.raises(ModalabValueError, match="rank deficient"):
            serep_expand(an, test)                                      # 12 modes on 4 DOFs

    def test_oblique_sensor(self, model):
        K, M, dofs, an = model
        # sensor 900+Z reads 0.6*(3+Z) + 0.8*(4+Z)
        dm = DofMap(dofs={"900+Z": {"3+Z": 0.6, "4+Z": 0.8}})
        phi = an.shapes[:, [0, 1]]
        meas = np.vstack([phi[[1, 4, 7]], 0.6 * phi[2] + 0.8 * phi[3]])
        test = ModeSet(freq_hz=an.freq_hz[:2], shapes=meas, dofs=["2+Z", "5+Z", "8+Z", "900+Z"])
        out = serep_expand(an, test, dofmap=dm, modes=[0, 1, 2])
        np.testing.assert_allclose(out.shapes, phi, atol=1e-12)


class TestModalExpansion:
    def test_exact_with_paired_modes(self, model):
        K, M, dofs, an = model
        test = an.select_modes([1, 4]).select_dofs(MEAS)
        out = modal_expand(an, test, modes=[1, 4])
        np.testing.assert_allclose(out.shapes, an.shapes[:, [1, 4]], atol=1e-12)

    def test_keep_measured_substitutes_measurement(self, model):
        K, M, dofs, an = model
        rng = np.random.default_rng(1)
        test = an.select_modes([0]).select_dofs(MEAS)
        test.shapes = test.shapes + 1e-3 * rng.normal(size=test.shapes.shape)
        hyb = modal_expand(an, test, modes=[0], keep_measured=True)
        smooth = modal_expand(an, test, modes=[0], keep_measured=False)
        idx = [1, 4, 7, 11]
        np.testing.assert_allclose(hyb.shapes[idx], test.shapes, atol=1e-15)
        # eqs. 2.53/2.50 with n > m: least-squares fit, ν = Φ11⁺ φ1
        nu = np.linalg.lstsq(an.shapes[idx][:, [0]], test.shapes, rcond=None)[0]
        np.testing.assert_allclose(smooth.shapes, an.shapes[:, [0]] @ nu, atol=1e-14)
        unmeasured = [i for i in range(12) if i not in idx]
        np.testing.assert_allclose(hyb.shapes[unmeasured], smooth.shapes[unmeasured], atol=1e-15)

    def test_equal_counts_fit_exactly(self, model):
        # n = m: the pseudo-inverse is the inverse and the expanded mode fits the data exactly (2.1.2.2)
        K, M, dofs, an = model
        test = ModeSet(freq_hz=[1.0], shapes=np.array([[1.0], [0.3], [-0.2], [0.5]]), dofs=MEAS)
        out = modal_expand(an, test, modes=[0, 1, 2, 3], keep_measured=False)
        np.testing.assert_allclose(out.shapes[[1, 4, 7, 11]], test.shapes, atol=1e-12)
