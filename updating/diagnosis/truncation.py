"""What a record cut off: the tails of lightly damped modes that outlive the record of a measured FRF, restored.

A mode of pole λ whose response starts at ``t0`` in a record of length ``T = 1/Δf`` (the hit, ``t0`` the
pretrigger) and is seen through an exponential window ``e^{−β(t − t0)}`` (β = 0 without one) is transformed at
the lines ``s_k = iω_k + β`` of the spectral estimate as

    A [s_k^q − λ^q e^{(λ − β)(T − t0)} e^{iω_k t0}] / (s_k − λ),

``A`` its receptance residue and ``q`` the derivative measured (2: accelerance): the untruncated FRF minus the
transform of the tail ``A λ^q e^{λt}``, ``t > T − t0``, cut off at the record's end (the DFT of a truncated
exponential; ``e^{−iω_k T} = 1`` at the lines).  It is not a multiple of the untruncated FRF: the factor
``e^{iω_k t0}`` turns once per ``1/t0`` Hz, so no residual term of the modal fits (real coefficients of powers
of s) holds it.  On the demo structure's exact, unwindowed data (4 s, ζ = 1 %) the cut reads the FRFs −72 %
at the 1 Hz bounce mode, −25 % at 5-10 Hz and +4 % at 10-14 Hz, and it moved every E and ρ of the exact model
in the FRF diagnosis by −0.14..−0.27 % (3.5-7.6 std); with the tails restored here the FRFs are within 0.7 %
rms above the bounce mode's lines (3.25 Hz), 0.3 % above 5 Hz, and E and ρ within 0.005 % (0.7 std).

:func:`restore_tails` fits, on the lines up to halfway from the highest such mode to the next peak, every FRF
by those modes with the truncated form above (their poles from the peaks, :func:`peak_poles`; ``t0`` by a
one-dimensional search of the fit's misfit, :func:`trigger_time`, since the FRF file does not carry it) and a
polynomial residual, then adds the fitted tails back.  A mode that keeps more than :data:`UNRESOLVED` of its
response past the record's end is restored too (its tail reaches the lines above it), but its own lines, up to
halfway to the next peak, are to be left out (:attr:`Restored.cut_hz`): the tail is there several times the data
and its error several times that of the pole, which a record of a few periods of it does not resolve (the 1 Hz
bounce mode of the demo, 77 % left at 4 s, restored to −3 % at 1-2 Hz, +0.3 % at 2-5 Hz).

References: A. Brandt, *Noise and Vibration Analysis*, Wiley 2011 (leakage of impact tests whose response has
not died out); K. Fladung & R. Rost, "Application and correction of the exponential window for frequency
response functions", *Mech. Syst. Signal Process.* 11(1), 1997 (a window as a shift of the lines to
``s = iω + β``).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.signal import find_peaks

from modalab.core.frf import FRF
from updating.diagnosis.testmodes import refine_pole

log = logging.getLogger(__name__)
__all__ = ["Restored", "restore_tails", "peak_poles", "trigger_time", "RESTORE_FROM", "RESTORED_SHARE", "TAIL_MIN",
           "UNRESOLVED", "SHARP"]

#: share of its response a mode keeps at the record's end above which the record's tails are restored (the
#: level ``fit.LEAKAGE_WARN`` warns at): below it the fit's leakage bound (``fit.decay_leakage``, counted as
#: noise) covers them, as for the usual exponential windows (1-5 % left; the concealed cases' windowed 8 s
#: records keep at most 2.2 % and are left as they were)
RESTORE_FROM = 0.05
#: share left below which a mode's tail is not restored (once a record is): on the demo's exact unwindowed data
#: 0.05 instead (the 15.7 Hz mode's 2 % left alone) read the FRFs 2 % off at 10-30 Hz and left E and ρ at
#: −0.02..+0.005 % (at most 1.6 std) instead of 0.000..+0.005 % (at most 1.1 std; both with the restored
#: modes' leakage bound counted in full, before :data:`RESTORED_SHARE`)
TAIL_MIN = 0.01
#: share of a restored mode's leakage bound (``fit.decay_leakage``) left to count as noise: the restoration
#: leaves a few hundredths of the cut (demo: 0.07 % of 25 % at 5-10 Hz, 0.3 % of 6.6 % at 10-14 Hz, 0.7 % of
#: 31 % at 3.25-5 Hz), a tenth is counted
RESTORED_SHARE = 0.1
#: share left at the record's end above which a mode's own lines are left out (:attr:`Restored.cut_hz`)
UNRESOLVED = 0.5
#: a peak of the summed power is a mode that outlives the record only when its half-power width is at most this
#: many times what such a mode gives: its own half-power width plus the two lines either side of the peak line
#: (the demo's exact unwindowed records, 4 s and 16 s: 0.8-1.0 times for the modes that keep more than
#: :data:`TAIL_MIN`; 1300 times for the broad hump of the summed power at 630 Hz whose local fit gave ζ = 10⁻⁵)
SHARP = 2.0
_Q = {"receptance": 0, "mobility": 1, "accelerance": 2}


@dataclass
class Restored:
    """:func:`restore_tails`' result: the FRF with the tails added back (``frf``), the modes restored
    (``poles``, rad/s), the hit's time in the record (``t0``, s), and the frequency (Hz) up to which lines are
    dominated by a mode too far from decayed to restore (0: none)."""

    frf: FRF
    poles: np.ndarray
    t0: float = 0.0
    cut_hz: float = 0.0


def peak_poles(frf: FRF, quantity: str) -> np.ndarray:
    """Poles (rad/s) of the peaks of the summed power of ``frf`` as ``quantity``, refined between the lines
    (:func:`~updating.diagnosis.testmodes.refine_pole`); lines at or below 0 Hz and without a finite value are
    left out.  Empty when fewer than 8 lines remain."""
    return np.array([p for p, _ in _peaks(frf, quantity)], complex)


def _peaks(frf: FRF, quantity: str) -> list:
    """:func:`peak_poles` with the half-power width (Hz) of each pole's peak of the summed power: a list of
    ``(pole, width)``; a peak whose half-power points lie beyond the lines has the band it spans."""
    f = frf.band(max(float(frf.freq_hz[0]), 1e-9), None) if frf.freq_hz[0] <= 0 else frf
    rec = f.to(quantity)
    ok = np.all(np.isfinite(rec.H), axis=(0, 1))
    if np.count_nonzero(ok) < 8:
        return []
    if not ok.all():
        rec = rec.lines(ok)
    P = np.sum(np.abs(rec.H) ** 2, axis=(0, 1))
    lg = np.log10(P + 1e-300)
    pk, _ = find_peaks(lg, prominence=0.05 * max(float(np.ptp(lg)), 1e-12))
    out = []
    for k, i in enumerate(pk):
        p = refine_pole(rec.s, rec.H, P, int(i), int(pk[k - 1]) if k else 0,
                        int(pk[k + 1]) if k + 1 < pk.size else P.size - 1)
        if p is not None:
            above = np.flatnonzero(P[i:] <= P[i] / 2)
            below = np.flatnonzero(P[:i + 1] <= P[i] / 2)
            hi = rec.freq_hz[i + above[0]] if above.size else rec.freq_hz[-1]
            lo = rec.freq_hz[below[-1]] if below.size else rec.freq_hz[0]
            out.append((p, float(hi - lo)))
    return out


def _columns(frf: FRF, lam, t0: float, T: float):
    """Real design columns of the truncated modes ``lam`` (a pair per mode: ``Re A``, ``Im A`` with the
    conjugate pole's term tied to it) and of their tails, on the lines of ``frf``: two (n_lines, 2m) arrays."""
    s, beta, q = frf.s, float(frf.window_beta_per_s), _Q[frf.quantity]
    turn = np.exp(2j * np.pi * frf.freq_hz * t0)
    fit, tail = [], []
    for lr in np.asarray(lam, complex):
        parts = []
        for p in (lr, np.conj(lr)):
            t = np.exp((p - beta) * (T - t0)) * turn * p ** q / (s - p)
            parts.append((s ** q / (s - p) - t, t))
        (a, ta), (b, tb) = parts
        fit += [a + b, 1j * (a - b)]
        tail += [ta + tb, 1j * (ta - tb)]
    return np.stack(fit, 1), np.stack(tail, 1)


def _solve(frf: FRF, lam, t0: float, T: float):
    """Least-squares fit of every FRF of ``frf`` by the truncated modes and a residual ``s^(q−2), s^q, s^(q+2)``
    (complex coefficients): ``(coefficients of the modes (2m, n_frf), relative misfit)``."""
    A, _ = _columns(frf, lam, t0, T)
    q = _Q[frf.quantity]
    poly = np.stack([frf.s ** k for k in (q - 2, q, q + 2)], 1)
    B = np.concatenate([A, poly, 1j * poly], axis=1)
    Br = np.concatenate([B.real, B.imag], axis=0)
    Y = frf.H.reshape(-1, frf.freq_hz.size).T
    Yr = np.concatenate([Y.real, Y.imag], axis=0)
    scale = np.linalg.norm(Br, axis=0)
    X, *_ = np.linalg.lstsq(Br / scale, Yr, rcond=None)
    misfit = np.linalg.norm(Yr - (Br / scale) @ X) / max(np.linalg.norm(Yr), 1e-300)
    return (X / scale[:, None])[:A.shape[1]], float(misfit)


def trigger_time(frf: FRF, lam, T: float) -> float:
    """The time ``t0`` (s) of the hit in the record that fits the truncated modes ``lam`` best: a grid over the
    first quarter of the record, fine enough that ``e^{iωt0}`` turns by at most π/4 between its points on the
    lines of ``frf`` (at most 401 points), then a bounded search around the grid's best point."""
    n = int(min(400, np.ceil(0.25 * T * 8 * float(np.max(frf.freq_hz))))) + 1
    grid = np.linspace(0.0, 0.25 * T, max(n, 41))
    k = int(np.argmin([_solve(frf, lam, t, T)[1] for t in grid]))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    return float(minimize_scalar(lambda t: _solve(frf, lam, t, T)[1], bounds=(lo, hi), method="bounded").x)


def restore_tails(frf: FRF) -> Restored:
    """``frf`` with the tails of the modes that outlive its record added back (see the module docstring): every
    mode that keeps more than :data:`TAIL_MIN` of its response at the record's end, once one keeps more than
    :data:`RESTORE_FROM`.  FRFs whose metadata name no spectral estimator (synthesised), or where no mode keeps
    that much, come back as given."""
    if not frf.metadata.get("estimator") or frf.freq_hz.size < 8 or frf.quantity not in _Q:
        return Restored(frf, np.zeros(0, complex))
    pos = frf.freq_hz > 0
    T = 1.0 / float(np.min(np.diff(frf.freq_hz)))
    peaks = _peaks(frf, "accelerance")          # the receptance's rising low end hides a bounce mode's peak
    lam = np.array([p for p, _ in peaks], complex)
    left = np.exp((lam.real - float(frf.window_beta_per_s)) * T)
    # a mode that outlives the record shows a peak a few lines wide: its own half-power width |Re λ|/π, within
    # the two lines either side that sample it.  A pole far narrower than its peak is a local fit's artefact
    # (16 s exact demo records: a 176 Hz wide hump of the summed power at 630 Hz refined to ζ = 10⁻⁵, which
    # counted as 62 % left and cut every line), not a mode the record cut off
    wide = np.array([w > SHARP * (-p.real / np.pi + 2 / T) for p, w in peaks], bool)
    odd = wide & (left > TAIL_MIN)
    if np.any(odd):
        log.info("the peaks at %s Hz (%s Hz wide) are wider than their refined poles allow: not taken for modes "
                 "that outlive the record", ", ".join(f"{v:.4g}" for v in lam[odd].imag / (2 * np.pi)),
                 ", ".join(f"{w:.3g}" for (_, w), b in zip(peaks, odd) if b))
    left = np.where(wide, 0.0, left)
    slow = lam[left > TAIL_MIN]
    if not np.any(left > RESTORE_FROM):
        return Restored(frf, np.zeros(0, complex))
    band = pos & (frf.freq_hz <= _halfway(lam, slow))
    sub = frf.lines(band)
    t0 = trigger_time(sub, slow, T)
    X, _ = _solve(sub, slow, t0, T)
    H = frf.H.copy()
    _, tails = _columns(frf.lines(pos), slow, t0, T)
    H[..., pos] += (tails @ X).T.reshape(H[..., pos].shape)
    log.info("restored the record's cut tails of the modes at %s Hz (the hit %.4g s into the %.3g s record)",
             ", ".join(f"{v:.3g}" for v in slow.imag / (2 * np.pi)), t0, T)
    return Restored(frf._replace(H=H), slow, t0, _halfway(lam, lam[left > UNRESOLVED]))


def _halfway(lam, which) -> float:
    """Frequency (Hz) halfway from the highest pole of ``which`` to the next pole of ``lam`` above it (three
    times its frequency when none); 0 when ``which`` is empty."""
    if np.size(which) == 0:
        return 0.0
    top = float(np.max(np.asarray(which).imag))
    above = lam.imag[lam.imag > top * (1 + 1e-6)]
    return (top + (float(above.min()) if above.size else 3 * top)) / (4 * np.pi)
