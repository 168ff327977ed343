"""Localisation and linear screening of candidate physics on the condensed force residual.

With the measured responses ``x_m`` expanded through the current model (see
:func:`~updating.correlation.condensation.condensed_residual`), the residual
``r_m(s) = [Z(s) x(s) − f]_m`` (the negative MCI of thesis eq. 3.89) is, to
first order, produced by what the model gets wrong:

    r_m ≈ − Σ_q Δp_q Tᵀ ∂Z/∂p_q x  −  Σ_c θ_c Tᵀ G_c(s) x

where ``G_c(s)`` is a candidate's unit dynamic stiffness (``G``, ``s²G``,
``sG`` or ``iG``) — which makes the frequency signature decide the kind of
physics — and ``T`` the dynamic expansion matrix, which carries a candidate
at an unmeasured DOF to the measured ones.  Parameter corrections ``Δp`` are
always in the regression (the "background"); candidates enter one at a time
by orthogonal matching pursuit with θ ≥ 0, each only if it removes at least
``min_gain`` of the residual that remains.  The result ranks every candidate
by the share of the residual it alone would explain.
"""
from __future__ import annotations

import logging
import weakref
from dataclasses import dataclass, field

import numpy as np

from modalab.core.dof import locate

from updating.correlation.condensation import condensed_residual
from updating.fe import ParametricFEModel

log = logging.getLogger(__name__)
__all__ = ["screen", "ScreenResult", "residual_map", "mci_update", "residual_system"]


@dataclass
class ScreenResult:
    selected: list                     # [(Candidate, theta, gain)]
    ranking: list                      # [(Candidate, theta, gain)] best first, single-candidate gains
    rss_background: float
    rss_final: float
    dof_energy_before: np.ndarray      # per measured DOF, after the background fit only
    dof_energy_after: np.ndarray       # with the selected candidates
    responses: list
    node_scores: dict = field(default_factory=dict)


def _factor(matrix: str, s: np.ndarray) -> np.ndarray:
    return {"K": np.ones_like(s), "M": s ** 2, "C": s, "D": 1j * np.ones_like(s)}[matrix]


def _column(T, x_full, A, factor, w):
    """−Tᵀ (A·factor) x, weighted, stacked real/imag, for a sparse A."""
    A = A.tocsr()
    rows = np.unique(A.nonzero()[0])
    if rows.size == 0:
        return None
    n, nq, ns = x_full.shape
    v = (A[rows] @ x_full.reshape(n, -1)).reshape(rows.size, nq, ns) * factor[None, None, :]
    if rows.size <= 4:
        c = -np.einsum("smf,sqf->mqf", T[rows], v)
    else:   # one BLAS product per line
        c = -np.matmul(T[rows].transpose(2, 1, 0), v.transpose(2, 0, 1)).transpose(1, 2, 0)
    c = c * w[None]
    return np.concatenate([c.real.ravel(), c.imag.ravel()])


def _stack(r, w):
    y = r * w[None]
    return np.concatenate([y.real.ravel(), y.imag.ravel()])


def residual_map(structure, data, force_sign=True):
    """Per measured DOF and line |r_m| of the structure against the data (the MCI map), (n_m, n_s)."""
    cols = data.on_model(structure.dofs)
    _, r, _, sigma = condensed_residual(structure.K, structure.M, structure.C, structure.D, data.s, cols.measured,
                                        cols.theta, cols.force)
    return np.sqrt(np.sum(np.abs(r) ** 2 / (sigma[None] + 1e-300) ** 2 * data.quality ** 2, axis=1))


def screen(structure, background_derivs, candidates, data, *, max_terms: int = 4, min_gain: float = 0.12,
           x_modes=None) -> ScreenResult:
    """Rank and select shared candidates on the condensed residual (module docstring).

    ``data`` is an :class:`~updating.diagnosis.fit.FRFData` (receptance), or ``x_modes`` a tuple
    ``(s, shapes, dof_labels)`` of identified modes (homogeneous residual, no force).
    """
    K, M, C, D = structure.K, structure.M, structure.C, structure.D
    s, mi, x_meas, F, coh, responses = _measured(structure, data, x_modes)
    x_full, r, T, sigma = condensed_residual(K, M, C, D, s, mi, x_meas, F)
    w = coh / (sigma + 1e-12 * np.max(sigma))
    y = _stack(r, w)
    # background
    cols = []
    for d in background_derivs:
        parts = [c for c in (_column(T, x_full, A, _factor(k, s), w) if A is not None else None
                             for A, k in ((d.dK, "K"), (d.dM, "M"), (d.dC, "C"), (d.dD, "D"))) if c is not None]
        if parts:
            cols.append(np.sum(parts, axis=0))
    B = np.array(cols).T if cols else np.zeros((y.size, 0))
    if B.shape[1]:
        Q, _ = np.linalg.qr(B / np.maximum(np.linalg.norm(B, axis=0), 1e-300))
    else:
        Q = np.zeros((y.size, 0))
    res = y - Q @ (Q.T @ y)
    rss_bg = float(res @ res)
    nm, nq, ns = r.shape

    def dof_energy(vec):
        v = vec[: vec.size // 2] + 1j * vec[vec.size // 2:]
        return np.sqrt(np.sum(np.abs(v.reshape(nm, nq, ns)) ** 2, axis=(1, 2)))

    energy_before = dof_energy(res)
    # candidate columns
    G = []
    keep = []
    for c in candidates:
        if not c.shared or c.G is None:
            continue
        g = _column(T, x_full, c.G, _factor(c.matrix, s), w)
        if g is None or not np.any(g):
            continue
        G.append(g)
        keep.append(c)
    if not keep:
        return ScreenResult([], [], rss_bg, rss_bg, energy_before, energy_before, responses)
    Gm = np.array(G).T
    Gp = Gm - Q @ (Q.T @ Gm)
    nrm2 = np.einsum("ij,ij->j", Gp, Gp)
    proj = Gp.T @ res
    theta1 = proj / np.maximum(nrm2, 1e-300)
    gain1 = np.where(theta1 > 0, proj ** 2 / np.maximum(nrm2, 1e-300), 0.0) / max(rss_bg, 1e-300)
    order = np.argsort(-gain1)
    ranking = [(keep[i], float(theta1[i]), float(gain1[i])) for i in order if gain1[i] > 0]
    selected_idx, cur, rss = _matching_pursuit(Gm, Q, res, max_terms, min_gain)
    # joint estimates of the selected values (background free, candidates >= 0 by selection)
    selected = []
    if selected_idx:
        A = np.column_stack([B, Gm[:, selected_idx]]) if B.shape[1] else Gm[:, selected_idx]
        sol, *_ = np.linalg.lstsq(A, y, rcond=None)
        th = sol[B.shape[1]:]
        for k, t in zip(selected_idx, th):
            selected.append((keep[k], float(max(t, 0.0)), float(gain1[k])))
    energy_after = dof_energy(cur)
    node_scores: dict[int, float] = {}
    for d, e in zip(responses, energy_before):
        node_scores[d.node] = node_scores.get(d.node, 0.0) + float(e) ** 2
    log.info("screening: background RSS %.4g, with %d candidate(s) %.4g", rss_bg, len(selected), rss)
    return ScreenResult(selected, ranking, rss_bg, rss, energy_before, energy_after, list(responses), node_scores)


def _measured(structure, data, x_modes):
    """What :func:`screen` expands: ``(s, measured rows, x_meas, forces, line weights, response labels)`` of
    FRF ``data`` or, with ``x_modes = (s, shapes, labels)``, of identified modes (one "line" per mode, no force)."""
    if x_modes is None:
        cols = data.on_model(structure.dofs)
        coh = np.sqrt(np.mean(data.quality ** 2, axis=0))         # (n_r, n_s)
        return data.s, cols.measured, cols.theta, cols.force, coh, data.responses
    s, shapes, labels = x_modes
    mi, ms = locate(structure.dofs, labels, "measured DOF")
    x_meas = (shapes * np.asarray(ms, float)[:, None])[:, None, :]          # (n_m, 1, n_modes)
    return s, mi, x_meas, np.zeros((structure.n_dof, 1)), np.ones((1, s.size)), labels


def _matching_pursuit(Gm, Q, res, max_terms: int, min_gain: float):
    """Orthogonal matching pursuit with positivity: candidate columns ``Gm`` enter one at a time (the one that
    removes most of the residual ``res`` left after the background basis ``Q`` and the terms already in) while
    each removes at least ``min_gain`` of what remains.  Returns the chosen columns, the final residual and
    its sum of squares."""
    selected_idx: list[int] = []
    Qs = Q.copy()
    cur = res.copy()
    rss = float(res @ res)
    for _ in range(max_terms):
        Gq = Gm - Qs @ (Qs.T @ Gm)
        n2 = np.einsum("ij,ij->j", Gq, Gq)
        pr = Gq.T @ cur
        th = pr / np.maximum(n2, 1e-300)
        gain = np.where((th > 0) & (n2 > 1e-20 * np.max(n2)), pr ** 2 / np.maximum(n2, 1e-300), 0.0)
        gain[selected_idx] = 0.0
        k = int(np.argmax(gain))
        if gain[k] < min_gain * rss or gain[k] <= 0:
            break
        q = Gq[:, k] / np.sqrt(n2[k])
        Qs = np.column_stack([Qs, q])
        cur = cur - q * (q @ cur)
        rss = float(cur @ cur)
        selected_idx.append(k)
    return selected_idx, cur, rss


@dataclass
class ResidualSystem:
    """The weighted, stacked condensed residual ``y`` of a model against data, and what builds its columns."""

    y: np.ndarray
    x_full: np.ndarray
    T: np.ndarray
    w: np.ndarray
    s: np.ndarray
    shape: tuple

    def column(self, A, matrix: str):
        return _column(self.T, self.x_full, A, _factor(matrix, self.s), self.w)

    def derivative_columns(self, derivs) -> np.ndarray:
        cols = []
        for d in derivs:
            parts = [c for c in (self.column(A, k) if A is not None else None
                                 for A, k in ((d.dK, "K"), (d.dM, "M"), (d.dC, "C"), (d.dD, "D"))) if c is not None]
            cols.append(np.sum(parts, axis=0) if parts else np.zeros_like(self.y))
        return np.array(cols).T if cols else np.zeros((self.y.size, 0))


def residual_system(structure, data, weights=None) -> ResidualSystem:
    """Condensed residual of ``structure`` against FRF ``data`` (see :func:`condensed_residual`), weighted.

    ``weights`` (n_r, n_s) fixes the line weights (so that residuals of different models compare); by
    default they are √coherence / σ of this model.
    """
    cols = data.on_model(structure.dofs)
    if data.homogeneous:
        # mode shapes: one vector per "line" (mode), no force (the homogeneous residual Z(iω_j) φ_j)
        F = np.zeros((structure.n_dof, data.H.shape[1]))
    else:
        F = cols.force
    x_full, r, T, sigma = condensed_residual(structure.K, structure.M, structure.C, structure.D, data.s,
                                             cols.measured, cols.theta, F)
    if weights is None:
        coh = np.sqrt(np.mean(data.quality ** 2, axis=0))
        weights = coh / (sigma + 1e-12 * np.max(sigma))
    return ResidualSystem(_stack(r, weights), x_full, T, weights, data.s, r.shape)


_DERIV_CACHE: weakref.WeakKeyDictionary | None = None
_LINEAR_FIELDS = ("E", "rho", "k", "c", "mass", "inertia", "nsm")


def derivatives(pmodel, p):
    """``pmodel.derivatives(p)``, cached per model for parameters that enter the matrices linearly.

    For fields that scale an element or material matrix (E, ρ, k, c, mass, inertia, nsm) the derivative
    does not depend on p itself, only on the values of the model-wide damping fields (PARAM G, Rayleigh)
    that multiply K or M and of non-linear parameters (section dimensions, ν, GE); the cache is keyed by
    those.  Saves the complex-step re-assembly (one model per parameter) in iterated MCI updates.
    """
    global _DERIV_CACHE
    if _DERIV_CACHE is None:
        _DERIV_CACHE = weakref.WeakKeyDictionary()
    pars = getattr(pmodel, "parameters", None)
    if pars is None:
        return pmodel.derivatives(p)
    p = np.asarray(p, float)
    lin = np.array([par.field in _LINEAR_FIELDS for par in pars])
    key = tuple(np.round(p[~lin], 12))
    try:
        store = _DERIV_CACHE.setdefault(pmodel, {})
    except TypeError:  # pragma: no cover - not weak-referenceable
        return pmodel.derivatives(p)
    if key not in store:
        if len(store) > 8:
            store.clear()
        store[key] = pmodel.derivatives(p)
        return list(store[key])
    out = list(store[key])
    nonlin = np.flatnonzero(~lin)
    if nonlin.size:
        # the derivatives of the non-linear fields (e.g. PARAM G: ∂D/∂g = K(p)) depend on every parameter
        sub = ParametricFEModel(pmodel.model_at(p), [pars[i] for i in nonlin])
        for i, d in zip(nonlin, sub.derivatives(sub.p0)):
            if pars[i].mode == "factor":
                f = 1.0 / p[i] if p[i] != 0 else 0.0
                d = type(d)(*(None if A is None else A * f for A in (d.dK, d.dM, d.dC, d.dD)))
            out[i] = d
    return out


def _solve_ls(B, y, reg):
    """Least squares with normalised columns and a Tikhonov term by the normal equations (small n_col)."""
    nrm = np.maximum(np.linalg.norm(B, axis=0), 1e-300)
    Bn = B / nrm
    N = Bn.T @ Bn + reg * np.eye(B.shape[1])
    dz = np.linalg.solve(N, Bn.T @ y)
    return dz / nrm


def mci_update(pmodel, p, data, lower, upper, *, iters: int = 6, weights=None, tol: float = 1e-3,
               reg: float = 1e-6, free=None):
    """Parameter estimation by minimising the MCI (thesis section 3.2.4): iterate expansion and solution.

    Each iteration expands the measured responses with the current model, solves the weighted linear
    least-squares problem ``r ≈ −Σ Δp_q Tᵀ ∂Z/∂p_q x`` (exact in Δp for parameters that enter the matrices
    linearly), clips the step to the bounds and repeats until the step is below ``tol`` (relative).
    A small Tikhonov term ``reg`` keeps unidentifiable parameters in place (the trivial-solution guard of
    thesis 6.1.2).  Returns the parameters, the final weighted residual norm² and the line weights.
    """
    p = np.asarray(p, float).copy()
    lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    free = np.ones(p.size, bool) if free is None else np.asarray(free, bool)
    rss = np.inf
    for _ in range(iters):
        rsys = residual_system(pmodel.structure(p), data, weights)
        if weights is None:
            weights = rsys.w
        ders = derivatives(pmodel, p)
        B = rsys.derivative_columns([d for d, f in zip(ders, free) if f])
        rss = float(rsys.y @ rsys.y)
        dp = np.zeros(p.size)
        dp[free] = _solve_ls(B, rsys.y, reg)
        p_new = np.clip(p + dp, lo, hi)
        step = np.max(np.abs(p_new - p) / np.maximum(np.abs(p), 1e-12))
        p = p_new
        if step < tol:
            break
    rsys = residual_system(pmodel.structure(p), data, weights)
    return p, float(rsys.y @ rsys.y), weights


def rank_candidates(pmodel, p, candidates, data, weights=None, free=None):
    """Single-candidate share of the residual each shared candidate explains at ``p`` (parameters ``free``
    in the regression, all by default)."""
    rsys = residual_system(pmodel.structure(p), data, weights)
    ders = derivatives(pmodel, p)
    if free is not None:
        ders = [d for d, f in zip(ders, free) if f]
    B = rsys.derivative_columns(ders)
    if B.shape[1]:
        Q, _ = np.linalg.qr(B / np.maximum(np.linalg.norm(B, axis=0), 1e-300))
    else:
        Q = np.zeros((rsys.y.size, 0))
    res = rsys.y - Q @ (Q.T @ rsys.y)
    rss = float(res @ res)
    out = []
    for c in candidates:
        if not c.shared or c.G is None:
            continue
        g = rsys.column(c.G, c.matrix)
        if g is None:
            continue
        g = g - Q @ (Q.T @ g)
        n2 = float(g @ g)
        if n2 <= 0:
            continue
        pr = float(g @ res)
        th = pr / n2
        if th > 0:
            out.append((c, th, pr * pr / n2 / max(rss, 1e-300)))
    out.sort(key=lambda t: -t[2])
    nm, nq, ns = rsys.shape
    v = res[: res.size // 2] + 1j * res[res.size // 2:]
    energy = np.sqrt(np.sum(np.abs(v.reshape(nm, nq, ns)) ** 2, axis=(1, 2)))
    return out, rss, energy
