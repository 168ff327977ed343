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
from dataclasses import dataclass, field

import numpy as np

from acquisition.windows import correct_poles
from modalab.core.errors import ModalabValueError, ShapeError, fmt_error
from modalab.core.frf import FRF
from modalab.core.modes import ModeSet
from . import indicators as ind
from .stabilisation import pole_freq_damping

log = logging.getLogger(__name__)

__all__ = ["LSFDResult", "lsfd", "refine_poles", "driving_points", "modes_from_poles", "frf_noise_variance",
           "pole_uncertainty", "window_corrected_covariance"]

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


def _basis(s, q, lam, L, lower_residual, upper_residual):
    """Real LSFD design matrix on the lines ``s = iω`` (rows: real then imaginary parts)."""
    n_in = L.shape[0]
    g = s[None, :] ** q / (s[None, :] - lam[:, None])
    gc = s[None, :] ** q / (s[None, :] - lam.conj()[:, None])
    lg = L[:, :, None] * g[None]
    lgc = L.conj()[:, :, None] * gc[None]
    blocks = [np.transpose(lg + lgc, (0, 2, 1)), np.transpose(1j * (lg - lgc), (0, 2, 1))]
    eye = np.eye(n_in)
    if lower_residual:
        blocks.append(eye[:, None, :] * (s ** (q - 2))[None, :, None])
    if upper_residual:
        blocks.append(eye[:, None, :] * (s ** q)[None, :, None])
    A = np.concatenate(blocks, axis=2).reshape(n_in * s.size, -1)
    return np.concatenate([A.real, A.imag], axis=0)


class _LocalProjection:
    """Variable-projection objective ``‖(I − P(x))Y‖²/‖Y‖²`` of one pole ``λ(ω_n, ζ)``, minimised by LM.

    The local basis is ``A = [E, B, a(x)]``: ``E`` the quadratic residual terms — per reference and per
    real/imaginary part the same three polynomials ``poly`` (lines × 3) on that reference's rows, so
    ``(I − P_E)`` is the projection off one 3-column basis applied segment by segment (no QR of the
    6·n_in columns, which dominated with many references) —, ``B`` the other modes in the window
    (projected off ``E``); neither depends on the refined pole, ``a(x)`` are the two columns "Re ψ",
    "Im ψ" of the refined mode.  ``B = Q_B R_B`` is factored once; every evaluation projects ``a`` and ``Y``
    off ``E`` and ``B`` and factors the two remaining columns (``P = Q_B Q_Bᵀ + q qᵀ``, ``q`` the orthonormal
    basis of ``(I − Q_B Q_Bᵀ) a``), and the coefficients of ``a`` are those of the regression of the
    projected data on the projected columns (Frisch–Waugh–Lovell).

    The Jacobian is Kaufman's (1975) ``J_k = −(I − P)(∂a/∂x_k) c`` (``c`` the coefficients of ``a``), the
    projection of a rank-two matrix, so ``JᵀJ`` and ``Jᵀr`` reduce to inner products of short vectors.
    It drops the Golub–Pereyra term ``−(A⁺)ᵀ(∂A/∂x_k)ᵀ r``, whose product with the residual vanishes
    (``A⁺ r = 0``), so the gradient ``Jᵀr`` and the stationary points are exact.
    """

    def __init__(self, s, q, lam, L, k_r, poly, Y, ynorm):
        self.s, self.q, self.k_r = s, q, k_r
        self.l = np.asarray(L, complex)[:, k_r]
        self.sq = s ** q
        self.Q0 = np.linalg.qr(np.asarray(poly, float))[0]                     # (lines, 3) orthonormal
        others = np.delete(np.arange(np.size(lam)), k_r)
        B = self._off_poly(_basis(s, q, np.asarray(lam, complex)[others], np.asarray(L, complex)[:, others],
                                  False, False))
        sc = np.linalg.norm(B, axis=0)
        sc[sc == 0] = 1.0
        self.QB = np.linalg.qr(B / sc)[0]
        Y = Y / ynorm
        self.Yp = self._off_B(Y)                                                  # data off E and B

    @staticmethod
    def pole(x):
        w0, z0 = x
        return -z0 * w0 + 1j * w0 * np.sqrt(1 - z0 ** 2)

    def _off_poly(self, V):
        """``(I − P_E) V``: every (real/imaginary part, reference) segment of the rows off ``Q0``."""
        nl = self.Q0.shape[0]
        if V.size == 0:
            return V
        W = V.reshape(V.shape[0] // nl, nl, -1)
        W = W - self.Q0 @ (self.Q0.T @ W)                                     # batched over the segments
        return W.reshape(V.shape)

    def _off_B(self, V):
        """``(I − P_B)(I − P_E) V``; ``P_B`` twice (classical Gram–Schmidt with one re-orthogonalisation)."""
        V = self._off_poly(V)
        if not self.QB.shape[1]:
            return V
        V = V - self.QB @ (self.QB.T @ V)
        return V - self.QB @ (self.QB.T @ V)

    def _columns(self, lam):
        """The two real columns ("Re ψ", "Im ψ") of one pole, rows (reference, line) real then imaginary,
        and ``l g``, ``l̄ gc``, ``1/(s − λ)``, ``1/(s − λ̄)`` for the derivatives."""
        inv = 1.0 / (self.s - lam)
        invc = 1.0 / (self.s - lam.conjugate())
        lg = self.l[:, None] * (self.sq * inv)[None, :]
        lgc = self.l.conj()[:, None] * (self.sq * invc)[None, :]
        cre, cim = (lg + lgc).ravel(), (1j * (lg - lgc)).ravel()
        a = np.stack([np.concatenate([cre.real, cre.imag]), np.concatenate([cim.real, cim.imag])], axis=1)
        return a, (lg, lgc, inv, invc)

    def factor(self, x):
        """Projection at ``x``: the state used by :meth:`normal` (``cost`` is ``‖r‖²``)."""
        lam = self.pole(x)
        a, parts = self._columns(lam)
        a = self._off_B(a)                                                     # (rows, 2)
        # QR of two columns by Gram–Schmidt with one re-orthogonalisation
        r11 = np.linalg.norm(a[:, 0])
        q1 = a[:, 0] / r11 if r11 > 0 else a[:, 0]
        v = a[:, 1] - q1 * (q1 @ a[:, 1])
        v -= q1 * (q1 @ v)
        r22 = np.linalg.norm(v)
        q2 = v / r22 if r22 > 0 else v
        qa = np.stack([q1, q2], axis=1)
        ra = np.array([[r11, q1 @ a[:, 1]], [0.0, r22]])
        QtY = qa.T @ self.Yp
        res = self.Yp - qa @ QtY
        return {"x": np.array(x, float), "lam": lam, "q": qa, "r": ra, "QtY": QtY, "res": res,
                "cost": float(np.sum(res * res)), "parts": parts}

    def residual(self, x):
        """The residual vector (for checks; the solver uses :meth:`factor`)."""
        return self.factor(x)["res"].ravel()

    def _derivatives(self, st):
        """``∂a/∂x_k`` as real vectors (columns Re ψ: ∂ω_n, ∂ζ; Im ψ: ∂ω_n, ∂ζ), coefficients ``c``."""
        (r11, r12), (_, r22) = st["r"]
        if r11 > 0 and r22 > 0:
            c1 = st["QtY"][1] / r22
            c = np.stack([(st["QtY"][0] - r12 * c1) / r11, c1])                # (2, n_out): R c = QᵀY
        else:
            c = np.linalg.lstsq(st["r"], st["QtY"], rcond=None)[0]
        lg, lgc, inv, invc = st["parts"]
        g1 = lg * inv[None, :]                                   # l ∂g/∂λ = l s^q/(s − λ)², (n_in, nf)
        g2 = lgc * invc[None, :]                                               # l̄ ∂ḡ/∂λ̄
        # ∂/∂σ and ∂/∂ω_d of the columns l g + l̄ gc ("Re ψ") and i(l g − l̄ gc) ("Im ψ")
        re = lambda v: np.concatenate([v.real.ravel(), v.imag.ravel()])  # noqa: E731
        s_re, s_im = re(g1 + g2), re(1j * (g1 - g2))
        w_re, w_im = s_im, -s_re
        w0, z0 = st["x"]
        sq = np.sqrt(1 - z0 ** 2)
        dsig = (-z0, -w0)                                                       # ∂σ/∂(ω_n, ζ)
        dwd = (sq, -w0 * z0 / sq)                                               # ∂ω_d/∂(ω_n, ζ)
        D = np.stack([dsig[j] * s_re + dwd[j] * w_re for j in range(2)]
                     + [dsig[j] * s_im + dwd[j] * w_im for j in range(2)], axis=1)   # (rows, 4)
        return D, c

    def _project(self, st, V):
        V = self._off_B(V)
        return V - st["q"] @ (st["q"].T @ V)

    def jacobian(self, x):
        """Kaufman Jacobian of :meth:`residual` (formed explicitly; for checks)."""
        st = self.factor(x)
        D, c = self._derivatives(st)
        J = np.empty((st["res"].size, 2))
        for j in range(2):
            G = np.outer(D[:, j], c[0]) + np.outer(D[:, 2 + j], c[1])
            J[:, j] = -self._project(st, G).ravel()
        return J

    def normal(self, st):
        """``JᵀJ`` (2×2) and ``Jᵀr`` (2) from inner products: ``J_k = −P⊥(d_re,k c_0ᵀ + d_im,k c_1ᵀ)``."""
        D, c = self._derivatives(st)
        Dp = self._project(st, D)
        Dg = Dp.T @ Dp                                                          # <d_a, P⊥ d_b>
        Cg = c @ c.T                                                            # <c_a, c_b>
        # JtJ[i, j] = Σ_ab <d_a,i, P⊥ d_b,j> <c_a, c_b>, D columns ordered (a, i)
        JtJ = np.einsum("aibj,ab->ij", Dg.reshape(2, 2, 2, 2), Cg)
        RC = st["res"] @ c.T                                                    # (rows, 2): r c_a
        Jtr = -(D[:, :2].T @ RC[:, 0] + D[:, 2:].T @ RC[:, 1])
        return JtJ, Jtr


_MAX_NFEV = 20


def _minimise_lm(vp, x0, lo, hi, x_scale, *, xtol=1e-10, ftol=1e-12, max_nfev=_MAX_NFEV):
    """Box-constrained Levenberg–Marquardt on two variables (projected steps, scaled by ``x_scale``).

    A variable on a bound whose gradient points out of the box is held there (active set).

    Stops like ``scipy.optimize.least_squares``: when a step is shorter than
    ``xtol·(xtol + ‖x‖)`` or an accepted step lowers the cost by less than ``ftol`` (relative), or
    after ``max_nfev`` evaluations.  Returns the best point and the number of evaluations.
    Physical poles converge in 3–8 evaluations; poles still creeping along a flat valley after
    ``max_nfev`` = 20 are noise poles (their damping runs towards a bound), keep their last
    estimate and are left to the damping and MPC tests of the selection.
    """
    D = np.asarray(x_scale, float)
    st = vp.factor(np.clip(x0, lo, hi))
    nfev = 1
    JtJ, Jtr = vp.normal(st)
    mu = 1e-3 * max(float(np.max(np.diag(JtJ) * D ** 2)), 1e-300)
    while nfev < max_nfev:
        # variables on a bound that the gradient pushes outwards stay there (active set)
        free = ~(((st["x"] <= lo) & (Jtr > 0)) | ((st["x"] >= hi) & (Jtr < 0)))
        if not free.any():
            break
        Hs = (JtJ * np.outer(D, D))[np.ix_(free, free)]
        gs = (Jtr * D)[free]
        step = np.zeros(2)
        Hm = Hs + mu * np.eye(gs.size)
        if gs.size == 2:
            det = Hm[0, 0] * Hm[1, 1] - Hm[0, 1] * Hm[1, 0]
            if not det > 0:
                break
            sol = np.array([Hm[1, 1] * gs[0] - Hm[0, 1] * gs[1], Hm[0, 0] * gs[1] - Hm[1, 0] * gs[0]]) / det
        else:
            if not Hm[0, 0] > 0:
                break
            sol = gs / Hm[0, 0]
        step[free] = -sol * D[free]
        x_new = np.clip(st["x"] + step, lo, hi)
        dx = x_new - st["x"]
        if np.linalg.norm(dx) <= xtol * (xtol + np.linalg.norm(st["x"])):      # scipy's xtol test
            break
        new = vp.factor(x_new)
        nfev += 1
        if new["cost"] < st["cost"]:
            small = st["cost"] - new["cost"] <= ftol * st["cost"]
            st = new
            if small:
                break
            JtJ, Jtr = vp.normal(st)
            mu *= 0.3
        else:
            mu = max(mu * 10.0, 1e-12 * max(float(np.max(np.diag(Hs))), 1e-300))
    return st["x"], nfev


def refine_poles(frf: FRF, lam, participation, *, passes: int = 2, half_bandwidths: float = 12.0,
                 lower_residual: bool = True, upper_residual: bool = True) -> np.ndarray:
    """Refine each pole by variable-projection least squares on the lines around it.

    For mode r, ``λ_r`` (2 real unknowns) minimises ``‖(I − P(λ)) H‖`` over the
    lines within ``f_r ± max(min(half_bandwidths·ζ_r, 0.1)·f_r, 4 lines)``, where ``P(λ)``
    projects on the LSFD basis of the poles inside that window plus, per
    reference, a complex quadratic in frequency for all modes outside it (shapes and
    these local residuals eliminated linearly, Golub & Pereyra 1973).  Modes are swept ``passes`` times.  The
    frequency may move by at most half the distance to the neighbouring modes and
    the damping stays in ``(0, 0.5)``, so a pole never jumps to a neighbour.
    This is the single-pole counterpart of the maximum-likelihood refinement of
    PolyMAX Plus; it reduces the noise bias of the linearised pLSCF damping.

    Each pole is minimised by :func:`_minimise_lm` (analytic Kaufman Jacobian, at most 20
    evaluations); a pole that uses them all is a noise pole creeping along a flat valley and is
    not swept again.
    """
    lam = np.array(np.atleast_1d(lam), complex)
    L = np.asarray(participation, complex).reshape(frf.n_in, lam.size)
    m = lam.size
    if m == 0:
        return lam
    f = frf.freq_hz
    q = _Q[frf.quantity]
    df = float(np.median(np.diff(f))) if f.size > 1 else 1.0
    Yall = frf.H.transpose(1, 2, 0)                                   # (n_in, nf, n_out)
    unsettled = np.zeros(m, bool)           # hit the evaluation cap: a noise pole creeping along a valley
    for _ in range(int(passes)):
        order = np.argsort(lam.imag)
        for r in order:
            if unsettled[r]:
                continue
            loc = _local_problem(frf, f, q, df, Yall, lam, L, r, half_bandwidths)
            if loc is None:
                continue
            vp, wn, zr, wlo, whi = loc["vp"], loc["wn"], loc["zr"], loc["wlo"], loc["whi"]
            x, nfev = _minimise_lm(vp, np.array([wn, zr]), np.array([wlo, 1e-6]), np.array([whi, 0.5]),
                                   [max(zr * wn, 1e-3 * wn), max(zr, 1e-4)], max_nfev=_MAX_NFEV)
            unsettled[r] = nfev >= _MAX_NFEV
            w0, z0 = x
            lam[r] = -z0 * w0 + 1j * w0 * np.sqrt(1 - z0 ** 2)
    return lam


def _local_problem(frf, f, q, df, Yall, lam, L, r, half_bandwidths):
    """The local variable-projection problem of pole ``r`` used by :func:`refine_poles` (and by
    :func:`pole_uncertainty` at the refined pole): window, bounds and :class:`_LocalProjection`.

    ``None`` when the window holds fewer than 6 lines or the neighbours leave no room.
    """
    m = lam.size
    wn = abs(lam[r])
    fr = wn / (2 * np.pi)
    zr = -lam[r].real / wn
    hw = max(min(half_bandwidths * zr, 0.1) * fr, 4 * df)
    sel = np.abs(f - fr) <= hw
    if sel.sum() < 6:
        return None
    s = 2j * np.pi * f[sel]
    Y = Yall[:, sel, :].reshape(-1, frf.n_out)
    Y = np.concatenate([Y.real, Y.imag], axis=0)
    ynorm = np.linalg.norm(Y)
    others = np.abs(lam.imag - lam[r].imag)
    others[r] = np.inf
    gap = others.min() if m > 1 else wn
    wlo, whi = max(wn - 0.5 * gap, 0.5 * wn), min(wn + 0.5 * gap, 1.5 * wn)
    if not (wlo < wn < whi):
        return None

    # local basis: the modes inside the window plus, per reference, a complex quadratic in
    # frequency standing for every mode outside it (well conditioned on a short band)
    inwin = np.flatnonzero(np.abs(np.abs(lam) / (2 * np.pi) - fr) <= hw)
    k_r = int(np.flatnonzero(inwin == r)[0])
    x_loc = (f[sel] - fr) / hw
    n_in = frf.n_in
    # per reference a complex quadratic: real coefficients on the real rows and on the imaginary rows
    poly = np.stack([np.ones_like(x_loc), x_loc, x_loc ** 2], axis=1)
    vp = _LocalProjection(s, q, lam[inwin], L[:, inwin], k_r, poly, Y, ynorm)
    return {"vp": vp, "wn": wn, "zr": zr, "wlo": wlo, "whi": whi, "sel": sel, "ynorm": ynorm,
            "n_lin": 2 * inwin.size + 6 * n_in}


# --------------------------------------------------------------------------- pole uncertainty
def frf_noise_variance(frf: FRF):
    """Variance of the FRF estimate on every line, ``E|Ĥ − H|²`` (complex), shape like ``H``, and its source.

    In order of preference:

    ``'H_variance'``
        ``frf.variance``, the variance across averages of each FRF line (real,
        ``>= 0``, same shape as ``H``).
    ``'coherence'``
        From the ordinary coherence ``γ²`` and ``metadata['n_averages']`` = n >= 2: the random
        error of the H1 estimate has ``var|Ĥ| ≈ |H|² var(arg Ĥ) ≈ (1−γ²)/(2nγ²)·|H|²``
        (Bendat & Piersol, *Random Data*, eq. 9.73; circular, so each of Re, Im carries that and
        ``E|Ĥ − H|² ≈ (1−γ²)/(nγ²)·|H|²``).
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
        return (1.0 - g2) / (int(n) * g2) * np.abs(H) ** 2, "coherence"
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
    (well-separated modes); the local model (modes in the window plus a quadratic per
    reference) fits the noise-free FRF.  A pole on a bound of the refinement has no meaningful
    covariance.

    The noise comes from ``noise_variance`` (shape of ``H``, ``E|δH|²``) or
    :func:`frf_noise_variance`; without either it is estimated per FRF from the residual of the
    local fit (``s² = ‖r_oi‖²/ν``, ν the degrees of freedom).  ``chi2_ratio`` is
    ``Σ r²/V / ν`` — about 1 when the given variances describe the scatter about the model
    (NaN for the residual estimate, where it is 1 by construction).

    Returns a dict: ``freq_std_hz``, ``damping_std``, ``chi2_ratio`` (m,), ``cov`` (m, 2, 2) of
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
           "cov": np.full((m, 2, 2), np.nan), "source": source}
    if m == 0:
        return out
    f = frf.freq_hz
    q = _Q[frf.quantity]
    df = float(np.median(np.diff(f))) if f.size > 1 else 1.0
    Yall = frf.H.transpose(1, 2, 0)
    Vall = None if var is None else 0.5 * var.transpose(1, 2, 0)          # per real component
    for r in range(m):
        loc = _local_problem(frf, f, q, df, Yall, lam, L, r, half_bandwidths)
        if loc is None:
            continue
        vp, ynorm, sel = loc["vp"], loc["ynorm"], loc["sel"]
        st = vp.factor(np.array([loc["wn"], loc["zr"]]))
        D, c = vp._derivatives(st)
        Dp = vp._project(st, D)                                                 # (rows, 4)
        # J[:, o, k] = −P⊥(d_re,k c_0o + d_im,k c_1o), back in the units of H
        J = -(Dp[:, None, :2] * c[0][None, :, None] + Dp[:, None, 2:] * c[1][None, :, None]) * ynorm
        res = st["res"] * ynorm                                                 # (rows, n_out)
        n_rows, n_out = res.shape
        nu = n_rows * n_out - loc["n_lin"] * n_out - 2
        if nu <= 0:
            continue
        if Vall is not None:
            V = Vall[:, sel, :].reshape(-1, n_out)
            V = np.concatenate([V, V], axis=0)
            pos = V > 0
            chi2 = float(np.sum(res[pos] ** 2 / V[pos])) / nu if pos.any() else np.nan
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
            continue
        cov = Ai @ Bm @ Ai
        if not np.all(np.isfinite(cov)):
            continue
        _, _, cov = window_corrected_covariance(loc["wn"], loc["zr"], cov, float(window_beta))
        out["cov"][r] = cov
        out["freq_std_hz"][r] = np.sqrt(max(cov[0, 0], 0.0)) / (2 * np.pi)
        out["damping_std"][r] = np.sqrt(max(cov[1, 1], 0.0))
        out["chi2_ratio"][r] = chi2
    return out


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
