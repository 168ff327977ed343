"""MisCorrelation Index (thesis 3.2.4): localisation, expansion, assembly, updater modes, figures."""
import numpy as np
import pytest

from modalab.core.errors import ModalabValueError, NotFittedError
from modalab.core.frf import FRF
from cases import six_dof_model, six_dof_pair
from updating.methods.mci import (MCIUpdater, condensation_operator, dynamic_expansion, lsq_expansion, mci, mci_system,
                          measured_columns, miscorrelation, plot_convergence, plot_mci_map, plot_mci_maxima)

F = np.arange(0.5, 25.0, 0.5)


@pytest.fixture(scope="module")
def X():
    return six_dof_model("experimental")


def with_params(model, p):
    from updating.fe.parametric import MatrixModel
    return MatrixModel(dofs=model.dofs, terms=list(zip(model.parameter_names, model.derivatives())), p0=p)


def test_zero_for_the_right_model(X):
    frf = X.structure().frf(F, references=["3+X"])
    r = mci(X, frf)
    assert r.max_per_dof().max() < 1e-9


@pytest.mark.parametrize("param,dofs", [("k3", {2, 3}), ("k9", {2, 5}), ("m5", {5}), ("k1", {1})])
def test_localises_the_error(X, param, dofs):
    """Eq. (3.68): MCI_r ≠ 0 exactly at the coordinates whose rows of Δ are non-zero."""
    frf = X.structure().frf(F, references=["1+X"])
    p = X.p0.copy()
    p[X.parameter_names.index(param)] *= 1.3
    r = mci(with_params(X, p), frf)
    mx = r.max_per_dof()
    hit = {i + 1 for i in np.flatnonzero(mx > 1e-6 * mx.max())}
    assert hit == dofs
    assert {d.node for d in r.ranked_dofs()[:len(dofs)]} == dofs


def test_mci_equals_delta_times_theta(X):
    """MCI_r = Σ_k Δ_rk θ_k (Eq. 3.68) with Δ = Z_X − Z_A (Eq. 3.64)."""
    A = six_dof_model("analytical")
    frf = X.structure().frf(F, references=["2+X"], quantity="receptance")
    r = mci(A, frf)
    Kx, Mx, _, _ = X.matrices()
    Ka, Ma, _, _ = A.matrices()
    theta = frf.H[:, 0, :]
    for k, f in enumerate(F):
        w = 2 * np.pi * f
        D = (Kx - Ka) - w ** 2 * (Mx - Ma)
        np.testing.assert_allclose(r.values[:, 0, k], D @ theta[:, k], rtol=1e-8, atol=1e-10)


def test_dynamic_expansion_recovers_unmeasured_frfs(X):
    full = X.structure().frf(F, references=["2+X"], quantity="receptance")
    part = full.select(responses=["2+X", "3+X", "4+X"])
    data = measured_columns(X, part)
    th = dynamic_expansion(X, data)
    np.testing.assert_allclose(th[:, 0, :], full.H[:, 0, :], rtol=1e-8, atol=1e-14)
    th2, *_ = lsq_expansion(X, data)
    np.testing.assert_allclose(th2, th, rtol=1e-8, atol=1e-14)


def test_expanded_rows_have_zero_mci():
    X, A = six_dof_pair()
    frf = X.structure().frf(F, responses=["2+X", "3+X", "4+X"], references=["2+X"])
    r = mci(A, frf)
    mx = r.max_per_dof()
    assert mx[[0, 4, 5]].max() < 1e-9 and mx[[1, 2, 3]].min() > 1e-2


def test_assembly_is_the_derivative_of_the_mci():
    X, A = six_dof_pair(damping=True)
    frf = X.structure().frf(F, references=["1+X", "4+X"])
    data = measured_columns(A, frf)
    full = dynamic_expansion(A, data)
    Amat, b = mci_system(A, full, data.omega, data.references, A.p0)
    for i in (0, 7, 12, 20):
        h = 1e-6 * max(abs(A.p0[i]), 1.0)
        pp = A.p0.copy()
        pp[i] += h
        m1 = miscorrelation(A, full, data.omega, data.references, pp)
        fd = -(np.transpose(m1, (1, 2, 0)).reshape(-1) - b) / h
        col = Amat[:, i].toarray().ravel()
        np.testing.assert_allclose(col, fd, rtol=1e-5, atol=1e-7 * np.abs(fd).max())
    # rows and params subsets pick the right entries
    A2, b2 = mci_system(A, full, data.omega, data.references, A.p0, rows=[1, 4], params=[3, 20])
    full_idx = (np.arange(2 * F.size)[:, None] * 6 + np.array([1, 4])[None, :]).ravel()
    np.testing.assert_allclose(A2.toarray(), Amat.toarray()[full_idx][:, [3, 20]])
    np.testing.assert_allclose(b2, b[full_idx])


def test_condensation_jacobian_matches_finite_differences():
    X, A = six_dof_pair()
    frf = X.structure().frf(F, responses=["2+X", "3+X", "4+X"], references=["2+X"])
    data = measured_columns(A, frf)

    def res(p):
        full = dynamic_expansion(A, data, p)
        v = miscorrelation(A, full, data.omega, data.references, p)
        return np.transpose(v[data.measured], (1, 2, 0)).reshape(-1), full

    r, full = res(A.p0)
    Am, b = mci_system(A, full, data.omega, data.references, A.p0)
    J = (condensation_operator(A, data, A.p0) @ Am).toarray()
    for i in (2, 11):
        h = 1e-6 * A.p0[i]
        pp = A.p0.copy()
        pp[i] += h
        fd = -(res(pp)[0] - r) / h
        np.testing.assert_allclose(J[:, i], fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())


@pytest.mark.parametrize("mode", ["projected", "condensed"])
def test_updater_modes_agree(mode):
    X, A = six_dof_pair()
    frf = X.structure().frf(np.arange(0.2, 30, 0.2), responses=["2+X", "3+X", "4+X"], references=["3+X"])
    u = MCIUpdater(jacobian=mode, tol=1e-10).fit(A, frf)
    np.testing.assert_allclose(u.p_, X.p0, rtol=1e-8)
    assert u.mode_ == mode


def test_damping_parameters_and_bands():
    X, A = six_dof_pair(damping=True)
    frf = X.structure().frf(np.arange(0.2, 40, 0.2), references=["1+X"])
    u = MCIUpdater(bands=[(1.0, 25.0)], tol=1e-10).fit(A, frf)
    np.testing.assert_allclose(u.p_[:16], X.p0[:16], rtol=1e-7)
    np.testing.assert_allclose(u.p_[16:], X.p0[16:], rtol=1e-5)


def test_bounds_and_penalty_hold_parameters():
    X, A = six_dof_pair()
    frf = X.structure().frf(np.arange(0.2, 30, 0.2), responses=["2+X", "3+X", "4+X"], references=["2+X"])
    lo, hi = 0.9 * A.p0, 1.1 * A.p0
    u = MCIUpdater(bounds=(lo, hi), max_iter=10).fit(A, frf)
    assert np.all(u.p_ >= lo - 1e-12) and np.all(u.p_ <= hi + 1e-12)
    stiff = MCIUpdater(penalty=1e3, max_iter=10).fit(A, frf)
    free = MCIUpdater(max_iter=10).fit(A, frf)
    assert np.abs(stiff.p_ / A.p0 - 1).max() < np.abs(free.p_ / A.p0 - 1).max()


def test_figures_and_history(tmp_path):
    X, A = six_dof_pair()
    frf = X.structure().frf(np.arange(0.2, 30, 0.2), responses=["2+X", "3+X", "4+X"], references=["2+X"])
    u = MCIUpdater(tol=1e-8).fit(A, frf)
    plot_mci_map(u.mci_initial_, tmp_path / "map.png")
    plot_mci_maxima([u.mci_initial_, u.mci_final_], tmp_path / "max.png", labels=["initial", "final"])
    u.plot_convergence(tmp_path / "conv.png", model=A, reference=X.p0)
    for name in ("map.png", "max.png", "conv.png"):
        assert (tmp_path / name).stat().st_size > 1000
    H = u.parameter_history()
    assert H.shape == (u.n_iter_ + 1, 16)
    np.testing.assert_array_equal(H[0], A.p0)


def test_errors():
    X, A = six_dof_pair()
    with pytest.raises(NotFittedError):
        MCIUpdater().parameter_history()
    frf = X.structure().frf([1.0, 2.0], references=["1+X"])
    with pytest.raises(ModalabValueError, match="jacobian"):
        MCIUpdater(jacobian="newton").fit(A, frf)
    with pytest.raises(ModalabValueError, match="no frequency lines"):
        MCIUpdater(bands=[(50, 60)]).fit(A, frf)
    with pytest.raises(ModalabValueError, match="FRF"):
        mci(A, np.ones((6, 1, 2)))
    bad = FRF(freq_hz=[1.0], H=np.ones((1, 1, 1)), responses=["9+X"], references=["1+X"])
    with pytest.raises(ModalabValueError, match="9"):
        mci(A, bad)
