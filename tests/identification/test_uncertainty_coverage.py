"""Issue 16 item 4: the stated standard deviations of frequency and damping are calibrated.

Synthetic roving-hammer data with known noise (``roving_lab``: H1-consistent noise and coherence, 5
averages, 30 dB): for a calibrated ±1σ about 68.3 % of the true values fall inside.  Over ``n`` (mode,
realisation) pairs the count inside is binomial, so the observed fraction is accepted within three
binomial standard deviations, ``3·√(0.683·0.317/n)`` (±0.15 for n = 88): a test that fails on an
optimistic std (the noise term alone covered ~50 % here, because of model-error biases of up to 25σ
on some modes) and on a grossly conservative one (the raw order spread covered ~97 %).

Seeds: the combination ``σ² = σ_noise² + s²/n`` (:func:`identification.polymax.combined_std`) was
chosen on seeds 0-5; the test runs on the odd seeds 101..115, never looked at while choosing.
Deterministic: fixed seeds, one BLAS thread (tests/conftest.py).
"""
import numpy as np

from identification import identify
from modalab.core.frf import FRF
from roving_lab import roving_hammer_export

SEEDS = range(101, 117, 2)
P68 = 0.6827


def _run():
    inside_f, inside_z, noise_only_f = [], [], []
    for seed in SEEDS:
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
        noise_only_f.append(np.abs(modes.freq_hz - fn[j]) <= ind["freq_std_noise_hz"])
    return np.concatenate(inside_f), np.concatenate(inside_z), np.concatenate(noise_only_f)


def test_one_sigma_coverage_is_about_68_percent():
    inside_f, inside_z, noise_only = _run()
    n = inside_f.size
    tol = 3 * np.sqrt(P68 * (1 - P68) / n)
    for name, inside in (("frequency", inside_f), ("damping", inside_z)):
        frac = inside.mean()
        assert abs(frac - P68) <= tol, (f"{name}: {frac:.3f} of {n} true values inside ±1σ; expected "
                                        f"{P68:.3f} ± {tol:.3f} (3 binomial std)")
    # the noise term alone is optimistic on these data (biases of the close pair and of the local model)
    assert noise_only.mean() < inside_f.mean()
