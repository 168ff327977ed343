"""Quality indicators of identified modes and of the synthesised FRFs.

MPC — modal phase collinearity (Pappa, Elliott & Schenk 1993), in its
eigenvalue form: with ``S = [[Re·Re, Re·Im], [Re·Im, Im·Im]]`` of a shape φ,
``MPC = ((λ₁−λ₂)/(λ₁+λ₂))² = |φᵀφ|² / (φᴴφ)²``; 1 for a real (normal) mode.

MCF — modal complexity factor, ``1 − MPC`` (0 for a normal mode).

MPD — mean phase deviation (degrees): the |φ|-weighted mean angle between
each complex component and the best straight line through the components in
the complex plane (principal direction of ``[Re φ, Im φ]``); 0 for a normal mode.

MOV — mode overcomplexity value (fraction 0..1): with unit-modal-mass
(a-normalised) driving-point residues ``R_oo``, adding mass at DOF o changes
the pole by ``dλ = −λ² R_oo dm``; a physically consistent response lowers the
frequency (``Im dλ < 0``).  MOV is the |R_oo|-weighted fraction of responses
that do; defined only for scaled modes.

Pole uncertainty (``freq_std_hz``, ``damping_std``, ``chi2_ratio`` in ``ModeSet.indicators``):
standard deviations of the refined natural frequency (Hz) and damping ratio — the first-order
propagation of the variance of the FRF lines (:func:`identification.lsfd.pole_uncertainty`, parts
``freq_std_noise_hz``/``damping_std_noise``) combined with the spread of the pole over the stable
orders (parts ``freq_std_orders_hz``/``damping_std_orders``, :func:`identification.polymax.combined_std`)
— and the chi-square ratio of the local fit (about 1 when the FRF noise model fits the scatter).

FRF correlation: ``|H_sᴴH_m|² / (H_sᴴH_s · H_mᴴH_m)`` per FRF (FRAC) and the
relative synthesis error ``‖H_s − H_m‖ / ‖H_m‖``.

Band edges (:func:`edge_resonances`): a resonance of the data whose peak lies within its half-power bandwidth
of an edge of the analysis band is cut by the band: its peak half inside, half outside, it is neither
identified (poles at the edges are dropped) nor modelled as a neighbour, and it biases its neighbours.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import find_peaks, peak_widths
from .stabilisation import mac_vectors

__all__ = ["mpc", "mcf", "mpd", "mov", "frf_correlation", "synthesis_error", "auto_mac", "edge_resonances"]

#: a peak of Σ|H|² counts as a resonance when it stands this far (natural log, ~4.3 dB) above its surroundings
EDGE_PEAK_PROMINENCE = 1.0


def mpc(shapes) -> np.ndarray:
    """Modal phase collinearity of each column (0..1)."""
    phi = np.atleast_2d(np.asarray(shapes, complex))
    num = np.abs(np.sum(phi * phi, axis=0)) ** 2
    den = np.sum(np.abs(phi) ** 2, axis=0) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / den, np.nan)


def mcf(shapes) -> np.ndarray:
    """Modal complexity factor ``1 − MPC``."""
    return 1.0 - mpc(shapes)


def mpd(shapes) -> np.ndarray:
    """Mean phase deviation in degrees (|φ|-weighted)."""
    phi = np.atleast_2d(np.asarray(shapes, complex))
    out = np.full(phi.shape[1], np.nan)
    for k in range(phi.shape[1]):
        v = phi[:, k]
        a = np.abs(v)
        if not np.any(a > 0):
            continue
        X = np.column_stack([v.real, v.imag])
        _, _, Vt = np.linalg.svd(X, full_matrices=False)
        u = Vt[0]
        cross = np.abs(v.real * u[1] - v.imag * u[0])
        with np.errstate(divide="ignore", invalid="ignore"):
            ang = np.arcsin(np.clip(np.where(a > 0, cross / a, 0.0), 0, 1))
        out[k] = np.degrees(np.sum(a * ang) / np.sum(a))
    return out


def mov(lam, driving_residues) -> np.ndarray:
    """Mode overcomplexity value from poles ``lam`` (m,) and driving-point residues ``(n_dp, m)``.

    ``driving_residues[o, r]`` is the residue ``R_oo`` of mode r at a DOF that
    is both response and reference, in unit-modal-mass scaling.
    """
    R = np.atleast_2d(np.asarray(driving_residues, complex))
    lam = np.asarray(lam, complex)
    if R.size == 0:
        return np.full(lam.size, np.nan)
    dlam = -(lam[None, :] ** 2) * R
    w = np.abs(R)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sum(w * (dlam.imag < 0), axis=0) / np.sum(w, axis=0)


def frf_correlation(H_syn, H_meas) -> np.ndarray:
    """FRAC per FRF over the last axis (0..1)."""
    a = np.asarray(H_syn)
    b = np.asarray(H_meas)
    num = np.abs(np.sum(a.conj() * b, axis=-1)) ** 2
    den = np.sum(np.abs(a) ** 2, axis=-1) * np.sum(np.abs(b) ** 2, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / den, np.nan)


def synthesis_error(H_syn, H_meas) -> np.ndarray:
    """Relative synthesis error ``‖H_s − H_m‖ / ‖H_m‖`` per FRF."""
    a = np.asarray(H_syn)
    b = np.asarray(H_meas)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.linalg.norm(a - b, axis=-1) / np.linalg.norm(b, axis=-1)


def auto_mac(shapes) -> np.ndarray:
    """MAC of every pair of columns, ``(m, m)``."""

    phi = np.asarray(shapes)
    return mac_vectors(phi, phi)


def edge_resonances(freq_hz, H, band_hz) -> list[dict]:
    """Resonances of the data cut by an edge of ``band_hz``: peaks of ``Σ|H|²`` over every response and
    reference (prominence :data:`EDGE_PEAK_PROMINENCE` in log) whose frequency lies within one half-power
    bandwidth (the peak's width at half its power, at least one line) of an edge, inside or outside the band.

    ``H``: (..., n_freq) FRFs on the lines ``freq_hz`` (Hz) of the whole measurement, not only the band.
    Returns one dict per cut resonance: ``freq_hz``, ``width_hz``, ``edge`` ('lower'/'upper'), ``edge_hz``
    and ``suggest_hz``: an edge three widths beyond the peak (rounded outwards, within the data; for a lower
    edge with no line that far below the peak, three widths above it), or None when the data end before."""
    f = np.asarray(freq_hz, float)
    lo, hi = float(band_hz[0]), float(band_hz[1])
    if f.size < 5:
        return []
    power = (np.abs(np.asarray(H)) ** 2).reshape(-1, f.size).sum(axis=0)
    ok = np.isfinite(power) & (power > 0)
    if not ok.all():
        power = np.where(ok, power, power[ok].min() if ok.any() else 1.0)
    peaks, _ = find_peaks(np.log(power), prominence=EDGE_PEAK_PROMINENCE)
    peaks = peaks[(peaks > 0) & (peaks < f.size - 1)]
    if not peaks.size:
        return []
    df = float(np.median(np.diff(f)))
    widths = np.maximum(peak_widths(power, peaks, rel_height=0.5)[0] * df, df)
    out = []
    for k, w in zip(peaks, widths):
        fp = float(f[k])
        for edge, e in (("lower", lo), ("upper", hi)):
            if abs(fp - e) <= w:
                step = 10.0 ** np.floor(np.log10(max(3 * w, df)))
                if edge == "upper":
                    s = float(np.ceil((fp + 3 * w) / step) * step)
                    s = s if s <= f[-1] else None
                else:                  # below the peak; when the data start too close, above it (left out)
                    s = float(np.floor((fp - 3 * w) / step) * step)
                    s = s if s > f[0] else float(np.ceil((fp + 3 * w) / step) * step)
                out.append({"freq_hz": fp, "width_hz": float(w), "edge": edge, "edge_hz": e, "suggest_hz": s})
    return out
