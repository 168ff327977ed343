"""Issue 15, "a typed window": an exponentially windowed FRF gives the same answer as the unwindowed one.

The windowed data are written here from the structure's matrices (not through the code under test):
the transfer function at ``s = iω + β`` (the transform of the impulse response times ``e^{−βt}``),
accelerance ``s²·X(s)``, labelled with ``FRF.window_beta_per_s = β``.  MCI and RFM (model FRFs and
expansions at ``s``), inverse eigensensitivity (on modes identified with the window correction) and
the diagnosis fit residual must give what they give on the unwindowed FRF.  β = 0.8 1/s adds 4 % of
critical damping to the first mode (3.2 Hz): ignoring it would move every answer by far more than the
tolerances below.
"""
import numpy as np
import pytest

from modalab.core.frf import FRF
from cases import six_dof_model
from updating.methods.eigensensitivity import InverseEigensensitivity
from updating.methods.mci import MCIUpdater, measured_columns, mci
from updating.methods.rfm import ResponseFunctionMethod

BETA = 0.8
F = np.arange(0.5, 30.0, 0.1)
RESP = ["1+X", "2+X", "3+X", "4+X", "5+X", "6+X"]
REFS = ["2+X", "5+X"]


def _frf(model, beta, quantity="accelerance", p=None):
    """FRF of ``model`` at s = iω + β from its matrices (dense solve per line)."""
    st = model.structure(p)
    K, M = st.K.toarray(), st.M.toarray()
    C = np.zeros_like(K) if st.C is None else st.C.toarray()
    dofs = [str(d) for d in st.dofs]
    io = [dofs.index(r) for r in RESP]
    ii = [dofs.index(r) for r in REFS]
    s = 2j * np.pi * F + beta
    q = {"receptance": 0, "mobility": 1, "accelerance": 2}[quantity]
    H = np.empty((len(io), len(ii), F.size), complex)
    E = np.eye(K.shape[0])[:, ii]
    for k, sk in enumerate(s):
        H[:, :, k] = np.linalg.solve(K + sk ** 2 * M + sk * C, E)[io] * sk ** q
    return FRF(freq_hz=F, H=H, responses=RESP, references=REFS, quantity=quantity, window_beta_per_s=beta)


@pytest.fixture(scope="module")
def models():
    return six_dof_model("experimental", damping=True), six_dof_model("analytical", damping=True)


@pytest.fixture(scope="module")
def frfs(models):
    X, _ = models
    return _frf(X, 0.0), _frf(X, BETA)


def test_the_windowed_data_differ(frfs):
    plain, win = frfs
    assert np.max(np.abs(win.H - plain.H)) > 0.05 * np.max(np.abs(plain.H))


def test_mci_is_zero_for_the_right_model_either_way(models, frfs):
    X, _ = models
    for frf in frfs:
        r = mci(X, frf)
        assert np.max(np.abs(r.values)) < 1e-8
    # read as unwindowed (β dropped), the windowed data leave a large miscorrelation
    wrong = mci(X, frfs[1]._replace(window_beta_per_s=0.0))
    assert np.max(np.abs(wrong.values)) > 1e-2
    assert measured_columns(X, frfs[1]).beta == BETA


def test_mci_updating_same_answer(models, frfs):
    X, A = models
    p = [MCIUpdater(tol=1e-10).fit(A, frf).p_ for frf in frfs]
    np.testing.assert_allclose(p[1], p[0], rtol=1e-6)
    np.testing.assert_allclose(p[0], X.p0, rtol=1e-5)


def test_rfm_updating_same_answer(models, frfs):
    X, A = models
    p = [ResponseFunctionMethod(weighting="none").fit(A, frf).p_ for frf in frfs]
    np.testing.assert_allclose(p[1], p[0], rtol=1e-6)
    np.testing.assert_allclose(p[0], X.p0, rtol=1e-5)


def test_eigensensitivity_on_identified_modes_same_answer(models, frfs):
    from identification import identify

    X, A = models
    sets = [identify(frf, band_hz=(1.0, 29.0), max_order=30)[0] for frf in frfs]
    for m in sets:
        assert m.n_modes == 6
    np.testing.assert_allclose(sets[1].freq_hz, sets[0].freq_hz, rtol=3e-5)
    # the window adds β/ω_n = 0.004..0.04 to the damping ratios; corrected, what is left is the identification's
    # own model error on windowed data (its basis uses (iω)^q, the data s^q): ~2e-5 on the close pair 7.9/8.3 Hz
    assert np.all(BETA / (2 * np.pi * sets[0].freq_hz) > 5e-3)
    np.testing.assert_allclose(sets[1].damping, sets[0].damping, rtol=0, atol=5e-5)
    # the six masses from the six frequencies (springs and dampers held); shapes left out: an ill-conditioned
    # shape residual would amplify the 1e-4 differences of two identifications, which is not the point here
    p = [InverseEigensensitivity(params=list(range(10, 16)), use_shapes=False, regularisation=None).fit(A, m).p_
         for m in sets]
    assert np.max(np.abs(p[0][10:16] / A.p0[10:16] - 1)) > 0.05        # the masses did move
    np.testing.assert_allclose(p[1], p[0], rtol=2e-4)


def test_diagnosis_fit_residual_same_answer(models, frfs):
    from updating.diagnosis.fit import frf_data, model_frf

    X, A = models
    for model, tiny in ((X, True), (A, False)):
        res = []
        for frf in frfs:
            data = frf_data(frf, band_hz=(1.0, 29.0))
            Hm = model_frf(model.structure(), data)
            res.append(np.linalg.norm(Hm - data.H) / np.linalg.norm(data.H))
        if tiny:
            assert max(res) < 1e-8                      # the exact model fits the windowed data exactly
        else:
            assert res[0] > 0.1 and abs(res[1] / res[0] - 1) < 0.5   # the same misfit, not an artefact of β
