"""Issue 15, a typed window: a model FRF compared with exponentially windowed data is evaluated at
``s = iω + β`` (``FRF.s``).  ``Structure.frf(..., window_beta_per_s=β)`` (modal and direct) equals the direct
solve ``(K + iD + sC + s²M)⁻¹`` at that s; a windowed simulated FRF correlated with the model through
:func:`updating.correlation.frf_criteria.frf_correlation` (which passes the test's β) scores as the unwindowed
one does."""
import numpy as np
import pytest

from modalab.core.errors import ModalabValueError
from modalab.core.structure import Structure

DOFS = ["1+X", "2+X", "3+X"]


def _chain(D=False):
    k, m = 4.0e4, np.array([1.0, 1.5, 0.8])
    K = k * np.array([[2.0, -1, 0], [-1, 2, -1], [0, -1, 1]])
    M = np.diag(m)
    C = 1e-4 * K + 0.5 * M
    return Structure(M=M, K=K, C=C, D=0.01 * K if D else None, dofs=DOFS)


@pytest.mark.parametrize("hysteretic", [False, True])
@pytest.mark.parametrize("method", ["modal", "direct"])
def test_model_frf_at_s_is_the_direct_solve_there(method, hysteretic):
    st = _chain(hysteretic)
    f, beta = np.linspace(1.0, 80.0, 60), 3.0
    H = st.frf(f, quantity="receptance", method=method, window_beta_per_s=beta)
    assert H.window_beta_per_s == beta
    np.testing.assert_allclose(H.s, 2j * np.pi * f + beta)
    K, M, C = st.K.toarray(), st.M.toarray(), st.C.toarray()
    if hysteretic:
        K = K + 1j * st.D.toarray()
    ref = np.stack([np.linalg.inv(K + s * C + s * s * M) for s in H.s], axis=-1)
    np.testing.assert_allclose(H.H, ref, rtol=1e-8, atol=1e-12 * np.abs(ref).max())
    acc = st.frf(f, method=method, window_beta_per_s=beta)
    np.testing.assert_allclose(acc.H, ref * H.s ** 2, rtol=1e-8, atol=1e-12 * np.abs(ref * H.s ** 2).max())
    assert not np.allclose(st.frf(f, quantity="receptance", method=method).H, ref, rtol=1e-3)


def test_beta_must_be_a_finite_decay():
    for bad in (-1.0, np.inf, "2"):
        with pytest.raises(ModalabValueError, match="window_beta_per_s"):
            _chain().frf([10.0], window_beta_per_s=bad)


def _simulated(st, beta, fs=1024.0, T=16.0):
    """Receptance FRF of the hammer test by the FFT of the sampled impulse response, windowed by e^{−βt}."""
    from modalab.core.frf import FRF

    t = np.arange(int(fs * T)) / fs
    h = st.modal_model().impulse_response(t, DOFS, ["1+X"]) * np.exp(-beta * t)
    Hf = np.fft.rfft(h, axis=-1) / fs
    f = np.fft.rfftfreq(t.size, 1 / fs)
    sel = (f >= 2.0) & (f <= 60.0)
    return FRF(freq_hz=f[sel], H=Hf[..., sel], responses=DOFS, references=["1+X"], quantity="receptance",
               window_beta_per_s=beta)


def test_windowed_and_unwindowed_data_correlate_alike_with_the_model():
    from updating.correlation.frf_criteria import frf_correlation

    st = _chain()
    plain, windowed = _simulated(st, 0.0), _simulated(st, 4.0)
    err_plain = 1 - frf_correlation(st, plain).frac
    err_win = 1 - frf_correlation(st, windowed).frac
    assert err_plain.max() < 1e-4 and err_win.max() < 1e-4
    np.testing.assert_allclose(err_win, err_plain, atol=1e-4)
    # the model at s = iω (β ignored, as before) misses the windowed data
    at_iw = st.frf(windowed.freq_hz, quantity="receptance", references=["1+X"])
    from updating.correlation.frf_criteria import frac

    assert (1 - frac(at_iw, windowed)).max() > 10 * max(err_win.max(), 1e-5)


def test_a_ready_model_frf_at_another_beta_is_warned_about(caplog):
    """A ready analysis FRF evaluated at another β than the test's is compared with a logged warning naming both
    β; one at the test's β, or a Structure (evaluated at the test's β), is compared silently."""
    import logging

    from updating.correlation.frf_criteria import frf_correlation

    st = _chain()
    f = np.linspace(2.0, 60.0, 80)
    test = st.frf(f, quantity="receptance", references=["1+X"], window_beta_per_s=4.0)
    logger = "updating.correlation.frf_criteria"
    for quiet in (st, st.frf(f, quantity="receptance", references=["1+X"], window_beta_per_s=4.0)):
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger=logger):
            frf_correlation(quiet, test)
        assert not [r for r in caplog.records if r.name == logger]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger=logger):
        frf_correlation(st.frf(f, quantity="receptance", references=["1+X"]), test)
    warned = [r.getMessage() for r in caplog.records if r.name == logger and r.levelno == logging.WARNING]
    assert len(warned) == 1 and "s = iω + 0 1/s" in warned[0] and "s = iω + 4 1/s" in warned[0], warned
