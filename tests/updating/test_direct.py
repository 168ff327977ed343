"""Direct methods (thesis 3.1) with incomplete modal data: the constraints each method enforces hold."""
import numpy as np
import pytest
import scipy.linalg as sla

from modalab.core.errors import ModalabValueError, ShapeError
from cases import six_dof_pair
from updating.methods.direct import (baruch_orthogonalise, direct_matrix_updating, error_matrix, lagrange_mass,
                             lagrange_mass_stiffness, lagrange_stiffness, matrix_mixing)


@pytest.fixture(scope="module")
def sys6():
    X, A = six_dof_pair()
    Kx, Mx, _, _ = X.matrices()
    Ka, Ma, _, _ = A.matrices()
    Kx, Mx, Ka, Ma = (a.toarray() for a in (Kx, Mx, Ka, Ma))
    wx, px = sla.eigh(Kx, Mx)
    wa, pa = sla.eigh(Ka, Ma)
    return dict(Kx=Kx, Mx=Mx, Ka=Ka, Ma=Ma, wx=np.sqrt(wx), px=px, wa=np.sqrt(wa), pa=pa)


M3 = slice(0, 3)   # three measured modes only


def test_baruch_stiffness_orthogonality_with_three_modes(sys6):
    s = sys6
    u = lagrange_stiffness(s["Ka"], s["Ma"], s["px"][:, M3], s["wx"][M3])
    phi = baruch_orthogonalise(s["px"][:, M3], s["Ma"])
    np.testing.assert_allclose(u.K, u.K.T, atol=1e-9)                                     # (3.2)
    np.testing.assert_allclose(phi.T @ u.K @ phi, np.diag(s["wx"][M3] ** 2), atol=1e-8)   # (3.3)
    np.testing.assert_allclose(phi.T @ s["Ma"] @ phi, np.eye(3), atol=1e-12)


def test_berman_mass_orthogonality_with_three_modes(sys6):
    s = sys6
    u = lagrange_mass(s["Ma"], s["px"][:, M3])
    np.testing.assert_allclose(u.M, u.M.T, atol=1e-12)                                    # (3.7)
    np.testing.assert_allclose(s["px"][:, M3].T @ u.M @ s["px"][:, M3], np.eye(3), atol=1e-10)  # (3.8)
    assert np.all(np.isnan(u.K))        # no stiffness given


@pytest.mark.parametrize("fn", [lagrange_mass_stiffness, direct_matrix_updating])
def test_updated_model_reproduces_measured_modes(sys6, fn):
    s = sys6
    u = fn(s["Ka"], s["Ma"], s["px"][:, M3], s["wx"][M3])
    phi = s["px"][:, M3]
    # eigen-equation (3.12) for the measured modes
    np.testing.assert_allclose(u.K @ phi, u.M @ phi @ np.diag(s["wx"][M3] ** 2), atol=1e-7 * np.abs(u.K).max())
    np.testing.assert_allclose(phi.T @ u.M @ phi, np.eye(3), atol=1e-10)


def test_matrix_mixing_three_modes_reproduces_flexibility(sys6):
    s = sys6
    u = matrix_mixing(s["Ka"], s["Ma"], s["pa"][:, M3], s["wa"][M3], s["px"][:, M3], s["wx"][M3])
    # the measured modes' flexibility replaces the analytical one (3.30)
    F = np.linalg.inv(u.K)
    Fa = np.linalg.inv(s["Ka"])
    expect = Fa + s["px"][:, M3] @ np.diag(s["wx"][M3] ** -2) @ s["px"][:, M3].T \
        - s["pa"][:, M3] @ np.diag(s["wa"][M3] ** -2) @ s["pa"][:, M3].T
    np.testing.assert_allclose(F, expect, rtol=1e-9, atol=1e-12)


def test_error_matrix_zero_for_identical_models(sys6):
    s = sys6
    u = error_matrix(s["Ka"], s["Ma"], s["pa"], s["wa"], s["pa"], s["wa"])
    assert np.abs(u.dK).max() < 1e-9 * np.abs(s["Ka"]).max()
    assert np.abs(u.dM).max() < 1e-12


def test_no_correction_when_model_is_right(sys6):
    s = sys6
    for u in (lagrange_stiffness(s["Kx"], s["Mx"], s["px"], s["wx"]),
              direct_matrix_updating(s["Kx"], s["Mx"], s["px"], s["wx"])):
        assert np.abs(u.dK).max() < 1e-9 * np.abs(s["Kx"]).max()


def test_errors_name_the_problem(sys6):
    s = sys6
    with pytest.raises(ShapeError, match="expand"):
        lagrange_stiffness(s["Ka"], s["Ma"], s["px"][:4], s["wx"])
    with pytest.raises(ShapeError, match="one per mode"):
        lagrange_stiffness(s["Ka"], s["Ma"], s["px"], s["wx"][:3])
    with pytest.raises(ModalabValueError, match="complex"):
        lagrange_mass(s["Ma"], s["px"] * 1j)
    with pytest.raises(ModalabValueError, match="rigid"):
        error_matrix(s["Ka"], s["Ma"], s["pa"], s["wa"] * 0, s["px"], s["wx"])
    with pytest.raises(ShapeError, match="same number"):
        matrix_mixing(s["Ka"], s["Ma"], s["pa"][:, :2], s["wa"][:2], s["px"][:, M3], s["wx"][M3])
