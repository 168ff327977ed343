"""FRF estimation from averaged hammer hits: H1, H2, Hv and coherence, SIMO and MIMO.

By task
-------
Arrays (scipy.signal style, ``axis=`` is the time axis)
    :func:`cross_spectra` → :class:`CrossSpectra`; :func:`h1`, :func:`h2`, :func:`hv`,
    :func:`coherence`, :func:`multiple_coherence` return ``(freq_hz, values)``.
Hits (:class:`modalab.records.TimeRecord`) → labelled :class:`modalab.frf.FRF`
    :func:`estimate_frf` (one channel layout, SIMO or MIMO), :func:`estimate_frf_roving`
    (hits grouped by hammer DOF, concatenated along the references),
    :class:`SpectralAverager` (running average: ``add(record)`` / ``remove(hit_id)`` / ``frf()``).

Conventions
-----------
Every hit is one average (no segmentation: an impact record is a transient).  With ``X_j(f)`` the
DFT of force channel j and ``Y_i(f)`` of response channel i, both scaled by Δt (so in unit·s, the
continuous Fourier transform of the record), the averaged one-sided energy spectral densities are

    G_xx[a, b] = 2 E[X_a X_b*],   G_yx[i, b] = 2 E[Y_i X_b*],   G_yy[i] = 2 E[|Y_i|²]

(factor 1 at DC and Nyquist), in unit²·s/Hz.  The estimators (Bendat & Piersol 2010, ch. 6 and 7;
Ewins 2000, ch. 3) are

    H1 = G_yx G_xx⁻¹                               (noise on the response; the usual choice)
    H2 = G_yy / G_xy,  G_xy = G_yx*                (single reference only; noise on the force)
    Hv : total least squares per response i: the eigenvector u of the smallest eigenvalue of the
         Hermitian (n_in+1)² matrix [[G_xx, G_xy_i], [G_yx_i, G_yy_i]] gives H_i = −u_x^H / u_y*
         (equal relative noise on force and response; not invariant to the units' scale).
    γ²_ij = |G_yx_ij|² / (G_xx_jj G_yy_i)          ordinary coherence
    γ²_i  = Re(G_yx_i H1_i^H) / G_yy_i              multiple coherence of response i

Lines where the force auto-spectrum is zero up to round-off (below 1e-24 of its strongest line)
give NaN FRFs; coherence is 0 where either signal has no energy, and where the forces of a MIMO
set are not independent (multiple coherence there is 0, and H1 NaN).

For several force channels (MIMO) the FRF container's coherence holds the *multiple* coherence of
each response (repeated along the references) and ``metadata['coherence_kind'] == 'multiple'``.

References
----------
J. S. Bendat, A. G. Piersol, *Random Data*, 4th ed., Wiley 2010, ch. 6 (single input), ch. 7 (multiple
inputs), ch. 9 (statistical errors of the estimates).
D. J. Ewins, *Modal Testing: Theory, Practice and Application*, 2nd ed., 2000, ch. 3 (mobility
measurement: impact excitation, H1/H2).
H. Vold, J. Crowley, G. T. Rocklin, "New ways of estimating frequency response functions",
Sound and Vibration 18(11), 1984 (the Hv estimator).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from modalab.dof import Dof
from modalab.errors import ModalabValueError, ShapeError
from modalab.frf import FRF, concat
from modalab.records import TimeRecord
from modalab.units import to_si

from .windows import ExponentialWindow, ForceWindow

__all__ = [
    "CrossSpectra",
    "cross_spectra",
    "h1",
    "h2",
    "hv",
    "coherence",
    "multiple_coherence",
    "SpectralAverager",
    "estimate_frf",
    "estimate_frf_roving",
    "group_by_reference",
    "quantity_from_unit",
    "ESTIMATORS",
]

log = logging.getLogger(__name__)

ESTIMATORS = ("H1", "H2", "Hv")
#: auto-spectrum lines below this fraction of the strongest line count as empty (round-off of zero)
_EPS_REL = 1e-24

_QUANTITY_OF_UNIT = {
    "m/s^2": "accelerance", "m/s2": "accelerance", "m/s**2": "accelerance", "m/s²": "accelerance",
    "g": "accelerance", "mm/s^2": "accelerance", "in/s^2": "accelerance",
    "m/s": "mobility", "mm/s": "mobility", "in/s": "mobility",
    "m": "receptance", "mm": "receptance", "um": "receptance", "in": "receptance",
}
_FORCE_UNITS = ("N", "kN", "lbf")


def quantity_from_unit(unit: str) -> str:
    """FRF quantity measured by a response channel in ``unit``: m/s² → accelerance, m/s → mobility, m → receptance."""
    u = str(unit).strip()
    q = _QUANTITY_OF_UNIT.get(u)
    if q is None:
        raise ModalabValueError(
            f"response unit {unit!r} is not a motion unit; expected one of {', '.join(sorted(_QUANTITY_OF_UNIT))}. "
            "Give the response channels' units in SI (m/s^2 for accelerometers)")
    return q


# ============================================================================ spectra
@dataclass
class CrossSpectra:
    """Averaged one-sided energy spectral densities of forces x and responses y.

    Attributes
    ----------
    freq_hz : (n_freq,) frequency lines in Hz.
    Gxx : (n_in, n_in, n_freq) complex, ``2 E[X_a X_b*]`` (force unit² · s/Hz).
    Gyx : (n_out, n_in, n_freq) complex, ``2 E[Y_i X_b*]``.
    Gyy : (n_out, n_freq) real, ``2 E[|Y_i|²]``.
    n_averages : number of hits averaged.
    """

    freq_hz: np.ndarray
    Gxx: np.ndarray
    Gyx: np.ndarray
    Gyy: np.ndarray
    n_averages: int

    @property
    def n_in(self) -> int:
        return self.Gxx.shape[0]

    @property
    def n_out(self) -> int:
        return self.Gyx.shape[0]

    # ------------------------------------------------------------------ estimators
    def _no_energy(self, g: np.ndarray) -> np.ndarray:
        """Lines whose auto-spectrum is zero up to round-off (relative to the strongest line)."""
        return g <= _EPS_REL * max(float(np.max(g, initial=0.0)), np.finfo(float).tiny)

    def h1(self) -> np.ndarray:
        """H1 = G_yx G_xx⁻¹, shape (n_out, n_in, n_freq); NaN where the force has no energy."""
        return self._h1(strict=True)

    def _h1(self, strict: bool) -> np.ndarray:
        if self.n_in == 1:
            gxx = self.Gxx[0, 0].real
            with np.errstate(divide="ignore", invalid="ignore"):
                H = self.Gyx / gxx[None, None, :]
            H[:, :, self._no_energy(gxx)] = np.nan
            return H
        if strict and self.n_averages < self.n_in:
            raise ModalabValueError(
                f"MIMO H1 with {self.n_in} force channels needs at least {self.n_in} averages with independent "
                f"forces; got {self.n_averages}. Record more hits before estimating")
        A = self.Gxx.transpose(2, 1, 0)                        # (nf, n_in, n_in) = Gxxᵀ
        B = self.Gyx.transpose(2, 1, 0)                        # (nf, n_in, n_out) = Gyxᵀ
        with np.errstate(all="ignore"):
            cond = np.linalg.cond(A)
        bad = ~np.isfinite(cond) | (cond > 1e12)
        H = np.full((A.shape[0], self.n_in, self.n_out), np.nan, complex)
        if np.any(~bad):
            H[~bad] = np.linalg.solve(A[~bad], B[~bad])
        if np.any(bad) and strict:
            frac = bad.mean()
            msg = (f"G_xx is singular at {int(bad.sum())} of {bad.size} lines: the {self.n_in} forces are not "
                   "independent there (H1 set to NaN)")
            if frac > 0.5:
                raise ModalabValueError(msg + ". Use hits whose force channels are not all proportional "
                                              "(different hit points or shakers), or a single force channel")
            log.warning(msg)
        return H.transpose(2, 1, 0)

    def h2(self) -> np.ndarray:
        """H2 = G_yy / G_xy for a single force channel, shape (n_out, 1, n_freq)."""
        if self.n_in != 1:
            raise ModalabValueError(
                f"H2 is defined here for one force channel; the data have {self.n_in}. "
                "Use estimator='H1' or 'Hv' for several references")
        gxy = np.conj(self.Gyx[:, 0, :])
        with np.errstate(divide="ignore", invalid="ignore"):
            H = self.Gyy / gxy
        H[~np.isfinite(H)] = np.nan
        H[:, self._no_energy(self.Gxx[0, 0].real)] = np.nan
        return H[:, None, :]

    def hv(self) -> np.ndarray:
        """Hv (total least squares) per response, shape (n_out, n_in, n_freq)."""
        n_in, n_out, nf = self.n_in, self.n_out, self.freq_hz.size
        Z = np.zeros((nf, n_out, n_in + 1, n_in + 1), complex)
        Z[:, :, :n_in, :n_in] = self.Gxx.transpose(2, 0, 1)[:, None, :, :]
        gyx = self.Gyx.transpose(2, 0, 1)                     # (nf, n_out, n_in)
        Z[:, :, n_in, :n_in] = gyx
        Z[:, :, :n_in, n_in] = np.conj(gyx)
        Z[:, :, n_in, n_in] = self.Gyy.T
        _, V = np.linalg.eigh(Z)
        u = V[..., 0]                                          # (nf, n_out, n_in+1)
        ux, uy = u[..., :n_in], u[..., n_in]
        with np.errstate(divide="ignore", invalid="ignore"):
            H = -np.conj(ux) / np.conj(uy)[..., None]
        H[~np.isfinite(H)] = np.nan
        gxx = np.real(np.einsum("iif->f", self.Gxx))
        H[self._no_energy(gxx)] = np.nan
        return H.transpose(1, 2, 0)

    def estimate(self, estimator: str = "H1") -> np.ndarray:
        """The FRF by name: 'H1', 'H2' or 'Hv'."""
        e = _check_estimator(estimator)
        return {"H1": self.h1, "H2": self.h2, "Hv": self.hv}[e]()

    # ------------------------------------------------------------------ coherence
    def coherence(self) -> np.ndarray:
        """Ordinary coherence γ²_ij in [0, 1], shape (n_out, n_in, n_freq); 0 where a signal has no energy."""
        gxx = np.real(np.einsum("iif->if", self.Gxx))          # (n_in, nf)
        den = self.Gyy[:, None, :] * gxx[None, :, :]
        with np.errstate(divide="ignore", invalid="ignore"):
            c = np.abs(self.Gyx) ** 2 / den
        dead = self._no_energy(gxx)[None, :, :] | self._no_energy(self.Gyy)[:, None, :]
        c[~np.isfinite(c) | (den <= 0) | dead] = 0.0
        return np.clip(c, 0.0, 1.0)

    def multiple_coherence(self) -> np.ndarray:
        """Multiple coherence of each response with all forces, in [0, 1], shape (n_out, n_freq)."""
        if self.n_in == 1:
            return self.coherence()[:, 0, :]
        H = self._h1(strict=False)
        num = np.real(np.einsum("oif,oif->of", self.Gyx, np.conj(H)))
        with np.errstate(divide="ignore", invalid="ignore"):
            c = num / self.Gyy
        c[~np.isfinite(c) | self._no_energy(self.Gyy)] = 0.0
        return np.clip(c, 0.0, 1.0)


def _check_estimator(estimator: str) -> str:
    e = {"h1": "H1", "h2": "H2", "hv": "Hv"}.get(str(estimator).strip().lower())
    if e is None:
        raise ModalabValueError(f"estimator {estimator!r} unknown; expected one of {', '.join(ESTIMATORS)}")
    return e


def _one_sided_factor(nfft: int, nf: int) -> np.ndarray:
    fac = np.full(nf, 2.0)
    fac[0] = 1.0
    if nfft % 2 == 0:
        fac[-1] = 1.0
    return fac


def _spectra_sums(X: np.ndarray, Y: np.ndarray, fac: np.ndarray):
    """Sums over hits of the products (X: (n_avg, n_in, nf), Y: (n_avg, n_out, nf))."""
    Gxx = np.einsum("haf,hbf->abf", X, np.conj(X)) * fac
    Gyx = np.einsum("hif,hbf->ibf", Y, np.conj(X)) * fac
    Gyy = np.einsum("hif,hif->if", Y, np.conj(Y)).real * fac
    return Gxx, Gyx, Gyy


def _canon(a, name, axis):
    arr = np.asarray(a)
    if not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
        raise ModalabValueError(f"{name} must be a real numeric array of time samples; got dtype {arr.dtype}")
    arr = arr.astype(float, copy=False)
    if arr.ndim == 0 or arr.ndim > 3:
        raise ShapeError(f"{name} has shape {arr.shape}; expected (n_samples,), (n_avg, n_samples) or "
                         "(n_avg, n_channels, n_samples) with time along `axis`")
    try:
        arr = np.moveaxis(arr, axis, -1)
    except np.exceptions.AxisError:
        raise ShapeError(f"axis={axis} is out of range for {name} of shape {arr.shape}") from None
    single = arr.ndim <= 2
    if arr.ndim == 1:
        arr = arr[None, None, :]
    elif arr.ndim == 2:
        arr = arr[:, None, :]
    if not np.all(np.isfinite(arr)):
        raise ModalabValueError(f"{name} contains NaN or infinite samples; drop or repair the record first")
    return arr, single


def cross_spectra(x, y, fs: float, *, axis: int = -1, window_x=None, window_y=None,
                  nfft: int | None = None) -> CrossSpectra:
    """Averaged auto/cross energy spectral densities of forces ``x`` and responses ``y``.

    Parameters
    ----------
    x : force time signals, (n_samples,), (n_avg, n_samples) or (n_avg, n_in, n_samples), in N
        (any unit; the spectra are in that unit).
    y : response signals, (n_samples,), (n_avg, n_samples) or (n_avg, n_out, n_samples).
    fs : sampling rate in Hz.
    axis : the time axis of ``x`` and ``y`` (moved last before the other axes are read).
    window_x, window_y : optional windows multiplied onto x and y, broadcastable to
        (n_avg, n_channels, n_samples) — typically (n_samples,) arrays from
        :mod:`acquisition.windows`.
    nfft : FFT length (zero-padding when > n_samples); default n_samples.

    Returns
    -------
    CrossSpectra with ``n_freq = nfft // 2 + 1`` lines at ``k · fs / nfft`` Hz.
    """
    fs = _check_fs(fs)
    X, _ = _canon(x, "x", axis)
    Y, _ = _canon(y, "y", axis)
    if X.shape[0] != Y.shape[0]:
        raise ShapeError(f"x has {X.shape[0]} averages but y has {Y.shape[0]}; give one force record per response record")
    if X.shape[-1] != Y.shape[-1]:
        raise ShapeError(f"x has {X.shape[-1]} samples but y has {Y.shape[-1]}; records must have the same length")
    n = X.shape[-1]
    nfft = n if nfft is None else int(nfft)
    if nfft < n:
        raise ModalabValueError(f"nfft={nfft} is shorter than the record ({n} samples); use nfft >= n_samples")
    for w, arr, nm in ((window_x, X, "window_x"), (window_y, Y, "window_y")):
        if w is not None:
            try:
                np.broadcast_shapes(np.shape(w), arr.shape)
            except ValueError:
                raise ShapeError(f"{nm} of shape {np.shape(w)} does not broadcast to {arr.shape}") from None
    if window_x is not None:
        X = X * window_x
    if window_y is not None:
        Y = Y * window_y
    Xf = np.fft.rfft(X, n=nfft, axis=-1) / fs
    Yf = np.fft.rfft(Y, n=nfft, axis=-1) / fs
    fac = _one_sided_factor(nfft, Xf.shape[-1])
    Gxx, Gyx, Gyy = _spectra_sums(Xf, Yf, fac)
    m = X.shape[0]
    return CrossSpectra(freq_hz=np.fft.rfftfreq(nfft, 1.0 / fs), Gxx=Gxx / m, Gyx=Gyx / m, Gyy=Gyy / m,
                        n_averages=m)


def _check_fs(fs):
    try:
        f = float(fs)
    except (TypeError, ValueError):
        f = np.nan
    if not np.isfinite(f) or f <= 0:
        raise ModalabValueError(f"fs={fs!r} must be a positive sampling rate in Hz")
    return f


def _array_api(kind, x, y, fs, axis, kw):
    cs = cross_spectra(x, y, fs, axis=axis, **kw)
    single = np.ndim(x) <= 2 and np.ndim(y) <= 2
    if kind == "mcoh":
        out = cs.multiple_coherence()
        return cs.freq_hz, (out[0] if single else out)
    out = cs.coherence() if kind == "coh" else cs.estimate(kind)
    return cs.freq_hz, (out[0, 0] if single else out)


def h1(x, y, fs: float, *, axis: int = -1, window_x=None, window_y=None, nfft: int | None = None):
    """H1 estimate ``G_yx G_xx⁻¹`` from time signals (see :func:`cross_spectra` for shapes).

    Returns ``(freq_hz, H)``: H is (n_freq,) when x and y are single-channel (≤ 2-D), otherwise
    (n_out, n_in, n_freq); in units of y per unit of x (m/s²/N for accelerance).

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> x = rng.standard_normal((4, 256)); y = 3.0 * x
    >>> f, H = h1(x, y, 1000.0)
    >>> bool(np.allclose(H, 3.0))
    True
    """
    return _array_api("H1", x, y, fs, axis, dict(window_x=window_x, window_y=window_y, nfft=nfft))


def h2(x, y, fs: float, *, axis: int = -1, window_x=None, window_y=None, nfft: int | None = None):
    """H2 estimate ``G_yy / G_xy`` (one force channel); returns ``(freq_hz, H)`` shaped like :func:`h1`."""
    return _array_api("H2", x, y, fs, axis, dict(window_x=window_x, window_y=window_y, nfft=nfft))


def hv(x, y, fs: float, *, axis: int = -1, window_x=None, window_y=None, nfft: int | None = None):
    """Hv (total least squares) estimate; returns ``(freq_hz, H)`` shaped like :func:`h1`."""
    return _array_api("Hv", x, y, fs, axis, dict(window_x=window_x, window_y=window_y, nfft=nfft))


def coherence(x, y, fs: float, *, axis: int = -1, window_x=None, window_y=None, nfft: int | None = None):
    """Ordinary coherence ``|G_yx|²/(G_xx G_yy)`` in [0, 1]; returns ``(freq_hz, γ²)`` shaped like :func:`h1`."""
    return _array_api("coh", x, y, fs, axis, dict(window_x=window_x, window_y=window_y, nfft=nfft))


def multiple_coherence(x, y, fs: float, *, axis: int = -1, window_x=None, window_y=None,
                       nfft: int | None = None):
    """Multiple coherence of each response with all forces; ``(freq_hz, γ²)`` with γ² (n_out, n_freq) or (n_freq,)."""
    return _array_api("mcoh", x, y, fs, axis, dict(window_x=window_x, window_y=window_y, nfft=nfft))


# ============================================================================ hits -> FRF
def _as_force_window(fw):
    if fw is None or isinstance(fw, ForceWindow):
        return fw
    if isinstance(fw, dict):
        return ForceWindow(**{k: v for k, v in fw.items() if k != "type"})
    raise ModalabValueError(f"force_window={fw!r}; pass acquisition.windows.ForceWindow(...) or None")


def _as_exp_window(ew):
    if ew is None or isinstance(ew, ExponentialWindow):
        return ew
    if isinstance(ew, dict):
        return ExponentialWindow(**{k: v for k, v in ew.items() if k != "type"})
    raise ModalabValueError(f"exp_window={ew!r}; pass acquisition.windows.ExponentialWindow(beta=... or "
                            "end_level=...) or None")


@dataclass(frozen=True)
class _Layout:
    fs: float
    n_samples: int
    force_idx: tuple
    resp_idx: tuple
    references: tuple
    responses: tuple
    force_scale: np.ndarray
    resp_scale: np.ndarray
    quantity: str

    @classmethod
    def of(cls, rec: TimeRecord) -> "_Layout":
        if not isinstance(rec, TimeRecord):
            raise ModalabValueError(f"expected a modalab.records.TimeRecord; got {type(rec).__name__}")
        fi, ri = tuple(rec.force_channels), tuple(rec.response_channels)
        if not fi:
            raise ModalabValueError(f"hit {rec.hit_id} has no force channel (roles {rec.roles}); mark the hammer "
                                    "channel with role 'force'")
        if not ri:
            raise ModalabValueError(f"hit {rec.hit_id} has no response channel (roles {rec.roles}); mark the "
                                    "accelerometers with role 'response'")
        fscale = []
        for i in fi:
            u = rec.units[i]
            if u not in _FORCE_UNITS:
                raise ModalabValueError(f"force channel {rec.dofs[i]} of hit {rec.hit_id} has unit {u!r}; expected "
                                        f"one of {', '.join(_FORCE_UNITS)}")
            fscale.append(float(to_si(1.0, u)))
        qs, rscale = [], []
        for i in ri:
            u = rec.units[i]
            qs.append(quantity_from_unit(u))
            rscale.append(float(to_si(1.0, u.replace("²", "^2"))))
        if len(set(qs)) != 1:
            raise ModalabValueError(
                f"hit {rec.hit_id} mixes response quantities {sorted(set(qs))} (units "
                f"{[rec.units[i] for i in ri]}); an FRF holds one quantity. Estimate each sensor type separately")
        return cls(fs=rec.sample_rate_hz, n_samples=rec.n_samples, force_idx=fi, resp_idx=ri,
                   references=tuple(rec.dofs[i] for i in fi), responses=tuple(rec.dofs[i] for i in ri),
                   force_scale=np.asarray(fscale), resp_scale=np.asarray(rscale), quantity=qs[0])

    def check(self, rec: TimeRecord, first_id) -> None:
        other = _Layout.of(rec)
        if other.fs != self.fs:
            raise ModalabValueError(f"hit {rec.hit_id} is sampled at {other.fs:g} Hz but hit {first_id} at "
                                    f"{self.fs:g} Hz; average hits of one sampling rate only")
        if other.n_samples != self.n_samples:
            raise ModalabValueError(f"hit {rec.hit_id} has {other.n_samples} samples but hit {first_id} has "
                                    f"{self.n_samples}; records must have the same length")
        if other.references != self.references:
            raise ModalabValueError(
                f"hit {rec.hit_id} has force at {[str(d) for d in other.references]} but hit {first_id} at "
                f"{[str(d) for d in self.references]}; only hits at the same point are averaged. "
                "For roving-hammer data use estimate_frf_roving")
        if other.responses != self.responses or other.quantity != self.quantity:
            raise ModalabValueError(
                f"hit {rec.hit_id} has responses {[str(d) for d in other.responses]} ({other.quantity}) but hit "
                f"{first_id} has {[str(d) for d in self.responses]} ({self.quantity}); use one channel setup")


class SpectralAverager:
    """Running average of hammer hits into auto/cross spectra, for a live FRF.

    Parameters (keyword-only; ``__init__`` only stores them)
    ----------
    estimator : 'H1' (default), 'H2' or 'Hv' — what :meth:`frf` returns.
    force_window : :class:`~acquisition.windows.ForceWindow` applied to the force channels, or None.
    exp_window : :class:`~acquisition.windows.ExponentialWindow` applied to all channels, or None.
        With ``end_level`` the decay rate β is fixed by the first hit (its length and trigger) and
        used for all hits, so every average carries the same added damping.
    nfft : FFT length (default the record length).

    ``add(record)`` costs one FFT per channel plus O(n_channels · n_in · n_freq) products;
    ``remove(hit_id)`` subtracts a hit's stored contribution in the same time; ``frf()`` solves the
    estimator.  Each hit's windowed spectra are kept (n_channels · n_freq complex numbers per hit) so
    a hit can be removed exactly.  Windows start at each hit's own ``trigger_index``.
    """

    def __init__(self, *, estimator: str = "H1", force_window: ForceWindow | None = None,
                 exp_window: ExponentialWindow | None = None, nfft: int | None = None):
        self.estimator = estimator
        self.force_window = force_window
        self.exp_window = exp_window
        self.nfft = nfft
        self._layout: _Layout | None = None
        self._first_id = None
        self._beta = 0.0
        self._hits: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._sums = None

    # ------------------------------------------------------------------ state
    @property
    def n_averages(self) -> int:
        return len(self._hits)

    @property
    def hit_ids(self) -> list[int]:
        return list(self._hits)

    @property
    def beta(self) -> float:
        """Decay rate β (1/s) of the exponential window in use (0 without one)."""
        return self._beta

    def reset(self) -> "SpectralAverager":
        """Forget every hit (the parameters stay)."""
        self._layout, self._first_id, self._beta, self._hits, self._sums = None, None, 0.0, {}, None
        return self

    def _spectra(self, rec: TimeRecord):
        L = self._layout
        n, fs, ti = L.n_samples, L.fs, rec.trigger_index
        x = rec.data[list(L.force_idx)] * L.force_scale[:, None]
        y = rec.data[list(L.resp_idx)] * L.resp_scale[:, None]
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            raise ModalabValueError(f"hit {rec.hit_id} contains NaN or infinite samples; discard it")
        if self.exp_window is not None:
            ew = np.exp(-self._beta * ((np.arange(n) - ti) / fs if self.exp_window.before_trigger == "extend"
                                       else np.maximum((np.arange(n) - ti) / fs, 0.0)))
            x = x * ew
            y = y * ew
        if self.force_window is not None:
            x = x * self.force_window.array(n, fs, ti)
        nfft = n if self.nfft is None else int(self.nfft)
        return np.fft.rfft(x, n=nfft, axis=-1) / fs, np.fft.rfft(y, n=nfft, axis=-1) / fs

    def _contribution(self, X, Y):
        return _spectra_sums(X[None], Y[None], self._fac)

    def add(self, record: TimeRecord) -> "SpectralAverager":
        """Add one hit; returns self.  Raises if its layout differs from the first hit's."""
        _check_estimator(self.estimator)
        fw, ew = _as_force_window(self.force_window), _as_exp_window(self.exp_window)
        self.force_window, self.exp_window = fw, ew
        if self._layout is None:
            layout = _Layout.of(record)
            nfft = layout.n_samples if self.nfft is None else int(self.nfft)
            if nfft < layout.n_samples:
                raise ModalabValueError(f"nfft={nfft} is shorter than the record ({layout.n_samples} samples)")
            self._layout, self._first_id = layout, record.hit_id
            self._beta = 0.0 if ew is None else ew.resolve_beta(layout.n_samples, layout.fs, record.trigger_index)
            self._fac = _one_sided_factor(nfft, nfft // 2 + 1)
            self._freq = np.fft.rfftfreq(nfft, 1.0 / layout.fs)
        else:
            self._layout.check(record, self._first_id)
        if record.hit_id in self._hits:
            raise ModalabValueError(f"hit {record.hit_id} is already in the average; hit ids must be unique "
                                    "(remove it first to replace it)")
        X, Y = self._spectra(record)
        c = self._contribution(X, Y)
        self._sums = list(c) if self._sums is None else [s + d for s, d in zip(self._sums, c)]
        self._hits[record.hit_id] = (X, Y)
        log.debug("added hit %s (%d averages)", record.hit_id, self.n_averages)
        return self

    def remove(self, hit) -> "SpectralAverager":
        """Remove a hit (its ``hit_id`` or the record) from the average; returns self."""
        hid = hit.hit_id if isinstance(hit, TimeRecord) else int(hit)
        if hid not in self._hits:
            raise ModalabValueError(f"hit {hid} is not in the average (hits: {self.hit_ids}); nothing removed")
        X, Y = self._hits.pop(hid)
        c = self._contribution(X, Y)
        self._sums = [s - d for s, d in zip(self._sums, c)]
        if not self._hits:
            self.reset()
        return self

    def spectra(self) -> CrossSpectra:
        """The averaged :class:`CrossSpectra` of the hits added so far."""
        if not self._hits:
            raise ModalabValueError("no hits in the average yet; call add(record) first")
        m = self.n_averages
        Gxx, Gyx, Gyy = self._sums
        return CrossSpectra(freq_hz=self._freq, Gxx=Gxx / m, Gyx=Gyx / m, Gyy=np.maximum(Gyy / m, 0.0),
                            n_averages=m)

    def frf(self, estimator: str | None = None) -> FRF:
        """The labelled FRF (responses × force channels) with coherence and window metadata."""
        est = _check_estimator(self.estimator if estimator is None else estimator)
        cs = self.spectra()
        H = cs.estimate(est)
        L = self._layout
        if cs.n_in == 1:
            coh, kind = cs.coherence(), "ordinary"
        else:
            coh, kind = np.repeat(cs.multiple_coherence()[:, None, :], cs.n_in, axis=1), "multiple"
        meta = {
            "estimator": est,
            "n_averages": cs.n_averages,
            "hit_ids": self.hit_ids,
            "force_window": None if self.force_window is None else self.force_window.to_dict(),
            "exp_window": None if self.exp_window is None else self.exp_window.to_dict(),
            "window_origin": "trigger",
            "coherence_kind": kind,
            "sample_rate_hz": L.fs,
            "n_samples": L.n_samples,
        }
        return FRF(freq_hz=cs.freq_hz, H=H, responses=list(L.responses), references=list(L.references),
                   coherence=coh, quantity=L.quantity, metadata=meta, window_beta_per_s=float(self._beta))


def _records_list(records) -> list[TimeRecord]:
    if isinstance(records, TimeRecord):
        return [records]
    recs = list(records)
    if not recs:
        raise ModalabValueError("no hits given; pass a list of TimeRecord")
    return recs


def estimate_frf(records: Sequence[TimeRecord] | TimeRecord, *, estimator: str = "H1",
                 force_window: ForceWindow | None = None, exp_window: ExponentialWindow | None = None,
                 nfft: int | None = None) -> FRF:
    """FRF from a set of averaged hits with one channel layout (SIMO or MIMO).

    Parameters
    ----------
    records : hits (:class:`~modalab.records.TimeRecord`), all with the same sampling rate, length,
        force DOFs and response DOFs.  Data in engineering units (N; m/s², m/s or m, or g etc.,
        converted to SI).
    estimator : 'H1', 'H2' (one force channel) or 'Hv'.
    force_window : :class:`~acquisition.windows.ForceWindow` for the force channels, or None.
    exp_window : :class:`~acquisition.windows.ExponentialWindow` for all channels, or None.
    nfft : FFT length (default the record length).

    Returns
    -------
    FRF with ``responses`` = response-channel DOFs, ``references`` = force-channel DOFs, quantity
    from the response unit (m/s² → accelerance, m/s → mobility, m → receptance), coherence, and
    metadata ``estimator``, ``n_averages``, ``force_window``; ``FRF.window_beta_per_s`` (1/s; remove it
    with :func:`acquisition.windows.correct_damping`), ``hit_ids``, ``coherence_kind``.
    """
    avg = SpectralAverager(estimator=estimator, force_window=force_window, exp_window=exp_window, nfft=nfft)
    for r in _records_list(records):
        avg.add(r)
    return avg.frf()


def group_by_reference(records: Sequence[TimeRecord]) -> dict[tuple[Dof, ...], list[TimeRecord]]:
    """Hits grouped by their force-channel DOFs, in order of first appearance."""
    out: dict[tuple[Dof, ...], list[TimeRecord]] = {}
    for r in _records_list(records):
        if not isinstance(r, TimeRecord):
            raise ModalabValueError(f"expected TimeRecord items; got {type(r).__name__}")
        out.setdefault(tuple(r.force_dofs), []).append(r)
    return out


def estimate_frf_roving(records: Sequence[TimeRecord], **kw) -> FRF:
    """Roving-hammer FRFs: hits grouped by hammer DOF, each group averaged, concatenated along references.

    Every group must measure the same response DOFs.  Keywords as :func:`estimate_frf`; an
    exponential window given by ``end_level`` is resolved to one β from the first hit and used for
    every hit point, so all columns carry the same added damping.
    ``metadata['n_averages']`` is the smallest group's count; ``n_averages_per_reference`` lists all.
    """
    groups = group_by_reference(records)
    ew = _as_exp_window(kw.get("exp_window"))
    if ew is not None and ew.beta is None:
        first = next(iter(groups.values()))[0]
        kw["exp_window"] = ExponentialWindow(
            beta=ew.resolve_beta(first.n_samples, first.sample_rate_hz, first.trigger_index),
            before_trigger=ew.before_trigger)
    frfs = []
    for refs, recs in groups.items():
        if not refs:
            raise ModalabValueError(f"hit {recs[0].hit_id} has no force channel; mark the hammer channel 'force'")
        frfs.append(estimate_frf(recs, **kw))
    resp0 = [(d.node, d.axis) for d in frfs[0].responses]
    for f in frfs[1:]:
        if [(d.node, d.axis) for d in f.responses] != resp0:
            raise ModalabValueError(
                f"hits at {[str(d) for d in f.references]} measured responses {[str(d) for d in f.responses]} but "
                f"the first group measured {[str(d) for d in frfs[0].responses]}; roving-hammer hits must share "
                "the fixed sensors")
    out = concat(frfs, axis="references") if len(frfs) > 1 else frfs[0]
    per = {",".join(str(d) for d in refs): len(recs) for refs, recs in groups.items()}
    out.metadata["n_averages"] = min(per.values())
    out.metadata["n_averages_per_reference"] = per
    out.metadata["hit_ids"] = [r.hit_id for recs in groups.values() for r in recs]
    return out
