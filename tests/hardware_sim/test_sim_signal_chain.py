"""Signal chain of the simulated lab: pulse spectrum, IEPE high-pass, anti-alias filter, ADC.

The force channel of a record is checked against the closed form of what a
DAQ samples: the DFT of the record equals ``fs · Σ_m G(f+m·fs) F(f+m·fs) e^{2πi(f+m·fs)τ0}``
with F the half-sine spectrum, G the conditioner and anti-alias filter and the
sum over the alias images present in the synthesis band (m = 0, −1).
"""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from hardware_sim import (AcquisitionSetup, ChannelSetup, Hammer, SimulatedLab, antialias_response, half_sine,
                          half_sine_spectrum, iepe_highpass, quantization_step, quantize,
                          synthesis_taper)
from modalab.core.structure import Structure


def one_dof(f_hz=1700.0, zeta=0.01, m=1.0, dof="1+Z"):
    w = 2 * np.pi * f_hz
    return Structure(M=[[m]], K=[[m * w * w]], C=[[2 * zeta * m * w]], dofs=[dof])


def quiet_channels(force_corner=0.0, resp_iepe=False):
    return [ChannelSetup(dof="1+Z", role="force", sensitivity=2e-3, range_v=5.0, iepe=force_corner > 0,
                         highpass_hz=force_corner, noise_v_rms=0.0),
            ChannelSetup(dof="1+Z", role="response", sensitivity=1e-2, range_v=5.0, iepe=resp_iepe,
                         noise_v_rms=0.0)]


def expected_force_dft(rec, lab, chain):
    """Closed-form DFT of the sampled force channel (noise-free), every alias image of the synthesis band."""
    fs, n = rec.sample_rate_hz, rec.n_samples
    nyq = fs * lab.oversample_used / 2
    f = np.fft.rfftfreq(n, 1 / fs)
    sim = rec.metadata["sim"]
    tau0 = -rec.trigger_index / fs
    out = np.zeros(f.size, complex)
    for m in range(-lab.oversample_used, lab.oversample_used + 1):
        g = f + m * fs
        F = sum(half_sine_spectrum(g, a, w, s) for a, w, s in
                zip(sim["pulse_peaks_n"], sim["pulse_widths_s"], sim["pulse_starts_s"]))
        out += fs * chain(g) * synthesis_taper(g, nyq) * F * np.exp(2j * np.pi * g * tau0)
    return f, out


class TestHalfSine:
    @settings(max_examples=25, deadline=None)
    @given(amp=st.floats(1.0, 1e3), width=st.floats(1e-4, 5e-3), t0=st.floats(0.0, 2e-3))
    def test_spectrum_is_the_fourier_transform(self, amp, width, t0):
        fs = 2e6
        t = np.arange(int(0.02 * fs)) / fs
        x = half_sine(t, amp, width, t0)
        f = np.fft.rfftfreq(t.size, 1 / fs)[:400]
        num = np.fft.rfft(x)[:400] / fs
        ana = half_sine_spectrum(f, amp, width, t0)
        assert np.abs(num - ana).max() <= 2e-3 * np.abs(ana).max()

    def test_dc_value_is_the_impulse_and_singular_point_is_finite(self):
        A, T = 100.0, 1e-3
        assert half_sine_spectrum([0.0], A, T)[0] == pytest.approx(2 * A * T / np.pi)
        # ωT = π exactly: limit −iAT/2
        assert half_sine_spectrum([1 / (2 * T)], A, T)[0] == pytest.approx(-0.5j * A * T)
        near = half_sine_spectrum([1 / (2 * T) * (1 + 1e-5)], A, T)[0]
        assert near == pytest.approx(-0.5j * A * T, rel=1e-4)

    def test_first_zero_at_one_and_a_half_over_width(self):
        T = 1e-3
        f = np.linspace(1000, 2000, 100001)
        mag = np.abs(half_sine_spectrum(f, 1.0, T))
        assert f[np.argmin(mag)] == pytest.approx(1.5 / T, rel=1e-4)


class TestAdc:
    def test_step_is_range_over_2_pow_23(self):
        assert quantization_step(5.0, 24) == 5.0 / 2 ** 23
        assert quantization_step(10.0) == 10.0 / 2 ** 23

    @settings(max_examples=50, deadline=None)
    @given(st.lists(st.floats(-20, 20, allow_nan=False), min_size=1, max_size=50), st.floats(0.1, 10.0),
           st.integers(8, 24))
    def test_quantize_clips_rounds_and_flags(self, vals, rng_v, bits):
        v = np.array(vals)
        q, over = quantize(v, rng_v, bits)
        step = quantization_step(rng_v, bits)
        assert np.allclose(q / step, np.round(q / step), atol=1e-6)
        assert q.min() >= -rng_v and q.max() <= rng_v - step * (1 - 1e-9)
        inside = np.abs(v) < rng_v - step
        assert np.all(np.abs(q[inside] - v[inside]) <= step / 2 * (1 + 1e-9))
        assert bool(over) == bool(np.any(np.abs(v) >= rng_v))

    def test_record_values_sit_on_the_24_bit_grid(self):
        lab = SimulatedLab(one_dof(300.0), quiet_channels(), AcquisitionSetup(sample_rate_hz=4096, n_samples=2048,
                                                                              pretrigger_samples=64), rng=3)
        rec = lab.hit(force_n=100.0)
        for c in range(rec.n_channels):
            volts = rec.data[c] * rec.sensitivity[c]
            step = 5.0 / 2 ** 23
            assert np.abs(volts / step - np.round(volts / step)).max() < 1e-6
            assert rec.metadata["quantization_step_v"][c] == step
        # a coarser converter shows a coarser grid
        lab12 = SimulatedLab(one_dof(300.0), quiet_channels(), AcquisitionSetup(
            sample_rate_hz=4096, n_samples=2048, pretrigger_samples=64, adc_bits=12), rng=3)
        v = lab12.hit(force_n=100.0).data[1] * 1e-2
        step12 = 5.0 / 2 ** 11
        assert np.abs(v / step12 - np.round(v / step12)).max() < 1e-6
        assert np.diff(np.unique(v)).min() == pytest.approx(step12)


class TestForceChannelSpectrum:
    """The sampled force equals the closed form for each filter, aliasing included."""

    @pytest.mark.parametrize("aa", ["none", "delta-sigma", "butterworth"])
    def test_force_dft_matches_closed_form(self, aa):
        setup = AcquisitionSetup(sample_rate_hz=2048, n_samples=2048, pretrigger_samples=64, aa_filter=aa,
                                 aa_cutoff=0.4, aa_order=6, adc_noise_v_rms=0.0)
        # without a filter, a point-sampled 0.2 ms pulse would slip between 0.49 ms samples: use the medium
        # tip there and a synthesis band (0.8 x 8 x fs/2) that holds its spectrum
        lab = SimulatedLab(one_dof(), quiet_channels(), setup, rng=5, oversample=8 if aa == "none" else None,
                           hammer=Hammer(tip="medium" if aa == "none" else "hard", placement_scatter_m=0.0))
        rec = lab.hit(force_n=300.0)
        f, exp = expected_force_dft(rec, lab, lambda g: antialias_response(g, 2048, aa, 0.4, 6))
        got = np.fft.rfft(rec.force[0])
        assert np.abs(got - exp).max() < 2e-4 * np.abs(exp).max()
        # the alias image matters without a filter and vanishes with the delta-sigma filter
        _, no_alias = expected_force_dft(rec, lab, lambda g: antialias_response(g, 2048, aa, 0.4, 6)
                                         * ((g >= 0) & (g <= 1024)))
        alias_free = f <= 0.4 * 2048         # images from beyond the stop edge (1 - 0.4) fs
        alias = np.abs(exp - no_alias)[alias_free].max() / np.abs(exp).max()
        if aa == "none":
            assert alias > 0.1
        elif aa == "delta-sigma":
            assert alias < 1e-5

    def test_iepe_highpass_shapes_the_force_spectrum(self):
        setup = AcquisitionSetup(sample_rate_hz=2048, n_samples=2048, pretrigger_samples=64, adc_noise_v_rms=0.0)
        lab = SimulatedLab(one_dof(), quiet_channels(force_corner=20.0), setup, rng=6,
                           hammer=Hammer(tip="soft", placement_scatter_m=0.0))
        rec = lab.hit(force_n=300.0)
        chain = lambda g: antialias_response(g, 2048) * iepe_highpass(g, 20.0)  # noqa: E731
        f, exp = expected_force_dft(rec, lab, chain)
        got = np.fft.rfft(rec.force[0])
        assert np.abs(got - exp).max() < 2e-4 * np.abs(exp).max()
        # the effect is real: at 5 Hz the coupling removes ~97 % of the force spectrum
        _, dc = expected_force_dft(rec, lab, lambda g: antialias_response(g, 2048))
        k = np.argmin(abs(f - 5.0))
        assert abs(got[k]) / abs(dc[k]) == pytest.approx(5 / np.hypot(5, 20), rel=1e-3)


class TestStructuralAliasing:
    def test_mode_above_nyquist_aliases_only_without_filter(self):
        """A 1700 Hz mode sampled at 2048 Hz folds to 348 Hz unless the anti-alias filter removes it."""
        spectra = {}
        for aa in ("none", "delta-sigma"):
            setup = AcquisitionSetup(sample_rate_hz=2048, n_samples=2048, pretrigger_samples=64, aa_filter=aa)
            lab = SimulatedLab(one_dof(1700.0), quiet_channels(), setup, rng=9,
                               hammer=Hammer(tip="hard", placement_scatter_m=0.0))
            rec = lab.hit(force_n=300.0)
            spectra[aa] = np.abs(np.fft.rfft(rec.response[0]))
        f = np.fft.rfftfreq(2048, 1 / 2048)
        band = (f > 100) & (f < 900)
        assert f[band][np.argmax(spectra["none"][band])] == pytest.approx(348.0, abs=1.5)
        k = np.argmin(abs(f - 348))
        assert spectra["delta-sigma"][k] < 3e-3 * spectra["none"][k]
        # what is left at 348 Hz is the mode's own stiffness-line response, rising towards 1700 Hz: no peak
        seg = spectra["delta-sigma"][(f > 300) & (f < 400)]
        assert np.all(np.diff(seg) > 0)

    def test_butterworth_response_is_causal_lowpass(self):
        f = np.array([0.0, 100.0, 819.2, 2000.0])
        h = antialias_response(f, 2048, "butterworth", 0.4, 8)
        assert abs(h[0]) == pytest.approx(1.0)
        assert abs(h[2]) == pytest.approx(2 ** -0.5, rel=1e-9)
        assert abs(h[3]) < 1e-2
        assert np.conj(antialias_response([-100.0], 2048, "butterworth", 0.4, 8))[0] == pytest.approx(h[1])
