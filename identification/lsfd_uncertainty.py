"""Pole uncertainty from FRF noise: the variance of the FRF on every line (:func:`frf_noise_variance`),
propagated to first order through the local pole problem to frequency and damping standard deviations
(:func:`pole_uncertainty`), with the exponential-window correction of the covariance
(:func:`window_corrected_covariance`).

Split out of :mod:`identification.lsfd` (which re-exports these names).
"""

from __future__ import annotations

import logging
import numpy as np
from scipy.stats import f as f_dist

from acquisition.windows import correct_poles
from modalab.core.errors import ModalabValueError, ShapeError, fmt_error
from modalab.core.frf import FRF
from .lsfd_linear import _Q
from .lsfd_refine import _local_problem

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- pole uncertainty
def frf_noise_variance(frf: FRF):
    """Variance of the FRF estimate on every line, ``E|Ĥ − H|²`` (complex), shape like ``H``, and its source.

    In order of preference:

    ``'H_variance'``
        ``frf.variance``, the variance across averages of each FRF line (real,
        ``>= 0``, same shape as ``H``).
    ``'coherence'``
        From the ordinary coherence ``γ̂²`` and ``metadata['n_averages']`` = n >= 2: the random
        error of the H1 estimate has ``var|Ĥ| ≈ |H|² var(arg Ĥ) ≈ (1−γ²)/(2nγ²)·|H|²`` with the
        *true* coherence γ² (Bendat & Piersol, *Random Data*, eq. 9.73; circular, so each of Re, Im
        carries that and ``E|Ĥ − H|² ≈ (1−γ²)/(nγ²)·|H|²``).  The coherence in the file is itself
        estimated from the same n averages and is biased high: ``1 − γ̂²`` is the output power left
        after fitting one complex coefficient per line, ``Σ|Y − ĤX|²/Σ|Y|²``, whose mean holds n − 1
        averages' worth of noise, so ``E[(1−γ̂²)/γ̂²] ≈ (n−1)/n · (1−γ²)/γ²`` and the unbiased
        variance is ``E|Ĥ − H|² ≈ (1−γ̂²)/((n−1)γ̂²)·|Ĥ|²`` (with n = 5 averages the textbook form
        read with γ̂² is 20 % low: measured 1.25 on the roving-plate generator,
        ``tests/identification/test_pole_uncertainty.py``).
    ``'residual'``
        Neither is usable: returns ``None``; :func:`pole_uncertainty` then estimates the noise
        from the residual of the local fit (least reliable: model error counts as noise).

    Raises ``ModalabValueError`` naming the bad value when ``n_averages`` is not a positive integer
    (the variance itself is checked by :class:`~modalab.core.frf.FRF`: shape, finite, >= 0).
    """
    H = frf.H
    if frf.variance is not None:
        v = frf.variance
        return v, "H_variance"
    if frf.coherence is not None:
        n = frf.metadata.get("n_averages")
        if n is None:
            log.info("coherence without metadata['n_averages']: FRF noise taken from the fit residual")
            return None, "residual"
        try:
            n_ok = float(n) == int(n) and int(n) >= 1
        except (TypeError, ValueError):
            n_ok = False
        if not n_ok:
            raise ModalabValueError(fmt_error("FRF.metadata['n_averages']", n, "a positive integer",
                                              "Store the number of averages of the FRF estimate"))
        if int(n) < 2:
            log.info("one average (coherence is 1 by construction): FRF noise taken from the fit residual")
            return None, "residual"
        g2 = np.clip(np.nan_to_num(frf.coherence, nan=0.0), 1e-6, 1.0)
        return (1.0 - g2) / ((int(n) - 1) * g2) * np.abs(H) ** 2, "coherence"
    return None, "residual"


def window_corrected_covariance(wn, zeta, cov, beta: float = 0.0):
    """Move ``(ω_n, ζ)`` of a measured pole and their 2×2 covariance through the window correction.

    The exponential window ``e^{−βt}`` shifts the pole by a constant, ``λ_true = λ_meas + β``:
    ``σ_true = σ_meas + β`` (``σ = Re λ = −ζω_n``), ``ω_d`` unchanged.  The covariance of
    ``(σ, ω_d)`` is therefore unchanged by the correction; it is mapped there from the measured
    ``(ω_n, ζ)`` (``σ = −ζω_n``, ``ω_d = ω_n√(1−ζ²)``) and back at the *corrected* pole
    (``ω_n = √(σ² + ω_d²)``, ``ζ = −σ/ω_n``).  In particular ``std ζ`` is not simply carried over:
    ``ζ_true ≈ ζ_meas − β/ω_n`` also scatters with ``ω_n`` (negligible unless β/ω_n is comparable
    to ζ).  Returns ``(wn_true, zeta_true, cov_true)``.
    """
    cov = np.asarray(cov, float)
    if beta == 0.0:
        return wn, zeta, cov
    sq = np.sqrt(1.0 - zeta ** 2)
    T = np.array([[-zeta, -wn], [sq, -wn * zeta / sq]])                 # ∂(σ, ω_d)/∂(ω_n, ζ)
    lt = correct_poles(-zeta * wn + 1j * wn * sq, beta)
    sig, wd = lt.real, lt.imag
    wt = np.hypot(sig, wd)
    G = np.array([[sig / wt, wd / wt], [-wd ** 2 / wt ** 3, sig * wd / wt ** 3]])   # ∂(ω_n, ζ)/∂(σ, ω_d)
    K = G @ T
    return wt, -sig / wt, K @ cov @ K.T


def pole_uncertainty(frf: FRF, lam, participation, *, half_bandwidths: float = 12.0, window_beta: float = 0.0,
                     noise_variance=None):
    """First-order standard deviations of the refined natural frequencies and damping ratios.

    Each pole ``x = (ω_n, ζ)`` of :func:`refine_poles` minimises ``‖r(x)‖² = ‖(I − P(x)) Y‖²`` on
    the lines of its window (variable projection: the shapes and the local residual terms are
    eliminated).  Linearising the stationarity condition ``Jᵀr = 0`` around the noise-free
    solution gives ``δx = −(JᵀJ)⁻¹ Jᵀ δY`` with ``J`` the Jacobian of the projected residual
    (Kaufman's, exact at ``r = 0``; the linear unknowns estimated from the same data are accounted
    for by the projection: this is the x-block of the linearised covariance of the full problem, by the
    Schur complement).  With the noise variances ``V`` of the real and
    imaginary parts of every FRF line (``E|δH|²/2`` each),

        cov x = (JᵀJ)⁻¹ (Jᵀ V J) (JᵀJ)⁻¹,

    the covariance of the (unweighted) least-squares estimate actually computed.  In the whitened
    form ``J_w = V^{−1/2} J`` this is ``(J_wᵀJ_w)⁻¹`` when every line has the same variance (the
    usual ``s²(JᵀJ)⁻¹`` with ``s² = 1`` for true variances).  Cost: one projection and one
    Jacobian per mode, no extra fit.

    Assumptions: first order (small noise: the std must be small against the damping bandwidth
    ``ζω_n``); noise uncorrelated across lines, references and outputs and circular (Re and Im
    independent, equal variance); the other poles of the window held at their estimates
    (well-separated modes); the local model (modes in and near the window plus a cubic per
    reference) fits the noise-free FRF.  A pole on a bound of the refinement has no meaningful
    covariance.

    The noise comes from ``noise_variance`` (shape of ``H``, ``E|δH|²``) or
    :func:`frf_noise_variance`; without either it is estimated per FRF from the residual of the
    local fit (``s² = ‖r_oi‖²/ν``, ν the degrees of freedom).  ``chi2_ratio`` is
    ``Σ r²/V / ν`` — about 1 when the given variances describe the scatter about the model
    (NaN for the residual estimate, where it is 1 by construction).  Variances from coherence
    are themselves estimates with ``2(n−1)`` degrees of freedom per line, and ``E[1/V̂] =
    (n−1)/(n−2) · 1/V`` (inverse chi-square): the ratio is divided by that factor (n >= 3), so that it
    is about 1 there too (it read 1.33 with 5 averages on data the model fits).

    With several references the residues of each mode are also tested for rank one
    (:meth:`~identification.lsfd_refine._LocalProjection.rank_one_test`): ``rank2_F``, its p-value ``rank2_p``
    under F(dof1, dof2) and ``rank2_fraction`` (energy beyond rank one / energy of the mode), NaN with one
    reference or one response (the residues are of rank one whatever the data).  A merged close pair fails the test (see :func:`~identification.polymax.may_be_pair`).

    Returns a dict: ``freq_std_hz``, ``damping_std``, ``chi2_ratio``, ``rank2_*`` (m,), ``cov`` (m, 2, 2) of
    ``(ω_n [rad/s], ζ)`` of the window-corrected poles (see :func:`window_corrected_covariance`),
    ``source`` ('H_variance', 'coherence', 'residual' or 'given').  Modes whose window is too
    short for the refinement get NaN.
    """
    lam = np.array(np.atleast_1d(lam), complex)
    m = lam.size
    L = np.asarray(participation, complex).reshape(frf.n_in, m)
    if noise_variance is None:
        var, source = frf_noise_variance(frf)
    else:
        var, source = np.asarray(noise_variance, float), "given"
        if var.shape != frf.H.shape:
            raise ShapeError(f"noise_variance has shape {var.shape}; expected {frf.H.shape} like H")
    out = {"freq_std_hz": np.full(m, np.nan), "damping_std": np.full(m, np.nan), "chi2_ratio": np.full(m, np.nan),
           "cov": np.full((m, 2, 2), np.nan), "source": source, "rank2_F": np.full(m, np.nan),
           "rank2_p": np.full(m, np.nan), "rank2_fraction": np.full(m, np.nan)}
    if m == 0:
        return out
    f = frf.freq_hz
    q = _Q[frf.quantity]
    df = float(np.median(np.diff(f))) if f.size > 1 else 1.0
    Yall = frf.H.transpose(1, 2, 0)
    Vall = None if var is None else 0.5 * var.transpose(1, 2, 0)          # per real component
    n_avg = int(frf.metadata.get("n_averages", 0)) if source == "coherence" else 0
    for r in range(m):
        loc = _local_problem(frf, f, q, df, Yall, lam, L, r, half_bandwidths)
        if loc is not None:
            _mode_std(out, r, frf, loc, Vall, source, n_avg, float(window_beta))
    return out


def _mode_std(out: dict, r: int, frf: FRF, loc: dict, Vall, source: str, n_avg: int, window_beta: float) -> None:
    """Mode ``r`` of :func:`pole_uncertainty`: the rank-one test of its residues and the covariance of its
    ``(ω_n, ζ)`` from its local problem ``loc`` (:func:`_local_problem`), written into ``out``; left NaN where
    the window has no degrees of freedom left or the normal matrix is singular."""
    vp, ynorm, sel = loc["vp"], loc["ynorm"], loc["sel"]
    st = vp.factor(np.array([loc["wn"], loc["zr"]]))
    if frf.n_in > 1:
        F, d1, d2, frac = vp.rank_one_test(np.array([loc["wn"], loc["zr"]]))
        if d1 > 0 and d2 > 0 and np.isfinite(F):
            out["rank2_F"][r], out["rank2_fraction"][r] = F, frac
            out["rank2_p"][r] = float(f_dist.sf(F, d1, d2))
    D, c = vp._derivatives(st)
    Dp = vp._project(st, D)                                                 # (rows, 4)
    # J[:, o, k] = −P⊥(d_re,k c_0o + d_im,k c_1o), back in the units of H
    J = -(Dp[:, None, :2] * c[0][None, :, None] + Dp[:, None, 2:] * c[1][None, :, None]) * ynorm
    res = st["res"] * ynorm                                                 # (rows, n_out)
    n_rows, n_out = res.shape
    nu = n_rows * n_out - loc["n_lin"] * n_out - 2
    if nu <= 0:
        return
    if Vall is not None:
        V = Vall[:, sel, :].reshape(-1, n_out)
        V = np.concatenate([V, V], axis=0)
        pos = V > 0
        chi2 = float(np.sum(res[pos] ** 2 / V[pos])) / nu if pos.any() else np.nan
        if source == "coherence" and n_avg >= 3:
            chi2 *= (n_avg - 2) / (n_avg - 1)               # E[1/V̂] of a variance with 2(n−1) dof
    else:
        # per FRF (reference i, output o): s² from the residual, corrected for the fitted unknowns
        r4 = res.reshape(2, frf.n_in, -1, n_out)
        s2 = np.mean(r4 ** 2, axis=(0, 2)) * (n_rows * n_out / nu)            # (n_in, n_out)
        V = np.broadcast_to(s2[None, :, None, :], r4.shape).reshape(n_rows, n_out)
        chi2 = np.nan
    A = np.einsum("rok,rol->kl", J, J)
    Bm = np.einsum("rok,ro,rol->kl", J, V, J)
    try:
        Ai = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return
    cov = Ai @ Bm @ Ai
    if not np.all(np.isfinite(cov)):
        return
    _, _, cov = window_corrected_covariance(loc["wn"], loc["zr"], cov, window_beta)
    out["cov"][r] = cov
    out["freq_std_hz"][r] = np.sqrt(max(cov[0, 0], 0.0)) / (2 * np.pi)
    out["damping_std"][r] = np.sqrt(max(cov[1, 1], 0.0))
    out["chi2_ratio"][r] = chi2
