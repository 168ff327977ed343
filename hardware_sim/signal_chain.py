"""Pure functions for the analog and digital stages between a sensor and a sample.

Everything here is a transfer function evaluated on a frequency grid, or an
elementwise operation on volts; the simulated lab (:mod:`hardware_sim.lab`)
strings them together:

    force / acceleration  ->  × sensitivity (V/unit)  ->  IEPE AC coupling (high-pass)
      ->  anti-alias filter  ->  sampling at fs  ->  + noise  ->  ADC range (clip, overload)
      ->  24-bit quantisation  ->  ÷ sensitivity (engineering units)

Functions
---------
half_sine               the hammer force pulse in time.
half_sine_spectrum      its continuous Fourier transform (N·s), exact.
iepe_highpass           first-order AC-coupling high-pass ``s/(s+ω_c)``.
antialias_response      delta-sigma (linear phase, brick-wall) or analog Butterworth anti-alias filter.
quantization_step       ADC step ``range/2**(bits-1)``.
quantize                clip to the ADC range and round to the ADC step; returns overload flags.
synthesis_taper         the analog bandwidth of the simulation: a raised-cosine roll-off to zero
                        at the Nyquist frequency of the synthesis grid (no Gibbs ringing).
"""
from __future__ import annotations

import numpy as np
from scipy import signal

from modalab.core.errors import ModalabValueError

__all__ = ["half_sine", "half_sine_spectrum", "iepe_highpass", "antialias_response", "AA_FILTERS",
           "quantization_step", "quantize", "synthesis_taper"]

AA_FILTERS = ("delta-sigma", "butterworth", "none")


def half_sine(t, amplitude: float, width_s: float, t0_s: float = 0.0) -> np.ndarray:
    """Half-sine pulse ``A sin(π (t−t0)/T)`` for ``t0 <= t <= t0+T``, zero elsewhere (N)."""
    t = np.asarray(t, dtype=float)
    x = (t - t0_s) / width_s
    return np.where((x >= 0) & (x <= 1), amplitude * np.sin(np.pi * np.clip(x, 0, 1)), 0.0)


def half_sine_spectrum(freq_hz, amplitude: float, width_s: float, t0_s: float = 0.0) -> np.ndarray:
    """Continuous Fourier transform ``∫ f(t) e^{-iωt} dt`` of :func:`half_sine` (N·s).

    ``F(ω) = A T π (1 + e^{-iωT}) / (π² − (ωT)²) · e^{-iω t0}``, with the removable
    singularity at ``ωT = π`` replaced by its limit ``−i A T / 2``.  ``F(0) = 2AT/π``
    (the impulse of the hit).

    >>> round(float(abs(half_sine_spectrum([0.0], 100.0, 1e-3)[0]) * np.pi / 2), 12)   # A·T
    0.1
    """
    if not width_s > 0:
        raise ModalabValueError(f"pulse width {width_s!r} s must be positive")
    f = np.asarray(freq_hz, dtype=float)
    x = 2 * np.pi * f * width_s                                    # ωT
    den = np.pi ** 2 - x ** 2
    near = np.abs(den) < 1e-6
    safe = np.where(near, 1.0, den)
    F = amplitude * width_s * np.pi * (1 + np.exp(-1j * x)) / safe
    F = np.where(near, -0.5j * amplitude * width_s, F)
    return F * np.exp(-2j * np.pi * f * t0_s)


def iepe_highpass(freq_hz, corner_hz: float) -> np.ndarray:
    """First-order AC-coupling high-pass ``s/(s + 2π f_c)`` of an IEPE conditioner; ones for ``f_c = 0``."""
    f = np.asarray(freq_hz, dtype=float)
    if corner_hz < 0:
        raise ModalabValueError(f"high-pass corner {corner_hz!r} Hz must be >= 0 (0 = DC coupled)")
    if corner_hz == 0:
        return np.ones(f.shape, complex)
    s = 2j * np.pi * f
    return s / (s + 2 * np.pi * corner_hz)


def antialias_response(freq_hz, sample_rate_hz: float, kind: str = "delta-sigma", cutoff: float = 0.45,
                       order: int = 8, stop_db: float = 110.0) -> np.ndarray:
    """Complex response of the anti-alias filter at ``freq_hz``.

    kind='delta-sigma'
        The decimation filter of a delta-sigma DSA card after its delay has been
        compensated: zero phase, flat to ``cutoff·fs`` (pass edge), falling smoothly
        (a C² step in dB) to ``−stop_db`` at ``(1−cutoff)·fs`` (stop edge) and
        staying there.  This is how NI 4431/9234-class inputs behave.
    kind='butterworth'
        An analog Butterworth low-pass of ``order`` with its −3 dB point at
        ``cutoff·fs``, causal, with its phase (older front ends).
    kind='none'
        No filter (everything above fs/2 aliases).
    """
    f = np.asarray(freq_hz, dtype=float)
    if kind not in AA_FILTERS:
        raise ModalabValueError(f"anti-alias filter {kind!r} unknown; expected one of {', '.join(AA_FILTERS)}")
    if kind == "none":
        return np.ones(f.shape, complex)
    if not 0 < cutoff < 0.5:
        raise ModalabValueError(f"anti-alias cutoff {cutoff!r} (fraction of fs) must lie in (0, 0.5); "
                                "0.45 is typical for delta-sigma, 0.39 (fs/2.56) for analog filters")
    fs = float(sample_rate_hz)
    fa = np.abs(f)
    if kind == "delta-sigma":
        fp, fst = cutoff * fs, (1 - cutoff) * fs
        x = np.clip((fa - fp) / (fst - fp), 0.0, 1.0)
        att_db = stop_db * x ** 3 * (10 - 15 * x + 6 * x * x)      # C² 'smootherstep' in dB
        return (10 ** (-att_db / 20)).astype(complex)
    if int(order) < 1:
        raise ModalabValueError(f"Butterworth order {order!r} must be >= 1")
    wc = 2 * np.pi * cutoff * fs
    z, p, k = signal.butter(int(order), wc, analog=True, output="zpk")
    _, h = signal.freqs_zpk(z, p, k, worN=2 * np.pi * fa)
    return np.where(f < 0, np.conj(h), h)


def quantization_step(range_v: float, bits: int = 24) -> float:
    """Voltage of one ADC count: ``range / 2**(bits−1)`` for a ±range bipolar converter."""
    if not range_v > 0:
        raise ModalabValueError(f"ADC range {range_v!r} V must be positive")
    if not 2 <= int(bits) <= 32:
        raise ModalabValueError(f"ADC resolution {bits!r} bits must be within 2..32")
    return float(range_v) / 2.0 ** (int(bits) - 1)


def quantize(volts, range_v: float, bits: int = 24, axis: int = -1):
    """Clip to ±``range_v`` and round to the ADC step.

    Returns ``(quantised volts, overload)`` where ``overload`` is True (reduced
    over ``axis``) when any input reached or exceeded the range.  Codes run
    from ``−2**(bits−1)`` to ``2**(bits−1) − 1`` as in a two's-complement ADC.
    """
    v = np.asarray(volts, dtype=float)
    step = quantization_step(range_v, bits)
    full = 2 ** (int(bits) - 1)
    over = np.any(np.abs(v) >= range_v, axis=axis)
    codes = np.clip(np.round(v / step), -full, full - 1)
    return codes * step, over


def synthesis_taper(freq_hz, nyquist_hz: float, start: float = 0.8) -> np.ndarray:
    """Raised-cosine roll-off from ``start·nyquist_hz`` to zero at ``nyquist_hz`` (real, zero phase).

    The simulated lab multiplies every signal by it: the front end's analog
    bandwidth ends at ``start`` × the synthesis Nyquist frequency, so truncating
    the spectrum there causes no Gibbs ringing.
    """
    fa = np.abs(np.asarray(freq_hz, dtype=float))
    x = np.clip((fa - start * nyquist_hz) / ((1 - start) * nyquist_hz), 0.0, 1.0)
    return 0.5 * (1 + np.cos(np.pi * x))
