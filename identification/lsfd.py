"""Poly-reference least-squares frequency-domain (LSFD) estimation of mode shapes.

With the poles ``λ_r`` and participation vectors ``l_r`` fixed, every output
``o`` is fitted by

    H_oi(ω) = (iω)^q [ Σ_r ( ψ_or l_ri/(iω − λ_r) + ψ*_or l*_ri/(iω − λ*_r) ) + LR_oi/(iω)² + UR_oi ],

``q`` = 0, 1, 2 for receptance, mobility, accelerance, so that the residues
``A_r = ψ_r l_rᵀ`` and the residuals are always in receptance units (Peeters
et al. 2004, eq. 11; Heylen, Lammens & Sas, *Modal Analysis Theory and
Testing*, ch. 3.4).  ``LR`` (lower residual, the mass line of the modes below
the band) and ``UR`` (upper residual, the static flexibility of the modes
above it) are real.  The unknowns ``Re ψ, Im ψ, LR, UR`` enter linearly; the
basis does not depend on the output, so one least-squares solve with
``n_out`` right-hand sides fits every output at once.

Unit-modal-mass scaling (``A_r = φ_r φ_rᵀ / (2iω_d,r)`` for mass-normalised
φ): at every driving point (a response DOF that is also a reference DOF, signs
of the labels respected) ``l_ri = c_r² Q_r ψ_{o_i r}``, ``Q_r = 1/(2i ω_d,r)``;
``c_r²`` is the least-squares fit over the driving points and ``φ_r = c_r ψ_r``.
The reported participation ``L_r = l_r / c_r`` keeps ``A_r = φ_r L_rᵀ``.

Exponential-window correction: the window ``e^{−βt}`` moves every pole by
``−β`` and leaves the residues unchanged, so the fit uses the measured poles and
the reported poles are ``λ_true = λ_meas + β`` (σ_true = σ_meas − β).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from modalab.errors import ModalabValueError
from modalab.frf import FRF
from modalab.modes import ModeSet
from . import indicators as ind
from .stabilisation import pole_freq_damping

log = logging.getLogger(__name__)

__all__ = ["LSFDResult", "lsfd", "driving_points", "modes_from_poles"]

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
            H = np.einsum("oir,rf->oif", A, g) + np.einsum("oir,rf->oif", A.conj(), gc)
            if residuals:
                H = H + self.lower[:, :, None] * (s ** (q - 2))[None, None, :] \
                    + self.upper[:, :, None] * (s ** q)[None, None, :]
        return FRF(freq_hz=f, H=H, responses=self.responses, references=self.references, quantity=self.quantity,
                   metadata={"estimator": "synthesised", "source": "LSFD"})


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


def driving_points(frf: FRF):
    """Pairs ``(o, i, sign)`` where response o and reference i are the same DOF (sign = product of label signs)."""
    out = []
    for i, r in enumerate(frf.references):
        for o, d in enumerate(frf.responses):
            if d.node == r.node and d.axis == r.axis:
                out.append((o, i, d.sign * r.sign))
    return out


def modes_from_poles(frf: FRF, lam, participation, *, lower_residual: bool = True, upper_residual: bool = True,
                     window_beta: float = 0.0, extra_indicators: dict | None = None):
    """LSFD, window correction, scaling and indicators: returns ``(ModeSet, LSFDResult)``."""
    res = lsfd(frf, lam, participation, lower_residual=lower_residual, upper_residual=upper_residual)
    m = res.lam.size
    lam_true = res.lam + float(window_beta)
    fn, zeta = pole_freq_damping(lam_true)
    psi = res.psi
    L = res.participation
    dps = driving_points(frf)
    Q = 1.0 / (2j * np.where(lam_true.imag > 0, lam_true.imag, np.abs(lam_true)))
    if dps and m:
        num = np.zeros(m, complex)
        den = np.zeros(m)
        for o, i, sg in dps:
            a = Q * sg * psi[o]
            num += a.conj() * L[i]
            den += np.abs(a) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            c2 = np.where(den > 0, num / den, np.nan)
        c = np.sqrt(c2.astype(complex))
        bad = ~np.isfinite(c) | (c == 0)
        c[bad] = 1.0
        phi = psi * c[None, :]
        Lrep = L / c[None, :]
        scaling = "unit_modal_mass" if not bad.any() else "arbitrary"
        dp_res = np.array([Q * (phi[o] ** 2) for o, _, _ in dps])
        mov = ind.mov(lam_true, dp_res)
    else:
        if m:
            log.info("no driving point (response DOF = reference DOF): shapes scaled to unit maximum")
        k = np.argmax(np.abs(psi), axis=0) if m else np.zeros(0, int)
        c = 1.0 / psi[k, np.arange(m)] if m else np.zeros(0, complex)
        c[~np.isfinite(c)] = 1.0
        phi = psi * c[None, :]
        Lrep = L / c[None, :]
        scaling = "unit_max"
        mov = np.full(m, np.nan)
    # rotate so that each complex shape is closest to real with positive largest entry (scaling-neutral
    # for unit-modal-mass shapes only up to a sign: keep the sign of c, it is fixed by the residue)
    syn = res.synthesise(frf)
    indic = {"MPC": ind.mpc(phi) if m else np.zeros(0), "MPD": ind.mpd(phi) if m else np.zeros(0),
             "MCF": ind.mcf(phi) if m else np.zeros(0), "MOV": mov}
    for k2, v in (extra_indicators or {}).items():
        indic[k2] = np.asarray(v)
    # modal contribution to the synthesis, per mode (fraction of the synthesised energy)
    if m:
        contrib = np.empty(m)
        tot = np.sum(np.abs(frf.H) ** 2)
        s = 2j * np.pi * frf.freq_hz
        q = _Q[frf.quantity]
        for r in range(m):
            g = s ** q / (s - res.lam[r])
            gc = s ** q / (s - res.lam[r].conj())
            Ar = res.residues[:, :, r]
            Hr = Ar[..., None] * g + Ar.conj()[..., None] * gc
            contrib[r] = np.sum(np.abs(Hr) ** 2) / tot
        indic["contribution"] = contrib
    res.metadata.update({"frf_correlation": ind.frf_correlation(syn.H, frf.H),
                         "synthesis_error": ind.synthesis_error(syn.H, frf.H), "window_beta": float(window_beta)})
    modes = ModeSet(freq_hz=fn, damping=zeta, shapes=phi, dofs=frf.responses, participation=Lrep,
                    references=frf.references, scaling=scaling, indicators=indic,
                    metadata={"quantity": frf.quantity})
    return modes, res
