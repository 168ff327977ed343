"""Cross-spectral matrices and the FRF estimators on arrays: H1, H2, Hv, ordinary and multiple coherence.

The array level of :mod:`acquisition.spectral` (which re-exports every public name here and turns hits
into labelled FRFs with these estimators).

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

import numpy as np

from modalab.core.errors import ModalabValueError, ShapeError

__all__ = ["CrossSpectra", "cross_spectra", "h1", "h2", "hv", "coherence", "multiple_coherence", "ESTIMATORS"]

log = logging.getLogger(__name__)

ESTIMATORS = ("H1", "H2", "Hv")
#: auto-spectrum lines below this fraction of the strongest line count as empty (round-off of zero)
_EPS_REL = 1e-24


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
