"""Impact-testing windows and the exponential-window damping correction."""
import numpy as np
import pytest

from acquisition.windows import (ExponentialWindow, ForceWindow, beta_from_end_level, correct_damping, correct_poles,
                                 exponential_window, force_window, windowed_force)
from modalab.core.errors import ModalabValueError


class TestForceWindow:
    def test_flat_over_pulse_zero_after_with_cosine_taper(self):
        fs, ti = 1000.0, 10
        w = force_window(1000, fs, trigger_index=ti, length_s=0.05, taper_s=0.02)
        t = (np.arange(1000) - ti) / fs
        assert np.all(w[t <= 0.05 + 1e-12] == 1.0)           # whole pretrigger kept (lead_s=None) and 50 ms after
        assert np.all(w[t >= 0.07] == 0.0)
        k = np.flatnonzero(np.isclose(t, 0.06))[0]          # middle of the taper
        assert w[k] == pytest.approx(0.5)
        taper = w[(t > 0.05) & (t < 0.07)]
        assert np.all(np.diff(taper) < 0)

    def test_lead_zeroes_early_pretrigger_and_tapers_in(self):
        fs, ti = 1000.0, 100
        w = force_window(500, fs, trigger_index=ti, length_s=0.01, lead_s=0.02, taper_s=0.01)
        t = (np.arange(500) - ti) / fs
        assert np.all(w[(t >= -0.02) & (t <= 0.01)] == 1.0)
        assert np.all(w[t <= -0.03] == 0.0)
        assert w[np.flatnonzero(np.isclose(t, -0.025))[0]] == pytest.approx(0.5)

    def test_hard_rectangle_and_fraction(self):
        a = force_window(200, 100.0, trigger_index=20, fraction=0.25)
        b = force_window(200, 100.0, trigger_index=20, length_s=0.25 * 180 / 100.0)
        np.testing.assert_array_equal(a, b)
        assert set(np.unique(a)) == {0.0, 1.0}
        assert a[:20 + 45 + 1].all() and not a[20 + 46:].any()

    def test_taper_as_fraction_of_the_window(self):
        a = ForceWindow(fraction=0.05, taper=0.25).array(1000, 1000.0, 0)
        b = force_window(1000, 1000.0, fraction=0.05, taper_s=0.25 * 0.05)
        np.testing.assert_array_equal(a, b)
        with pytest.raises(ModalabValueError, match="taper width once"):
            ForceWindow(fraction=0.05, taper=0.25, taper_s=0.01)

    def test_spec_object_matches_function(self):
        spec = ForceWindow(length_s=0.01, taper_s=0.002, lead_s=0.001)
        np.testing.assert_array_equal(spec.array(300, 1000.0, 30),
                                      force_window(300, 1000.0, trigger_index=30, length_s=0.01, taper_s=0.002,
                                                   lead_s=0.001))
        assert spec.to_dict()["type"] == "force" and spec.to_dict()["length_s"] == 0.01

    @pytest.mark.parametrize("kw, match", [
        (dict(), "exactly one"),
        (dict(length_s=0.1, fraction=0.1), "exactly one"),
        (dict(fraction=1.5), r"\(0, 1\]"),
        (dict(length_s=-1.0), "positive"),
        (dict(length_s=0.1, taper_s=-0.1), "taper_s"),
        (dict(length_s=0.1, lead_s=-0.1), "lead_s"),
    ])
    def test_bad_parameters(self, kw, match):
        with pytest.raises(ModalabValueError, match=match):
            force_window(100, 100.0, **kw)

    def test_bad_record(self):
        with pytest.raises(ModalabValueError, match="trigger_index"):
            force_window(100, 100.0, trigger_index=100, length_s=0.1)
        with pytest.raises(ModalabValueError, match="sample_rate_hz"):
            force_window(100, -1.0, length_s=0.1)


class TestExponentialWindow:
    def test_starts_at_one_on_the_trigger_and_reaches_end_level(self):
        n, fs, ti = 2048, 512.0, 48
        w, beta = exponential_window(n, fs, trigger_index=ti, end_level=0.01)
        T = (n - 1 - ti) / fs
        assert beta == pytest.approx(-np.log(0.01) / T, rel=1e-14)
        assert w[ti] == 1.0                      # no amplitude normalisation
        assert w[-1] == pytest.approx(0.01, rel=1e-12)
        t = (np.arange(n) - ti) / fs
        np.testing.assert_allclose(w, np.exp(-beta * t), rtol=1e-14)
        assert w[0] == pytest.approx(np.exp(beta * ti / fs)) and w[0] > 1   # 'extend' continues into the pretrigger

    def test_one_before_trigger(self):
        w, beta = exponential_window(100, 100.0, trigger_index=10, beta=3.0, before_trigger="one")
        assert beta == 3.0
        assert np.all(w[:11] == 1.0) and w[11] == pytest.approx(np.exp(-0.03))

    def test_beta_from_end_level(self):
        assert beta_from_end_level(0.01, 1001, 1000.0) == pytest.approx(np.log(100))
        assert ExponentialWindow(end_level=0.015).resolve_beta(10242, 1000.0, 1) == pytest.approx(-np.log(0.015) / 10.24)
        with pytest.raises(ModalabValueError, match="end_level"):
            beta_from_end_level(1.0, 100, 1.0)

    @pytest.mark.parametrize("kw, match", [
        (dict(), "exactly one"),
        (dict(beta=1.0, end_level=0.1), "exactly one"),
        (dict(beta=-1.0), ">= 0"),
        (dict(end_level=0.0), r"\(0, 1\)"),
        (dict(beta=1.0, before_trigger="zero"), "extend"),
    ])
    def test_bad_parameters(self, kw, match):
        with pytest.raises(ModalabValueError, match=match):
            ExponentialWindow(**kw)

    def test_windowing_a_decay_adds_beta_to_its_rate(self):
        fs, n, ti = 1000.0, 4000, 0
        sigma, beta = 2.0, 3.0
        t = np.arange(n) / fs
        x = np.exp(-sigma * t) * np.cos(2 * np.pi * 50 * t)
        w, b = exponential_window(n, fs, beta=beta)
        env = np.abs(x * w)[::20]            # peaks of the cosine at multiples of 20 ms
        rate = -np.polyfit(t[::20], np.log(env), 1)[0]
        assert rate == pytest.approx(sigma + beta, rel=1e-9)


class TestDampingCorrection:
    def test_pole_form_is_exact(self):
        fn = np.array([10.0, 150.0, 1200.0])
        zeta = np.array([0.001, 0.02, 0.05])
        beta = 4.0
        w = 2 * np.pi * fn
        lam = -zeta * w + 1j * w * np.sqrt(1 - zeta ** 2)
        lam_m = lam - beta                                   # what identification sees
        f_m = np.abs(lam_m) / (2 * np.pi)
        z_m = -lam_m.real / np.abs(lam_m)
        np.testing.assert_allclose(correct_damping(f_m, z_m, beta), zeta, atol=1e-14)
        np.testing.assert_allclose(correct_poles(lam_m, beta), lam, atol=1e-12)

    def test_first_order_form(self):
        assert correct_damping(100.0, 0.05, 2 * np.pi, exact=False) == pytest.approx(0.04)
        fn, z_true, beta = 80.0, 0.01, 5.0
        w = 2 * np.pi * fn
        lam = -z_true * w + 1j * w * np.sqrt(1 - z_true ** 2) - beta
        z_m = -lam.real / abs(lam)
        approx = correct_damping(abs(lam) / 2 / np.pi, z_m, beta, exact=False)
        assert abs(approx - z_true) < 1e-4                       # differs by O(zeta*beta/omega)

    def test_bad_input(self, caplog):
        with pytest.raises(ModalabValueError, match="beta"):
            correct_damping(10.0, 0.01, -1.0)
        with pytest.raises(ModalabValueError, match="rigid-body"):
            correct_damping(0.0, 0.01, 1.0)
        with pytest.raises(ModalabValueError, match="one damping ratio per frequency"):
            correct_damping([1.0, 2.0, 3.0], [0.1, 0.2], 1.0)
        with caplog.at_level("WARNING"):
            z = correct_damping(10.0, 0.001, 5.0)
        assert z < 0 and "negative damping" in caplog.text


def test_windowed_force_keeps_the_ac_coupling_undershoot_and_cuts_the_noise():
    """A half-sine hit through a 0.5 Hz AC coupling (synthesised continuously, as the simulated lab does):
    its undershoot −A ω_c e^{−ω_c t} lasts the whole record and the response channels keep it.  The force
    window with the corner given leaves the samples inside it as they were and continues the undershoot after
    it (to 5e-4 of the undershoot, measured 2.5e-4: the noise integrated inside the window), the noise there
    cut; the plain window (corner 0, as before) cuts it: the force's spectrum at 1 Hz then reads 10-30 % off."""
    fs, n, ti, fc = 2048.0, 8192, 128, 0.5
    L = 16 * n
    f = np.fft.rfftfreq(L, 1 / fs)
    x = 2 * np.pi * f * 8e-4
    pulse = 200.0 * 8e-4 * np.pi * (1 + np.exp(-1j * x)) / np.where(np.abs(np.pi ** 2 - x ** 2) < 1e-9, 1.0,
                                                                    np.pi ** 2 - x ** 2)
    hp = 2j * np.pi * f / (2j * np.pi * f + 2 * np.pi * fc)
    lowpass = np.exp(-(f / 300.0) ** 2)                          # band-limited, as behind an anti-alias filter
    clean = np.fft.irfft(pulse * hp * lowpass * np.exp(-2j * np.pi * f * ti / fs), n=L)[:n] * fs
    noise = 1e-3 * np.random.default_rng(0).standard_normal(n)
    w = ForceWindow(fraction=0.05).array(n, fs, ti)
    kept = windowed_force(clean + noise, w, fs, fc)
    np.testing.assert_allclose(kept[w == 1], (clean + noise)[w == 1], rtol=0, atol=1e-10 * clean.max())
    tail = w == 0
    assert clean[tail].min() < -0.16        # the undershoot at the window's end: −A ω_c e^{−0.2 ω_c} = −0.17 N
    assert np.abs(kept[tail] - clean[tail]).max() < 5e-4 * np.abs(clean[tail]).max()     # measured 2.5e-4
    np.testing.assert_array_equal(windowed_force(clean, w, fs, 0.0), clean * w)
    line = int(round(1.0 * n / fs))
    ratio = np.fft.rfft(clean * w)[line] / np.fft.rfft(clean)[line]
    assert 0.1 < abs(ratio - 1) < 0.3
    assert abs(np.fft.rfft(windowed_force(clean, w, fs, fc))[line] / np.fft.rfft(clean)[line] - 1) < 1e-5
    with pytest.raises(ModalabValueError, match="AC-coupling corner -1 Hz must be >= 0"):
        windowed_force(clean, w, fs, -1)
