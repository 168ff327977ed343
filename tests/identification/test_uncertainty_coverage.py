"""Issue 16 item 4: the stated standard deviations of frequency and damping are calibrated.

For a calibrated ±1σ about 68.3 % of the true values fall inside.  Over ``n`` (mode, realisation) pairs the
count inside is binomial, so the observed fraction is accepted within three binomial standard deviations,
``3·√(0.683·0.317/n)``: a test that fails on an optimistic std and on a grossly conservative one.

Main test: the roving plate (``roving_plate``: finite-difference orthotropic plate, non-proportional
damping, H1 and coherence *estimated* from 5 hits as an analyser does, a 0.3 % close pair and modes near
both band edges; it shares no code with ``identification``).  Before issue 16's fix 45 % (frequency) and
36 % (damping) of the truths were inside ±1σ there: the local refinement cut through neighbours just beyond
its band edges (biases up to 55σ).  The σ combination (:func:`identification.polymax.combined_std`) was
chosen on seeds 0-11 and 101-147 (odd); seeds 201-247 (odd, 336 pairs) gave 73.5 % / 71.1 % inside ±1σ,
96.7 % / 97.6 % inside ±2σ; the seeds here (301-323 odd) were not used for any choice.

Second test: ``roving_lab`` (modal superposition with noise drawn from the *true* coherence, which an
analyser never exports): the coherence-based noise variance assumes an estimated coherence (n − 1, see
:func:`identification.lsfd.frf_noise_variance`), so σ is conservative there by about √(5/4); the test
checks it is not optimistic and not grossly conservative (±2σ below 100 % is not required).
Deterministic: fixed seeds, one BLAS thread (tests/conftest.py).
"""
import numpy as np

from identification import identify
from modalab.core.frf import FRF
from roving_lab import roving_hammer_export
from roving_plate import roving_export, true_modes

P68 = 0.6827


def _tol(n):
    return 3 * np.sqrt(P68 * (1 - P68) / n)


def test_one_sigma_coverage_on_the_roving_plate():
    ft, zt, _ = true_modes()
    zf, zz, noise_f = [], [], []
    for seed in range(301, 325, 2):
        d = roving_export(n_points=40, seed=seed)
        frf = FRF(freq_hz=d["freq_hz"], H=d["H"], responses=[f"{n}+Z" for n in d["accel_nodes"]],
                  references=[f"{n}+Z" for n in d["hammer_nodes"]], coherence=d["coherence"],
                  window_beta_per_s=d["beta"], metadata={"n_averages": 5}).transpose()
        modes, _ = identify(frf)
        assert modes.metadata["pole_std_source"] == "coherence"
        assert modes.n_modes == ft.size, np.round(modes.freq_hz, 3)
        j = np.argmin(np.abs(modes.freq_hz[None, :] - ft[:, None]), axis=1)
        assert np.unique(j).size == ft.size and np.all(np.abs(modes.freq_hz[j] / ft - 1) < 1e-3)
        ind = modes.indicators
        zf.append(np.abs(modes.freq_hz[j] - ft) / ind["freq_std_hz"][j])
        zz.append(np.abs(modes.damping[j] - zt) / ind["damping_std"][j])
        noise_f.append(np.abs(modes.freq_hz[j] - ft) / ind["freq_std_noise_hz"][j])
    zf, zz = np.concatenate(zf), np.concatenate(zz)
    n = zf.size
    for name, z in (("frequency", zf), ("damping", zz)):
        frac = np.mean(z <= 1)
        assert abs(frac - P68) <= _tol(n), (f"{name}: {frac:.3f} of {n} true values inside ±1σ; expected "
                                            f"{P68:.3f} ± {_tol(n):.3f} (3 binomial std)")
        frac2 = np.mean(z <= 2)
        assert abs(frac2 - 0.9545) <= 3 * np.sqrt(0.9545 * 0.0455 / n), f"{name}: {frac2:.3f} inside ±2σ"
    # the noise term alone is optimistic here (the pair and the modes below the band edge)
    assert np.mean(np.concatenate(noise_f) <= 1) < np.mean(zf <= 1)


def test_coverage_with_true_coherence_is_not_optimistic():
    inside_f, inside_z = [], []
    for seed in range(101, 117, 2):
        d = roving_hammer_export(seed=seed, noise_snr_db=30.0)
        frf = FRF(freq_hz=d["freq_hz"], H=d["H"], responses=d["responses"], references=d["references"],
                  coherence=d["coherence"], window_beta_per_s=d["beta"], metadata={"n_averages": d["n_averages"]})
        modes, _ = identify(frf, band_hz=(40.0, 200.0))
        assert modes.metadata["pole_std_source"] == "coherence"
        fn, zeta = d["modes"]["freq_hz"], d["modes"]["damping"]
        fn_in = fn[fn > 41.0]
        assert modes.n_modes == fn_in.size, np.round(modes.freq_hz, 3)
        j = np.searchsorted(fn, fn_in)
        ind = modes.indicators
        inside_f.append(np.abs(modes.freq_hz - fn[j]) <= ind["freq_std_hz"])
        inside_z.append(np.abs(modes.damping - zeta[j]) <= ind["damping_std"])
        # the noise model over-states this generator's noise by n/(n-1): chi-square about (n-2)/n = 0.6
        assert abs(np.median(ind["chi2_ratio"]) - 0.6) < 0.1, np.round(ind["chi2_ratio"], 2)
    for name, inside in (("frequency", np.concatenate(inside_f)), ("damping", np.concatenate(inside_z))):
        n = inside.size
        assert P68 - _tol(n) <= inside.mean() <= 0.95, f"{name}: {inside.mean():.3f} of {n} inside ±1σ"
