"""MisCorrelation Index (MCI): error localisation and model updating, thesis section 3.2.4.

For a measured receptance column ``θ^i(ω)`` (excitation at DOF ``i``) and the
analytical dynamic stiffness ``Z(ω) = K + iD + iωC − ω²M`` (Eq. 3.59) the
miscorrelation index of coordinate ``r`` is (Eq. 3.67, 3.69)

    MCI_r(ω) = δ_ir − Z_r(ω) · θ^i(ω)

— zero for every ``r`` and ω when the model is right, non-zero at the
coordinates whose rows of the error matrix ``[Δ]`` (Eq. 3.60, 3.68) are non-zero.

Unmeasured DOFs (thesis: "one has to use the analytically calculated FRF
values for unmeasured coordinates") are filled by *dynamic expansion* with the
current model at each frequency line — the frequency-domain analogue of
Kidder's expansion (Eq. 2.45–2.48): the unmeasured rows ``s`` of
``Z θ = e_i`` give ``θ_s = Z_ss⁻¹ (e_i,s − Z_sm θ_m)``.  The MCI is then zero on
the expanded rows by construction and, on the measured rows, equals the
miscorrelation of the dynamically condensed model.

**Minimisation** (Eq. 3.70–3.78): with ``ΔM = Σ m_i M_i``, ``ΔC = Σ c_i C_i``,
``ΔK = Σ k_i K_i`` (here: the parameter derivatives of any
:class:`~updating.fe.parametric.ParametricModel`, plus ``iΔD`` for hysteretic
damping) the updated model satisfies ``Σ_i Δp_i [∂Z/∂p_i θ]_r = MCI_r(ω)``
(Eq. 3.77) for all chosen rows and frequency lines — a linear system
``[A]{Δp} = {δ}`` (Eq. 3.78) solved in the least-squares sense.  As the
thesis prescribes, expansion and solution alternate until the parameters
converge (a Gauss–Newton iteration on the MCI; for non-linear parameters the
derivatives are re-evaluated at every step), in the iteration loop all FRF-based updaters share
(:func:`updating.methods.iteration.iterate`).

Against the *trivial solution* the thesis warns of in 6.1.2 (MCI driven to zero
by system matrices that shrink towards null) :class:`MCIUpdater` offers
parameter bounds (default: every parameter with a non-zero nominal value
stays within [0.05, 20]× its nominal value and keeps its sign), a Tikhonov
penalty on the relative departure from the initial values, and a limit on
the relative step per iteration.

The coefficient matrix is assembled for all frequency lines and parameters at
once from the stacked non-zeros of the derivative matrices
(:meth:`~updating.fe.sensitivity.StackedDerivatives.pair_operators`): sparse
products, no Python loop over elements, parameters or lines.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from modalab.core.dense import use_dense
from modalab.core.errors import ModalabValueError, NotFittedError
from modalab.core.frf import FRF

from updating.correlation.condensation import condensed_residual, dynamic_stiffness, dynamic_stiffness_batch
from updating.correlation.receptance import MeasuredColumns, measured_columns
from updating.fe.parametric import parameter_indices
from updating.fe.sensitivity import StackedDerivatives
from updating.methods.iteration import Proposal, iterate, start
from updating.methods.mci_plots import plot_convergence, plot_mci_map, plot_mci_maxima

log = logging.getLogger(__name__)

__all__ = [
    "MeasuredColumns",
    "measured_columns",
    "dynamic_expansion",
    "miscorrelation",
    "MCIResult",
    "mci",
    "mci_system",
    "condensation_operator",
    "lsq_expansion",
    "mci_from_columns",
    "MCIUpdater",
    "plot_mci_map",
    "plot_mci_maxima",
    "plot_convergence",
]


# ----------------------------------------------------------------------------- model matrices
def _mats(model, p):
    st = model.structure(p)
    return st.K.tocsr(), st.M.tocsr(), (None if st.C is None else st.C.tocsr()), (None if st.D is None else st.D.tocsr())


def dynamic_expansion(model, data: MeasuredColumns, p=None) -> np.ndarray:
    """Full receptance columns ``(n, n_ref, F)``: measured rows kept, the rest from ``θ_s = Z_ss⁻¹(e_i,s − Z_sm θ_m)``.

    The frequency-domain form of Kidder's expansion (Eq. 2.47–2.48) with the model at ``p``, evaluated at
    every line (:func:`updating.correlation.condensation.condensed_residual`, the one implementation
    diagnosis uses too).  The expansion is singular at the resonances of the model constrained at the
    measured DOFs; a line that hits one exactly is solved in the least-squares sense and named in the log.
    """
    p = model.p0 if p is None else np.asarray(p, float)
    K, M, C, D = _mats(model, p)
    full, *_ = condensed_residual(K, M, C, D, data.s, data.measured, data.theta, data.force)
    return full


def miscorrelation(model, theta_full: np.ndarray, omega: np.ndarray, references: np.ndarray, p=None) -> np.ndarray:
    """``MCI[r, j, f] = δ_{i_j r} − Z_r(ω_f) θ^{i_j}(ω_f)`` (Eq. 3.69) for full columns ``theta_full`` (n, R, F)."""
    p = model.p0 if p is None else np.asarray(p, float)
    K, M, C, D = _mats(model, p)
    n, R, F = theta_full.shape
    X = theta_full.reshape(n, R * F)
    w = np.tile(omega, R)
    Zx = K @ X - (w ** 2)[None] * (M @ X)
    if C is not None:
        Zx = Zx + 1j * w[None] * (C @ X)
    if D is not None:
        Zx = Zx + 1j * (D @ X)
    out = -Zx.reshape(n, R, F)
    out[references, np.arange(R), :] += 1.0
    return out


@dataclass
class MCIResult:
    """MCI values ``values[r, j, f]`` on model DOFs, reference DOFs and frequency lines."""

    freq_hz: np.ndarray
    values: np.ndarray
    dofs: list
    references: list
    measured: np.ndarray = field(default_factory=lambda: np.zeros(0, int))

    def max_per_dof(self) -> np.ndarray:
        """Absolute maximum of the MCI over frequency and references, per DOF (the thesis' Figures 17, 26–27, 34–35)."""
        return np.abs(self.values).max(axis=(1, 2))

    def ranked_dofs(self) -> list:
        """DOF labels sorted by decreasing maximum MCI (the suspect coordinates first)."""
        order = np.argsort(-self.max_per_dof())
        return [self.dofs[k] for k in order]


def mci(model, frf: FRF, p=None, *, references=None, bands=None) -> MCIResult:
    """MCI map of ``model`` at ``p`` against measured FRFs, unmeasured DOFs dynamically expanded (Eq. 3.69)."""
    data = measured_columns(model, frf, references=references, bands=bands)
    full = dynamic_expansion(model, data, p)
    vals = miscorrelation(model, full, data.w, data.references, p)
    return MCIResult(freq_hz=data.freq_hz, values=vals, dofs=list(model.dofs),
                     references=[model.dofs[i] for i in data.references], measured=data.measured)


# ----------------------------------------------------------------------------- linear system
def mci_system(model, theta_full: np.ndarray, omega: np.ndarray, references: np.ndarray, p=None, *,
               rows=None, params=None, derivatives=None):
    """Coefficient matrix and right-hand side of Eq. (3.77)–(3.78).

    Returns ``(A, b)``: ``A`` sparse complex, one row per (reference, line, model row) —
    row index ``(j·F + f)·len(rows) + k`` — and one column per parameter
    (``params`` subset, default all) with ``A[., i] = [∂Z/∂p_i(ω_f) θ^j(ω_f)]_{rows[k]}``;
    ``b`` the MCI values in the same order.  The solution ``Δp`` of ``A Δp ≈ b``
    is the parameter correction.
    """
    p = model.p0 if p is None else np.asarray(p, float)
    n, R, F = theta_full.shape
    rows = np.arange(n) if rows is None else np.asarray(rows, int)
    sd = derivatives if isinstance(derivatives, StackedDerivatives) else StackedDerivatives(
        model.derivatives(p) if derivatives is None else derivatives, n)
    P = sd.P
    params = np.arange(P) if params is None else np.asarray(params, int)
    colmap = np.full(P, -1)
    colmap[params] = np.arange(params.size)
    rowpos = np.full(n, -1)
    rowpos[rows] = np.arange(rows.size)
    pp, pr, ops = sd.pair_operators()
    sel = (colmap[pp] >= 0) & (rowpos[pr] >= 0)
    X = theta_full.reshape(n, R * F)
    w = np.tile(omega, R)
    V = np.zeros((int(sel.sum()), R * F), complex)
    for key, coef in (("K", np.ones_like(w) + 0j), ("M", -(w ** 2) + 0j), ("C", 1j * w), ("D", 1j * np.ones_like(w))):
        if key in ops:
            V += (ops[key][sel] @ X) * coef[None, :]
    q = np.arange(R * F)
    rr = (q[None, :] * rows.size + rowpos[pr[sel]][:, None]).ravel()
    cc = np.broadcast_to(colmap[pp[sel]][:, None], V.shape).ravel()
    A = sp.csr_matrix((V.ravel(), (rr, cc)), shape=(R * F * rows.size, params.size))
    mcv = miscorrelation(model, theta_full, omega, references, p)       # (n, R, F)
    b = np.transpose(mcv[rows], (1, 2, 0)).reshape(-1)
    return A, b


def _condensation(model, data: MeasuredColumns, p):
    """``G = Z_ss⁻¹Z_sm`` per line (F, ns, nm) and the least-squares expansion computed from it.

    The left null space of ``Z_{:,s}`` is spanned by ``V = [I; −Ḡ]``, so the part of
    ``rhs = e − Z_{:,m}θ_m`` no expansion removes is ``V y`` with ``(VᴴV) y = rhs_m − Gᵀ rhs_s``, and the
    least-squares expansion is ``θ_s = Z_ss⁻¹(rhs_s + Ḡ y)`` — the same as :func:`lsq_expansion`,
    with one sparse factorisation of ``Z_ss`` per line.
    """
    n, m = data.n, data.measured
    s = np.setdiff1d(np.arange(n), m)
    R, F, nm = data.references.size, data.omega.size, m.size
    full = np.zeros((n, R, F), complex)
    full[m] = data.theta
    G = np.zeros((F, s.size, nm), complex)
    if s.size == 0:
        return G, full
    mats = _mats(model, p)
    E = np.zeros((n, R))
    E[data.references, np.arange(R)] = 1.0
    if use_dense(n, "solve"):
        Z = dynamic_stiffness_batch(*mats, data.s)
        Zss, Zsm, Zmm = Z[:, s][:, :, s], Z[:, s][:, :, m], Z[:, m][:, :, m]
        G = np.linalg.solve(Zss, Zsm)
        th = np.transpose(data.theta, (2, 0, 1))                               # (F, nm, R)
        rhs_m = E[m][None] - Zmm @ th
        rhs_s = E[s][None] - Zsm @ th
        Trhs = rhs_m - np.transpose(G, (0, 2, 1)) @ rhs_s
        y = np.linalg.solve(np.eye(nm)[None] + np.transpose(G, (0, 2, 1)) @ G.conj(), Trhs)
        full[s] = np.transpose(np.linalg.solve(Zss, rhs_s + G.conj() @ y), (1, 2, 0))
        return G, full
    for k, sk in enumerate(data.s):
        Z = dynamic_stiffness(*mats, sk).tocsr()
        Zsm = Z[s][:, m].toarray()
        Zmm = Z[m][:, m].toarray()
        solve = spla.splu(sp.csc_matrix(Z[s][:, s])).solve
        Gk = solve(Zsm)
        G[k] = Gk
        th = data.theta[:, :, k]
        rhs_m = E[m] - Zmm @ th
        rhs_s = E[s] - Zsm @ th
        Trhs = rhs_m - Gk.T @ rhs_s
        VhV = np.eye(nm) + Gk.T @ Gk.conj()
        y = np.linalg.solve(VhV, Trhs)
        full[s, :, k] = solve(rhs_s + Gk.conj() @ y)
    return G, full


def condensation_operator(model, data: MeasuredColumns, p=None, *, whiten: bool = False,
                          G=None) -> sp.csr_matrix:
    """Sparse block operator ``T`` from the rows of the full system of :func:`mci_system` (rows = all DOFs)
    to the measured rows of the condensed one: per (reference, line) block ``[T x] = L(ω)(x_m − G(ω)ᵀ x_s)``
    with ``G = Z_ss⁻¹ Z_sm`` (Z symmetric) and ``L = I`` or, with ``whiten``, ``L = (I + GᵀḠ)^{-1/2}``.

    ``T @ A`` (L = I) is the exact Jacobian (up to sign) of the measured-row MCI when the unmeasured rows are
    re-expanded with the model (``∂θ_s/∂p_i = −Z_ss⁻¹[∂Z/∂p_i θ]_s``); ``T @ b`` equals ``b`` on the measured
    rows because the expanded rows have zero MCI.

    With ``whiten`` the columns of ``[I; −G]`` span the left null space of ``Z_{:,s}``, so ``‖T·rhs‖`` is the
    norm of the part of ``rhs = e − Z_{:,m}θ_m`` that no expansion can remove: the same residual as the
    least-squares expansion of :func:`lsq_expansion`, computed with one sparse factorisation of ``Z_ss``
    per line instead of a dense QR of ``Z_{:,s}`` — and free of the poles of the plain condensed residual.
    """
    p = model.p0 if p is None else np.asarray(p, float)
    n, m = data.n, data.measured
    s = np.setdiff1d(np.arange(n), m)
    R, F, nm = data.references.size, data.omega.size, m.size
    if G is not None:
        G = np.asarray(G)
    elif s.size == 0:
        G = np.zeros((F, 0, nm), complex)
    else:
        # the dynamic expansion matrices T = [I; −Z_ss⁻¹Z_sm] of the one Kidder-type expansion
        K, M, C, D = _mats(model, p)
        _, _, T, _ = condensed_residual(K, M, C, D, data.s, m, data.theta, data.force)
        G = -np.transpose(T[s], (2, 0, 1))                                   # (F, ns, nm)
    if whiten:
        H = np.eye(nm)[None] + np.einsum("fsa,fsb->fab", G, G.conj())
        ev, U = np.linalg.eigh(H)
        L = np.einsum("fab,fb,fcb->fac", U, ev ** -0.5, U.conj())            # (F, nm, nm)
    else:
        L = np.broadcast_to(np.eye(nm, dtype=complex), (F, nm, nm))
    blk = np.arange(R * F)
    fidx = blk % F
    Lb = L[fidx]                                                             # (RF, nm, nm)
    r0 = blk[:, None] * nm + np.arange(nm)[None, :]
    rows = [np.broadcast_to(r0[:, :, None], Lb.shape).ravel()]
    cols = [np.broadcast_to((blk[:, None, None] * n + m[None, None, :]), Lb.shape).ravel()]
    vals = [Lb.ravel()]
    if s.size:
        B = -np.einsum("fab,fsb->fas", L, G)[fidx]                          # −L Gᵀ: (RF, nm, ns)
        rows.append(np.broadcast_to(r0[:, :, None], B.shape).ravel())
        cols.append(np.broadcast_to((blk[:, None, None] * n + s[None, None, :]), B.shape).ravel())
        vals.append(B.ravel())
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(R * F * nm, R * F * n))


def _lsq(A, b, *, col_scale, penalty=0.0, x_prior=None):
    """Least squares of a complex system for a real unknown: min ‖A x − b‖² + penalty²‖x − x_prior‖² (x in scaled units)."""
    Ar = sp.vstack([A.real, A.imag]).tocsr() if sp.issparse(A) else np.vstack([A.real, A.imag])
    br = np.concatenate([b.real, b.imag])
    Ar = Ar @ sp.diags(col_scale) if sp.issparse(Ar) else Ar * col_scale[None, :]
    P = Ar.shape[1]
    if sp.issparse(Ar) and Ar.shape[0] * P > 4e7:
        N = (Ar.T @ Ar).toarray()
        g = Ar.T @ br
        if penalty:
            N += penalty ** 2 * np.eye(P)
            g += penalty ** 2 * (x_prior if x_prior is not None else 0)
        y = np.linalg.lstsq(N, g, rcond=None)[0]
        return y * col_scale, None
    Ad = Ar.toarray() if sp.issparse(Ar) else Ar
    if penalty:
        Ad = np.vstack([Ad, penalty * np.eye(P)])
        br = np.concatenate([br, penalty * (x_prior if x_prior is not None else np.zeros(P))])
    y, *_ = np.linalg.lstsq(Ad, br, rcond=None)
    sv = np.linalg.svd(Ad, compute_uv=False)
    return y * col_scale, sv


def lsq_expansion(model, data: MeasuredColumns, p=None):
    """Least-squares dynamic expansion: ``θ_s = argmin ‖e_i − Z_{:,m} θ_m − Z_{:,s} θ_s‖`` over *all* rows.

    Returns ``(full, Q, rhs, Z)``: full columns (n, R, F), orthonormal bases
    ``Q`` (F, n, n_s) of range(Z_{:,s}), ``rhs = e − Z_{:,m}θ_m`` (F, n, R) and
    the dynamic stiffness matrices (F, n, n).  With a consistent model it
    equals :func:`dynamic_expansion` (both make ``Zθ = e``); for a wrong model
    it spreads the misfit over all rows instead of forcing it onto the measured
    ones, and it has no poles where ``Z_ss`` is singular.  Dense; meant for
    models up to a few hundred DOFs.
    """
    p = model.p0 if p is None else np.asarray(p, float)
    n, m = data.n, data.measured
    s = np.setdiff1d(np.arange(n), m)
    R, F = data.references.size, data.omega.size
    Z = dynamic_stiffness_batch(*_mats(model, p), data.s)
    E = np.zeros((n, R))
    E[data.references, np.arange(R)] = 1.0
    rhs = E[None] - np.einsum("fnm,mjf->fnj", Z[:, :, m], data.theta)
    full = np.zeros((n, R, F), complex)
    full[m] = data.theta
    if s.size == 0:
        return full, np.zeros((F, n, 0), complex), rhs, Z
    Q, Rr = np.linalg.qr(Z[:, :, s])
    QhR = np.einsum("fns,fnj->fsj", Q.conj(), rhs)
    full[s] = np.transpose(np.linalg.solve(Rr, QhR), (1, 2, 0))
    return full, Q, rhs, Z


class MCIUpdater:
    """MCI minimisation updater (thesis 3.2.4, Eq. 3.70–3.78) iterating expansion and solution.

    Parameters
    ----------
    params : names or indices of the parameters to update (default all).
    bands : list of (f_lo, f_hi) Hz bands of updating lines (default all lines > 0 Hz).
    references : reference DOFs of the FRF to use (default all).
    jacobian : how the unmeasured DOFs enter each least-squares step

        ``'projected'`` (default for models up to :data:`modalab.core.dense.PROJECTED_LIMIT` DOFs): the unmeasured FRFs are
        expanded in the least-squares sense over all rows of ``Zθ = e``
        (:func:`lsq_expansion`) and Eq. (3.77) is projected onto the orthogonal
        complement of ``range(Z_{:,s})`` — a variable-projection Gauss–Newton
        step (Golub & Pereyra; Kaufman's Jacobian) on the MCI that the best
        expansion leaves.  Smooth in the parameters; converges in a handful of
        iterations on the six-DOF case.
        ``'condensed'`` (default above that, sparse): the same residual and
        step as ``'projected'``, computed from the Kidder-type condensation
        ``G = Z_ss⁻¹Z_sm`` (one sparse factorisation per line) whitened by
        ``(I + GᴴG)^{-1/2}`` (:func:`condensation_operator`); the plain
        condensed residual (without whitening) has poles at the resonances of
        the model constrained at the measured DOFs and stalls in local minima.
        ``'fixed'``: the thesis' scheme literally — θ frozen at the current
        expansion while (3.78) is solved, then re-expanded.  With incomplete
        data it drifts towards the trivial solution (parameters shrinking
        towards their bounds; see the tests); with every DOF measured all three agree.
    weighting : ``'noise'`` (default): every (reference, line) block of equations
        is divided by ``‖Z_{:,m}(ω) diag θ_m(ω)‖``, the MCI a 100 % relative FRF
        error would cause — the whitening for proportional FRF noise, which
        also keeps lines near resonance from dominating; ``'none'``: as printed.
    rows : for ``jacobian='fixed'``: ``'all'`` (as the thesis) or ``'measured'``.
    penalty : Tikhonov weight on the departure from the initial parameters
        (in the column-equilibrated units of the step; 0 = none).
    bounds : (lower, upper) arrays in parameter units, or None for the default
        ``[0.05, 20]×p0`` (sign kept); parameters with p0 = 0 (e.g. damping) are kept ≥ 0.
    line_search : halve the step until the weighted residual (plus penalty) does not increase.
    step_limit : largest relative parameter change per iteration (step scaled down to it).
    max_iter, tol : iteration limit; convergence when the largest relative change is below ``tol``.

    Attributes after :meth:`fit`
    ----------------------------
    p_ : full updated parameter vector; ``params_`` the updated indices; ``p_init_`` the start.
    history_ : list of dicts (iteration, p, max_rel_change, cost).
    mci_initial_, mci_final_ : :class:`MCIResult` before and after (Kidder-type expansion, Eq. 3.69).
    covariance_ : covariance of the updated parameters ``params_`` from the last Jacobian,
        ``s²(JᵀJ)⁻¹`` with ``s²`` the weighted residual variance (meaningful with ``weighting='noise'``).
    converged_, n_iter_, mode_ (the Jacobian mode used).
    """

    def __init__(self, params=None, *, bands=None, references=None, jacobian: str = "auto",
                 weighting: str = "noise", rows: str = "all", penalty: float = 0.0, bounds=None,
                 line_search: bool = True, step_limit: float = 0.5, max_iter: int = 100, tol: float = 1e-8):
        self.params = params
        self.bands = bands
        self.references = references
        self.jacobian = jacobian
        self.weighting = weighting
        self.rows = rows
        self.penalty = penalty
        self.bounds = bounds
        self.line_search = line_search
        self.step_limit = step_limit
        self.max_iter = max_iter
        self.tol = tol

    def _check_fitted(self):
        if not hasattr(self, "p_"):
            raise NotFittedError("this MCIUpdater is not fitted yet; call fit(model, frf) first")

    def _linearise(self, model, data, p, idx, mode, need_jac=True, w=None):
        """Weighted residual r (complex), Jacobian J with ``J Δp ≈ r`` and the line weights used.

        ``w`` given: use these weights (frozen during a line search so the cost compared is one function).
        """
        n, m = data.n, data.measured
        R, F = data.references.size, data.omega.size
        if mode == "projected":
            full, Q, rhs, Z = lsq_expansion(model, data, p)
            QhR = np.einsum("fns,fnj->fsj", Q.conj(), rhs)
            r = rhs - np.einsum("fns,fsj->fnj", Q, QhR)                       # (F, n, R)
            r = np.transpose(r, (2, 0, 1))                                      # (R, F, n)
            w = self._weights(data, Zm=Z[:, :, m]) if w is None else w          # (R, F)
            r = (r * w[:, :, None]).reshape(-1)
            if not need_jac:
                return r, None, w
            A, _ = mci_system(model, full, data.w, data.references, p, params=idx)
            Ad = A.toarray().reshape(R, F, n, -1)
            Ad = Ad - np.einsum("fns,fks,jfkp->jfnp", Q, Q.conj(), Ad, optimize=True)
            return r, (Ad * w[:, :, None, None]).reshape(R * F * n, -1), w
        if mode == "condensed":
            G, full = _condensation(model, data, p)
        else:
            full = dynamic_expansion(model, data, p)
        vals = miscorrelation(model, full, data.w, data.references, p)
        if w is None:
            w = self._weights(data, model=model, p=p)
        if mode == "condensed":
            T = condensation_operator(model, data, p, whiten=True, G=G)
            b = np.transpose(vals, (1, 2, 0)).reshape(-1)
            r = (T @ b) * np.repeat(w.reshape(-1), m.size)
            if not need_jac:
                return r, None, w
            A, _ = mci_system(model, full, data.w, data.references, p, params=idx)
            W = sp.diags(np.repeat(w.reshape(-1), m.size))
            return r, (W @ (T @ A)).tocsr(), w
        if not need_jac:
            r = (np.transpose(vals[m], (1, 2, 0)) * w[:, :, None]).reshape(-1)
            return r, None, w
        rr = np.arange(n) if self.rows == "all" else m
        r = (np.transpose(vals[rr], (1, 2, 0)) * w[:, :, None]).reshape(-1)
        A, _ = mci_system(model, full, data.w, data.references, p, rows=rr, params=idx)
        W = sp.diags(np.repeat(w.reshape(-1), rr.size))
        return r, (W @ A).tocsr(), w

    def _weights(self, data, Zm=None, model=None, p=None):
        R, F = data.references.size, data.omega.size
        if self.weighting == "none":
            return np.ones((R, F))
        m = data.measured
        if Zm is None and use_dense(data.n, "projected"):
            Zm = dynamic_stiffness_batch(*_mats(model, p), data.s)[:, :, m]
        if Zm is not None:
            sig = np.linalg.norm(np.einsum("fnm,mjf->jfnm", Zm, data.theta), axis=(2, 3))
        else:
            mats = _mats(model, p)
            sig = np.empty((R, F))
            for k, sk in enumerate(data.s):
                Zc = dynamic_stiffness(*mats, sk).tocsr()[:, m]
                for j in range(R):
                    sig[j, k] = spla.norm(Zc @ sp.diags(data.theta[:, j, k]))
        sig = np.where(sig > 0, sig, 1.0)
        return 1.0 / sig

    def fit(self, model, frf: FRF, p_init=None) -> "MCIUpdater":
        mode = self.jacobian
        if mode == "auto":
            mode = "projected" if use_dense(len(model.dofs), "projected") else "condensed"
        if mode not in ("projected", "condensed", "fixed"):
            raise ModalabValueError(f"jacobian={self.jacobian!r}; expected 'auto', 'projected', 'condensed' or 'fixed'")
        if self.weighting not in ("noise", "none"):
            raise ModalabValueError(f"weighting={self.weighting!r}; expected 'noise' or 'none'")
        if self.rows not in ("all", "measured"):
            raise ModalabValueError(f"rows={self.rows!r}; expected 'all' or 'measured'")
        data = measured_columns(model, frf, references=self.references, bands=self.bands)
        idx = _param_indices(model, self.params)
        p, lo, hi = start(model, p_init, self.bounds)
        p_start = p.copy()
        self.p_init_ = p_start.copy()
        self.mode_ = mode
        self.params_ = idx
        self.mci_initial_ = mci_from_columns(model, data, p)
        scale_ref = np.where(p_start != 0, np.abs(p_start), 1.0)
        run = iterate(lambda q: self._propose(model, data, q, p_start, idx, mode), p, idx, lo, hi,
                      max_iter=self.max_iter, tol=self.tol, change_ref=lambda *_: scale_ref,
                      step_limit=self.step_limit, step_ref=scale_ref, label="MCI")
        self.history_, self.converged_, self.n_iter_, p = run.history, run.converged, run.n_iter, run.p
        if not self.converged_:
            log.warning("MCI minimisation did not converge in %d iterations (last relative change %.3g)",
                        self.max_iter, run.change)
        self.covariance_ = self._covariance(model, data, p, idx, mode)
        self.p_ = p
        self.mci_final_ = mci_from_columns(model, data, p)
        return self

    def _propose(self, model, data, p, p_start, idx, mode) -> Proposal:
        """The Gauss–Newton step at ``p`` on the column-equilibrated system (Eq. 3.78), with the Tikhonov
        penalty on the departure from ``p_start`` and, for the line search, the cost at frozen weights."""
        r, J, wts = self._linearise(model, data, p, idx, mode)
        cn = np.sqrt(np.asarray(abs(J).power(2).sum(axis=0)).ravel()) if sp.issparse(J) \
            else np.linalg.norm(J, axis=0)
        cn[cn == 0] = 1.0
        col_scale = 1.0 / cn
        x_prior = (p_start[idx] - p[idx]) / col_scale if self.penalty else None
        dp, _ = _lsq(J, r, col_scale=col_scale, penalty=self.penalty, x_prior=x_prior)
        cost0 = _cost(r, p_start, p, idx, col_scale, self.penalty)
        if not self.line_search:
            return Proposal(dp, cost0)

        def accept(p_new):
            r_new, _, _ = self._linearise(model, data, p_new, idx, mode, need_jac=False, w=wts)
            return _cost(r_new, p_start, p_new, idx, col_scale, self.penalty) <= cost0
        return Proposal(dp, cost0, accept)

    def _covariance(self, model, data, p, idx, mode):
        """``s²(JᵀJ)⁻¹`` of the updated parameters from the Jacobian at ``p``."""
        r, J, _ = self._linearise(model, data, p, idx, mode)
        Jd = J.toarray() if sp.issparse(J) else J
        Jr = np.vstack([Jd.real, Jd.imag])
        rr = np.concatenate([r.real, r.imag])
        dof = max(Jr.shape[0] - Jr.shape[1], 1)
        return float(rr @ rr) / dof * np.linalg.pinv(Jr.T @ Jr)

    def parameter_history(self) -> np.ndarray:
        """(n_iter + 1, P) parameter vectors, the initial one first."""
        self._check_fitted()
        return np.vstack([self.p_init_] + [h["p"] for h in self.history_])

    def plot_convergence(self, path, model=None, reference=None):
        """Parameter convergence figure (values relative to ``reference``, default the initial values)."""
        self._check_fitted()
        names = None if model is None else model.parameter_names
        return plot_convergence(self.parameter_history(), path, names=names, reference=reference,
                                params=self.params_)


def mci_from_columns(model, data: MeasuredColumns, p=None) -> MCIResult:
    """MCI (Eq. 3.69) of ``model`` at ``p`` for already-mapped measured columns, Kidder-type expansion."""
    full = dynamic_expansion(model, data, p)
    vals = miscorrelation(model, full, data.w, data.references, p)
    return MCIResult(freq_hz=data.freq_hz, values=vals, dofs=list(model.dofs), measured=data.measured,
                     references=[model.dofs[i] for i in data.references])


def _cost(r, p_start, p, idx, col_scale, penalty):
    c = float(np.sum(np.abs(r) ** 2))
    if penalty:
        c += penalty ** 2 * float(np.sum(((p[idx] - p_start[idx]) / col_scale) ** 2))
    return c


_param_indices = parameter_indices
