"""LSFD, the linear part: residues (mode shapes) and residual terms for given poles and participation
vectors, by one real least-squares solve (dense, or with the residual columns eliminated reference by
reference when there are many references), and the :class:`LSFDResult` that holds them.

Split out of :mod:`identification.lsfd` (which re-exports these names); the model is described there.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import numpy as np
from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF


_Q = {"receptance": 0, "mobility": 1, "accelerance": 2}


@dataclass
class LSFDResult:
    """Modal model fitted by LSFD (measured poles; receptance-unit residues)."""

    lam: np.ndarray            # (m,) poles, rad/s, as used in the fit
    participation: np.ndarray  # (n_in, m)
    psi: np.ndarray            # (n_out, m) complex shape coefficients
    lower: np.ndarray          # (n_out, n_in) lower residuals
    upper: np.ndarray          # (n_out, n_in) upper residuals
    quantity: str
    responses: list
    references: list
    metadata: dict = field(default_factory=dict)

    @property
    def residues(self) -> np.ndarray:
        """``A[o, i, r] = ψ_or l_ri`` (receptance units)."""
        return self.psi[:, None, :] * self.participation[None, :, :]

    def synthesise(self, freq, *, residuals: bool = True) -> FRF:
        """Synthesised FRFs on the lines of ``freq`` (an array in Hz or an FRF)."""
        f = freq.freq_hz if isinstance(freq, FRF) else np.asarray(freq, float)
        s = 2j * np.pi * f
        q = _Q[self.quantity]
        A = self.residues
        with np.errstate(divide="ignore", invalid="ignore"):
            g = s[None, :] ** q / (s[None, :] - self.lam[:, None])          # (m, nf)
            gc = s[None, :] ** q / (s[None, :] - self.lam.conj()[:, None])
            n_o, n_i, m = A.shape
            A2 = A.reshape(n_o * n_i, m)
            H = (A2 @ g + A2.conj() @ gc).reshape(n_o, n_i, f.size)
            if residuals:
                H = H + self.lower[:, :, None] * (s ** (q - 2))[None, None, :] \
                    + self.upper[:, :, None] * (s ** q)[None, None, :]
        return FRF(freq_hz=f, H=H, responses=self.responses, references=self.references, quantity=self.quantity,
                   metadata={"estimator": "synthesised", "source": "LSFD"})


_DENSE_RESIDUAL_MAX_IN = 8      # more references: the residual columns are eliminated reference by reference


def _lsfd_structured(blocks, H, s, q, lower_residual, upper_residual):
    """LSFD with the residual terms eliminated per reference (many references, e.g. 74 hammer points).

    The residual columns of reference ``i`` are the same functions of frequency (``s^(q−2)``, ``s^q``, real
    coefficients) on that reference's rows only, so the projection off them is one small basis applied
    reference by reference (Frisch–Waugh–Lovell): the modal coefficients come from the projected problem
    (2m columns instead of 2m + 2·n_in) and the residuals from the remainder — the same least-squares
    solution as the dense design matrix, in a fraction of its memory.
    """
    n_in, nf, two_m = blocks.shape
    n_out = H.shape[0]
    m = two_m // 2
    basis = ([s ** (q - 2)] if lower_residual else []) + ([s ** q] if upper_residual else [])
    Rb = np.stack(basis, axis=1)                                            # (nf, k) complex
    Rr = np.concatenate([Rb.real, Rb.imag], axis=0)                         # (2nf, k): one reference's rows
    rs = np.linalg.norm(Rr, axis=0)
    Qr, Rtri = np.linalg.qr(Rr / rs)
    # per reference: rows [Re; Im] of its lines
    Am = np.concatenate([blocks.real, blocks.imag], axis=1)                  # (n_in, 2nf, 2m)
    Y = H.transpose(1, 2, 0)                                                # (n_in, nf, n_out)
    Yr = np.concatenate([Y.real, Y.imag], axis=1)                           # (n_in, 2nf, n_out)

    def off(V):
        return V - np.einsum("rk,ikc->irc", Qr, np.einsum("rk,irc->ikc", Qr, V))

    Ap, Yp = off(Am), off(Yr)
    A2 = Ap.reshape(-1, two_m)
    scale = np.linalg.norm(A2, axis=0)
    scale[scale == 0] = 1.0
    X, *_ = np.linalg.lstsq(A2 / scale, Yp.reshape(-1, n_out), rcond=None)
    X = X / scale[:, None]                                                  # (2m, n_out)
    psi = (X[:m] + 1j * X[m:]).T
    rem = Yr - np.einsum("irc,co->iro", Am, X)                              # (n_in, 2nf, n_out)
    C = np.linalg.solve(Rtri, np.einsum("rk,iro->iko", Qr, rem)) / rs[None, :, None]   # (n_in, k, n_out)
    LR = np.zeros((n_out, n_in))
    UR = np.zeros((n_out, n_in))
    k = 0
    if lower_residual:
        LR = C[:, k, :].T
        k += 1
    if upper_residual:
        UR = C[:, k, :].T
    return psi, LR, UR


def lsfd(frf: FRF, lam, participation, *, lower_residual: bool = True, upper_residual: bool = True) -> LSFDResult:
    """Fit shapes and residuals to ``frf`` for fixed poles ``lam`` (m,) and participation ``(n_in, m)``."""
    lam = np.atleast_1d(np.asarray(lam, complex))
    L = np.asarray(participation, complex).reshape(frf.n_in, lam.size)
    n_out, n_in, nf = frf.shape
    f = frf.freq_hz
    if np.any(f <= 0):
        raise ModalabValueError("LSFD needs lines above 0 Hz (the residual terms diverge at DC); band-select first")
    m = lam.size
    s = 2j * np.pi * f
    q = _Q[frf.quantity]
    g = s[None, :] ** q / (s[None, :] - lam[:, None])              # (m, nf)
    gc = s[None, :] ** q / (s[None, :] - lam.conj()[:, None])
    # columns: Re ψ_r, Im ψ_r (m each), then LR_i, UR_i (per reference)
    lg = L[:, :, None] * g[None]                                    # (n_in, m, nf)
    lgc = L.conj()[:, :, None] * gc[None]
    cols = [np.transpose(lg + lgc, (0, 2, 1)), np.transpose(1j * (lg - lgc), (0, 2, 1))]   # (n_in, nf, m)
    blocks = np.concatenate(cols, axis=2)
    if n_in > _DENSE_RESIDUAL_MAX_IN and (lower_residual or upper_residual):
        psi, LR, UR = _lsfd_structured(blocks, frf.H, s, q, lower_residual, upper_residual)
        return LSFDResult(lam=lam, participation=L, psi=psi, lower=LR, upper=UR, quantity=frf.quantity,
                          responses=list(frf.responses), references=list(frf.references))
    extra = []
    eye = np.eye(n_in)
    if lower_residual:
        extra.append(eye[:, None, :] * (s ** (q - 2))[None, :, None])
    if upper_residual:
        extra.append(eye[:, None, :] * (s ** q)[None, :, None])
    if extra:
        blocks = np.concatenate([blocks] + extra, axis=2)
    A = blocks.reshape(n_in * nf, -1)
    Ar = np.concatenate([A.real, A.imag], axis=0)
    Y = frf.H.transpose(1, 2, 0).reshape(n_in * nf, n_out)
    Yr = np.concatenate([Y.real, Y.imag], axis=0)
    scale = np.linalg.norm(Ar, axis=0)
    scale[scale == 0] = 1.0
    X, *_ = np.linalg.lstsq(Ar / scale, Yr, rcond=None)
    X = X / scale[:, None]                                          # (n_par, n_out)
    psi = (X[:m] + 1j * X[m:2 * m]).T
    k = 2 * m
    LR = np.zeros((n_out, n_in))
    UR = np.zeros((n_out, n_in))
    if lower_residual:
        LR = X[k:k + n_in].T
        k += n_in
    if upper_residual:
        UR = X[k:k + n_in].T
    return LSFDResult(lam=lam, participation=L, psi=psi, lower=LR, upper=UR, quantity=frf.quantity,
                      responses=list(frf.responses), references=list(frf.references))
