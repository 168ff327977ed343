"""Inverse eigensensitivity updating (thesis 3.2.2) on a lumped model with out-of-order modes."""
import numpy as np
import pytest

from modalab.core.errors import ModalabValueError, NotFittedError
from modalab.core.modes import ModeSet
from updating.methods.eigensensitivity import (InverseEigensensitivity, choose_alpha, identifiability,
                                       sensitivity_ranking, sensitivity_system)
from updating.fe.parametric import Derivative, MatrixModel
from updating.fe.sensitivity import solve_modes

N = 6
CONN = [(None, 0), (0, 1), (1, 2), (2, 3), (0, 4), (2, 5)]   # chain 1-2-3-4, light oscillators 5 (on 1), 6 (on 3)
P_TRUE = np.r_[2e4, 1.5e4, 1.2e4, 1e4, 400, 300, 2, 1.5, 1.5, 1.0, 0.05, 0.05]
P_INIT = np.r_[2.3e4, 1.4e4, 1.2e4, 0.9e4, 270, 420, 2.2, 1.5, 1.5, 1.0, 0.05, 0.05]
UPD = ["k1", "k2", "k3", "k4", "k5", "k6", "m1", "m2"]


def _spring(a, b):
    K = np.zeros((N, N))
    for i in (a, b):
        if i is not None:
            K[i, i] += 1
    if a is not None and b is not None:
        K[a, b] -= 1
        K[b, a] -= 1
    return K


def model(p, extra_terms=()):
    terms = [(f"k{j + 1}", Derivative(dK=_spring(a, b))) for j, (a, b) in enumerate(CONN)]
    terms += [(f"m{j + 1}", Derivative(dM=np.diag(np.eye(N)[j]))) for j in range(N)]
    terms += list(extra_terms)
    return MatrixModel(dofs=[f"{j + 1}+Z" for j in range(N)], terms=terms, p0=p)


def test_modes(meas=(0, 2, 3, 4, 5), scale=3.0, noise=0.0, seed=0, sign=None):
    sx = solve_modes(model(P_TRUE))
    rng = np.random.default_rng(seed)
    f = sx.freq_hz * (1 + noise * rng.normal(size=N) * 0.2)
    shp = sx.phi[list(meas)] * scale
    shp = shp * (1 + noise * rng.normal(size=shp.shape))
    dofs = [f"{j + 1}+Z" for j in meas]
    if sign is not None:
        dofs[sign] = dofs[sign].replace("+", "-")
        shp[sign] *= -1
    return ModeSet(freq_hz=f, shapes=shp, dofs=dofs)


test_modes.__test__ = False


@pytest.mark.parametrize("reg", [None, "lcurve", "gcv", 1e-3])
def test_recovers_known_errors_with_out_of_order_modes(reg):
    tm = test_modes()
    u = InverseEigensensitivity(params=UPD, regularisation=reg).fit(model(P_INIT), tm)
    assert u.converged_
    np.testing.assert_allclose(u.p_, P_TRUE, rtol=1e-7)
    # modes 2 and 3 are swapped between the initial model and the test ...
    assert (2, 1) in u.initial_pairs_ and (1, 2) in u.initial_pairs_
    # ... and in order after updating
    assert all(a == x for a, x in u.pairs_)
    np.testing.assert_allclose(u.freq_a_hz_, tm.freq_hz, rtol=1e-9)


def test_plain_order_pairing_would_fail():
    """Without MAC re-pairing the swapped modes would be matched by index: the MAC of those pairs is low."""
    sa = solve_modes(model(P_INIT))
    tm = test_modes()
    from updating.correlation.metrics import mac
    Mm = mac(sa.phi[[0, 2, 3, 4, 5]], tm.shapes)
    assert Mm[1, 1] < 0.1 and Mm[2, 2] < 0.1


def test_eigenvalue_residual_and_frequency_only():
    tm = test_modes()
    u = InverseEigensensitivity(params=UPD, residual="eigenvalue").fit(model(P_INIT), tm)
    np.testing.assert_allclose(u.p_, P_TRUE, rtol=1e-7)
    # six frequencies identify six stiffnesses when the masses are right
    p0 = P_INIT.copy()
    p0[6:] = P_TRUE[6:]
    v = InverseEigensensitivity(params=UPD[:6], weights={"use_shapes": False}).fit(model(p0), tm)
    np.testing.assert_allclose(v.p_, P_TRUE, rtol=1e-6)


def test_noisy_data_and_covariance():
    """1 % shape noise and 0.2 % frequency noise; errors stay within a few posterior standard deviations."""
    errs = []
    for seed in range(3):
        tm = test_modes(noise=0.01, seed=seed)
        u = InverseEigensensitivity(params=UPD, freq_sigma=0.002, shape_sigma=0.01).fit(model(P_INIT), tm)
        z = (u.p_[:8] - P_TRUE[:8]) / u.std_
        errs.append(np.abs(z).max())
        assert np.abs(u.p_[:8] / P_TRUE[:8] - 1).max() < 0.05
    assert max(errs) < 5


def test_sign_flipped_test_dof():
    tm = test_modes(sign=1)      # '3-Z' measured: negated shape entries
    u = InverseEigensensitivity(params=UPD).fit(model(P_INIT), tm)
    np.testing.assert_allclose(u.p_, P_TRUE, rtol=1e-7)


def test_bounds_are_respected():
    lo = np.full(len(UPD), -np.inf)
    hi = np.full(len(UPD), np.inf)
    hi[5] = 380.0     # k6 true value 300, start 420: allowed
    lo[4] = 300.0     # k5 true value 400: allowed
    hi[0] = 2.1e4     # k1 true 2e4
    u = InverseEigensensitivity(params=UPD, bounds=(lo, hi)).fit(model(P_INIT), test_modes())
    np.testing.assert_allclose(u.p_, P_TRUE, rtol=1e-6)
    tight = InverseEigensensitivity(params=UPD, bounds=(None, np.r_[2.5e4, 1.45e4, 2e4, 2e4, 1e4, 1e4, 1e4, 1e4]))
    w = tight.fit(model(P_INIT), test_modes())
    assert w.p_[1] <= 1.45e4 + 1e-9


def test_history_records_convergence():
    u = InverseEigensensitivity(params=UPD).fit(model(P_INIT), test_modes())
    H = u.parameter_history()
    assert H.shape == (u.n_iter_, 12)
    costs = [h["cost"] for h in u.history_]
    assert all(b <= a * (1 + 1e-9) for a, b in zip(costs, costs[1:]))
    assert np.abs(u.history_[-1]["freq_error_pct"]).max() < 1e-6


def test_ranking_and_identifiability():
    tm = test_modes()
    dead = model(np.r_[P_INIT, 1.0], extra_terms=[("dead", Derivative(dK=np.zeros((N, N))))])
    rank = sensitivity_ranking(dead, tm, params=UPD + ["dead"])
    norms = [r[1] for r in rank]
    assert norms == sorted(norms, reverse=True)
    assert rank[-1] == ("dead", 0.0)
    S = sensitivity_system(dead, tm, params=UPD + ["dead"]).S
    np.testing.assert_allclose(sorted(np.linalg.norm(S, axis=0), reverse=True), norms, rtol=1e-12)
    ok = identifiability(model(P_INIT), tm, params=UPD)
    assert ok["rank"] == 8 and np.isfinite(ok["condition"])
    # a duplicated parameter (same derivative matrix as k3) is not identifiable
    dup = model(np.r_[P_INIT, P_INIT[2]], extra_terms=[("k3bis", Derivative(dK=_spring(1, 2)))])
    bad = identifiability(dup, tm, params=UPD + ["k3bis"])
    assert bad["rank"] == 8
    assert {n for n, _ in bad["unidentifiable"][0]} == {"k3", "k3bis"}


def test_choose_alpha_on_ill_posed_problem():
    from scipy.linalg import hilbert
    rng = np.random.default_rng(1)
    S = hilbert(12)
    x = np.ones(12)
    b = S @ x + 1e-4 * rng.normal(size=12)
    xs = np.linalg.lstsq(S, b, rcond=None)[0]
    for method in ("lcurve", "gcv"):
        a = choose_alpha(S, b, method)
        s = np.linalg.svd(S, compute_uv=False)
        assert s[-1] < a < s[0]
        xr = np.linalg.solve(S.T @ S + a ** 2 * np.eye(12), S.T @ b)
        assert np.linalg.norm(xr - x) < 0.1 * np.linalg.norm(xs - x)


def test_sensitivity_system_rows_and_pairs():
    sysm = sensitivity_system(model(P_TRUE), test_modes(), params=UPD)
    assert sysm.S.shape == (6 * (1 + 5), 8)
    assert np.abs(sysm.r).max() < 1e-9
    assert sysm.rows[0] == "f1" and sysm.rows[1] == "s1:1+Z"


def test_errors():
    with pytest.raises(NotFittedError):
        InverseEigensensitivity().parameter_history()
    with pytest.raises(ModalabValueError, match="ModeSet"):
        InverseEigensensitivity().fit(model(P_INIT), np.ones((6, 6)))
    with pytest.raises(ModalabValueError, match="not in the model"):
        InverseEigensensitivity(params=["k99"]).fit(model(P_INIT), test_modes())
    with pytest.raises(ModalabValueError, match="weights keys"):
        InverseEigensensitivity(params=UPD, weights={"freq": 1}).fit(model(P_INIT), test_modes())
    with pytest.raises(ModalabValueError, match="regularisation"):
        InverseEigensensitivity(params=UPD, regularisation="magic").fit(model(P_INIT), test_modes())
