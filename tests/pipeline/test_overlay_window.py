"""The FRF overlays compare like with like: data measured with an exponential window e^{-βt} are the transfer
function at s = iω + β, so the model curves drawn over them are evaluated there (issue 14)."""
import numpy as np
import pytest

from modalab.core.frf import FRF
from updating.fe.models.garteur import garteur_model


@pytest.fixture(scope="module")
def model():
    m = garteur_model(2, suspension=True)
    m.global_ge = 0.02
    return m


def _dense(model, dof_index, f, beta):
    st = model.structure()
    dense = lambda A: np.asarray(A.todense() if hasattr(A, "todense") else A)  # noqa: E731
    K = dense(st.K).astype(complex) + (0 if st.D is None else 1j * dense(st.D))
    M, C = dense(st.M), (None if st.C is None else dense(st.C))
    out = []
    for fk in f:
        s = 2j * np.pi * fk + beta
        Z = K + s * s * M + (0 if C is None else s * C)
        e = np.zeros(len(st.dofs))
        e[dof_index] = 1.0
        out.append(s * s * np.linalg.solve(Z, e)[dof_index])
    return str(st.dofs[dof_index]), np.array(out)


@pytest.mark.parametrize("beta", [0.0, 1.5, 6.0])
def test_model_frf_at_s_equals_a_dense_solve(model, beta):
    f = np.array([2.5, 9.0, 31.0, 77.0])
    dof, exact = _dense(model, 5, f, beta)
    H = model.frf(f, [dof], [dof], beta=beta)
    assert H.window_beta_per_s == beta
    np.testing.assert_allclose(H.H[0, 0], exact, rtol=1e-7)


def test_overlay_curves_carry_the_measurements_window(model, tmp_path, monkeypatch):
    """The overlay of the diagnose stage evaluates every model at the measured FRF's β: the model drawn over
    'measured' data made from the same model at s = iω + β coincides with them; at β = 0 it does not."""
    from modalab.app.stages import _diagnose

    dof = str(model.structure().dofs[5])
    f = np.linspace(1.0, 60.0, 300)
    beta = 4.0
    meas = model.frf(f, [dof], [dof], beta=beta)
    H = FRF(freq_hz=f, H=meas.H, responses=[dof], references=[dof], window_beta_per_s=beta)

    class _Diag:
        parameters = {}
        model = None

    d = _Diag()
    d.model = model
    seen = {}
    monkeypatch.setattr(_diagnose, "plot_frf_overlays",
                        lambda curves, path, **kw: seen.update(curves=curves, kw=kw) or path)
    path = _diagnose._frf_overlays(H, model, d, tmp_path, None, None)
    assert path.name == _diagnose.OVERLAY_NAME == "frf_overlay_models.png"
    assert seen["kw"]["beta"] == beta
    m, n = seen["curves"]["measured"], seen["curves"]["nominal"]
    np.testing.assert_allclose(n.H[0, 0], m.get(dof, dof), rtol=1e-9)
    unwindowed = model.frf(n.freq_hz, [dof], [dof]).H[0, 0]
    assert np.max(np.abs(unwindowed) / np.abs(n.H[0, 0])) > 1.5       # the old overlay's peak mismatch
