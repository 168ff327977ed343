"""Issue 15: the exponential window's pole correction lives in one place (:func:`acquisition.windows.correct_poles`)
and identification calls it, for the modes and for their standard deviations."""
import importlib

import numpy as np

import acquisition.windows
from identification import PolyMAX, modal_system, noisy_frf
from identification.stabilisation import pole_freq_damping

BETA = 2.0
# the modules, not the functions the package exports under the same names
lsfd_mod = importlib.import_module("identification.lsfd")
unc_mod = importlib.import_module("identification.lsfd_uncertainty")


def _windowed():
    mm, _ = modal_system([40.0, 90.0], [0.01, 0.015], 6, rng=4, window_beta=BETA)
    f = noisy_frf(mm, np.linspace(5.0, 150.0, 800), [mm.dofs[0], mm.dofs[3]], noise=0.002, rng=5)
    return f._replace(window_beta_per_s=BETA)


def test_identification_corrects_poles_with_the_acquisition_function(monkeypatch):
    assert lsfd_mod.correct_poles is acquisition.windows.correct_poles
    assert unc_mod.correct_poles is acquisition.windows.correct_poles
    calls = []

    def spy(poles, beta):
        calls.append(float(beta))
        return acquisition.windows.correct_poles(poles, beta)

    monkeypatch.setattr(lsfd_mod, "correct_poles", spy)
    monkeypatch.setattr(unc_mod, "correct_poles", spy)
    pm = PolyMAX(max_order=20).fit(_windowed())
    assert calls and set(calls) == {BETA}
    # the modes are the measured LSFD poles moved by beta, nothing else
    fn, z = pole_freq_damping(acquisition.windows.correct_poles(pm.lsfd_.lam, BETA))
    np.testing.assert_array_equal(pm.modes_.freq_hz, fn)
    np.testing.assert_array_equal(pm.modes_.damping, z)
    np.testing.assert_allclose(pm.modes_.freq_hz, [40.0, 90.0], rtol=1e-3)
    np.testing.assert_allclose(pm.modes_.damping, [0.01, 0.015], rtol=0.05)


def test_without_the_correction_the_window_damping_stays(monkeypatch):
    monkeypatch.setattr(lsfd_mod, "correct_poles", lambda poles, beta: np.asarray(poles, complex))
    pm = PolyMAX(max_order=20).fit(_windowed())
    # beta / omega_n added: 0.8 % at 40 Hz, 0.35 % at 90 Hz
    np.testing.assert_allclose(pm.modes_.damping, np.array([0.01, 0.015]) + BETA / (2 * np.pi * np.array([40, 90])),
                               rtol=0.05)
