"""Pole uncertainty: first-order std of the refined frequencies and damping ratios (issue #4, item 3).

The Monte Carlo tests draw noise of known variance, give that variance to the fit in
``FRF.variance`` and compare the predicted std with the scatter of the estimates.
"""
import json

import numpy as np

from modalab.app.outputs import write_json
import pytest

from identification import PolyMAX, identify, modal_system
from identification.lsfd import frf_noise_variance, pole_uncertainty, window_corrected_covariance
from identification.stabilisation import pole_freq_damping
from modalab.core.errors import ModalabValueError, ShapeError

FN = np.array([40.0, 95.0, 170.0])          # well separated
ZETA = np.array([0.015, 0.010, 0.020])
F = np.linspace(10.0, 230.0, 500)
N_MC = 30


def _clean(refs=(0,), window_beta=0.0):
    mm, _ = modal_system(FN, ZETA, 6, rng=5, window_beta=window_beta)
    return mm.frf(F, references=[mm.dofs[k] for k in refs], quantity="accelerance")


def _sigma(clean, noise=0.02):
    """Complex noise std per FRF line: ``noise`` × the RMS of each FRF (as identification.synthetic.noisy_frf)."""
    rms = np.sqrt(np.mean(np.abs(clean.H) ** 2, axis=-1, keepdims=True))
    return noise * rms * np.ones(clean.H.shape)


def _noisy(clean, sd, rng, **kw):
    """Noisy copy; ``kw`` are FRF fields (``variance``, ``window_beta_per_s``, ``metadata``)."""
    e = (rng.normal(size=clean.H.shape) + 1j * rng.normal(size=clean.H.shape)) / np.sqrt(2)   # E|e|² = 1
    return clean._replace(H=clean.H + sd * e, **{"metadata": {}, **kw})


def _fit(frf, **kw):
    return PolyMAX(max_order=16, select=list(FN), **kw).fit(frf)


@pytest.mark.parametrize("refs, beta", [((0,), 0.0), ((0, 3), 2 * np.pi * 40 * 0.01)],
                         ids=["one reference", "two references, exponential window"])
def test_monte_carlo_std_matches_prediction(refs, beta):
    clean = _clean(refs, beta)
    sd = _sigma(clean)
    rng = np.random.default_rng(2026)
    f, z, pf, pz, chi = [], [], [], [], []
    for _ in range(N_MC):
        meta = {"variance": sd ** 2, "window_beta_per_s": beta}
        pm = _fit(_noisy(clean, sd, rng, **meta))
        m = pm.modes_
        assert m.metadata["pole_std_source"] == "H_variance"
        f.append(m.freq_hz)
        z.append(m.damping)
        pf.append(m.indicators["freq_std_noise_hz"])
        pz.append(m.indicators["damping_std_noise"])
        chi.append(m.indicators["chi2_ratio"])
    f, z = np.array(f), np.array(z)
    # the window correction is applied: the estimates scatter around the true (unwindowed) values
    np.testing.assert_allclose(f.mean(0), FN, rtol=1e-4)
    np.testing.assert_allclose(z.mean(0), ZETA, rtol=0.02)
    ratio_f = f.std(0, ddof=1) / np.mean(pf, axis=0)
    ratio_z = z.std(0, ddof=1) / np.mean(pz, axis=0)
    msg = f"empirical/predicted std: frequency {ratio_f}, damping {ratio_z}"
    assert np.all((ratio_f > 1 / 1.6) & (ratio_f < 1.6)), msg
    assert np.all((ratio_z > 1 / 1.6) & (ratio_z < 1.6)), msg
    # pooled over the 6 ratios (sd of the log ~5 %): catches a factor √2 in the variance convention
    pooled = np.exp(np.mean(np.log(np.concatenate([ratio_f, ratio_z]))))
    assert 0.8 < pooled < 1.25, msg
    # the given variances are the true ones: chi-square per degree of freedom about 1
    np.testing.assert_allclose(np.mean(chi, axis=0), 1.0, atol=0.1)


def test_std_scales_linearly_with_noise():
    clean = _clean((0, 3))
    sd = _sigma(clean)
    e_rng = np.random.default_rng(7)
    e = (e_rng.normal(size=clean.H.shape) + 1j * e_rng.normal(size=clean.H.shape)) / np.sqrt(2)
    out = {}
    for k in (1.0, 2.0):
        for source in ("H_variance", "residual"):
            var = (k * sd) ** 2 if source == "H_variance" else None
            m = _fit(clean._replace(H=clean.H + k * sd * e, variance=var, metadata={})).modes_
            assert m.metadata["pole_std_source"] == source
            out[k, source] = np.concatenate([m.indicators["freq_std_noise_hz"], m.indicators["damping_std_noise"]])
    for source in ("H_variance", "residual"):
        r = out[2.0, source] / out[1.0, source]
        assert np.all(np.abs(r / 2 - 1) < 0.2), f"{source}: std(2σ)/std(σ) = {r}, expected 2 within 20 %"
    # the residual estimate of the noise (constant per FRF here, as it assumes) agrees with the true variance
    r = out[1.0, "residual"] / out[1.0, "H_variance"]
    assert np.all((r > 0.75) & (r < 1.33)), f"residual-based / variance-based std = {r}"


def test_coherence_model_equals_the_variance_it_implies():
    """Coherence estimated from n averages gives E|δH|² = (1−γ̂²)/((n−1)γ̂²)|Ĥ|² (Bendat & Piersol eq. 9.73,
    both parts, with the bias of the estimated coherence removed)."""
    clean = _clean((0, 3))
    sd = _sigma(clean)
    frf = _noisy(clean, sd, np.random.default_rng(3))
    n = 8
    g2 = 1.0 / (1.0 + (n - 1) * sd ** 2 / np.abs(frf.H) ** 2)     # so that (1−γ²)/((n−1)γ²)|Ĥ|² = σ²
    with_coh = frf._replace(coherence=g2, metadata={"n_averages": n})
    var, source = frf_noise_variance(with_coh)
    assert source == "coherence"
    np.testing.assert_allclose(var, sd ** 2, rtol=1e-9)
    pm = _fit(with_coh)
    ref = pole_uncertainty(pm.frf_, pm.refined_poles_, pm.selected_.participation, noise_variance=sd ** 2)
    assert pm.modes_.metadata["pole_std_source"] == "coherence"
    np.testing.assert_allclose(pm.modes_.indicators["freq_std_noise_hz"], ref["freq_std_hz"], rtol=1e-8)
    np.testing.assert_allclose(pm.modes_.indicators["damping_std_noise"], ref["damping_std"], rtol=1e-8)
    # coherence of a single average is 1 by construction, and without n_averages nothing is known
    for meta in ({"n_averages": 1}, {}):
        assert frf_noise_variance(frf._replace(coherence=g2, metadata=meta)) == (None, "residual")


def test_window_correction_of_the_covariance():
    """Propagation through λ_true = λ_meas + β equals the finite-difference Jacobian of the exact map."""
    wn, z, beta = 2 * np.pi * 40.0, 0.025, 2.5
    cov = np.array([[0.04, 3e-6], [3e-6, 4e-10]])                  # (ω_n rad/s, ζ)

    def corrected(x):
        lam = -x[1] * x[0] + 1j * x[0] * np.sqrt(1 - x[1] ** 2) + beta
        f, zz = pole_freq_damping(lam)
        return np.array([2 * np.pi * f, zz])

    x0 = np.array([wn, z])
    h = np.array([1e-4, 1e-8])
    K = np.stack([(corrected(x0 + h[j] * np.eye(2)[j]) - corrected(x0 - h[j] * np.eye(2)[j])) / (2 * h[j])
                  for j in range(2)], axis=1)
    wt, zt, cov_t = window_corrected_covariance(wn, z, cov, beta)
    np.testing.assert_allclose([wt, zt], corrected(x0), rtol=1e-12)
    np.testing.assert_allclose(cov_t, K @ cov @ K.T, rtol=1e-6)
    # the shift is not a plain carry-over of std ζ: ζ_true ≈ ζ − β/ω_n also scatters with ω_n
    assert abs(np.sqrt(cov_t[1, 1]) / np.sqrt(cov[1, 1]) - 1) > 1e-3
    np.testing.assert_array_equal(window_corrected_covariance(wn, z, cov, 0.0)[2], cov)


def test_identify_json_and_band_selection(tmp_path):
    clean = _clean((0, 3))
    sd = _sigma(clean)
    frf = _noisy(clean, sd, np.random.default_rng(11), variance=sd ** 2)
    # band and reference selection slice the variance with the data (the full-shape array is given)
    modes, report = identify(frf, band_hz=(20, 220), references=[frf.references[1]], max_order=16,
                             select=list(FN))
    assert modes.metadata["pole_std_source"] == "H_variance"
    for k in ("freq_std_hz", "damping_std", "chi2_ratio"):
        assert modes.indicators[k].shape == (3,) and np.all(np.isfinite(modes.indicators[k]))
    assert np.all(modes.indicators["freq_std_hz"] < 0.05 * FN * ZETA)      # well inside the half-power band
    d = json.loads(write_json(tmp_path / "report.json", report.to_dict()).read_text())   # the stage's writer
    assert d["modes"]["std_source"] == "H_variance" and d["settings"]["uncertainty"] is True
    np.testing.assert_allclose(d["modes"]["damping_std"], modes.indicators["damping_std"])
    modes.to_json(tmp_path / "modes.json")
    dm = json.loads((tmp_path / "modes.json").read_text())
    np.testing.assert_allclose(dm["indicators"]["freq_std_hz"], modes.indicators["freq_std_hz"])
    # not requested: nothing computed; without refinement: NaN (the std is that of the refined estimate)
    m_off, r_off = identify(frf, max_order=16, select=list(FN), uncertainty=False)
    assert "freq_std_hz" not in m_off.indicators and "freq_std_hz" not in r_off.to_dict()["modes"]
    m_nr = _fit(frf, refine=False).modes_
    assert np.all(np.isnan(m_nr.indicators["damping_std"]))
    assert "refine=False" in m_nr.metadata["pole_std_source"]


class TestMalformedVariance:
    def _frf(self):
        clean = _clean((0, 3))
        return _noisy(clean, _sigma(clean), np.random.default_rng(1))

    def test_wrong_shape_names_both_shapes(self):
        frf = self._frf()
        with pytest.raises(ShapeError, match=r"variance has shape \(6, 2, 499\); expected \(6, 2, 500\)"):
            frf.variance = np.ones((6, 2, 499))
        with pytest.raises(ShapeError, match=r"variance has shape \(500,\)"):
            frf._replace(variance=np.ones(500))
        assert frf.variance is None                    # a refused value leaves the FRF as it was

    def test_negative_non_finite_and_non_numeric(self):
        frf = self._frf()
        v = np.ones(frf.H.shape)
        v[2, 1, 17] = -0.5
        with pytest.raises(ModalabValueError, match=r"-0\.5 at \(response, reference, line\) \(2, 1, 17\)"):
            frf.variance = v
        v[2, 1, 17] = np.nan
        with pytest.raises(ModalabValueError, match=r"nan at .* \(2, 1, 17\)"):
            frf.variance = v
        with pytest.raises(ModalabValueError, match="variance must be a real array.*got str"):
            frf.variance = "large"

    def test_bad_n_averages(self):
        frf = self._frf()
        frf = frf._replace(coherence=np.full(frf.H.shape, 0.9), metadata={"n_averages": 2.5})
        with pytest.raises(ModalabValueError, match=r"n_averages'\]: got 2\.5; expected a positive integer"):
            frf_noise_variance(frf)


def test_coherence_variance_is_unbiased_on_an_analysers_h1():
    """On H1 and coherence estimated from 5 hits as an analyser does (the roving-plate generator, which shares no
    code with identification), the variance read from coherence matches the true E|Ĥ − H|²: the coherence is
    estimated from the same averages, so (1−γ̂²)/((n−1)γ̂²)|Ĥ|² and not the textbook n (20 % low with n = 5)."""
    from modalab.core.frf import FRF
    from roving_plate import roving_export

    err, pred = 0.0, 0.0
    for seed in (0, 1, 2):
        d = roving_export(n_points=12, seed=seed, n_averages=5)
        frf = FRF(freq_hz=d["freq_hz"], H=d["H"], responses=[f"{n}+Z" for n in d["accel_nodes"]],
                  references=[f"{n}+Z" for n in d["hammer_nodes"]], coherence=d["coherence"],
                  metadata={"n_averages": 5})
        var, source = frf_noise_variance(frf)
        assert source == "coherence"
        err += float(np.sum(np.abs(d["H"] - d["H_exact"]) ** 2))
        pred += float(np.sum(var))
    # ~270 000 lines, but the errors are dominated by the lines with the largest |H|: a few % of scatter;
    # the textbook form gives 1.25 here
    assert abs(err / pred - 1) < 0.08, f"true/predicted FRF noise variance {err / pred:.3f}"
