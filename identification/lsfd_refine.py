"""LSFD pole refinement: each pole re-estimated on its own band by a variable-projection objective (the
linear residues eliminated, :class:`_LocalProjection`) minimised by a bounded Levenberg-Marquardt
(:func:`_minimise_lm`), in :func:`refine_poles`; :func:`_local_problem` builds one pole's band problem
(also used by the pole uncertainty).

Split out of :mod:`identification.lsfd` (which re-exports these names); the model is described there.
"""

from __future__ import annotations

import numpy as np
from modalab.core.frf import FRF
from .lsfd_linear import _Q


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

    The local basis is ``A = [E, B, a(x)]``: ``E`` the polynomial residual terms (cubic) — per reference and per
    real/imaginary part the same ``POLY_DEG + 1`` polynomials ``poly`` (lines × 4) on that reference's rows, so
    ``(I − P_E)`` is the projection off one 4-column basis applied segment by segment (no QR of the
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
        self.Q0 = np.linalg.qr(np.asarray(poly, float))[0]                     # (lines, 4) orthonormal
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

    def _columns(self, lam, l=None):
        """The two real columns ("Re ψ", "Im ψ") of one pole, rows (reference, line) real then imaginary,
        and ``l g``, ``l̄ gc``, ``1/(s − λ)``, ``1/(s − λ̄)`` for the derivatives (``l`` the participation,
        the current one by default)."""
        l = self.l if l is None else l
        inv = 1.0 / (self.s - lam)
        invc = 1.0 / (self.s - lam.conjugate())
        lg = l[:, None] * (self.sq * inv)[None, :]
        lgc = l.conj()[:, None] * (self.sq * invc)[None, :]
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

    def free_participation(self, x):
        """The participation vector of the refined mode re-estimated at ``x``: its residues ``A_oi`` fitted
        free per output and reference (the other modes and the polynomials projected off as in the
        objective), then the best rank-one ``A ≈ ψ lᵀ`` (first singular pair); ``l`` scaled and phased like
        the current one (only its direction matters)."""
        lam = self.pole(x)
        g = self.sq / (self.s - lam)
        gc = self.sq / (self.s - lam.conjugate())
        n_in, nf = self.l.size, self.s.size
        cols = []
        for i in range(n_in):
            e = np.zeros((n_in, 1))
            e[i] = 1.0
            for v in ((e * (g + gc)[None, :]).ravel(), (1j * e * (g - gc)[None, :]).ravel()):
                cols.append(np.concatenate([v.real, v.imag]))
        C = self._off_B(np.stack(cols, axis=1))
        c = np.linalg.lstsq(C, self.Yp, rcond=None)[0]                          # (2 n_in, n_out)
        A = c[0::2] + 1j * c[1::2]                                              # (n_in, n_out)
        u = np.linalg.svd(A, full_matrices=False)[0][:, 0]
        p = np.vdot(u, self.l)
        if not abs(p) > 0:
            return self.l.copy()
        return u * (p / abs(p)) * np.linalg.norm(self.l)

    def rank_one_test(self, x):
        """How much better the refined mode's residues fit without the rank-one constraint, at ``x``.

        Returns ``(F, dof1, dof2, fraction)``: the F statistic of the residues free per output and reference
        (``2·n_in`` real columns) against ``ψ lᵀ`` with ``l`` fitted (:meth:`free_participation`), both on the
        same local problem, and ``fraction`` = the energy the free residues fit beyond the rank-one mode,
        relative to the rank-one mode's.  One mode gives residues of rank one, so ``F`` follows
        F(dof1, dof2) under white noise; two modes merged into one pole (a pair closer than the pole can
        resolve) give rank two: a large ``F``, and ``fraction`` ≈ (weaker/stronger residue)².
        """
        lam = self.pole(x)
        n_in = self.l.size
        cols = []
        for i in range(n_in):
            e = np.zeros(n_in, complex)
            e[i] = 1.0
            cols.append(self._columns(lam, e)[0])
        Q = np.linalg.qr(self._off_B(np.concatenate(cols, axis=1)))[0]
        c2 = float(np.sum((self.Yp - Q @ (Q.T @ self.Yp)) ** 2))
        keep = self.l
        self.l = self.free_participation(x)
        c1 = self.factor(x)["cost"]
        self.l = keep
        n_rows, n_out = self.Yp.shape
        dof1 = (2 * n_in - 2 - 2 * (n_in - 1) / n_out) * n_out        # free residues minus ψ (2 n_out) and l
        dof2 = n_rows * n_out - self.QB.shape[1] * n_out - 2 * n_in * n_out - self.Q0.shape[1] * 2 * n_in * n_out
        if dof1 <= 0 or dof2 <= 0 or c2 <= 0:
            # one response (or one reference): residues of rank one whatever the data; or no dof left: no test
            return float("nan"), dof1, dof2, float("nan")
        frac = max(c1 - c2, 0.0) / max(float(np.sum(self.Yp ** 2)) - c1, 1e-300)
        return (max(c1 - c2, 0.0) / dof1) / (c2 / dof2), dof1, dof2, frac

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
        return self._column_derivatives(st["parts"], st["x"]), c

    @staticmethod
    def _column_derivatives(parts, x):
        """``∂a/∂(ω_n, ζ)`` of the two columns from :meth:`_columns`' parts, (rows, 4): Re ψ then Im ψ."""
        lg, lgc, inv, invc = parts
        g1 = lg * inv[None, :]                                   # l ∂g/∂λ = l s^q/(s − λ)², (n_in, nf)
        g2 = lgc * invc[None, :]                                               # l̄ ∂ḡ/∂λ̄
        # ∂/∂σ and ∂/∂ω_d of the columns l g + l̄ gc ("Re ψ") and i(l g − l̄ gc) ("Im ψ")
        re = lambda v: np.concatenate([v.real.ravel(), v.imag.ravel()])  # noqa: E731
        s_re, s_im = re(g1 + g2), re(1j * (g1 - g2))
        w_re, w_im = s_im, -s_re
        w0, z0 = x
        sq = np.sqrt(1 - z0 ** 2)
        dsig = (-z0, -w0)                                                       # ∂σ/∂(ω_n, ζ)
        dwd = (sq, -w0 * z0 / sq)                                               # ∂ω_d/∂(ω_n, ζ)
        D = np.stack([dsig[j] * s_re + dwd[j] * w_re for j in range(2)]
                     + [dsig[j] * s_im + dwd[j] * w_im for j in range(2)], axis=1)   # (rows, 4)
        return D

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

#: the local basis of pole r holds every other mode within NEIGHBOUR_REACH window half-widths of it (their
#: poles and participations held at their estimates, their shapes fitted), not only those inside the window:
#: a neighbour just outside the band edge has its peak's skirt inside the window, which no low-degree
#: polynomial represents.  With the modes inside the window only (reach 1), the roving-plate poles with a
#: neighbour 1-2 half-bandwidths beyond an edge were biased by up to 55 sigma in frequency and 140 sigma in
#: damping (chi-square of the local fit up to 10^4); with reach 3 the biases are below 1 sigma and the
#: chi-square about 1 (tests/identification/test_roving_uncertainty.py).  Modes farther away are smooth
#: over the window: the polynomial takes them (as columns they would be nearly collinear with it).
NEIGHBOUR_REACH = 3.0
#: degree of the per-reference complex polynomial standing for the modes beyond the reach (the residual
#: terms of the local band).  Cubic, not quadratic: near the band edge the window is one-sided and the
#: modes beyond the band (not in the model at all) bend the FRF more than a quadratic follows (the
#: roving plate's two top modes, 187 and 194 Hz, 8 Hz below a group of four above 200 Hz: frequency
#: bias -3.6 sigma with a quadratic, -0.5 sigma with a cubic).
POLY_DEG = 3
#: the participation of a mode is re-estimated by the refinement only with no other mode within this many
#: half-power bandwidths (ζ·ω_n) of it (a pair 0.016 % apart with orthogonal participations was lost otherwise:
#: tests/identification/test_merged_pair_flag.py)
PARTICIPATION_CLEARANCE = 2.0


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
                 lower_residual: bool = True, upper_residual: bool = True, return_participation: bool = False):
    """Refine each pole by variable-projection least squares on the lines around it.

    For mode r, ``λ_r`` (2 real unknowns) minimises ``‖(I − P(λ)) H‖`` over the
    lines within ``f_r ± max(min(half_bandwidths·ζ_r, 0.1)·f_r, 4 lines)``, where ``P(λ)``
    projects on the LSFD basis of the poles within ``NEIGHBOUR_REACH`` (3) times that half-width (so a
    neighbour whose peak lies just beyond a window edge is modelled, not cut through) plus, per
    reference, a complex cubic in frequency for all modes farther away (shapes and
    these local residuals eliminated linearly, Golub & Pereyra 1973).  Modes are swept ``passes`` times.  The
    frequency may move by at most half the distance to the neighbouring modes and
    the damping stays in ``(0, 0.5)``, so a pole never jumps to a neighbour.
    This is the single-pole counterpart of the maximum-likelihood refinement of
    PolyMAX Plus; it reduces the noise bias of the linearised pLSCF damping.

    Each pole is minimised by :func:`_minimise_lm` (analytic Kaufman Jacobian, at most 20
    evaluations); a pole that uses them all is a noise pole creeping along a flat valley and is
    not swept again.

    With ``return_participation`` (several references) each mode's participation vector is re-estimated
    after its pole, from the same local problem (:meth:`_LocalProjection.free_participation`: residues
    free per output and reference, best rank-one fit), and used by the next pass and by the caller;
    returns ``(lam, participation)``.  The diagram's participation comes from one order's denominator
    and carries its noise: on the roving plate the two modes below the band edge had damping biased by
    1.3-1.4 sigma with it, 0.3 sigma re-estimated.
    """
    lam = np.array(np.atleast_1d(lam), complex)
    L = np.array(participation, complex).reshape(frf.n_in, lam.size)
    m = lam.size
    if m == 0:
        return (lam, L) if return_participation else lam
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
            if return_participation and L.shape[0] > 1 and not unsettled[r]:
                # not beside a mode within PARTICIPATION_CLEARANCE half-power bandwidths: the free residues of
                # two nearly coincident poles are nearly collinear (their difference is noise), while the
                # diagram's participations keep them apart
                near = np.abs(np.abs(lam) - w0) < PARTICIPATION_CLEARANCE * z0 * w0
                near[r] = False
                if not near.any():
                    L[:, r] = vp.free_participation(x)
    if return_participation:
        return lam, L
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

    # local basis: the modes inside the window and near its edges (NEIGHBOUR_REACH) plus, per reference, a
    # complex cubic in frequency standing for every mode farther away (well conditioned on a short band)
    inwin = np.flatnonzero(np.abs(np.abs(lam) / (2 * np.pi) - fr) <= NEIGHBOUR_REACH * hw)
    k_r = int(np.flatnonzero(inwin == r)[0])
    x_loc = (f[sel] - fr) / hw
    n_in = frf.n_in
    # per reference a complex polynomial: real coefficients on the real rows and on the imaginary rows
    poly = np.stack([x_loc ** k for k in range(POLY_DEG + 1)], axis=1)
    vp = _LocalProjection(s, q, lam[inwin], L[:, inwin], k_r, poly, Y, ynorm)
    return {"vp": vp, "wn": wn, "zr": zr, "wlo": wlo, "whi": whi, "sel": sel, "ynorm": ynorm,
            "n_lin": 2 * inwin.size + 2 * (POLY_DEG + 1) * n_in}
