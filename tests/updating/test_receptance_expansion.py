"""The one receptance adapter and the one dynamic expansion that MCI, RFM and diagnosis share."""
import logging

import numpy as np
import pytest
import scipy.sparse as sp

import modalab.core.dense as dense
from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF
from cases import six_dof_model
from updating.correlation.condensation import condensed_residual
from updating.correlation.receptance import frf_data, measured_columns, receptance_data
from updating.diagnosis.screen import residual_system
from updating.methods.mci import dynamic_expansion, mci

F = np.arange(0.5, 25.0, 0.5)
BETA = 3.0


def _windowed(model, beta):
    """Accelerance of ``model`` at s = iω + β: what an exponential window of decay β records."""
    st = model.structure()
    frf = st.frf(F, references=["1+X"], quantity="receptance")
    s = 2j * np.pi * F + beta
    H = frf.H * s[None, None, :] ** 2
    # the exact receptance at s, from the matrices (not from the FRF code under test)
    K, M = st.K.toarray(), st.M.toarray()
    C = None if st.C is None else st.C.toarray()
    D = None if st.D is None else st.D.toarray()
    X = np.empty((K.shape[0], F.size), complex)
    for k, sk in enumerate(s):
        Z = K + sk ** 2 * M + (0 if C is None else sk * C) + (0 if D is None else 1j * D)
        X[:, k] = np.linalg.solve(Z, np.eye(K.shape[0])[:, 0])
    frf = frf._replace(H=(X * s ** 2)[:, None, :], quantity="accelerance", units="m/s^2/N")
    frf.window_beta_per_s = beta
    return frf, X, H


def test_adapter_reads_windowed_accelerance_at_s():
    """Receptance = accelerance / s² with s = iω + β, the same for the MCI/RFM and the diagnosis entry points."""
    X = six_dof_model("experimental")
    frf, Xs, _ = _windowed(X, BETA)
    cols = measured_columns(X, frf)
    np.testing.assert_allclose(cols.theta[:, 0, :], Xs, rtol=1e-10)
    assert cols.beta == BETA
    np.testing.assert_allclose(cols.s, 2j * np.pi * F + BETA)
    diag = frf_data(frf, max_lines=1000, min_coherence=0.0).on_model(X.dofs)
    np.testing.assert_allclose(diag.theta, cols.theta, rtol=1e-14)
    np.testing.assert_array_equal(diag.measured, cols.measured)


def test_mci_of_measured_rows_is_minus_the_condensed_residual():
    """MCI (Eq. 3.69 from the full Z θ) on the measured rows = −(condensed residual) diagnosis screens."""
    X = six_dof_model("experimental")
    A = six_dof_model("analytical")
    frf = X.structure().frf(F, references=["2+X"], quantity="receptance").select(responses=["1+X", "2+X", "4+X"])
    r_mci = mci(A, frf)
    data = receptance_data(frf)
    rs = residual_system(A.structure(), data, weights=np.ones((1, F.size)))
    nm, nq, ns = rs.shape
    r_diag = (rs.y[: rs.y.size // 2] + 1j * rs.y[rs.y.size // 2:]).reshape(nm, nq, ns)
    meas = r_mci.measured
    np.testing.assert_allclose(r_mci.values[meas], -r_diag, rtol=1e-8, atol=1e-12 * np.abs(r_diag).max())
    assert np.abs(r_diag).max() > 1e-6                    # the models differ: the test compares non-zero values


def test_expansion_sparse_path_equals_dense():
    """The one expansion gives the same MCI columns through the per-line sparse LU as through dense solves."""
    X = six_dof_model("experimental")
    A = six_dof_model("analytical")
    frf = X.structure().frf(F, references=["1+X"]).select(responses=["1+X", "3+X", "6+X"])
    data = measured_columns(A, frf)
    old = dense.SOLVE_LIMIT
    try:
        dense.SOLVE_LIMIT = 1000
        a = dynamic_expansion(A, data)
        dense.SOLVE_LIMIT = 1
        b = dynamic_expansion(A, data)
    finally:
        dense.SOLVE_LIMIT = old
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12 * np.abs(a).max())


def test_singular_line_is_solved_by_least_squares_and_named(caplog):
    """A line exactly at a resonance of the model held at its measured DOFs: min-norm solution, logged."""
    k, m = 2.0, 1.0                                       # ω0 = 2 rad/s: Z_ss is exactly 0 there
    K = sp.csr_matrix(np.array([[2 * k, -k, 0], [-k, 2 * k, -k], [0, -k, k]]))
    M = sp.csr_matrix(np.eye(3) * m)
    meas = np.array([0, 2])
    w0 = np.sqrt(2 * k / m)                               # Z_ss = 2k − ω²m = 0 for the middle DOF
    s = 1j * np.array([0.5 * w0, w0, 1.5 * w0])
    x = np.ones((2, 1, 3), complex) * 1e-3
    Fv = np.zeros((3, 1))
    Fv[0, 0] = 1.0
    with caplog.at_level(logging.WARNING, logger="updating.correlation.condensation"):
        x_full, r, T, sigma = condensed_residual(K, M, None, None, s, meas, x, Fv)
    assert np.all(np.isfinite(x_full)) and np.all(np.isfinite(r))
    assert x_full[1, 0, 1] == 0                           # least squares of 0·x = b: the minimum-norm answer
    assert f"{w0 / (2 * np.pi):.6g}" in caplog.text


def test_dense_rule_names_its_operations():
    assert dense.use_dense(80, "solve") and not dense.use_dense(81, "solve")
    assert dense.use_dense(2000, "eigen") and not dense.use_dense(2001, "eigen")
    assert dense.use_dense(400, "projected") and not dense.use_dense(401, "projected")
    with pytest.raises(ModalabValueError, match="expected one of"):
        dense.use_dense(10, "eigne")


def test_screen_selects_the_missing_ground_spring_at_an_unmeasured_dof():
    """The condensed-residual screen names a spring to ground the model left out, seen through the expansion."""
    from modalab.core.frf import FRF
    from updating.diagnosis.library import Candidate
    from updating.diagnosis.screen import screen

    X = six_dof_model("experimental")
    st = X.structure()
    K, M = st.K.toarray(), st.M.toarray()
    k_extra = 0.01 * np.abs(np.diag(K)).mean()          # small: the screen is first order in the error
    Kt = K.copy()
    Kt[3, 3] += k_extra                                   # the test article: a spring to ground at 4+X
    H = np.stack([np.linalg.solve(Kt - (2 * np.pi * f) ** 2 * M, np.eye(6)[:, 0]) for f in F], axis=-1)
    meas = [0, 1, 2, 4, 5]                               # 4+X is not measured
    frf = FRF.from_arrays(F, H[meas], [st.dofs[i] for i in meas], ["1+X"], quantity="receptance")
    cands = []
    for i, d in enumerate(st.dofs):
        E = sp.csr_matrix(([1.0], ([i], [i])), shape=(6, 6))
        cands.append(Candidate("ground_spring", str(d), (d.node,), (str(d),), (), "k", "N/m", "K", True, G=E))
        cands.append(Candidate("added_mass", str(d), (d.node,), (str(d),), (), "m", "kg", "M", True, G=E))
    res = screen(st, [], cands, receptance_data(frf))
    best, theta, gain = res.selected[0]
    assert (best.physics, best.label) == ("ground_spring", "4+X")
    assert theta == pytest.approx(k_extra, rel=0.2)
    assert res.rss_final < 0.2 * res.rss_background


def test_rfm_receptance_rows_banded_equals_the_shared_solver():
    """RFM's H_A rows: the shared dense solver and the banded LU (models above the solve limit) agree."""
    from updating.methods.rfm import receptance_rows

    A = six_dof_model("analytical", damping=True, damping_values=np.full(10, 0.5))
    w = 2 * np.pi * F - 1j * BETA                          # a windowed line set: s = iω + β
    rows = [0, 2, 5]
    old = dense.SOLVE_LIMIT
    try:
        dense.SOLVE_LIMIT = 1000
        a = receptance_rows(A, A.p0, w, rows)
        dense.SOLVE_LIMIT = 1
        b = receptance_rows(A, A.p0, w, rows)
    finally:
        dense.SOLVE_LIMIT = old
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12 * np.abs(a).max())
    st = A.structure()
    Z = st.K.toarray() + (1j * w[3]) ** 2 * st.M.toarray() + 1j * w[3] * st.C.toarray()
    np.testing.assert_allclose(a[3], np.linalg.inv(Z)[rows], rtol=1e-9)


def test_diagnosis_and_mci_updater_linearise_the_same_mci():
    """The Jacobian diagnosis' mci_update steps with (−Tᵀ ∂Z/∂p x per parameter) is −(T A), the condensed
    Jacobian of MCIUpdater (Eq. 3.77 through the expansion): the two step proposals linearise one MCI."""
    from updating.methods.mci import condensation_operator, mci_system
    from updating.methods.mci_condensed import derivatives

    X = six_dof_model("experimental")
    A = six_dof_model("analytical")
    frf = X.structure().frf(F, references=["2+X"], quantity="receptance").select(responses=["1+X", "2+X", "4+X"])
    data = receptance_data(frf)
    rs = residual_system(A.structure(), data, weights=np.ones((1, F.size)))
    B = rs.derivative_columns(derivatives(A, A.p0))                     # (2·nm·nq·ns, P), rows (m, q, f)
    nm, nq, ns = rs.shape
    B = (B[: B.shape[0] // 2] + 1j * B[B.shape[0] // 2:]).reshape(nm, nq, ns, -1)
    cols = measured_columns(A, frf)
    full = dynamic_expansion(A, cols)
    Am, _ = mci_system(A, full, cols.w, cols.references, A.p0)
    J = (condensation_operator(A, cols, A.p0) @ Am).toarray().reshape(nq, ns, nm, -1)   # rows (q, f, m)
    J = np.transpose(J, (2, 0, 1, 3))
    np.testing.assert_allclose(B, -J, rtol=1e-8, atol=1e-10 * np.abs(J).max())
    assert np.abs(J).max() > 0


def test_structurally_zero_pairs_do_not_veto_every_line():
    """A planar frame measured with in-plane accelerometers and one out-of-plane hit (discovery case 875): the
    in-plane responses to the out-of-plane force are noise, coherence about 0.2 at every line, and they were
    most of the pairs, so the mean over all pairs stayed below 0.5 at every line and ``frf_data`` refused the
    data.  Lines are judged by the pairs whose median coherence reaches the limit; the dead pairs stay in the
    data with their coherence (weighted down by it); lines bad in the live pairs are still dropped."""
    f = np.linspace(1.0, 100.0, 200)
    rng = np.random.default_rng(0)
    H = (rng.standard_normal((4, 2, f.size)) + 1j * rng.standard_normal((4, 2, f.size))) * 1e-3
    coh = np.full(H.shape, 0.2)
    coh[0, 0] = 0.99                      # the out-of-plane response to the out-of-plane hit
    coh[1, 1] = 0.99                      # one in-plane response to the in-plane hit; six pairs dead
    coh[:, :, 50:60] = 0.3                # ten lines bad everywhere
    frf = FRF(freq_hz=f, H=H, responses=["1+Z", "2+X", "3+X", "4+Y"], references=["1+Z", "5+Y"],
              coherence=coh, quantity="receptance")
    d = frf_data(frf, max_lines=1000)
    assert d.H.shape == (4, 2, f.size - 10)
    assert not np.isin(f[50:60], d.freq_hz).any()
    assert np.allclose(d.coherence[1:, 0], 0.2)          # the dead pairs kept, with their coherence
    dead = FRF(freq_hz=f, H=H, responses=frf.responses, references=frf.references,
               coherence=np.full(H.shape, 0.2), quantity="receptance")
    with pytest.raises(ModalabValueError, match="too poor to diagnose"):
        frf_data(dead)


def test_a_column_no_sensor_sees_has_a_finite_weight():
    """An out-of-plane hit on a planar frame measured with in-plane sensors only: its column of FRFs is zero
    throughout (an independent truth writes exact zeros, a lab would record noise).  Its relative-error
    denominator took the column's own RMS, 0, and was 1e-300: the model's rounding there (1e-20 m/N) weighed
    1e280 and overflowed the first FRF fit of held-out case 2289 (set AA).  The column takes the RMS over all
    pairs instead: such rounding is no error, while the other columns keep their own denominators."""
    from updating.diagnosis.fit import frf_error
    f = np.linspace(1.0, 100.0, 200)
    rng = np.random.default_rng(1)
    H = (rng.standard_normal((3, 2, f.size)) + 1j * rng.standard_normal((3, 2, f.size))) * 1e-5
    H[:, 1] = 0.0                                     # responses 2+X, 3+X, 4+Y to the hit at 5+Z: none
    frf = FRF(freq_hz=f, H=H, responses=["2+X", "3+X", "4+Y"], references=["2+X", "5+Z"],
              coherence=np.where(H != 0, 0.99, 0.0), quantity="receptance")
    d = frf_data(frf, max_lines=1000)
    col0 = d.den[:, 0]
    assert np.all(np.isfinite(d.den)) and d.den[:, 1].min() > 1e-4 * 0.1 * np.sqrt(np.mean(np.abs(H[:, 0]) ** 2))
    np.testing.assert_allclose(d.den[:, 1], np.broadcast_to(d.den[0, 1], (3, d.s.size)), rtol=1e-12)  # per line
    rounding = d.H.copy()
    rounding[:, 1] += 1e-20
    assert frf_error(rounding, d) < 1e-9
    assert frf_error(d.H, d) == 0.0
    again = frf_data(FRF(freq_hz=f, H=H[:, :1], responses=frf.responses, references=["2+X"],
                         coherence=np.full((3, 1, f.size), 0.99), quantity="receptance"), max_lines=1000)
    np.testing.assert_array_equal(again.den[:, 0], col0)                       # the live column: its own
