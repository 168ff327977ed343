"""Response-function method (thesis 3.2.3): assembly against the printed equations, exactness, options."""
import numpy as np
import pytest
import scipy.sparse as sp

from modalab.core.errors import ModalabValueError, NotFittedError
from cases import six_dof_model
from updating.methods.mci import dynamic_expansion, measured_columns
from updating.fe.parametric import Derivative, MatrixModel
from updating.methods.rfm import ResponseFunctionMethod, receptance_rows, rfm_system


@pytest.fixture(scope="module")
def models():
    return six_dof_model("experimental", damping=True), six_dof_model("analytical", damping=True)


def test_identity_354(models):
    """H_A^j − H_X^j = H_A ΔZ H_X^j exactly (Eq. 3.54) for ΔZ = Z_X − Z_A."""
    X, A = models
    f = np.array([1.0, 5.5, 12.0])
    w = 2 * np.pi * f
    HA = receptance_rows(A, A.p0, w, np.arange(6))
    HX = receptance_rows(X, X.p0, w, np.arange(6))
    Kx, Mx, Cx, _ = X.matrices()
    Ka, Ma, Ca, _ = A.matrices()
    for k, wk in enumerate(w):
        dZ = (Kx - Ka) - wk ** 2 * (Mx - Ma) + 1j * wk * (Cx - Ca)
        np.testing.assert_allclose(HA[k][:, 0] - HX[k][:, 0], HA[k] @ (dZ @ HX[k][:, 0]), rtol=1e-9, atol=1e-15)


def test_assembly_matches_naive_loop(models):
    X, A = models
    f = np.linspace(1, 30, 7)
    frf = X.structure().frf(f, responses=["1+X", "3+X", "6+X"], references=["2+X", "5+X"], quantity="receptance")
    data = measured_columns(A, frf)
    full = dynamic_expansion(A, data, A.p0)
    R, b = rfm_system(A, full, data.omega, data.references, data.measured, A.p0)
    HA = receptance_rows(A, A.p0, data.omega, data.measured)
    ders = A.derivatives()
    naive = np.zeros_like(R)
    row = 0
    for j in range(2):
        for k, w in enumerate(data.omega):
            for r in range(3):
                for i, d in enumerate(ders):
                    dZ = sum(c * getattr(d, nm) for nm, c in (("dK", 1), ("dM", -w ** 2), ("dC", 1j * w))
                             if getattr(d, nm) is not None)
                    naive[row, i] = HA[k][r] @ (dZ @ full[:, j, k])
                row += 1
    np.testing.assert_allclose(R, naive, rtol=1e-10, atol=1e-14 * np.abs(naive).max())
    N, g = rfm_system(A, full, data.omega, data.references, data.measured, A.p0, normal=True, chunk=3)
    np.testing.assert_allclose(N, (R.conj().T @ R).real, rtol=1e-10, atol=1e-12 * np.abs(N).max())
    np.testing.assert_allclose(g, (R.conj().T @ b).real, rtol=1e-10, atol=1e-12 * np.abs(g).max())


def test_one_step_exact_with_complete_data(models):
    X, A = models
    frf = X.structure().frf(np.arange(0.5, 40, 0.5), references=["1+X"], quantity="accelerance")
    u = ResponseFunctionMethod(max_iter=1, weighting="none").fit(A, frf)
    np.testing.assert_allclose(u.p_, X.p0, rtol=1e-8)


def test_incomplete_data_with_expansion_converges(models):
    X, A = models
    frf = X.structure().frf(np.arange(0.2, 40, 0.2), responses=["1+X", "2+X", "4+X", "6+X"],
                            references=["1+X", "4+X"], quantity="accelerance")
    u = ResponseFunctionMethod(max_iter=60, tol=1e-10).fit(A, frf)
    np.testing.assert_allclose(u.p_[:16], X.p0[:16], rtol=1e-6)
    np.testing.assert_allclose(u.p_[16:], X.p0[16:], rtol=1e-4)


def test_bands_and_subset_of_parameters(models):
    X, A = models
    # only the stiffnesses are wrong: update k1..k10 from one band around the first modes
    B = MatrixModel(dofs=X.dofs, terms=list(zip(X.parameter_names, X.derivatives())),
                    p0=np.r_[A.p0[:10], X.p0[10:]])
    frf = X.structure().frf(np.arange(0.1, 60, 0.1), references=["3+X"], quantity="accelerance")
    u = ResponseFunctionMethod(params=[f"k{i}" for i in range(1, 11)], bands=[(2.0, 12.0)]).fit(B, frf)
    np.testing.assert_allclose(u.p_, X.p0, rtol=1e-7)
    assert list(u.params_) == list(range(10))


def test_errors():
    with pytest.raises(NotFittedError):
        ResponseFunctionMethod().predicted_frf(None, [1.0])
    X = six_dof_model()
    frf = X.structure().frf([1.0, 2.0], references=["1+X"])
    with pytest.raises(ModalabValueError, match="weighting"):
        ResponseFunctionMethod(weighting="bogus").fit(X, frf)
    with pytest.raises(ModalabValueError, match="no frequency lines"):
        ResponseFunctionMethod(bands=[(100, 200)]).fit(X, frf)


def test_receptance_rows_large_model_paths():
    """Above 400 DOFs: banded LU after RCM ordering (narrow band) agrees with a direct sparse solve."""
    import scipy.sparse.linalg as spla
    n = 600
    rng = np.random.default_rng(0)
    perm = rng.permutation(n)                      # scrambled numbering: RCM must find the band again
    main = np.full(n, 2.0)
    main[-1] = 1.0
    Kc = sp.diags([main, -np.ones(n - 1), -np.ones(n - 1)], [0, -1, 1], format="csr") * 1e4
    Kc = Kc[perm][:, perm]
    m = MatrixModel(dofs=[f"{j + 1}+Z" for j in range(n)],
                    terms=[("k", Derivative(dK=Kc)), ("m", Derivative(dM=sp.eye(n, format="csr"))),
                           ("c", Derivative(dC=Kc * 1e-4))], p0=[1.0, 1.0, 1.0])
    w = np.array([3.0, 40.0])
    H = receptance_rows(m, m.p0, w, [5, 300])
    K, M, C, _ = m.matrices()
    for k, wk in enumerate(w):
        e = np.zeros(n, complex)
        e[300] = 1
        x = spla.spsolve((K - wk ** 2 * M + 1j * wk * C).tocsc(), e)
        np.testing.assert_allclose(H[k, 1], x, rtol=1e-9, atol=1e-12 * np.abs(x).max())
