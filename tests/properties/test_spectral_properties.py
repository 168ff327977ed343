"""Property tests of the FRF estimators: coherence bounds, force-scale invariance, reciprocity to noise."""
import numpy as np
from hypothesis import example, given, settings, strategies as st
from hypothesis.extra.numpy import arrays

from acquisition.reciprocity import reciprocity_check
from acquisition.spectral import coherence, estimate_frf, estimate_frf_roving, h1, hv, multiple_coherence
from acquisition.windows import ExponentialWindow, ForceWindow
from modalab.core.dof import Dof, parse_dofs
from modalab.core.records import TimeRecord
from modalab.core.structure import Structure

# a sampled signal: zero or at least 1e-6 in magnitude.  Subnormal values (1e-309) are no physical force or
# response and their spectra lose all precision (squares underflow), so a scaled copy cannot agree with them
finite = st.one_of(st.just(0.0), st.floats(1e-6, 1e3), st.floats(-1e3, -1e-6))


@st.composite
def signal_pairs(draw, mimo=False):
    n_avg = draw(st.integers(1, 5))
    n = draw(st.integers(4, 64))
    n_in = draw(st.integers(1, 3)) if mimo else 1
    n_out = draw(st.integers(1, 3))
    x = draw(arrays(np.float64, (n_avg, n_in, n), elements=finite))
    y = draw(arrays(np.float64, (n_avg, n_out, n), elements=finite))
    return x, y


@settings(max_examples=60, deadline=None)
@given(signal_pairs(mimo=True))
def test_coherence_is_in_unit_interval(xy):
    x, y = xy
    _, c = coherence(x, y, 100.0)
    _, mc = multiple_coherence(x, y, 100.0)
    for v in (c, mc):
        assert np.all(np.isfinite(v))
        assert np.all((v >= 0.0) & (v <= 1.0))


def _rounding_rtol(x, y) -> np.ndarray:
    """The relative error rounding alone can leave in H1 = G_yx / G_xx on each line (n_out, 1, n_freq): a line of
    a record's FFT carries an absolute error up to about n eps ‖x‖₁, large against a line where the samples
    cancel (a force of 0, 1e-6 and four equal values: its Nyquist line is -1e-6 against ‖x‖₁ = 684).  Summed
    over the hits (Cauchy-Schwarz): G_xx is off by at most 2 n eps sqrt(Σ‖x‖₁²) / sqrt(G_xx) relatively, G_yx
    by 2 n eps sqrt(Σ‖x‖₁² Σ‖y‖₁²) / |G_yx|; H1 by their sum.  Twice that (both estimates compared carry it) and
    1e-8 where the lines are well conditioned."""
    n = x.shape[-1]
    X, Y = np.fft.rfft(x), np.fft.rfft(y)                       # (n_avg, 1, nf), (n_avg, n_out, nf)
    l1x2 = float(np.sum(np.abs(x).sum(-1) ** 2))
    l1y2 = np.sum(np.abs(y).sum(-1) ** 2, axis=0)                 # (n_out,)
    with np.errstate(divide="ignore", invalid="ignore"):
        kx = np.sqrt(l1x2 / np.sum(np.abs(X) ** 2, axis=(0, 1)))  # (nf,)
        ky = np.sqrt(l1x2 * l1y2)[:, None] / np.abs(np.sum(np.conj(X) * Y, axis=0))   # (n_out, nf)
    return (1e-8 + 4 * n * np.finfo(float).eps * (kx[None] + ky))[:, None, :]


@settings(max_examples=60, deadline=None)
@given(signal_pairs(), st.floats(1e-3, 1e3), st.sampled_from([1.0, -1.0]))
# found by CI on 2026-12-06: a Nyquist line where the force's samples cancel to 1e-6 of their sum, so that the
# scaled copy's rounding moved H by 3.8e-8 relatively (the former tolerance was 1e-8 on every line)
@example((np.array([[[0.0, 1e-6, 171.0, 171.0, 171.0, 171.0]]]), np.array([[[0.0, 1.0, 1.0, 1.0, 1.0, 1.0]]])),
         3.0, 1.0)
def test_h1_is_invariant_to_scaling_the_hit(xy, c, sign):
    x, y = xy
    c = c * sign
    _, H = h1(x, y, 10.0)
    _, Hs = h1(c * x, c * y, 10.0)          # a harder (or inverted) hit on a linear structure
    _, Hf = h1(c * x, y, 10.0)              # only the force scaled: H1 scales by 1/c
    ok = np.isfinite(H)
    assert np.array_equal(ok, np.isfinite(Hs))
    scale = np.abs(H[ok]).max(initial=0.0) + 1e-300
    rtol = np.broadcast_to(_rounding_rtol(x, y), H.shape)[ok]
    for other in (Hs, Hf * c):
        err = np.abs(other[ok] - H[ok])
        # where G_yx is exactly 0 the bound is infinite and H is 0: there the absolute tolerance alone
        rel = np.multiply(rtol, np.abs(H[ok]), out=np.zeros_like(rtol), where=np.abs(H[ok]) > 0)
        bad = err > 1e-10 * scale + rel
        assert not bad.any(), (other[ok][bad], H[ok][bad], rtol[bad])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), c=st.floats(1e-3, 1e3), n_hits=st.integers(1, 4),
       estimator=st.sampled_from(["H1", "Hv"]))
def test_frf_from_hits_is_invariant_to_the_hit_strength(seed, c, n_hits, estimator):
    # a linear structure hit c times harder: force and response both scale by c, the FRF does not change
    rng = np.random.default_rng(seed)
    s = _chain([1.0, 1.5], [4e4, 6e4], alpha=6.0)
    recs = _hits(s.modal_model(), "1+Z", ["1+Z", "2+Z"], 256.0, 512, 16, rng.uniform(20, 200, n_hits),
                 rng.uniform(4e-4, 8e-4, n_hits), 1e-3, rng, 1)
    strong = [r.copy() for r in recs]
    for r in strong:
        r.data = r.data * c
    kw = dict(estimator=estimator, exp_window=ExponentialWindow(end_level=0.05),
              force_window=ForceWindow(length_s=0.01, taper_s=0.01))
    a, b = estimate_frf(recs, **kw), estimate_frf(strong, **kw)
    np.testing.assert_allclose(b.H, a.H, rtol=1e-8, atol=1e-12 * np.abs(a.H).max())
    np.testing.assert_allclose(b.coherence, a.coherence, atol=1e-9)
    if estimator == "H1":          # only the force scaled (a mis-set hammer sensitivity): H1 scales by 1/c
        weak_force = [r.copy() for r in recs]
        for r in weak_force:
            r.data[0] = r.data[0] * c
        np.testing.assert_allclose(estimate_frf(weak_force, **kw).H * c, a.H, rtol=1e-9,
                                   atol=1e-12 * np.abs(a.H).max())


@settings(max_examples=40, deadline=None)
@given(signal_pairs(), st.floats(1e-2, 1e2))
def test_hv_equals_h1_when_signals_are_exactly_related(xy, gain):
    x, _ = xy
    x = x[:, :1]
    y = gain * np.roll(x, 1, axis=-1)        # a circular delay: exact for the DFT
    _, H1 = h1(x, y, 1.0)
    _, Hv = hv(x, y, 1.0)
    ok = np.isfinite(H1) & (np.abs(H1) > 0)
    X = np.fft.rfft(x, axis=-1)
    strong = (np.abs(X) ** 2).sum(0).ravel() > 1e-6 * (np.abs(X) ** 2).sum(0).max(initial=0) + 1e-300
    m = ok & strong
    np.testing.assert_allclose(Hv[m], H1[m], rtol=1e-6)


# -------------------------------------------------------------------------- reciprocity with noise
def _chain(m, k, alpha):
    n = len(m)
    K = np.zeros((n, n))
    for i, ki in enumerate(k):
        K[i, i] += ki
        if i > 0:
            K[i - 1, i - 1] += ki
            K[i, i - 1] -= ki
            K[i - 1, i] -= ki
    M = np.diag(m)
    return Structure(M=M, K=K, C=alpha * M, dofs=[f"{i + 1}+Z" for i in range(n)])


def _hits(model, hit, resp, fs, n, ti, amps, widths, noise, rng, hit0):
    """Exact band-limited hits: FT of a half-sine times the exact FRF, inverse FFT on an 8x longer grid."""
    L = 8 * n
    f = np.fft.rfftfreq(L, 1 / fs)
    H = model.frf(f, parse_dofs(resp), [Dof.parse(hit)]).H[:, 0, :]
    r = f / (fs / 2)
    G = np.where(r <= 0.55, 1.0, 0.5 * (1 + np.cos(np.pi * np.clip((r - 0.55) / 0.45, 0, 1))))
    out = []
    for h, (a, w) in enumerate(zip(amps, widths)):
        om, W = 2 * np.pi * f, np.pi / w
        F = a * W * (1 + np.exp(-1j * om * w)) / (W ** 2 - om ** 2) * G * np.exp(-1j * om * ti / fs)
        sig = np.fft.irfft(np.vstack([F[None], H * F[None]]), n=L, axis=-1)[:, :n] * fs
        sig += noise * np.abs(sig).max(1, keepdims=True) * rng.standard_normal(sig.shape)
        out.append(TimeRecord(sample_rate_hz=fs, data=sig, dofs=[hit] + list(resp),
                              roles=["force"] + ["response"] * len(resp), trigger_index=ti, hit_id=hit0 + h))
    return out


@settings(max_examples=10, deadline=None)
@given(m=st.lists(st.floats(0.5, 2.0), min_size=3, max_size=3),
       k=st.lists(st.floats(1e4, 1e5), min_size=3, max_size=3),
       seed=st.integers(0, 2 ** 31 - 1))
def test_reciprocity_of_a_symmetric_structure_holds_to_noise(m, k, seed):
    s = _chain(m, k, alpha=6.0)
    mm = s.modal_model()
    rng = np.random.default_rng(seed)
    fs, n, ti, noise, n_avg = 512.0, 2048, 32, 1e-4, 8
    recs = []
    for j, hit in enumerate(["1+Z", "3+Z"]):
        # widths of 0.25 .. 0.4 ms keep the force spectrum free of zeros in the band
        recs += _hits(mm, hit, ["1+Z", "3+Z"], fs, n, ti, rng.uniform(20, 200, n_avg),
                      rng.uniform(2.5e-4, 4e-4, n_avg), noise, rng, 100 * j)
    frf = estimate_frf_roving(recs)
    band = (2.0, 130.0)
    rep = reciprocity_check(frf, band_hz=band, min_coherence=0.99)
    assert len(rep) == 1
    pair = rep.worst
    # enough lines pass the coherence gate for the check to mean something: 35 % of the band at the heaviest and
    # softest chain drawn (m = 2 kg, k = 1e4 N/m everywhere; a grid of 729 chains over the drawn box, 36 % for the
    # next), so 30 % (0.4 failed there, deterministically, whatever the seed)
    assert pair.n_lines > 0.3 * np.sum((frf.freq_hz >= band[0]) & (frf.freq_hz <= band[1]))
    # channel noise of 1e-4 of the peak leaves differences of a few 1e-3 (amplitude-weighted) and
    # about 1 % (line-averaged, low-coherence lines dominate); 1e-5 noise gives ten times less.
    assert pair.norm_rel_diff < 1e-2
    assert pair.rel_diff < 5e-2
    # the check is not blind: a 5 % calibration error in one direction stands out
    frf.H[0, 1] *= 1.05
    assert reciprocity_check(frf, band_hz=band, min_coherence=0.99).worst.norm_rel_diff > 0.04
