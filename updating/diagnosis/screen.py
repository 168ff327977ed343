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
from dataclasses import dataclass, field

import numpy as np

from modalab.core.dof import locate

from updating.correlation.condensation import condensed_residual
from updating.methods.mci_condensed import (_column, _factor, _stack, derivatives, mci_update,  # noqa: F401
                                            residual_system)

log = logging.getLogger(__name__)
__all__ = ["screen", "ScreenResult", "residual_map", "rank_candidates", "mci_update", "residual_system"]


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
