"""A roving-hammer test of a plate, simulated as an analyser would export it (test data generator).

Written for the tests on its own (it shares no code with ``identification``): a free plate's
bending modes on a 74-point grid (simply-supported-like sine products, with some modes edited to
make the hard cases of issue 16), three accelerometers (fixed) and a hammer roving over the 74
points.  The analyser exports H1 accelerance with the accelerometers as responses and the hammer
points as references (3 x 74), 0..200 Hz at df = 0.125 Hz, after an exponential force/response
window of decay β: the exported FRF is the transfer function at ``s = iω + β``.

Modes (Hz, ζ):
    13 modes in 0..200 Hz; a close pair 125.2 / 125.6 Hz (0.3 % apart) that the third
    accelerometer does not see (it sits on a nodal line of both), and a 135.3 Hz mode with
    ζ = 0.9 % seen by the first accelerometer only.

Noise: complex Gaussian noise on each FRF with a standard deviation that follows an H1
coherence model ``γ² = SNR/(1+SNR)`` per line, and ``n_averages`` averages, so that the
coherence and the actual scatter agree (Bendat & Piersol eq. 9.73).
"""
from __future__ import annotations

import numpy as np

FREQ_HZ = np.array([18.4, 31.7, 44.9, 57.3, 71.8, 88.6, 104.1, 125.2, 125.6, 135.3, 152.7, 171.4, 188.9])
DAMPING = np.array([0.012, 0.008, 0.010, 0.007, 0.009, 0.011, 0.006, 0.005, 0.007, 0.009, 0.008, 0.010, 0.007])
PAIR = (7, 8)          # indices of the 0.3 % close pair
SINGLE = 9             # index of the mode seen by one accelerometer only
ACCEL_POINTS = (3, 40, 66)     # hammer-point indices where the accelerometers sit (driving points)
BETA = 0.139           # 1/s, the analyser's exponential window


#: participation of the close pair at the first two accelerometers: nearly orthogonal, or alike (MAC ~ 0.9)
PAIR_AT_ACCELS = {"orthogonal": ((0.35, 0.30), (-0.28, 0.33)), "alike": ((0.35, 0.30), (0.33, 0.17))}


def plate_shapes(n_points: int = 74, seed: int = 7, pair: str = "orthogonal", single_amp: float = 0.4):
    """(n_points, 13) real mode shapes, unit modal mass (plate of 1 m x 0.74 m, 10 kg)."""
    rng = np.random.default_rng(seed)
    nx, ny = 10, 8
    xs, ys = np.meshgrid(np.linspace(0.05, 0.95, nx), np.linspace(0.05, 0.69, ny))
    xy = np.column_stack([xs.ravel(), ys.ravel()])[:n_points]
    xy = xy + rng.normal(scale=0.004, size=xy.shape)          # a hand-marked grid is not perfect
    # (m, n) half-wave numbers of each mode
    mn = [(1, 1), (2, 1), (1, 2), (3, 1), (2, 2), (3, 2), (4, 1), (1, 3), (4, 2), (2, 3), (5, 1), (3, 3), (5, 2)]
    phi = np.column_stack([np.sin(m * np.pi * xy[:, 0] / 1.0) * np.sin(n * np.pi * xy[:, 1] / 0.74)
                           for m, n in mn])
    phi /= np.sqrt(10.0 / 4.0)                                 # m = ρ h A / 4 for sine modes
    a1, a2, a3 = ACCEL_POINTS
    # the close pair: the third accelerometer on a nodal line of both
    phi[a3, list(PAIR)] = 0.0
    # the single-reference mode: only the first accelerometer sees it
    phi[[a2, a3], SINGLE] = 0.0
    # the close pair must be seen clearly by the two accelerometers that see it
    (p1, p2), (q1, q2) = PAIR_AT_ACCELS[pair]
    phi[a1, PAIR[0]], phi[a2, PAIR[0]] = p1, p2
    phi[a1, PAIR[1]], phi[a2, PAIR[1]] = q1, q2
    phi[a1, SINGLE] = single_amp
    return phi


def roving_hammer_export(*, seed: int = 0, noise_snr_db: float = 40.0, n_averages: int = 5,
                         beta: float = BETA, freq_hz=None, damping=None, n_points: int = 74,
                         f_max: float = 200.0, df: float = 0.125, pair: str = "orthogonal",
                         single_amp: float = 0.4):
    """The analyser export: dict with ``freq_hz``, ``H`` (3, n_points, n_freq) accelerance, ``coherence``,
    ``responses``/``references`` labels, ``variance`` (the true E|δH|² per line), ``n_averages``,
    ``beta``, the true ``modes`` (freq_hz, damping) and ``shapes`` (n_points, n_modes)."""
    fn = FREQ_HZ if freq_hz is None else np.asarray(freq_hz, float)
    zeta = DAMPING if damping is None else np.asarray(damping, float)
    phi = plate_shapes(n_points, pair=pair, single_amp=single_amp)[:, :fn.size]
    f = np.arange(df, f_max + df / 2, df)
    s = 2j * np.pi * f + beta                                          # windowed: transfer function at iω + β
    wn = 2 * np.pi * fn
    lam = -zeta * wn + 1j * wn * np.sqrt(1 - zeta ** 2)
    acc = list(ACCEL_POINTS)
    # receptance X_ij = Σ φ_i φ_j / (m (s − λ)(s − λ*)), unit modal mass (m = 1)
    G = 1.0 / ((s[None, :] - lam[:, None]) * (s[None, :] - lam.conj()[:, None]))      # (modes, F)
    Hx = np.einsum("ar,jr,rf->ajf", phi[acc], phi, G)                    # (3, n_points, F)
    H = Hx * (s ** 2)[None, None, :]                                    # accelerance
    rng = np.random.default_rng(seed)
    # noise: a level relative to each FRF's RMS with a floor so antiresonances have low coherence
    rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=-1, keepdims=True))
    sigma_one = rms * 10 ** (-noise_snr_db / 20)                        # per-average noise amplitude
    var = sigma_one ** 2 / n_averages * np.ones_like(np.abs(H))         # E|δH|² of the mean of the averages
    e = (rng.normal(size=H.shape) + 1j * rng.normal(size=H.shape)) / np.sqrt(2)
    Hn = H + np.sqrt(var) * e
    # coherence of H1 consistent with that variance: var = (1−γ²)/(n γ²) |H|²
    ratio = var * n_averages / np.maximum(np.abs(H) ** 2, 1e-300)
    coh = 1.0 / (1.0 + ratio)
    responses = [f"{p + 1}+Z" for p in acc]
    references = [f"{p + 1}+Z" for p in range(n_points)]
    return {"freq_hz": f, "H": Hn, "coherence": coh, "responses": responses, "references": references,
            "variance": var, "n_averages": n_averages, "beta": beta,
            "modes": {"freq_hz": fn, "damping": zeta}, "shapes": phi}
