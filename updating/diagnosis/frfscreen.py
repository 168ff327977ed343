"""Non-linear single-candidate screening on the FRFs: every candidate at every size, by low-rank updates.

The MCI screening (:mod:`~updating.diagnosis.screen`) is linear in the candidate's value: it ranks well
what is small, but an omitted effect strong enough to change the mode shapes (a stiff support, a heavy
fixture) is mis-ranked, and with few measured DOFs the expansion smears it.  Here each shared candidate
(a unit dynamic stiffness ``θ f(s) G`` with ``G = L Lᵀ`` of low rank ``r``: 1 for a spring, dashpot or
rotary inertia on one DOF, 3 for a point mass, ≤ 12 for an element group) is added *exactly* to the
current model by the Woodbury identity

    H_θ(s) = H(s) − H(s) L [ I/(θ f(s)) + Lᵀ H(s) L ]⁻¹ Lᵀ H(s),

on a grid of values spanning what is physically plausible, and the training FRF error
(:func:`~updating.diagnosis.fit.frf_error`) of each is compared with the current one.  Nothing is
linearised and unmeasured DOFs need no expansion: the receptance columns at the candidate's DOFs come from
the model (exactly for small models, in a Ritz basis with the candidate DOFs' static corrections for large
ones).  The cost is a few r × r solves per candidate, value and line.

Around a fitted model the parameters have already absorbed part of what is missing, and the candidate that the
full fit (parameters re-fitted with it) would prefer can rank far down with the parameters held: on a clamped
portal with a 1.6e5 N/m spring at 3+X (odd seed 1543, an analysed miss) that spring made the error worse at the
parameter fit's values (0.16 against 0.052) and the screening's first was a rotational spring ten nodes away,
yet fitted with the parameters the spring leaves χ²/N 0.35 against 2.5 for the first.  With a
:class:`ParameterRefit` the parameters are re-fitted alongside every candidate value to first order — the
first-order sensitivity step of thesis eq. (3.44)-(3.47) taken on the FRFs and solved in the least-squares sense of
eq. (3.32), with the priors' rows (a linearised MAP step), exact in the candidate:

    min_δ ‖r(θ) + J δ‖² + ‖r_p + J_p δ‖² = ‖r(θ)‖² + ‖r_p‖² − ‖Wᵀ(Jᵀ r(θ) + J_pᵀ r_p)‖²,   W Wᵀ = (JᵀJ + J_pᵀJ_p)⁺,

``J`` the Jacobian of the weighted residual in the parameters at the fit (computed once), so each value costs
one projection on the few columns of ``J W`` more.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize_scalar

from modalab.core.parallel import fork_map
from updating.correlation.condensation import solve_columns
from updating.diagnosis.fit import RITZ_LIMIT, FRFData, _exact_rows, _indices, frf_error
from updating.diagnosis.ritz import RitzBasis

log = logging.getLogger(__name__)
__all__ = ["frf_screen", "ParameterRefit"]

_FACTOR = {"K": lambda s: np.ones_like(s), "M": lambda s: s ** 2, "C": lambda s: s,
           "D": lambda s: 1j * np.ones_like(s)}


def _low_rank(G):
    """``(rows, L)`` with ``G = E_rows L Lᵀ E_rowsᵀ`` (PSD part; None when G is empty)."""
    if hasattr(G, "low_rank"):          # a library LocalMatrix: the block is at hand
        return G.low_rank()
    G = sp.csr_matrix(G)
    rows = np.unique(G.nonzero()[0])
    if rows.size == 0:
        return None
    B = G[rows][:, rows].toarray()
    w, U = np.linalg.eigh(0.5 * (B + B.T))
    keep = w > 1e-9 * max(np.abs(w).max(), 1e-300)
    if not keep.any():
        return None
    return rows, U[:, keep] * np.sqrt(w[keep])


def _value_grid(c, K, M, rows, L, n: int = 13) -> np.ndarray:
    """Candidate values to try: log-spaced around the structure's own stiffness or mass at the place
    (``n`` values per 6 decades)."""
    kref = float(np.trace(L.T @ (K[rows][:, rows].toarray() @ L))) / max(L.shape[1], 1)
    mref = float(np.trace(L.T @ (M[rows][:, rows].toarray() @ L))) / max(L.shape[1], 1)
    nrm = float(np.sum(L * L)) / max(L.shape[1], 1)
    kref, mref = abs(kref) / max(nrm ** 2, 1e-300), abs(mref) / max(nrm ** 2, 1e-300)
    if c.matrix == "K":
        lo, hi = 1e-7 * kref, 1e1 * kref
    elif c.matrix == "M":
        lo, hi = 1e-3 * mref, 1e2 * mref
    elif c.matrix == "C":
        cc = np.sqrt(max(kref * mref, 1e-300))
        lo, hi = 1e-4 * cc, 1e1 * cc
    else:
        lo, hi = 1e-3, 1.0
    if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo > 0):
        return np.zeros(0)
    hi = min(hi, getattr(c, "upper", np.inf))
    if hi <= lo:
        return np.array([hi])
    return np.geomspace(lo, hi, max(int(round(n * np.log10(hi / lo) / 6.0)), 3))


def _singular(A: np.ndarray) -> np.ndarray:
    """Which of the stacked square matrices ``A`` (..., r, r) are singular to working precision: condition
    number not below 1/eps (:func:`numpy.linalg.cond`).  The SVD per line and value that ``cond`` takes is only
    needed where a cheap bound cannot decide: ``cond(A) = σ_max/σ_min ≤ ‖A‖_F^r / |det A|`` (``σ_max ≤ ‖A‖_F``,
    ``|det A| = Π σ_i ≤ σ_max^(r−1) σ_min``), so a matrix whose bound is a thousand times below 1/eps is
    regular; the rest (a small determinant, or entries that are not finite) go to ``cond`` as before.  The
    SVDs took 8 of the 99 s of the timing benchmark's diagnosis under profile; the verdicts are the same."""
    limit = 1.0 / np.finfo(float).eps
    r = A.shape[-1]
    with np.errstate(all="ignore"):
        det = np.abs(np.linalg.det(A))
        bound = np.linalg.norm(A, axis=(-2, -1)) ** r
        regular = det * (1e-3 * limit) > bound                     # NaN (not finite) compares False: checked
    out = np.zeros(A.shape[:-2], bool)
    rest = ~regular
    if rest.any():
        out[rest] = ~(np.linalg.cond(A[rest]) < limit)
    return out


def _updated_errors(inv, Hll, Hm, Hr, H0, sign, H, w, den2, wsum, refit=None) -> np.ndarray:
    """Weighted FRF errors of the model updated by a rank-r term, one per candidate value (Woodbury):
    ``H0 − Hm [I/(θ f) + Hll]⁻¹ Hr`` with ``inv = 1/(θ f)`` (n_t, n_s), ``Hll`` (r, r, n_s), ``Hm`` (n_m, r,
    n_s), ``Hr`` (r, n_r, n_s).  A value for which the r × r system is singular at some line (the updated,
    undamped model resonates exactly there: its FRF is unbounded) has an infinite error — an explicit
    answer, never a skipped candidate.  With a :class:`ParameterRefit` the parameters are re-fitted to first
    order alongside each value (module docstring)."""
    r = Hll.shape[0]
    A = np.eye(r)[None, None] * inv[:, :, None, None] + Hll.transpose(2, 0, 1)[None]     # (n_t, n_s, r, r)
    bad = _singular(A)                                                                    # (n_t, n_s)
    A = np.where(bad[:, :, None, None], np.eye(r)[None, None], A)
    X = np.linalg.solve(A, np.broadcast_to(Hr.transpose(2, 0, 1)[None], A.shape[:2] + Hr.shape[:2]))
    dH = np.einsum("mkf,tfkr->tmrf", Hm, X, optimize=True)
    rc = ((H0[None] - dH) * sign[None] - H[None]) * np.sqrt(w / den2)[None]
    tot = np.sum(np.abs(rc) ** 2, axis=(1, 2, 3))
    out = np.sqrt(np.clip(tot, 0, None) / wsum) if refit is None else refit.error(tot, refit.g(rc), wsum)
    return np.where(bad.any(axis=1), np.inf, out)


class ParameterRefit:
    """The parameters of ``pmodel`` re-fitted to first order about ``p`` on ``data`` (a linearised MAP step with
    the ``prior``'s rows, module docstring): ``Bc`` (k, n_m, n_r, n_s), the columns ``J W`` in the shape of the
    FRFs (complex: real and imaginary rows), and the prior's constant part ``c_p = Wᵀ J_pᵀ r_p`` and ``‖r_p‖²``.
    Directions in which the parameters do not move the FRFs (zero eigenvalues of the normal matrix) are left
    out."""

    def __init__(self, pmodel, p, data: FRFData, prior=None):
        p = np.asarray(p, float)
        fun, jac = _exact_rows(pmodel, p, data, np.ones(p.size, bool), prior)
        n = data.H.size
        Jd, Jp, rp = jac[:2 * n], jac[2 * n:], fun[2 * n:]
        lam, V = np.linalg.eigh(jac.T @ jac)
        keep = lam > 1e-12 * max(float(lam.max(initial=0.0)), 1e-300)
        W = V[:, keep] / np.sqrt(lam[keep])
        B = Jd @ W                                                          # (2n, k)
        self.Bc = (B[:n] + 1j * B[n:]).T.reshape((-1,) + data.H.shape)
        self.c_p = (Jp @ W).T @ rp if rp.size else np.zeros(W.shape[1])
        self.rp2 = float(rp @ rp)

    def g(self, rc) -> np.ndarray:
        """``Wᵀ(Jᵀ r + J_pᵀ r_p)`` for weighted complex residuals ``rc`` (..., n_m, n_r, n_s): (..., k)."""
        return self.c_p + np.einsum("kmrf,...mrf->...k", self.Bc.conj(), rc, optimize=True).real

    def projections(self, u) -> np.ndarray:
        """The line sums ``T`` (k, n_s) of a residual change ``u_f / d_f``: ``g`` changes by ``Re Σ_f T_f / d_f``
        (``u`` (n_m, n_r, n_s) weighted like the residual)."""
        return np.einsum("kmrf,mrf->kf", self.Bc.conj(), u, optimize=True)

    def error(self, tot, g, wsum: float):
        """The FRF error with the parameters re-fitted, from the weighted squared residual ``tot`` and its ``g``."""
        return np.sqrt(np.clip(tot + self.rp2 - np.sum(g ** 2, axis=-1), 0, None) / wsum)


class _Receptance:
    """Receptance blocks of a structure on the data's lines between the measured rows, the references and
    the DOFs a candidate touches: exact for small models; for large ones in the Ritz basis of the fits
    (modes to 3× the band top, static corrections at the measured and reference DOFs), which is what a
    ranking needs."""

    def __init__(self, structure, data: FRFData):
        self.s = data.s
        mi, ms, ri, rs = _indices(structure.dofs, data)
        self.mi, self.ri = np.asarray(mi), np.asarray(ri)
        self.sign = np.asarray(ms, float)[:, None, None] * np.asarray(rs, float)[None, :, None]
        self.ritz = structure.n_dof > RITZ_LIMIT
        if not self.ritz:
            self.X = solve_columns(structure.K, structure.M, structure.C, structure.D, data.s,
                                   np.arange(structure.n_dof))                       # (n, n, n_s), symmetric
            return
        rb = RitzBasis(structure, np.concatenate([self.mi, self.ri]), float(np.max(np.abs(data.s))) / (2 * np.pi))
        Q, Psi, w2, Cq, Dq = rb.modal(structure)
        m = w2.size
        Z = np.zeros((self.s.size, m, m), complex)
        Z[:, np.arange(m), np.arange(m)] = w2[None, :] + (self.s ** 2)[:, None]
        if Cq is not None:
            Z += self.s[:, None, None] * Cq[None]
        if Dq is not None:
            Z += 1j * Dq[None]
        self.G = np.linalg.inv(Z)                                                   # (n_s, m, m)
        self.Q = Q
        self.Am = np.matmul(Q[self.mi][None], self.G)                               # (n_s, n_m, m)
        self.Br = np.matmul(self.G, Q[self.ri].T[None])                             # (n_s, m, n_r)

    def meas_refs(self):
        if not self.ritz:
            return self.X[self.mi][:, self.ri]
        return np.einsum("fmk,kr->mrf", self.Am, self.Q[self.ri].T)

    def meas_cols(self, L, rows):
        """Σ_j H[m, rows_j] L[j, k]: (n_m, r, n_s)."""
        if not self.ritz:
            return np.einsum("mjf,jk->mkf", self.X[self.mi][:, rows], L)
        QL = self.Q[rows].T @ L                                                     # (m, r)
        return np.matmul(self.Am, QL[None]).transpose(1, 2, 0)

    def rows_refs(self, L, rows):
        """Σ_j L[j, k] H[rows_j, r]: (r, n_r, n_s)."""
        if not self.ritz:
            return np.einsum("jk,jrf->krf", L, self.X[rows][:, self.ri])
        QL = self.Q[rows].T @ L
        return np.matmul(QL.T[None], self.Br).transpose(1, 2, 0)

    def rows_rows(self, L, rows):
        """Lᵀ H[rows, rows] L: (r, r, n_s)."""
        if not self.ritz:
            return np.einsum("jk,jlf,lq->kqf", L, self.X[rows][:, rows], L, optimize=True)
        QL = self.Q[rows].T @ L
        return np.matmul(QL.T[None], np.matmul(self.G, QL[None])).transpose(1, 2, 0)


class _Misfit:
    """The current model's misfit on the data, which every candidate's Woodbury update is scored against:
    the receptance ``H0`` between measured rows and references (with the DOF signs ``sign``), the weights and
    the current error ``e0`` (with a :class:`ParameterRefit`: the error with the parameters re-fitted to first
    order, and so every value's).  The release screening's misfit is one too
    (:class:`~updating.diagnosis.release._ReleaseMisfit`)."""

    def __init__(self, H0, sign, data: FRFData, refit: ParameterRefit | None = None):
        self.H0, self.sign, self.data, self.refit = H0, sign, data, refit       # H0: (n_m, n_r, n_s)
        self.w = data.quality ** 2
        self.den2 = data.den ** 2
        self.wsum = max(float(np.sum(self.w)), 1e-300)
        self.E0 = self.H0 * sign - data.H                                 # current misfit
        self.Wt = self.w / self.den2
        self.c0 = float(np.sum(self.Wt * np.abs(self.E0) ** 2))
        self.e0 = frf_error(self.H0 * sign, data)
        if refit is not None:
            self.g0 = refit.g(np.sqrt(self.Wt) * self.E0)
            self.e0 = float(self.error(self.c0, self.g0))

    def error(self, tot, g=None):
        """The FRF error from the weighted squared residual ``tot`` (with the refit: and its projections ``g``)."""
        if self.refit is not None:
            return self.refit.error(tot, g, self.wsum)
        return np.sqrt(np.clip(tot, 0, None) / self.wsum)

    def errors(self, Hm, Hr, Hll, fac):
        """``errors(thetas)``: the weighted FRF error of the model with the candidate (blocks ``Hm``, ``Hr``,
        ``Hll`` of the receptance at its DOFs, frequency factor ``fac``) added at each value."""
        c0, wsum, refit = self.c0, self.wsum, self.refit
        if Hll.shape[0] == 1:
            # rank one: dH = u / d(θ) with u = H[m, j] H[j, r] fixed, so the weighted error is a sum over lines
            # c0 − 2 Re Σ_f P_f / d_f + Σ_f S_f / |d_f|²  (O(n_s) per value); with the refit, its projections
            # g(θ) = g0 − Re Σ_f T_f / d_f the same way
            u = Hm[:, 0, None, :] * Hr[None, 0, :, :] * self.sign
            P = np.sum(self.Wt * np.conj(self.E0) * u, axis=(0, 1))
            S = np.sum(self.Wt * np.abs(u) ** 2, axis=(0, 1))
            if refit is not None:
                T = refit.projections(np.sqrt(self.Wt) * u)

        def errors(thetas):
            # a value at which the modified model resonates without damping exactly on a line makes the r × r
            # system singular there: its FRF is unbounded at that line, so the error of that value is infinite
            # (an explicit answer, not a skipped candidate)
            inv = 1.0 / (thetas[:, None] * fac[None, :])                            # (n_t, n_s)
            if Hll.shape[0] == 1:
                d = inv + Hll[0, 0][None, :]
                bad = ~(np.abs(d) > 0)
                d = np.where(bad, 1.0, d)
                tot = c0 - 2 * np.sum((P[None] / d).real, axis=1) + np.sum(S[None] / np.abs(d) ** 2, axis=1)
                out = self.error(tot, None if refit is None else self.g0[None] - ((1.0 / d) @ T.T).real)
                return np.where(bad.any(axis=1), np.inf, out)
            return _updated_errors(inv, Hll, Hm, Hr, self.H0, self.sign, self.data.H, self.w, self.den2, wsum, refit)

        return errors


def _refined(errors, grid):
    """``(values, errors)``: the grid, refined twice between the neighbours of the best value."""
    t = grid
    err = errors(t)
    for _ in range(2):
        k = int(np.argmin(err))
        lo_t = t[max(k - 1, 0)]
        hi_t = t[min(k + 1, t.size - 1)]
        if hi_t <= lo_t:
            break
        t2 = np.geomspace(lo_t, hi_t, 7)
        e2 = errors(t2)
        t, err = np.concatenate([t, t2]), np.concatenate([err, e2])
        o = np.argsort(t)
        t, err = t[o], err[o]
        keep = np.r_[True, np.diff(t) > 1e-9 * t[1:]]                  # drop repeated values
        t, err = t[keep], err[keep]
    return t, err


def _polished(errors, t, err):
    """``(values, errors)`` with the best value polished by Brent's method in log θ (when that lowers it)."""
    k = int(np.argmin(err))
    a, b = np.log(t[max(k - 1, 0)]), np.log(t[min(k + 1, t.size - 1)])
    if b > a:
        sol = minimize_scalar(lambda x: float(errors(np.array([np.exp(x)]))[0]), bounds=(a, b),
                              method="bounded", options={"xatol": 1e-4})
        if sol.fun < err[k]:
            t, err = np.append(t, np.exp(sol.x)), np.append(err, sol.fun)
    return t, err


def frf_screen(structure, candidates, data: FRFData, *, loss_factor: float = 0.0, top: int | None = None,
               refit: ParameterRefit | None = None, jobs: int | None = 1) -> list:
    """Rank shared candidates by the training FRF error each alone leaves when added to ``structure`` at its
    best value on a plausible grid (with ``refit``, the parameters of the fit ``structure`` are re-fitted to
    first order alongside: module docstring).  Returns ``[(candidate, value, gain)]`` best first, ``gain`` the
    relative drop of :func:`~updating.diagnosis.fit.frf_error` (only candidates that lower it).

    ``loss_factor`` is the model-wide structural damping (PARAM G) that an added stiffness carries too
    (``θ (1 + i g) G``), as the element added to the model will.  The candidates on ``jobs`` processes
    (:func:`~modalab.core.parallel.fork_map`: the serial result bit for bit)."""
    work = []
    for c in candidates:
        if not c.shared or c.G is None:
            continue
        lr = _low_rank(c.G)
        if lr is None:
            continue
        work.append((c, lr))
    if not work:
        return []
    R = _Receptance(structure, data)
    K, M = sp.csr_matrix(structure.K), sp.csr_matrix(structure.M)
    fit = _Misfit(R.meas_refs(), R.sign, data, refit)
    e0 = fit.e0

    def best(c, rows, L):
        """The candidate's best value on its grid and the error it leaves, or None (no admissible value)."""
        # rank one costs O(n_s) per value: a fine grid, 241 values per six decades (a 6 % step: resonances
        # crossing lines make the error rough in the value); higher ranks a coarse one (13, a factor 2.9)
        grid = _value_grid(c, K, M, rows, L, n=241 if L.shape[1] == 1 else 13)
        if grid.size == 0:
            return None
        Hm = R.meas_cols(L, rows)                                         # (n_m, r, n_s)
        Hr = R.rows_refs(L, rows)                                         # (r, n_r, n_s)
        Hll = R.rows_rows(L, rows)                                        # (r, r, n_s)
        fac = _FACTOR[c.matrix](data.s) * ((1 + 1j * loss_factor) if c.matrix == "K" else 1.0)
        errors = fit.errors(Hm, Hr, Hll, fac)
        t, err = _refined(errors, grid)
        # rank one is cheap to polish, unless there are many candidates and this one barely helps
        if Hll.shape[0] == 1 and not (len(work) > 400 and err.min() > 0.9 * e0):
            t, err = _polished(errors, t, err)
        k = int(np.argmin(err))
        return float(t[k]), float(err[k])

    out = []
    for (c, _), r in zip(work, fork_map(lambda c, lr: best(c, *lr), work, jobs, by_reference=[c for c, _ in work])):
        if r is not None and r[1] < e0:
            out.append((c, r[0], 1.0 - r[1] / e0))
    out.sort(key=lambda t: -t[2])
    log.info("FRF screening of %d candidates (error %.4g now%s): best %s", len(work), e0,
             "" if refit is None else ", the parameters re-fitted to first order",
             ", ".join(f"{c.label} ({100 * g:.0f} %)" for c, _, g in out[:3]))
    return out[:top] if top else out
