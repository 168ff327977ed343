"""FRF estimators: hand-derivable array cases, then hits of a known structure against its exact FRF.

The structure tests synthesise each hit exactly: the continuous Fourier transform of a half-sine
force times the exact FRF of :class:`modalab.core.structure.Structure` (its ModalModel), band-limited
by an identical zero-phase anti-alias filter on every channel (as a DAQ's filters are matched),
inverse-transformed on a grid 8x longer than the record (no wrap-around) and truncated to the record.
"""
import dataclasses

import numpy as np
import pytest

from acquisition.spectral import (CrossSpectra, SpectralAverager, coherence, cross_spectra, estimate_frf,
                                  estimate_frf_roving, group_by_reference, h1, h2, hv, multiple_coherence,
                                  quantity_from_unit)
from acquisition.windows import ExponentialWindow, ForceWindow, correct_damping
from modalab.core.dof import Dof, parse_dofs
from modalab.core.errors import ModalabError, ModalabValueError, ShapeError
from modalab.core.records import TimeRecord
from modalab.core.structure import Structure
from modalab.core.units import G


# ------------------------------------------------------------------------------------------ synthesis
def chain(masses, stiffnesses, alpha=0.0, beta_k=0.0):
    """Grounded spring-mass chain; spring i joins mass i-1 (ground for i = 0) and mass i; C = αM + βK."""
    n = len(masses)
    K = np.zeros((n, n))
    for i, k in enumerate(stiffnesses):
        K[i, i] += k
        if i > 0:
            K[i - 1, i - 1] += k
            K[i, i - 1] -= k
            K[i - 1, i] -= k
    M = np.diag(np.asarray(masses, float))
    return Structure(M=M, K=K, C=alpha * M + beta_k * K, dofs=[f"{i + 1}+Z" for i in range(n)])


def halfsine_spectrum(f_hz, amp, width):
    """Fourier transform (N s) of amp*sin(pi t/width) on 0 <= t <= width."""
    w = 2 * np.pi * np.asarray(f_hz, float)
    W = np.pi / width
    den = W ** 2 - w ** 2
    near = np.abs(den) < 1e-9 * W ** 2
    out = np.empty(w.shape, complex)
    out[~near] = amp * W * (1 + np.exp(-1j * w[~near] * width)) / den[~near]
    out[near] = amp * width / 2 * np.exp(-1j * W * width / 2) * (-1j)
    return out


def aa_gain(f_hz, fs, start=0.55):
    r = np.asarray(f_hz) / (fs / 2)
    return np.where(r <= start, 1.0, 0.5 * (1 + np.cos(np.pi * np.clip((r - start) / (1 - start), 0, 1))))


def synth_hits(model, hit_dof, resp_dofs, *, fs, n, ti, widths, amps, quantity="accelerance", noise=0.0,
               rng=None, units="m/s^2", hit0=1, long=8):
    L = long * n
    f = np.fft.rfftfreq(L, 1 / fs)
    hit, resp = Dof.parse(hit_dof), parse_dofs(resp_dofs)
    H = model.frf(f, resp, [hit], quantity=quantity).H[:, 0, :]
    H[~np.isfinite(H)] = 0.0
    G_ = aa_gain(f, fs)
    recs = []
    for h, (w, a) in enumerate(zip(widths, amps)):
        F = halfsine_spectrum(f, a, w) * G_ * np.exp(-2j * np.pi * f * ti / fs)
        sig = np.fft.irfft(np.vstack([F[None], H * F[None]]), n=L, axis=-1)[:, :n] * fs
        if noise:
            sig = sig + noise * np.abs(sig).max(1, keepdims=True) * rng.standard_normal(sig.shape)
        recs.append(TimeRecord(sample_rate_hz=fs, data=sig, dofs=[hit] + resp,
                               roles=["force"] + ["response"] * len(resp), units=["N"] + [units] * len(resp),
                               trigger_index=ti, hit_id=hit0 + h))
    return recs


FS, N, TI = 1024.0, 4096, 64
BAND = (5.0, 250.0)


def shifted_exact(model, freq_hz, responses, references, beta, quantity="accelerance"):
    """Exact FRF of the structure with every pole moved by -beta, for data in `quantity`.

    Windowing multiplies the measured impulse response by exp(-beta t), so the windowed FRF is
    H(s) evaluated at s = i*omega + beta: poles shifted, residues of the measured quantity kept.
    """
    mm = dataclasses.replace(model, poles=model.poles - beta)
    rec = mm.frf(freq_hz, responses, references, quantity="receptance")
    order = {"receptance": 0, "mobility": 1, "accelerance": 2}[quantity]
    rec.H = rec.H * (2j * np.pi * np.asarray(freq_hz) + beta) ** order
    return rec


def rel_err(est, ref):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.abs(np.abs(est) / np.abs(ref) - 1)


@pytest.fixture(scope="module")
def damped():
    return chain([1.0, 1.0, 1.0], [3e5, 2e5, 2e5], alpha=4.0, beta_k=2e-5)


@pytest.fixture(scope="module")
def light():
    return chain([1.0, 1.0, 1.0], [3e5, 2e5, 2e5], alpha=0.5, beta_k=2e-5)


# ------------------------------------------------------------------------------------------ arrays
class TestArrayEstimators:
    def test_h1_of_a_gain_is_the_gain(self):
        rng = np.random.default_rng(0)
        x = rng.standard_normal((3, 128))
        f, H = h1(x, -2.5 * x, 100.0)
        assert f.shape == (65,) and f[1] == pytest.approx(100.0 / 128)
        np.testing.assert_allclose(H, -2.5, rtol=1e-12)

    def test_circular_filter_is_recovered_exactly(self):
        rng = np.random.default_rng(1)
        n = 64
        h = np.zeros(n)
        h[:3] = [1.0, 0.5, -0.25]
        x = rng.standard_normal((4, n))
        y = np.fft.irfft(np.fft.rfft(x) * np.fft.rfft(h), n)
        for fn in (h1, h2, hv):
            _, H = fn(x, y, 10.0)
            np.testing.assert_allclose(H, np.fft.rfft(h), atol=1e-10)
        _, c = coherence(x, y, 10.0)
        np.testing.assert_allclose(c, 1.0, atol=1e-10)

    def test_axis_argument(self):
        rng = np.random.default_rng(2)
        x = rng.standard_normal((5, 32))
        _, a = h1(x, 2 * x + 0.1 * rng.standard_normal((5, 32)), 1.0)
        y = 2 * x + 0.1 * np.random.default_rng(2).standard_normal((5, 32))
        _, b = h1(x.T, y.T, 1.0, axis=0)
        assert b.shape == a.shape

    def test_output_noise_biases_h2_up_and_not_h1(self):
        rng = np.random.default_rng(3)
        x = rng.standard_normal((400, 64))
        y = 2.0 * x + rng.standard_normal((400, 64))          # SNR 4 on the output
        _, H1 = h1(x, y, 1.0)
        _, H2 = h2(x, y, 1.0)
        _, Hv = hv(x, y, 1.0)
        _, c = coherence(x, y, 1.0)
        assert np.median(np.abs(H1)) == pytest.approx(2.0, rel=0.03)
        assert np.median(np.abs(H2)) == pytest.approx(2.0 * (1 + 1 / 4), rel=0.05)   # |H2| = |H|/γ²
        assert 2.0 < np.median(np.abs(Hv)) < np.median(np.abs(H2))
        assert np.median(c) == pytest.approx(0.8, abs=0.03)                        # 4/(4+1)

    def test_input_noise_biases_h1_down(self):
        rng = np.random.default_rng(4)
        u = rng.standard_normal((400, 64))
        x = u + 0.5 * rng.standard_normal((400, 64))
        y = 2.0 * u
        _, H1 = h1(x, y, 1.0)
        _, H2 = h2(x, y, 1.0)
        assert np.median(np.abs(H2)) == pytest.approx(2.0, rel=0.03)
        assert np.median(np.abs(H1)) == pytest.approx(2.0 / 1.25, rel=0.03)

    def test_mimo_two_inputs(self):
        rng = np.random.default_rng(5)
        n, m = 64, 12
        h_a = np.zeros(n); h_a[:2] = [1.0, 0.3]
        h_b = np.zeros(n); h_b[1:3] = [-0.7, 0.2]
        x = rng.standard_normal((m, 2, n))
        Xa, Xb = np.fft.rfft(x[:, 0]), np.fft.rfft(x[:, 1])
        y = np.fft.irfft(Xa * np.fft.rfft(h_a) + Xb * np.fft.rfft(h_b), n)[:, None, :]
        _, H = h1(x, y, 1.0)
        assert H.shape == (1, 2, n // 2 + 1)
        np.testing.assert_allclose(H[0, 0], np.fft.rfft(h_a), atol=1e-9)
        np.testing.assert_allclose(H[0, 1], np.fft.rfft(h_b), atol=1e-9)
        _, Hv = hv(x, y, 1.0)
        np.testing.assert_allclose(Hv, H, atol=1e-8)
        _, mc = multiple_coherence(x, y, 1.0)
        np.testing.assert_allclose(mc, 1.0, atol=1e-9)
        _, oc = coherence(x, y, 1.0)
        assert oc.max() < 1.0 and oc.min() >= 0.0

    def test_mimo_needs_as_many_averages_as_inputs(self):
        x = np.random.default_rng(6).standard_normal((1, 2, 32))
        with pytest.raises(ModalabValueError, match="at least 2 averages"):
            h1(x, x[:, :1], 1.0)

    def test_h2_rejects_several_inputs(self):
        x = np.random.default_rng(7).standard_normal((4, 2, 32))
        with pytest.raises(ModalabValueError, match="H1"):
            h2(x, x[:, :1], 1.0)

    def test_clear_errors_for_bad_arrays(self):
        x = np.zeros((3, 32))
        with pytest.raises(ShapeError, match="averages"):
            h1(x, np.zeros((2, 32)), 1.0)
        with pytest.raises(ShapeError, match="samples"):
            h1(x, np.zeros((3, 31)), 1.0)
        with pytest.raises(ModalabValueError, match="fs"):
            h1(x, x, 0.0)
        with pytest.raises(ModalabValueError, match="NaN"):
            h1(np.full(8, np.nan), np.ones(8), 1.0)
        with pytest.raises(ModalabValueError, match="nfft"):
            cross_spectra(x, x, 1.0, nfft=16)

    def test_zero_padding_interpolates(self):
        rng = np.random.default_rng(8)
        x = rng.standard_normal((2, 32))
        f, H = h1(x, 3 * x, 1.0, nfft=128)
        assert f.size == 65
        np.testing.assert_allclose(H, 3.0, rtol=1e-10)

    def test_crossspectra_scaling_is_parseval(self):
        # one-sided ESD integrates to the signal energy: sum(G) df = sum(x^2) dt
        rng = np.random.default_rng(9)
        x = rng.standard_normal(256)
        fs = 50.0
        cs = cross_spectra(x, x, fs)
        assert isinstance(cs, CrossSpectra) and cs.n_averages == 1 and cs.Gxx.shape == (1, 1, 129)
        df = fs / 256
        assert cs.Gxx[0, 0].real.sum() * df == pytest.approx(np.sum(x ** 2) / fs, rel=1e-12)


# ------------------------------------------------------------------------------------------ hits
class TestKnownStructure:
    def test_h1_within_half_percent_where_coherent(self, damped):
        rng = np.random.default_rng(10)
        recs = synth_hits(damped.modal_model(), "1+Z", ["1+Z", "3+Z"], fs=FS, n=N, ti=TI,
                          widths=rng.uniform(0.3e-3, 0.5e-3, 5), amps=rng.uniform(50, 150, 5),
                          noise=1e-6, rng=rng)
        frf = estimate_frf(recs)
        assert frf.quantity == "accelerance" and frf.units == "m/s^2/N"
        assert [str(d) for d in frf.responses] == ["1+Z", "3+Z"] and [str(d) for d in frf.references] == ["1+Z"]
        assert frf.metadata["estimator"] == "H1" and frf.metadata["n_averages"] == 5
        assert frf.window_beta_per_s == 0.0 and frf.metadata["force_window"] is None
        exact = damped.frf(frf.freq_hz, frf.responses, frf.references)
        band = (frf.freq_hz >= BAND[0]) & (frf.freq_hz <= BAND[1])
        good = band & (frf.coherence[:, 0] > 0.99)
        assert good.sum() > 0.95 * 2 * band.sum()      # coherent almost everywhere at this noise level
        assert rel_err(frf.H[:, 0], exact.H[:, 0])[good].max() < 5e-3

    def test_noise_lowers_coherence_and_h1_stays_within_its_random_error(self, damped):
        rng = np.random.default_rng(11)
        m = 20
        recs = synth_hits(damped.modal_model(), "1+Z", ["2+Z"], fs=FS, n=N, ti=TI,
                          widths=rng.uniform(0.3e-3, 0.5e-3, m), amps=rng.uniform(50, 150, m),
                          noise=3e-4, rng=rng)
        frf = estimate_frf(recs)
        exact = damped.frf(frf.freq_hz, frf.responses, frf.references)
        band = (frf.freq_hz >= BAND[0]) & (frf.freq_hz <= BAND[1])
        c = frf.coherence[0, 0]
        assert c[band].min() < 0.9                       # antiresonance / high-frequency lines lose coherence
        use = band & (c > 0.8)
        # Bendat & Piersol (2010), ch. 9: normalised random error of |H| = sqrt(1-γ²)/(|γ| sqrt(2 n_d))
        eps = np.sqrt(1 - c[use]) / (np.sqrt(c[use]) * np.sqrt(2 * m))
        err = rel_err(frf.H[0, 0], exact.H[0, 0])[use]
        assert np.mean(err < 4 * eps + 1e-3) > 0.99
        assert np.median(err) < 5e-3

    def test_exponential_window_equals_pole_shifted_structure(self, light):
        mm = light.modal_model()
        rng = np.random.default_rng(12)
        recs = synth_hits(mm, "1+Z", ["1+Z", "3+Z"], fs=FS, n=N, ti=TI, widths=[0.4e-3, 0.35e-3],
                          amps=[80.0, 120.0])
        ew = ExponentialWindow(end_level=0.001)
        frf = estimate_frf(recs, exp_window=ew, force_window=ForceWindow(length_s=0.01, taper_s=0.005))
        beta = frf.window_beta_per_s
        assert beta == pytest.approx(-np.log(0.001) / ((N - 1 - TI) / FS), rel=1e-12)
        exact = shifted_exact(mm, frf.freq_hz, frf.responses, frf.references, beta)
        band = (frf.freq_hz >= BAND[0]) & (frf.freq_hz <= BAND[1])
        assert rel_err(frf.H[:, 0], exact.H[:, 0])[:, band].max() < 2e-3
        np.testing.assert_allclose(frf.H[:, 0, band], exact.H[:, 0, band],
                                   atol=2e-3 * np.abs(exact.H[:, 0, band]).max())
        # without the shift the same comparison fails near the lightly damped first mode
        plain = light.frf(frf.freq_hz, frf.responses, frf.references)
        assert rel_err(frf.H[:, 0], plain.H[:, 0])[:, band].max() > 0.2

    def test_exponential_window_on_receptance_matches_shifted_modal_model_directly(self, light):
        mm = light.modal_model()
        recs = synth_hits(mm, "2+Z", ["1+Z", "2+Z"], fs=FS, n=N, ti=TI, widths=[0.4e-3], amps=[100.0],
                          quantity="receptance", units="m")
        frf = estimate_frf(recs, exp_window=ExponentialWindow(end_level=0.001))
        assert frf.quantity == "receptance"
        beta = frf.window_beta_per_s
        shifted = dataclasses.replace(mm, poles=mm.poles - beta).frf(frf.freq_hz, frf.responses, frf.references,
                                                                     quantity="receptance")
        band = (frf.freq_hz >= BAND[0]) & (frf.freq_hz <= BAND[1])
        assert rel_err(frf.H[:, 0], shifted.H[:, 0])[:, band].max() < 2e-3

    def test_damping_correction_recovers_true_damping(self, light):
        mm = light.modal_model()
        recs = synth_hits(mm, "1+Z", ["1+Z"], fs=FS, n=N, ti=TI, widths=[0.4e-3, 0.45e-3], amps=[90.0, 110.0])
        frf = estimate_frf(recs, exp_window=ExponentialWindow(end_level=0.01))
        beta = frf.window_beta_per_s
        wn_true, _ = light.normal_modes()
        up = mm.poles[mm.poles.imag > 0]
        up = up[np.argsort(up.imag)]
        zeta_true = -up.real / np.abs(up)
        f_meas, z_meas = [], []
        for lam in up:
            fit = _sdof_fit(frf.freq_hz, frf.H[0, 0], abs(lam) / (2 * np.pi))
            f_meas.append(abs(fit) / (2 * np.pi))
            z_meas.append(-fit.real / abs(fit))
        z_meas = np.array(z_meas)
        assert np.abs(z_meas - zeta_true).max() > 5e-3                # uncorrected, the window's damping shows
        for exact in (True, False):
            z = correct_damping(f_meas, z_meas, beta, exact=exact)
            np.testing.assert_allclose(z, zeta_true, atol=1e-3)

    def test_units_set_the_quantity_and_scale(self, damped):
        mm = damped.modal_model()
        base = synth_hits(mm, "1+Z", ["2+Z"], fs=FS, n=N, ti=TI, widths=[0.4e-3], amps=[100.0])[0]
        in_g = base.copy()
        in_g.data[1] /= G
        in_g.units = ["N", "g"]
        a, b = estimate_frf([base]), estimate_frf([in_g])
        assert b.quantity == "accelerance"
        np.testing.assert_allclose(b.H, a.H, rtol=1e-9)
        mob = synth_hits(mm, "1+Z", ["2+Z"], fs=FS, n=N, ti=TI, widths=[0.4e-3], amps=[100.0],
                         quantity="mobility", units="m/s")
        assert estimate_frf(mob).quantity == "mobility"
        assert quantity_from_unit("m") == "receptance"
        with pytest.raises(ModalabValueError, match="motion unit"):
            quantity_from_unit("V")

    def test_mimo_from_two_hit_points_with_hv(self, damped):
        mm = damped.modal_model()
        rng = np.random.default_rng(13)
        # two independent forces per record: sum of two synthetic hits at different DOFs and times
        recs = []
        for k in range(4):
            a = synth_hits(mm, "1+Z", ["1+Z", "3+Z"], fs=FS, n=N, ti=TI, widths=[rng.uniform(3e-4, 5e-4)],
                           amps=[rng.uniform(50, 150)])[0]
            b = synth_hits(mm, "3+Z", ["1+Z", "3+Z"], fs=FS, n=N, ti=TI + int(rng.integers(5, 200)),
                           widths=[rng.uniform(3e-4, 5e-4)], amps=[rng.uniform(50, 150)])[0]
            fb = b.data
            data = np.vstack([a.data[:1], fb[:1], a.data[1:] + fb[1:]])
            recs.append(TimeRecord(sample_rate_hz=FS, data=data, dofs=["1+Z", "3+Z", "1+Z", "3+Z"],
                                   roles=["force", "force", "response", "response"], trigger_index=TI, hit_id=k))
        exact = damped.frf(np.fft.rfftfreq(N, 1 / FS), ["1+Z", "3+Z"], ["1+Z", "3+Z"])
        band = (exact.freq_hz >= BAND[0]) & (exact.freq_hz <= BAND[1])
        for est in ("H1", "Hv"):
            frf = estimate_frf(recs, estimator=est)
            assert frf.shape == (2, 2, exact.n_freq) and frf.metadata["coherence_kind"] == "multiple"
            assert rel_err(frf.H, exact.H)[..., band].max() < 5e-3
            np.testing.assert_allclose(frf.coherence[..., band], 1.0, atol=1e-6)

    def test_h1_h2_hv_agree_on_clean_data(self, damped):
        recs = synth_hits(damped.modal_model(), "2+Z", ["1+Z"], fs=FS, n=N, ti=TI, widths=[3e-4, 4e-4, 5e-4],
                          amps=[50.0, 100.0, 70.0])
        band = slice(int(BAND[0] * N / FS), int(BAND[1] * N / FS))
        Hs = [estimate_frf(recs, estimator=e).H[0, 0, band] for e in ("H1", "H2", "Hv")]
        np.testing.assert_allclose(Hs[1], Hs[0], rtol=1e-6)
        np.testing.assert_allclose(Hs[2], Hs[0], rtol=1e-6)


def _sdof_fit(freq_hz, H, f0_hz, half_width=0.06):
    """Pole (rad/s) of H ≈ (b0 + b1 s + b2 s²)/(s² + a1 s + a0) fitted by linear least squares near f0."""
    m = np.abs(freq_hz - f0_hz) <= half_width * f0_hz
    w0 = 2 * np.pi * f0_hz
    s = 2j * np.pi * freq_hz[m] / w0
    h = H[m]
    A = np.column_stack([np.ones_like(s), s, s ** 2, -s * h, -h])
    b = s ** 2 * h
    Ar = np.vstack([A.real, A.imag])
    br = np.concatenate([b.real, b.imag])
    x, *_ = np.linalg.lstsq(Ar, br, rcond=None)
    r = np.roots([1.0, x[3], x[4]]) * w0
    return r[np.argmax(r.imag)]


# ------------------------------------------------------------------------------------------ averager
class TestSpectralAverager:
    @pytest.fixture(scope="class")
    @classmethod
    def hits(cls):
        s = chain([1.0, 2.0], [2e5, 1e5], alpha=5.0)
        rng = np.random.default_rng(14)
        return synth_hits(s.modal_model(), "1+Z", ["1+Z", "2+Z"], fs=FS, n=N, ti=TI,
                          widths=rng.uniform(3e-4, 5e-4, 4), amps=rng.uniform(50, 150, 4), noise=1e-3, rng=rng)

    def test_add_remove_matches_batch(self, hits):
        avg = SpectralAverager(exp_window=ExponentialWindow(beta=2.0))
        for r in hits:
            avg.add(r)
        avg.remove(hits[1].hit_id).remove(hits[3])
        ref = estimate_frf([hits[0], hits[2]], exp_window=ExponentialWindow(beta=2.0))
        got = avg.frf()
        np.testing.assert_allclose(got.H, ref.H, rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(got.coherence, ref.coherence, atol=1e-9)
        assert got.metadata["n_averages"] == 2 and got.metadata["hit_ids"] == [hits[0].hit_id, hits[2].hit_id]
        assert got.window_beta_per_s == 2.0 and avg.beta == 2.0

    def test_init_only_stores_and_errors_are_clear(self, hits):
        avg = SpectralAverager(estimator="nonsense")
        assert avg.n_averages == 0
        with pytest.raises(ModalabValueError, match="estimator"):
            avg.add(hits[0])
        avg = SpectralAverager()
        with pytest.raises(ModalabValueError, match="no hits"):
            avg.frf()
        avg.add(hits[0])
        with pytest.raises(ModalabValueError, match="already"):
            avg.add(hits[0])
        with pytest.raises(ModalabValueError, match="not in the average"):
            avg.remove(99)
        avg.remove(hits[0].hit_id)
        assert avg.n_averages == 0

    def test_end_level_beta_is_fixed_by_the_first_hit(self, hits):
        late = hits[1].copy()
        late.trigger_index = TI + 100
        avg = SpectralAverager(exp_window=ExponentialWindow(end_level=0.01)).add(hits[0]).add(late)
        assert avg.beta == pytest.approx(-np.log(0.01) / ((N - 1 - TI) / FS))

    def test_layout_mismatches(self, hits):
        r = hits[0]
        other_fs = TimeRecord(sample_rate_hz=2 * FS, data=r.data, dofs=r.dofs, roles=r.roles, hit_id=50)
        short = TimeRecord(sample_rate_hz=FS, data=r.data[:, :-1], dofs=r.dofs, roles=r.roles, hit_id=51)
        moved = TimeRecord(sample_rate_hz=FS, data=r.data, dofs=["2+Z", "1+Z", "2+Z"], roles=r.roles, hit_id=52)
        no_force = TimeRecord(sample_rate_hz=FS, data=r.data, dofs=r.dofs, roles=["response"] * 3, hit_id=53)
        no_resp = TimeRecord(sample_rate_hz=FS, data=r.data[:1], dofs=r.dofs[:1], roles=["force"], hit_id=54)
        mixed = TimeRecord(sample_rate_hz=FS, data=r.data, dofs=r.dofs, roles=r.roles, units=["N", "m/s^2", "m"],
                           hit_id=55)
        volts = TimeRecord(sample_rate_hz=FS, data=r.data, dofs=r.dofs, roles=r.roles, units=["V", "m/s^2", "m/s^2"],
                           hit_id=56)
        with pytest.raises(ModalabValueError, match="Hz"):
            estimate_frf([r, other_fs])
        with pytest.raises(ModalabValueError, match="same length"):
            estimate_frf([r, short])
        with pytest.raises(ModalabValueError, match="estimate_frf_roving"):
            estimate_frf([r, moved])
        with pytest.raises(ModalabValueError, match="no force channel"):
            estimate_frf([no_force])
        with pytest.raises(ModalabValueError, match="no response channel"):
            estimate_frf([no_resp])
        with pytest.raises(ModalabValueError, match="mixes response quantities"):
            estimate_frf([mixed])
        with pytest.raises(ModalabValueError, match="force channel"):
            estimate_frf([volts])
        with pytest.raises(ModalabValueError, match="no hits"):
            estimate_frf([])
        with pytest.raises(ModalabValueError, match="H1"):
            estimate_frf([r], estimator="H3")
        for e in (ModalabValueError, ModalabError, ValueError):
            assert issubclass(ModalabValueError, e)


def test_roving_hammer_groups_hits_by_reference(damped):
    mm = damped.modal_model()
    recs = []
    for k, hit in enumerate(["1+Z", "2+Z", "3+Z"]):
        recs += synth_hits(mm, hit, ["1+Z", "3+Z"], fs=FS, n=N, ti=TI, widths=[4e-4, 3.5e-4], amps=[100.0, 60.0],
                           hit0=10 * k)
    assert list(group_by_reference(recs)) == [(Dof.parse("1+Z"),), (Dof.parse("2+Z"),), (Dof.parse("3+Z"),)]
    frf = estimate_frf_roving(recs, exp_window=ExponentialWindow(end_level=0.05))
    assert frf.shape[:2] == (2, 3)
    assert frf.metadata["n_averages_per_reference"] == {"1+Z": 2, "2+Z": 2, "3+Z": 2}
    beta = frf.window_beta_per_s
    exact = shifted_exact(mm, frf.freq_hz, frf.responses, frf.references, beta)
    band = (frf.freq_hz >= BAND[0]) & (frf.freq_hz <= BAND[1])
    assert rel_err(frf.H, exact.H)[..., band].max() < 2e-3


def test_h1_of_the_simulated_lab_matches_its_structure():
    # cross-check with hardware_sim (24-bit ADC, IEPE high-pass, anti-alias filter, noise): without
    # placement scatter the hammer excites exactly the labelled DOF, so the windowed H1 must equal
    # the structure's exact FRF with every pole shifted by the window's beta.
    from hardware_sim import demo_lab
    from hardware_sim.demo import DEMO_HAMMER

    lab = demo_lab(rng=1, hammer=dataclasses.replace(DEMO_HAMMER, placement_scatter_m=0.0))
    recs = [lab.hit("14+Z", force_n=150.0) for _ in range(5)]
    frf = estimate_frf(recs, exp_window=ExponentialWindow(end_level=0.01),
                       force_window=ForceWindow(fraction=0.05, taper=0.25))
    exact = shifted_exact(lab.structure.modal_model(), frf.freq_hz, frf.responses, frf.references,
                          frf.window_beta_per_s)
    band = (frf.freq_hz >= 20.0) & (frf.freq_hz <= 800.0)
    good = band[None, None, :] & (frf.coherence > 0.99)
    assert good.sum() > 0.95 * band.sum() * frf.n_out
    err = rel_err(frf.H, exact.H)[good]
    assert np.median(err) < 1e-3
    assert np.quantile(err, 0.99) < 5e-3


def test_the_force_window_keeps_the_ac_coupling_of_the_simulated_lab_below_20_hz():
    """The same cross-check at 0.25-20 Hz, where the IEPE coupling (0.5 Hz corner on every channel) matters:
    the force window used to cut the coupling's undershoot from the force while the responses kept it, and the
    windowed H1 read 16.8 % off (median) at 0.25-2 Hz, 3.5 % at 2-5 Hz and 0.7 % at 5-20 Hz (issue 14 #2:
    E and ρ of an exact model rose by 0.4-0.6 %).  With the corners the records carry (metadata
    highpass_hz) it keeps the undershoot: the estimate equals the one without a force window within 0.1 % (the
    force noise it cuts, 0.02 % median), and the lab's noise is what remains: 0.56 % at 0.25-2 Hz, below
    0.08 % above 2 Hz."""
    from hardware_sim import demo_lab
    from hardware_sim.demo import DEMO_HAMMER

    lab = demo_lab(rng=1, hammer=dataclasses.replace(DEMO_HAMMER, placement_scatter_m=0.0))
    recs = [lab.hit("14+Z", force_n=150.0) for _ in range(5)]
    assert all(r.metadata["highpass_hz"] == [0.5] * 4 for r in recs)
    ew = ExponentialWindow(end_level=0.01)
    fw = ForceWindow(fraction=0.05, taper=0.25)
    frf = estimate_frf(recs, exp_window=ew, force_window=fw)
    plain = estimate_frf(recs, exp_window=ew)
    exact = shifted_exact(lab.structure.modal_model(), frf.freq_hz, frf.responses, frf.references,
                          frf.window_beta_per_s)
    f = frf.freq_hz
    for lo, hi, most in [(0.25, 2.0, 0.01), (2.0, 5.0, 2e-3), (5.0, 20.0, 2e-3)]:
        good = ((f >= lo) & (f < hi))[None, None, :] & (frf.coherence > 0.99)
        assert good.sum() >= 16
        assert np.median(rel_err(frf.H, exact.H)[good]) < most, (lo, hi)
        assert np.median(rel_err(frf.H, plain.H)[good]) < 1e-3, (lo, hi)     # the force noise it cuts
