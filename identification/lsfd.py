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
the reported poles are ``λ_true = λ_meas + β`` (σ_true = σ_meas − β), by
:func:`acquisition.windows.correct_poles` (the one implementation of that correction).
"""
from __future__ import annotations

import logging

import numpy as np

from acquisition.windows import correct_poles
from modalab.core.frf import FRF
from modalab.core.modes import ModeSet
from . import indicators as ind
from .stabilisation import pole_freq_damping
# the linear fit, the pole refinement and the pole uncertainty live in three modules, re-exported here
# (this stays the import path of every name below)
from .lsfd_linear import _Q, LSFDResult, lsfd
from .lsfd_refine import _basis, _LocalProjection, refine_poles  # noqa: F401
from .lsfd_uncertainty import frf_noise_variance, pole_uncertainty, window_corrected_covariance

log = logging.getLogger(__name__)

__all__ = ["LSFDResult", "lsfd", "refine_poles", "driving_points", "modes_from_poles", "frf_noise_variance",
           "pole_uncertainty", "window_corrected_covariance"]


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
    lam_true = correct_poles(res.lam, window_beta)
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
    syn = res.synthesise(frf)
    indic = {"MPC": ind.mpc(phi) if m else np.zeros(0), "MPD": ind.mpd(phi) if m else np.zeros(0),
             "MCF": ind.mcf(phi) if m else np.zeros(0), "MOV": mov}
    for k2, v in (extra_indicators or {}).items():
        indic[k2] = np.asarray(v)
    # modal contribution to the synthesis, per mode (fraction of the synthesised energy):
    # Σ_oif |A g + Ā gc|² = Σ_oi |A|² · Σ_f (|g|² + |gc|²) + 2 Re(Σ_oi A² · Σ_f g conj(gc))
    if m:
        tot = np.sum(np.abs(frf.H) ** 2)
        s = 2j * np.pi * frf.freq_hz
        q = _Q[frf.quantity]
        g = s[None, :] ** q / (s[None, :] - res.lam[:, None])                  # (m, nf)
        gc = s[None, :] ** q / (s[None, :] - res.lam.conj()[:, None])
        A = res.residues.reshape(-1, m)
        contrib = (np.sum(np.abs(A) ** 2, axis=0) * np.sum(np.abs(g) ** 2 + np.abs(gc) ** 2, axis=1)
                   + 2 * np.real(np.sum(A ** 2, axis=0) * np.sum(g * gc.conj(), axis=1))) / tot
        indic["contribution"] = contrib
    res.metadata.update({"frf_correlation": ind.frf_correlation(syn.H, frf.H),
                         "synthesis_error": ind.synthesis_error(syn.H, frf.H), "window_beta": float(window_beta)})
    modes = ModeSet(freq_hz=fn, damping=zeta, shapes=phi, dofs=frf.responses, participation=Lrep,
                    references=frf.references, scaling=scaling, indicators=indic,
                    metadata={"quantity": frf.quantity})
    return modes, res
