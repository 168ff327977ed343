"""Time windows for impact testing and the damping they add.

Two windows are used on hammer hits (Ewins 2000, ch. 3; Brandt 2011, ch. 13):

Force window (:func:`force_window`, spec :class:`ForceWindow`)
    Applied to the force channel(s) only.  It is 1 over the pulse and zero
    over the rest of the record, where the force signal holds nothing but
    noise (and the hammer's ringing).  The flat part starts ``lead_s`` seconds
    *before* the trigger, so the rising edge of the pulse that precedes the
    trigger-level crossing is kept, and lasts ``length_s`` seconds (or
    ``fraction`` of the record) after the trigger; a half-cosine (Hann) taper of
    ``taper_s`` seconds (or ``taper`` × the flat part) follows the flat part and, when
    the flat part does not begin at the first sample, a taper of the same width
    precedes it.  Samples before the lead-in are zeroed: pretrigger noise is not
    force.  As long as the window is 1 over the whole pulse it changes nothing but
    the noise, so it does not disturb the exponential window's exact pole shift.

    An AC-coupled force channel (IEPE conditioner, high-pass ``s/(s+ω_c)``) holds more than noise after
    the pulse: the coupling's undershoot ``−A ω_c e^{−ω_c t}`` (``A`` the pulse's impulse), which the
    response channels keep through the same coupling.  Cutting it from the force alone divides the FRF by
    the part of the coupling the window kept: measured on the demo structure (corner 0.5 Hz, window 0.2 s)
    +16..+22 % at 0.1-2 Hz, −3.4..−4 % at 2-5 Hz and ±2 % up to 15 Hz, exponential window or not; it
    raised every E and ρ of the exact demo model together by 0.4-0.6 % in ``modalab diagnose`` of
    unwindowed FRFs (issue 14 #2).  Given the corner (a record's
    ``metadata['highpass_hz']``), :func:`windowed_force` windows the force with the coupling undone and
    then puts it back, so the undershoot of the kept pulse stays and only noise is cut.

Exponential window (:func:`exponential_window`, spec :class:`ExponentialWindow`)
    Applied to force *and* response alike:

        w(t) = exp(−β (t − t₀)),      t₀ = trigger instant = trigger_index / fs,

    for every sample of the record.  With ``before_trigger='extend'`` (the
    default) the same exponential continues into the pretrigger, where it is
    slightly above 1 (at most ``exp(β·t₀)``, e.g. 1.005 for β = 5 1/s and 1 ms of
    pretrigger); with ``'one'`` it is clamped to 1 there.  There is **no
    amplitude normalisation** (pyFRF scales the window, which multiplies the FRF
    by a constant of ~4.6; here the window's value at the trigger is exactly 1).

    Because ``e^{−βt}(h∗f) = (e^{−βt}h)∗(e^{−βt}f)`` for every t, the FRF
    computed from windowed force and response is *exactly* the FRF of the
    structure evaluated at ``s = iω + β``: every pole ``λ_k`` moves to
    ``λ_k − β`` with its residue unchanged (for the quantity measured).  In
    damping terms (viscous pole ``λ = −ζω_n + iω_n√(1−ζ²)``)

        σ_true = σ_meas − β,          ζ_true ≈ ζ_meas − β / ω_n,

    which :func:`correct_damping` and :func:`correct_poles` apply.  With
    ``before_trigger='extend'`` the identity holds even when the force pulse
    starts before the trigger sample; with ``'one'`` it holds when force and
    response are zero before the trigger.

    Note for accelerance: the unchanged residues are those of the *measured*
    quantity.  The windowed accelerance equals ``(iω+β)²·Σ R_k/(iω−λ_k+β)``
    (``R_k`` receptance residues), which differs by O(β/ω) from the shifted
    receptance model multiplied by ``(iω)²``.  Identification that fits the
    measured quantity directly is unaffected.

The window's β is either given (1/s) or derived from the residual level it must
reach at the last sample of the record: ``β = −ln(end_level) / T`` with
``T = (n_samples − 1 − trigger_index) / fs`` the time from the trigger to the
last sample.  The thesis' tests (section 5.3, Table 7) used a force-exponential
window with a "cut-off" of 1.5 % over 10.24 s records; read as the exponential's level at
the record end that is ``end_level=0.015``, β ≈ 0.41 1/s.

References
----------
D. J. Ewins, *Modal Testing: Theory, Practice and Application*, 2nd ed., 2000, ch. 3 (impact excitation).
A. Brandt, *Noise and Vibration Analysis*, Wiley 2011, ch. 13 (impact excitation and its windows).
W. Fladung, R. Rost, "Application and correction of the exponential window for frequency
response functions", Mechanical Systems and Signal Processing 11(1), 1997, 23-36.
"""
from __future__ import annotations

import logging
from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np
from scipy.signal import lfilter

from modalab.core.errors import ModalabValueError
from modalab.core.frf import check_window_beta

__all__ = [
    "ForceWindow",
    "ExponentialWindow",
    "ExpWindowResult",
    "force_window",
    "windowed_force",
    "exponential_window",
    "beta_from_end_level",
    "correct_damping",
    "correct_poles",
]

log = logging.getLogger(__name__)


def _check_record(n_samples, sample_rate_hz, trigger_index):
    n = int(n_samples)
    if n < 2:
        raise ModalabValueError(f"n_samples={n_samples!r} is too short; a window needs at least 2 samples")
    fs = float(sample_rate_hz)
    if not np.isfinite(fs) or fs <= 0:
        raise ModalabValueError(f"sample_rate_hz={sample_rate_hz!r} must be a positive number of samples per second")
    ti = int(trigger_index)
    if ti < 0 or ti >= n:
        raise ModalabValueError(f"trigger_index={trigger_index!r} is outside the record of {n} samples; "
                                "give the number of pretrigger samples (0 <= trigger_index < n_samples)")
    return n, fs, ti


# ---------------------------------------------------------------------------------------------- force window
@dataclass(frozen=True)
class ForceWindow:
    """Parameters of a force window; see :func:`force_window`.

    Give exactly one of ``length_s`` (s after the trigger) or ``fraction``
    (of the record duration, measured from the trigger).  The half-cosine taper is
    ``taper_s`` seconds wide, or ``taper`` × the flat part's duration (give at most one);
    ``lead_s`` is how long before the trigger the window opens (``None``: at the first
    sample, the whole pretrigger kept).
    """

    length_s: float | None = None
    fraction: float | None = None
    taper_s: float = 0.0
    lead_s: float | None = None
    taper: float | None = None

    def __post_init__(self):
        if (self.length_s is None) == (self.fraction is None):
            raise ModalabValueError(
                f"ForceWindow(length_s={self.length_s!r}, fraction={self.fraction!r}): give exactly one of "
                "length_s (seconds after the trigger) or fraction (of the record, 0 < fraction <= 1)")
        if self.length_s is not None and not (np.isfinite(self.length_s) and self.length_s > 0):
            raise ModalabValueError(f"force window length_s={self.length_s!r} must be a positive duration in s")
        if self.fraction is not None and not (0 < self.fraction <= 1):
            raise ModalabValueError(f"force window fraction={self.fraction!r} must lie in (0, 1]; "
                                    "e.g. 0.1 keeps the first 10 % of the record after the trigger")
        if not (np.isfinite(self.taper_s) and self.taper_s >= 0):
            raise ModalabValueError(f"force window taper_s={self.taper_s!r} must be >= 0 s")
        if self.taper is not None:
            if not (np.isfinite(self.taper) and self.taper >= 0):
                raise ModalabValueError(f"force window taper={self.taper!r} must be >= 0 (a fraction of the flat part)")
            if self.taper_s:
                raise ModalabValueError(f"ForceWindow(taper_s={self.taper_s!r}, taper={self.taper!r}): give the taper "
                                        "width once, in seconds (taper_s) or as a fraction of the window (taper)")
        if self.lead_s is not None and not (np.isfinite(self.lead_s) and self.lead_s >= 0):
            raise ModalabValueError(f"force window lead_s={self.lead_s!r} must be >= 0 s (or None for the "
                                    "whole pretrigger)")

    def array(self, n_samples: int, sample_rate_hz: float, trigger_index: int = 0) -> np.ndarray:
        """The window for one record (see :func:`force_window`)."""
        return force_window(n_samples, sample_rate_hz, trigger_index=trigger_index, length_s=self.length_s,
                            fraction=self.fraction, taper_s=self.taper_s, lead_s=self.lead_s, taper=self.taper)

    def to_dict(self) -> dict:
        return {"type": "force", **asdict(self)}


def force_window(n_samples: int, sample_rate_hz: float, *, trigger_index: int = 0, length_s: float | None = None,
                 fraction: float | None = None, taper_s: float = 0.0, lead_s: float | None = None,
                 taper: float | None = None) -> np.ndarray:
    """Force window: rectangular around the pulse with half-cosine tapers.

    Parameters
    ----------
    n_samples : record length in samples.
    sample_rate_hz : sampling rate in Hz.
    trigger_index : sample of the trigger instant t₀ (= number of pretrigger samples).
    length_s : duration of the flat part after the trigger, in s.
    fraction : alternatively, that duration as a fraction of the record after the trigger
        (``fraction * (n_samples - trigger_index) / fs``).
    taper_s : width of the half-cosine taper after the flat part (and before it, when the
        flat part opens after the first sample), in s.  0 gives a hard rectangle.
    lead_s : the flat part opens ``lead_s`` s before the trigger (clipped to the record start);
        ``None`` opens it at the first sample, keeping the whole pretrigger.
    taper : alternatively to ``taper_s``, the taper width as a fraction of the flat part after the
        trigger (``taper * length_s``).

    Returns
    -------
    w : (n_samples,) float array in [0, 1]; 1 on samples ``i`` with
        ``t₀ − lead_s <= i/fs <= t₀ + length_s``, tapering to 0 within ``taper_s`` outside that
        interval, 0 elsewhere.

    Examples
    --------
    >>> w = force_window(1000, 1000.0, trigger_index=10, length_s=0.05, taper_s=0.01)
    >>> float(w[10]), float(w[60]), float(w[80])
    (1.0, 1.0, 0.0)
    """
    n, fs, ti = _check_record(n_samples, sample_rate_hz, trigger_index)
    spec = ForceWindow(length_s=length_s, fraction=fraction, taper_s=taper_s, lead_s=lead_s, taper=taper)
    if spec.length_s is not None:
        flat_s = spec.length_s
    else:
        flat_s = spec.fraction * (n - ti) / fs
    t = (np.arange(n) - ti) / fs                      # time from the trigger, s
    start = t[0] if spec.lead_s is None else max(-spec.lead_s, t[0])
    stop = flat_s
    w = np.zeros(n)
    w[(t >= start - 1e-12 / fs) & (t <= stop + 1e-12 / fs)] = 1.0
    tap = spec.taper_s if spec.taper is None else spec.taper * flat_s
    if tap > 0:
        after = (t > stop) & (t < stop + tap)
        w[after] = 0.5 * (1 + np.cos(np.pi * (t[after] - stop) / tap))
        if start > t[0]:
            before = (t < start) & (t > start - tap)
            w[before] = 0.5 * (1 + np.cos(np.pi * (start - t[before]) / tap))
    return w


def windowed_force(x, window, sample_rate_hz: float, highpass_hz: float = 0.0) -> np.ndarray:
    """A force window applied to force samples ``x`` (last axis time) recorded through an AC coupling.

    ``highpass_hz`` 0 (DC-coupled, or no coupling known): ``x · window``.  Otherwise the first-order
    coupling ``s/(s+ω_c)``, ``ω_c = 2π·highpass_hz``, is undone (its bilinear inverse ``1 + ω_c/s``, a
    running integral from rest at the first sample), the window applied to the force that remains, and the
    coupling applied again (its bilinear form, the exact inverse of the first step): inside the window the
    samples come back unchanged, after it the undershoot of the pulse the window kept continues as the
    coupling makes it (its pole ``(1 − ω_c h/2)/(1 + ω_c h/2)``, ``e^{−ω_c h}`` to third order in
    ``ω_c h``) while the noise there is cut.  The response channels, which pass the same coupling whole,
    then divide into the structure's FRF (see the module docstring for what cutting the undershoot does).
    """
    x = np.asarray(x, dtype=float)
    w = np.asarray(window, dtype=float)
    fc = float(highpass_hz)
    if not (np.isfinite(fc) and fc >= 0):
        raise ModalabValueError(f"AC-coupling corner {highpass_hz!r} Hz must be >= 0 (0 = DC coupled)")
    if fc == 0:
        return x * w
    a = np.pi * fc / float(sample_rate_hz)           # ω_c h / 2
    hp_b, hp_a = np.array([1.0, -1.0]) / (1 + a), np.array([1.0, (a - 1) / (1 + a)])
    force = lfilter(hp_a, hp_b, x, axis=-1)            # (1 + ω_c/s), bilinear: the coupling undone
    return lfilter(hp_b, hp_a, force * w, axis=-1)


# --------------------------------------------------------------------------------------- exponential window
def beta_from_end_level(end_level: float, n_samples: int, sample_rate_hz: float, trigger_index: int = 0) -> float:
    """Decay rate β (1/s) that brings the exponential window to ``end_level`` at the last sample.

    ``β = −ln(end_level) / T`` with ``T = (n_samples − 1 − trigger_index) / fs``.

    >>> round(beta_from_end_level(0.01, 1001, 1000.0), 6)   # 1 % after 1 s
    4.60517
    """
    n, fs, ti = _check_record(n_samples, sample_rate_hz, trigger_index)
    lvl = float(end_level)
    if not (0 < lvl < 1):
        raise ModalabValueError(f"end_level={end_level!r} must lie in (0, 1); e.g. 0.01 for 1 % at the record end")
    T = (n - 1 - ti) / fs
    if T <= 0:
        raise ModalabValueError(f"the trigger ({ti}) is at the last sample; no time left for the window to decay")
    return float(-np.log(lvl) / T)


class ExpWindowResult(NamedTuple):
    """The window samples and the decay rate β (1/s) it adds to every pole."""

    window: np.ndarray
    beta: float


@dataclass(frozen=True)
class ExponentialWindow:
    """Parameters of an exponential window; give ``beta`` (1/s) or ``end_level`` (0 < level < 1).

    See :func:`exponential_window`.  ``before_trigger`` is ``'extend'`` (the same exponential,
    > 1 in the pretrigger; exact pole shift) or ``'one'`` (clamped to 1 before the trigger).
    """

    beta: float | None = None
    end_level: float | None = None
    before_trigger: str = "extend"

    def __post_init__(self):
        if (self.beta is None) == (self.end_level is None):
            raise ModalabValueError(
                f"ExponentialWindow(beta={self.beta!r}, end_level={self.end_level!r}): give exactly one of beta "
                "(decay rate in 1/s) or end_level (window value at the record end, e.g. 0.01)")
        if self.beta is not None and not (np.isfinite(self.beta) and self.beta >= 0):
            raise ModalabValueError(f"exponential window beta={self.beta!r} must be a finite decay rate >= 0 (1/s)")
        if self.end_level is not None and not (0 < self.end_level < 1):
            raise ModalabValueError(f"exponential window end_level={self.end_level!r} must lie in (0, 1)")
        if self.before_trigger not in ("extend", "one"):
            raise ModalabValueError(f"before_trigger={self.before_trigger!r}; expected 'extend' or 'one'")

    def resolve_beta(self, n_samples: int, sample_rate_hz: float, trigger_index: int = 0) -> float:
        """β in 1/s for a record of this length and trigger position."""
        if self.beta is not None:
            return float(self.beta)
        return beta_from_end_level(self.end_level, n_samples, sample_rate_hz, trigger_index)

    def array(self, n_samples: int, sample_rate_hz: float, trigger_index: int = 0) -> ExpWindowResult:
        return exponential_window(n_samples, sample_rate_hz, trigger_index=trigger_index, beta=self.beta,
                                  end_level=self.end_level, before_trigger=self.before_trigger)

    def to_dict(self) -> dict:
        return {"type": "exponential", **asdict(self)}


def exponential_window(n_samples: int, sample_rate_hz: float, *, trigger_index: int = 0,
                       beta: float | None = None, end_level: float | None = None,
                       before_trigger: str = "extend") -> ExpWindowResult:
    """Exponential window ``w = exp(−β (t − t₀))`` starting at the trigger, without normalisation.

    Parameters
    ----------
    n_samples : record length in samples.
    sample_rate_hz : sampling rate in Hz.
    trigger_index : sample of the trigger instant t₀; ``w[trigger_index] == 1`` exactly.
    beta : decay rate in 1/s, or
    end_level : the window's value at the last sample (``β = −ln(end_level)/T``,
        ``T = (n_samples − 1 − trigger_index)/fs``), e.g. 0.01 for 1 %.
    before_trigger : ``'extend'`` continues the exponential into the pretrigger (values up to
        ``exp(β t₀) > 1``; keeps the pole shift exact for pulses that start before the trigger),
        ``'one'`` holds the window at 1 there.

    Returns
    -------
    ExpWindowResult(window, beta) : the (n_samples,) window and β in 1/s, to be stored with the FRF
        (``FRF.window_beta_per_s``) and removed by :func:`correct_damping`.

    Examples
    --------
    >>> w, beta = exponential_window(1001, 1000.0, end_level=0.01)
    >>> float(w[0]), round(float(w[-1]), 12), round(beta, 4)
    (1.0, 0.01, 4.6052)
    """
    n, fs, ti = _check_record(n_samples, sample_rate_hz, trigger_index)
    spec = ExponentialWindow(beta=beta, end_level=end_level, before_trigger=before_trigger)
    b = spec.resolve_beta(n, fs, ti)
    t = (np.arange(n) - ti) / fs
    if before_trigger == "one":
        t = np.maximum(t, 0.0)
    return ExpWindowResult(np.exp(-b * t), b)


# ------------------------------------------------------------------------------------- damping correction
def correct_poles(poles, beta: float) -> np.ndarray:
    """Remove the exponential window's decay from identified poles: ``λ_true = λ_meas + β``.

    Poles in rad/s (``λ = σ + iω_d`` with σ < 0 for a stable mode); the damped frequency is unchanged,
    ``σ_true = σ_meas + β`` (i.e. the decay rate ``−σ`` drops by β).
    """
    b = check_window_beta(beta)
    return np.asarray(poles, dtype=complex) + b


def correct_damping(freq_hz, damping, beta: float, *, exact: bool = True) -> np.ndarray:
    """Damping ratios with the exponential window's added damping removed.

    Parameters
    ----------
    freq_hz : natural frequencies identified from the windowed data, Hz.
    damping : damping ratios ζ identified from the windowed data.
    beta : the window's decay rate, 1/s (``FRF.window_beta_per_s``).
    exact : True applies the pole form: ``λ = −ζω_n + iω_n√(1−ζ²)``, ``σ_true = σ_meas − β``
        (σ = ζω_n the decay rate), ``ζ_true = σ_true/|λ_true|``; False applies the first-order
        form ``ζ_true = ζ_meas − β/ω_n`` with ``ω_n = 2π·freq_hz``.  They differ by O(ζβ/ω_n).

    Returns
    -------
    damping_true : array like ``damping``.  Negative values (β larger than the measured decay)
        are returned as computed and logged: the window or the identification is inconsistent.

    >>> round(float(correct_damping(100.0, 0.02, 2 * 3.141592653589793, exact=False)), 12)
    0.01
    """
    f = np.asarray(freq_hz, dtype=float)
    z = np.asarray(damping, dtype=float)
    b = check_window_beta(beta)
    try:
        f, z = np.broadcast_arrays(f, z)
    except ValueError:
        raise ModalabValueError(f"freq_hz shape {np.shape(freq_hz)} and damping shape {np.shape(damping)} "
                                "do not match; give one damping ratio per frequency") from None
    if np.any(f <= 0):
        raise ModalabValueError("natural frequencies must be > 0 Hz to correct damping; drop rigid-body modes first")
    w = 2 * np.pi * f
    if exact:
        lam = -z * w + 1j * w * np.sqrt(np.clip(1 - z ** 2, 0, None))
        lt = correct_poles(lam, b)
        out = -lt.real / np.abs(lt)
    else:
        out = z - b / w
    if np.any(out < 0):
        log.warning("damping correction gives negative damping for %d mode(s): the window's beta=%.4g 1/s exceeds "
                    "the identified decay rate", int(np.sum(out < 0)), b)
    return out
