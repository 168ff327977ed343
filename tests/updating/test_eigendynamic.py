"""Eigendynamic constraint method (thesis 3.2.1)."""
import numpy as np
import pytest

from modalab.core.errors import ModalabValueError
from modalab.core.modes import ModeSet
from cases import six_dof_pair
from updating.methods.eigendynamic import EigendynamicConstraint, eigendynamic_system, kidder_expand
from updating.fe.sensitivity import solve_modes


@pytest.fixture(scope="module")
def pair():
    X, A = six_dof_pair()
    return X, A, solve_modes(X)


def test_complete_modes_exact_in_one_step(pair):
    X, A, sx = pair
    tm = ModeSet(freq_hz=sx.freq_hz, shapes=sx.phi, dofs=X.dofs, scaling="unit_modal_mass")
    u = EigendynamicConstraint().fit(A, tm)
    np.testing.assert_allclose(u.p_, X.p0, rtol=1e-10)
    np.testing.assert_allclose(u.history_[1], X.p0, rtol=1e-10)   # the first step is already exact


def test_four_modes_enough_for_16_parameters(pair):
    X, A, sx = pair
    tm = ModeSet(freq_hz=sx.freq_hz[:4], shapes=sx.phi[:, :4], dofs=X.dofs, scaling="unit_modal_mass")
    u = EigendynamicConstraint().fit(A, tm)
    np.testing.assert_allclose(u.p_, X.p0, rtol=1e-10)


def test_system_residual_vanishes_at_truth(pair):
    X, A, sx = pair
    Amat, d = eigendynamic_system(X, sx.phi, sx.omega)
    assert Amat.shape == (6 * 7, 16)
    assert np.abs(d).max() < 1e-10


def test_sign_convention_moves_towards_truth(pair):
    """With the thesis' printed right-hand side the correction would point away from the truth."""
    X, A, sx = pair
    Amat, d = eigendynamic_system(A, sx.phi, sx.omega)
    dp = np.linalg.lstsq(Amat, d, rcond=None)[0]
    np.testing.assert_allclose(A.p0 + dp, X.p0, rtol=1e-10)


def test_kidder_expansion_exact_for_consistent_model(pair):
    X, A, sx = pair
    K, M, _, _ = X.matrices()
    meas = [1, 2, 3]
    full = kidder_expand(K, M, sx.omega, sx.phi[meas], meas)
    np.testing.assert_allclose(full, sx.phi, atol=1e-10)


def test_without_mass_normalisation_eq_337_is_dropped(pair):
    X, A, sx = pair
    tm = ModeSet(freq_hz=sx.freq_hz, shapes=sx.phi * 2.5, dofs=X.dofs, scaling="arbitrary")
    # all parameters free: K and M can only be found up to a common factor, so fix the masses
    u = EigendynamicConstraint(params=[f"k{i}" for i in range(1, 11)]).fit(
        A.__class__(dofs=X.dofs, terms=list(zip(X.parameter_names, X.derivatives())),
                    p0=np.r_[A.p0[:10], X.p0[10:]]), tm)
    np.testing.assert_allclose(u.p_[:10], X.p0[:10], rtol=1e-9)


def test_rejects_non_modeset(pair):
    X, A, sx = pair
    with pytest.raises(ModalabValueError, match="ModeSet"):
        EigendynamicConstraint().fit(A, sx.phi)
