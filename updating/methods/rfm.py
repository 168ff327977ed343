"""Response-function method (Lin & Ewins), thesis section 3.2.3, with damping parameters.

From the exact identity ``Z_X − Z_A = ΔZ`` one column ``j`` of the FRF matrices gives (Eq. 3.54)

    {H_A(ω)}^j − {H_X(ω)}^j = [H_A(ω)] [ΔZ(ω)] {H_X(ω)}^j,
    [ΔZ(ω)] = [ΔK] − ω²[ΔM] + iω[ΔC] (+ i[ΔD])                       (Eq. 3.55)

and with ``ΔZ = Σ_i Δp_i ∂Z/∂p_i`` the linear system ``[R(ω)]{Δp} = {ΔH(ω)}``
(Eq. 3.56), stacked over the updating lines (Eq. 3.57) and solved in the
least-squares sense; ``R(ω)[k, i] = H_A(ω)[k, :] · ∂Z/∂p_i(ω) · H_X^j(ω)`` for
the measured rows ``k``.  The identity is exact, so with complete noise-free
data and a linear parameterisation one step recovers the parameters; the
method iterates (re-evaluating ``H_A`` and, for incomplete data, the expansion
of ``H_X`` with the current model) for non-linear parameters, noise and
expansion.

Assembly (the obstacle the thesis met: "a couple of months" for its aircraft)
is vectorised: ``∂Z/∂p_i H_X`` for all parameters and lines comes from the
stacked derivative non-zeros (one sparse product), and ``R`` from a dense ×
sparse product per chunk of lines; no loop runs over elements or parameters.
The measured rows of ``H_A`` come from the shared receptance solver
(:func:`updating.correlation.condensation.solve_columns`: batched dense solves up to
:data:`modalab.core.dense.SOLVE_LIMIT` DOFs, one sparse LU per line above) or, for narrow-band models
above that size, a banded LU per line after reverse Cuthill–McKee ordering, with one right-hand side per
measured DOF.  Models above
:data:`modalab.core.dense.PROJECTED_LIMIT` DOFs accumulate the normal equations chunk by chunk instead of storing ``R``.

Weighting: ``'relative'`` (default) divides every equation by ``|H_X|`` at its
row and line — with proportional FRF noise the residual is then white and the
objective is the relative FRF misfit; ``'none'`` uses Eq. (3.57) as printed.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from modalab.core.dense import use_dense
from modalab.core.errors import ModalabValueError, NotFittedError
from modalab.core.frf import FRF

from updating.correlation.condensation import solve_columns
from updating.correlation.receptance import MeasuredColumns, measured_columns
from updating.fe.sensitivity import StackedDerivatives
from updating.methods.iteration import Proposal, iterate, start
from updating.methods.mci import _mats, _param_indices, dynamic_expansion

log = logging.getLogger(__name__)

__all__ = ["receptance_rows", "rfm_system", "ResponseFunctionMethod"]


def receptance_rows(model, p, omega, rows) -> np.ndarray:
    """``H_A(ω)[rows, :]`` for every line: (F, len(rows), n) complex receptance of the model at ``p``.

    ``omega`` in rad/s, or complex ``ω − iβ`` (:attr:`~updating.correlation.receptance.MeasuredColumns.w`) for data taken with
    an exponential window: the receptance is then evaluated at ``s = iω + β``, as the data were.
    """
    mats = _mats(model, np.asarray(p, float))
    n = mats[0].shape[0]
    rows = np.asarray(rows, int)
    omega = np.asarray(omega)
    omega = omega.astype(complex if np.iscomplexobj(omega) else float)
    if not use_dense(n, "solve"):
        banded = _banded_rows(mats, omega, rows)
        if banded is not None:
            return banded
    # Z symmetric: rows of Z⁻¹ are the transposed solutions for unit loads at `rows` (the shared solver)
    return np.transpose(solve_columns(*mats, 1j * omega, rows), (2, 1, 0))


def _banded_rows(mats, omega, rows):
    """:func:`receptance_rows` by a banded LU per line after reverse Cuthill–McKee ordering (``O(n·bw²)``,
    many right-hand sides cheap), or None when the ordered band is not narrow (``bw > max(50, n/20)``)."""
    K, M, C, D = mats
    n = K.shape[0]
    pat = abs(K) + abs(M) + (abs(C) if C is not None else 0) + (abs(D) if D is not None else 0)
    perm = reverse_cuthill_mckee(sp.csr_matrix(pat), symmetric_mode=True)
    P_ = sp.csr_matrix(pat)[perm][:, perm].tocoo()
    bw = int(np.abs(P_.row - P_.col).max()) if P_.nnz else 0
    if bw > max(50, n // 20):
        return None
    E = np.zeros((n, rows.size))
    E[rows, np.arange(rows.size)] = 1.0
    out = np.empty((omega.size, rows.size, n), complex)
    inv = np.empty(n, int)
    inv[perm] = np.arange(n)
    parts = [(sp.coo_matrix(A), c) for A, c in ((K, "k"), (M, "m"), (C, "c"), (D, "d")) if A is not None]
    Ep = E[perm]
    for k, w in enumerate(omega):
        ab = np.zeros((2 * bw + 1, n), complex)
        for A, c in parts:
            coef = {"k": 1.0, "m": -w ** 2, "c": 1j * w, "d": 1j}[c]
            i, j = inv[A.row], inv[A.col]
            np.add.at(ab, (bw + i - j, j), coef * A.data)
        out[k] = sla.solve_banded((bw, bw), ab, Ep, check_finite=False)[inv].T
    return out


def rfm_system(model, theta_full: np.ndarray, omega: np.ndarray, references: np.ndarray, rows, p=None, *,
               params=None, weights=None, normal: bool = False, chunk: int | None = None, HA=None):
    """Assemble Eq. (3.56)–(3.57) for measured ``rows`` and full experimental columns ``theta_full`` (n, R, F).

    Returns ``(Rm, b)`` with ``Rm`` complex (R·F·len(rows), P) — block ``(j, f)`` in row-major order — and
    ``b = H_A^j − H_X^j`` on the rows; with ``normal=True`` the real normal equations
    ``(Re(RᴴWR), Re(RᴴWb))`` accumulated over chunks of lines (W = ``weights``², shape (R, F, len(rows))).
    ``chunk`` lines per block (default: sized to keep the work array near 80 MB); ``HA`` optional
    precomputed :func:`receptance_rows`.
    """
    p = model.p0 if p is None else np.asarray(p, float)
    n, R, F = theta_full.shape
    rows = np.asarray(rows, int)
    nr = rows.size
    sd = StackedDerivatives(model.derivatives(p), n)
    params = np.arange(sd.P) if params is None else np.asarray(params, int)
    colmap = np.full(sd.P, -1)
    colmap[params] = np.arange(params.size)
    pp, pr, ops = sd.pair_operators()
    sel = colmap[pp] >= 0
    pp, pr = pp[sel], pr[sel]
    ops = {k: v[sel] for k, v in ops.items()}
    G = sp.csr_matrix((np.ones(pp.size), (np.arange(pp.size), colmap[pp])), shape=(pp.size, params.size))
    if HA is None:
        HA = receptance_rows(model, p, omega, rows)                       # (F, nr, n)
    if chunk is None:   # keep the (R, lines, rows, pairs) work array near 5e6 complex entries (80 MB)
        chunk = int(max(1, min(F, 5e6 // max(R * nr * max(pp.size, 1), 1))))
    P = params.size
    if normal:
        N = np.zeros((P, P))
        g = np.zeros(P)
    else:
        Rm = np.empty((R, F, nr, P), complex)
        bm = np.empty((R, F, nr), complex)
    for f0 in range(0, F, chunk):
        fs = np.arange(f0, min(F, f0 + chunk))
        w = omega[fs]
        X = theta_full[:, :, fs].reshape(n, R * fs.size)                 # columns ordered (j, f)
        wj = np.tile(w, R)
        V = np.zeros((pp.size, R * fs.size), complex)
        for key, coef in (("K", np.ones_like(wj) + 0j), ("M", -(wj ** 2) + 0j), ("C", 1j * wj),
                          ("D", 1j * np.ones_like(wj))):
            if key in ops:
                V += (ops[key] @ X) * coef[None, :]
        V = V.reshape(pp.size, R, fs.size)
        Hsel = HA[fs][:, :, pr]                                           # (fc, nr, npairs)
        T = Hsel[None, :, :, :] * np.transpose(V, (1, 2, 0))[:, :, None, :]   # (R, fc, nr, npairs)
        Rc = (G.T @ T.reshape(-1, pp.size).T).T.reshape(R, fs.size, nr, P)
        hx = np.transpose(theta_full[rows][:, :, fs], (1, 2, 0))          # (R, fc, nr)
        ha = np.transpose(HA[fs][:, :, references], (2, 0, 1))            # (R, fc, nr)
        bc = ha - hx
        if normal:
            wt = np.ones_like(bc.real) if weights is None else weights[:, fs, :]
            Rw = (Rc * wt[..., None]).reshape(-1, P)
            bw = (bc * wt).reshape(-1)
            N += (Rw.conj().T @ Rw).real
            g += (Rw.conj().T @ bw).real
        else:
            Rm[:, fs] = Rc
            bm[:, fs] = bc
    if normal:
        return N, g
    return Rm.reshape(R * F * nr, P), bm.reshape(-1)


class ResponseFunctionMethod:
    """Iterative response-function updater (Eq. 3.54–3.57) over mass, stiffness and damping parameters.

    Parameters
    ----------
    params : names or indices of the parameters to update (default all, including damping ones).
    bands : list of (f_lo, f_hi) Hz bands of updating lines (default all lines > 0 Hz).
    references : reference DOFs (FRF columns) to use (default all of the FRF's).
    weighting : ``'relative'`` (default) or ``'none'`` (see module docstring).
    bounds : (lower, upper) or None for the default: ``[0.05, 20]×p0`` (sign kept), ≥ 0 where p0 = 0.
    penalty : Tikhonov weight on the departure from the initial parameters (equilibrated units).
    max_iter, tol : iteration limit; convergence when the largest relative change
        (relative to |p0|, or to the current value where p0 = 0) is below ``tol``.

    Unmeasured DOFs of the experimental columns are filled by dynamic expansion
    with the current model (:func:`updating.methods.mci.dynamic_expansion`) at every iteration.

    Attributes after :meth:`fit`: ``p_``, ``params_``, ``history_`` (dicts with p, cost,
    max_rel_change), ``covariance_`` (s²(JᵀJ)⁻¹ of the updated parameters), ``converged_``, ``n_iter_``.
    """

    def __init__(self, params=None, *, bands=None, references=None, weighting: str = "relative", bounds=None,
                 penalty: float = 0.0, max_iter: int = 30, tol: float = 1e-8):
        self.params = params
        self.bands = bands
        self.references = references
        self.weighting = weighting
        self.bounds = bounds
        self.penalty = penalty
        self.max_iter = max_iter
        self.tol = tol

    def _weights(self, data: MeasuredColumns):
        if self.weighting == "none":
            return None
        a = np.abs(np.transpose(data.theta, (1, 2, 0)))                  # (R, F, nm)
        a = np.where(a > 0, a, np.max(a))
        return 1.0 / a

    def fit(self, model, frf: FRF, p_init=None) -> "ResponseFunctionMethod":
        if self.weighting not in ("relative", "none"):
            raise ModalabValueError(f"weighting={self.weighting!r}; expected 'relative' or 'none'")
        data = measured_columns(model, frf, references=self.references, bands=self.bands)
        idx = _param_indices(model, self.params)
        p, lo, hi = start(model, p_init, self.bounds)
        p_start = p.copy()
        W = self._weights(data)
        self.params_ = idx
        self.p_init_ = p_start.copy()
        big = not use_dense(data.n, "projected")      # above: normal equations accumulated chunk by chunk

        def propose(p):
            full = dynamic_expansion(model, data, p)
            N, g, cost = self._normal(model, data, full, p, idx, W, big)
            return Proposal(self._step(N, g, p_start[idx] - p[idx]), cost)

        def change_ref(p, p_new):
            return np.where(p_start != 0, np.abs(p_start), np.maximum(np.abs(p_new), 1e-300))
        run = iterate(propose, p, idx, lo, hi, max_iter=self.max_iter, tol=self.tol, change_ref=change_ref,
                      label="RFM")
        self.history_, self.converged_, it, p = run.history, run.converged, run.n_iter, run.p
        if not self.converged_:
            log.warning("response-function method did not converge in %d iterations (last change %.3g)",
                        self.max_iter, run.change)
        full = dynamic_expansion(model, data, p)
        N, g, cost = self._normal(model, data, full, p, idx, W, big)
        nobs = 2 * data.theta.size
        self.covariance_ = cost / max(nobs - idx.size, 1) * np.linalg.pinv(N)
        self.cost_ = cost
        self.n_iter_ = it
        self.p_ = p
        return self

    def _step(self, N, g, departure):
        """The least-squares step from the normal equations, columns equilibrated, with the Tikhonov penalty
        on the ``departure`` from the initial parameters."""
        cn = np.sqrt(np.clip(np.diag(N), 0, None))
        cn[cn == 0] = 1.0
        Ns = N / np.outer(cn, cn)
        gs = g / cn
        if self.penalty:
            Ns = Ns + self.penalty ** 2 * np.eye(N.shape[0])
            gs = gs + self.penalty ** 2 * departure * cn
        return np.linalg.lstsq(Ns, gs, rcond=None)[0] / cn

    def _normal(self, model, data, full, p, idx, W, big):
        if big:
            N, g = rfm_system(model, full, data.w, data.references, data.measured, p, params=idx,
                              weights=W, normal=True)
            # cost from the current misfit
            HA = receptance_rows(model, p, data.w, data.measured)
            ha = np.transpose(HA[:, :, data.references], (2, 0, 1))
            b = ha - np.transpose(data.theta, (1, 2, 0))
            cost = float(np.sum(np.abs(b * (1 if W is None else W)) ** 2))
            return N, g, cost
        Rm, b = rfm_system(model, full, data.w, data.references, data.measured, p, params=idx)
        if W is not None:
            w = W.reshape(-1)
            Rm = Rm * w[:, None]
            b = b * w
        N = (Rm.conj().T @ Rm).real
        g = (Rm.conj().T @ b).real
        return N, g, float(np.sum(np.abs(b) ** 2))

    def predicted_frf(self, model, freq_hz, responses=None, references=None, quantity="accelerance", *,
                      window_beta_per_s: float = 0.0):
        """FRFs of the updated model (exact, :meth:`modalab.core.structure.Structure.frf`) at ``s = iω + β``
        (β = ``window_beta_per_s``: a measured FRF's, to compare with exponentially windowed data)."""
        if not hasattr(self, "p_"):
            raise NotFittedError("fit the ResponseFunctionMethod first")
        return model.structure(self.p_).frf(freq_hz, responses, references, quantity, method="direct",
                                            window_beta_per_s=window_beta_per_s)
