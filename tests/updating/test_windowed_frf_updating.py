"""FRF updating on exponentially windowed FRFs (issue 14 #2): an exact model stays exact for MCI and RFM with
and without the window.  The windowed data are the model's receptance at s = β + iω (a response windowed by
e^{-βt} has the transform H(s + β)), written here from the matrices directly, not by the code under test."""
import numpy as np
import pytest

from modalab.core.frf import FRF
from cases import six_dof_model
from updating.methods.mci import MCIUpdater, measured_columns
from updating.methods.rfm import ResponseFunctionMethod

F = np.arange(0.5, 25.0, 0.25)
BETA = 1.5


def windowed(model, beta, quantity="accelerance", responses=("1+X", "2+X", "3+X", "4+X", "5+X", "6+X"),
             references=("2+X",)):
    K, M, C, D = model.matrices()
    K, M = np.asarray(K.toarray() if hasattr(K, "toarray") else K), np.asarray(M.toarray() if hasattr(M, "toarray")
                                                                              else M)
    C = 0 * K if C is None else np.asarray(C.toarray() if hasattr(C, "toarray") else C)
    D = np.asarray(D.toarray() if hasattr(D, "toarray") else D)
    labels = [str(d) for d in model.dofs]
    io = [labels.index(r) for r in responses]
    ii = [labels.index(r) for r in references]
    H = np.zeros((len(io), len(ii), F.size), complex)
    for k, f in enumerate(F):
        s = beta + 2j * np.pi * f
        X = np.linalg.solve(K + 1j * D + s * C + s * s * M, np.eye(K.shape[0])[:, ii])
        # accelerance of the windowed response: (s)^2 X(s) evaluated at s = beta + i omega
        H[:, :, k] = X[io] * (s ** 2 if quantity == "accelerance" else 1.0)
    return FRF(freq_hz=F, H=H, responses=list(responses), references=list(references), quantity=quantity,
               window_beta_per_s=beta)


@pytest.fixture(scope="module")
def X():
    """The thesis' six-DOF case with 2 % structural damping (constant D = 0.02 K at nominal)."""
    from updating.fe.parametric import MatrixModel

    m = six_dof_model("experimental")
    K = m.matrices()[0]
    return MatrixModel(dofs=m.dofs, terms=list(zip(m.parameter_names, m.derivatives())), p0=m.p0, D0=0.02 * K)


def test_window_is_read_and_used(X):
    data = measured_columns(X, windowed(X, BETA))
    assert data.beta == BETA and np.allclose(data.w, data.omega - 1j * BETA)


@pytest.mark.parametrize("beta", [0.0, BETA])
@pytest.mark.parametrize("cls", [MCIUpdater, ResponseFunctionMethod])
def test_exact_model_stays_exact(X, cls, beta):
    up = cls(max_iter=10).fit(X, windowed(X, beta))
    np.testing.assert_allclose(up.p_, X.p0, rtol=1e-6)


def test_ignoring_the_window_would_move_the_exact_model(X):
    frf = windowed(X, BETA)
    frf.window_beta_per_s = 0.0                  # what a tool that drops the window would see
    up = MCIUpdater(max_iter=10).fit(X, frf)
    assert np.max(np.abs(up.p_ / np.where(X.p0 != 0, X.p0, 1) - 1)) > 0.01
