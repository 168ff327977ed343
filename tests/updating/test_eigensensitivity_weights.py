"""Inverse eigensensitivity with frequency weights spread over orders of magnitude (issue 14).

The modes of a 3-DOF chain come from plain numpy (``scipy.linalg.eigh`` on matrices written out here), not from
the code under test.  Identification gives relative frequency sigma of 1e-10..1e-7: the weighted system is then
ill-conditioned, and the L-curve damping of the step grew every iteration until the step fell below the tolerance
— the updater stopped at k x1.023/1.023/1.004 (truth 0.9/1.2/1.0) with frequency errors of +1.4 %/-2.7 %,
"converged", ± 1e-6.  An exact model must come back to the truth whatever sigma the modes carry.
"""
import numpy as np
import pytest
from scipy.linalg import eigh

from modalab.core.modes import ModeSet
from updating.fe.parametric import Derivative, MatrixModel
from updating.methods.eigensensitivity import InverseEigensensitivity

MASS = np.array([1.0, 1.5, 0.8])
K_NOM = np.array([4e4, 3e4, 2e4])            # ground-1, 1-2, 2-3
TRUTH = np.array([0.9, 1.2, 1.0])            # factors on K_NOM
SIGMA = np.array([1.4e-10, 8.8e-8, 1.17e-7])  # relative frequency sigma, as identify reported them


def _unit(a, b):
    K = np.zeros((3, 3))
    K[b, b] += 1
    if a is not None:
        K[a, a] += 1
        K[a, b] = K[b, a] = -1
    return K


UNITS = [_unit(None, 0), _unit(0, 1), _unit(1, 2)]


def _model():
    terms = [(f"k{j}", Derivative(dK=UNITS[j])) for j in range(3)]
    terms += [(f"m{j}", Derivative(dM=np.diag(np.eye(3)[j]))) for j in range(3)]
    return MatrixModel(dofs=["1+Z", "2+Z", "3+Z"], terms=terms, p0=np.r_[K_NOM, MASS])


def _measured():
    K = sum(k * U for k, U in zip(K_NOM * TRUTH, UNITS))
    lam, phi = eigh(K, np.diag(MASS))
    return ModeSet(freq_hz=np.sqrt(lam) / (2 * np.pi), shapes=phi * 2.0, dofs=["1+Z", "2+Z", "3+Z"])


@pytest.mark.parametrize("reg", ["lcurve", "gcv"])
def test_exact_chain_comes_back_to_the_truth_with_spread_sigma(reg):
    u = InverseEigensensitivity(params=["k0", "k1", "k2"], freq_sigma=SIGMA, regularisation=reg,
                                bounds=(0.5 * K_NOM, 2 * K_NOM)).fit(_model(), _measured())
    assert u.converged_
    np.testing.assert_allclose(u.p_[:3] / K_NOM, TRUTH, rtol=1e-6)
    np.testing.assert_allclose(u.freq_a_hz_, _measured().freq_hz, rtol=1e-8)
    # the printed ± covers the truth
    assert np.all(np.abs(u.p_[:3] - K_NOM * TRUTH) <= 3 * u.std_ + 1e-9 * K_NOM)


def test_not_converged_when_stopped_short():
    u = InverseEigensensitivity(params=["k0", "k1", "k2"], freq_sigma=SIGMA, max_iter=1).fit(_model(), _measured())
    assert not u.converged_
