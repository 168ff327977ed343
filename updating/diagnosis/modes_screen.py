"""Single-candidate screening of the modes-only diagnosis (:func:`screen_modes`, issue 16 #8).

Each shared stiffness or mass candidate ``θ G = θ E L Lᵀ Eᵀ`` (:class:`~updating.diagnosis.local_matrix.LocalMatrix`:
a few DOF indices and a small block) is judged on the modal residual of
:class:`~updating.diagnosis.modes.ModalResidual` in two stages:

1. above :data:`PRESCREEN_ABOVE` candidates, a first-order pre-screen ranks all of them at once by the
   residual each removes to first order in its value: the eigenvalue and eigenvector sensitivities of the
   paired modes in the subspace of the lowest modes (Fox & Kapoor; thesis section 3.3, eq. 3.38 for
   ``∂λ_j/∂θ = φ_jᵀ(∂K − λ_j ∂M)φ_j``), with the best non-negative value of the linearised residual; the
   best :data:`PRESCREEN_KEEP` go on.  A candidate that acts on no paired mode has no first-order effect and
   ranks last;
2. each remaining candidate is added exactly at every value of a plausible grid in the subspace extended by
   the static corrections of its own DOFs (a small ``(m + r)`` eigenproblem per value), as before.

Nothing per candidate is of the model's size: the cost is one sparse solve per candidate of stage 2.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from updating.diagnosis.frfscreen import _low_rank, _value_grid
from updating.diagnosis.subspace import ModalSubspace, _extended_rows

log = logging.getLogger(__name__)
__all__ = ["screen_modes", "first_order_gains", "PRESCREEN_ABOVE", "PRESCREEN_KEEP"]

#: a candidate whose best value changes no paired (observed) model eigenvalue by this fraction acts only
#: on modes the sensors cannot see: its gain comes from pairing, not from evidence
MIN_OBSERVED_EFFECT = 1e-4
#: with more screenable candidates than this, a first-order pre-screen chooses which are evaluated exactly
PRESCREEN_ABOVE = 4000
#: ... and this many (the best by the first-order gain) are
PRESCREEN_KEEP = 500


def _candidate_effect(resid, fm, Vm_basis_modes, b_modes, theta, matrix):
    """Largest first-order relative change of a paired model eigenvalue for value ``theta`` (see
    :func:`screen_modes`)."""
    lam = (2 * np.pi * fm) ** 2
    s = np.sum(b_modes ** 2, axis=1) * theta
    rel = s / np.maximum(lam, 1e-300) if matrix == "K" else s
    return float(np.max(np.abs(rel))) if rel.size else 0.0


def _local_block(A, rows) -> sp.csr_matrix:
    """``A[rows][:, rows]`` (``rows`` sorted) as a small CSR matrix, without the O(n) column indexing of scipy."""
    sub = sp.coo_matrix(A[rows])
    p = np.clip(np.searchsorted(rows, sub.col), 0, rows.size - 1)
    hit = rows[p] == sub.col
    B = np.zeros((rows.size, rows.size))
    np.add.at(B, (sub.row[hit], p[hit]), sub.data[hit])
    return sp.csr_matrix(B)


class _ScreenState:
    """The nominal model in the screening subspace: its modes, the residual, the pairing."""

    def __init__(self, structure, resid, basis):
        self.K, self.M = sp.csr_matrix(structure.K), sp.csr_matrix(structure.M)
        if basis is None or not basis.matches(structure):
            # the lowest modes alone: each candidate brings the static corrections of its own DOFs
            basis = ModalSubspace(structure, [], float(resid.f.max()), resid.n_model_modes)
        self.basis, self.resid = basis, resid
        self.mi, self.ms = resid.rows(structure)
        Kr0, Mr0 = basis.project(self.K, self.M)
        self.w20, self.Psi0 = sla.eigh(Kr0, Mr0)
        self.kn = resid.n_pairable(np.sqrt(np.clip(self.w20, 0, None)) / (2 * np.pi))
        self.fm0 = np.sqrt(np.clip(self.w20[:self.kn], 0, None)) / (2 * np.pi)
        self.Um = (basis.rows_of(self.mi) * self.ms[:, None]) @ self.Psi0       # measured part of every mode
        Vm0 = self.Um[:, :self.kn]
        self.e0 = resid.residual(self.fm0, Vm0)
        self.r0 = float(self.e0 @ self.e0)
        self.a0, _ = resid.pairs(self.fm0, Vm0)

    def paired_rows(self, rows) -> np.ndarray:
        """The paired modes at full-DOF indices ``rows``: (len(rows), n_pairs)."""
        return self.basis.rows_of(rows) @ self.Psi0[:, self.a0]


def _jacobians(state: _ScreenState, matrix: str, R, Ls) -> np.ndarray:
    """``∂e/∂θ`` at θ = 0 of the modal residual (pairing fixed) for candidates ``E_R L Lᵀ E_Rᵀ`` of one kind
    (``matrix`` 'K' or 'M'; ``R`` (g, nr) full-DOF indices, ``Ls`` (g, nr, q)), as (g, n_e): from the
    sensitivities of the paired modes in the subspace (see :func:`first_order_gains`)."""
    r = state.resid
    lam, a0 = state.w20, state.a0
    n_p = a0.size
    lam_p = lam[a0]
    dl = lam_p[None, :] - lam[:, None]                                             # (m, n_p): λ_j − λ_k
    inv = np.zeros_like(dl)
    ok = np.abs(dl) > 1e-8 * np.maximum(np.abs(lam_p)[None, :], 1e-300)
    inv[ok] = 1.0 / dl[ok]
    inv[a0, np.arange(n_p)] = 0.0
    om = np.sqrt(np.maximum(lam_p, 1e-300))
    sf = np.broadcast_to(np.asarray(r.sigma_f, float), r.f.shape)
    g, nr = R.shape
    P = (state.basis.rows_of(R.ravel()) @ state.Psi0).reshape(g, nr, -1)
    bm = np.einsum("gnq,gnm->gqm", Ls, P)                                           # (g, q, m)
    C = np.einsum("gqm,gqj->gmj", bm, bm[:, :, a0])                                 # (g, m, n_p)
    Cjj = C[:, a0, np.arange(n_p)]                                                  # (g, n_p)
    if matrix == "K":
        dlam, dpsi = Cjj, C * inv[None]
    else:
        dlam, dpsi = -lam_p[None] * Cjj, -lam_p[None, None] * C * inv[None]
        dpsi[:, a0, np.arange(n_p)] += -0.5 * Cjj
    J = [dlam / (4 * np.pi * om[None]) / (sf * r.f)[None]]                          # ∂f_j / (σ_f f_j)
    if r.has_shapes:
        u0 = state.Um[:, a0]
        nu = np.maximum(np.linalg.norm(u0, axis=0), 1e-300)
        v = u0 / nu
        proj = np.einsum("ij,ij->j", v, r.phi)
        du = np.einsum("im,gmj->gij", state.Um, dpsi)                               # (g, n_meas, n_p)
        dv = (du - v[None] * np.einsum("ij,gij->gj", v, du)[:, None, :]) / nu[None, None]
        dvp = dv * proj[None, None] + v[None] * np.einsum("gij,ij->gj", dv, r.phi)[:, None, :]
        J.append((dvp / r.sigma_phi).reshape(g, -1))
    return np.concatenate(J, axis=1)


def first_order_gains(state: _ScreenState, work) -> np.ndarray:
    """For each ``(candidate, (rows, L))`` of ``work``, the relative drop of ‖e‖² to first order in its value:
    ``e(θ) ≈ e₀ + θ J``, ``θ* = max(−Jᵀe₀/JᵀJ, 0)`` (not above the candidate's ``upper``), gain ``1 − ‖e₀ +
    θ*J‖²/‖e₀‖²``.  ``J`` from the sensitivities of the paired modes in the subspace of the lowest modes
    (mass-normalised ``ψ``, ``λ``): ``∂λ_j = ψ_jᵀ A_j ψ_j``, ``∂ψ_j = Σ_{k≠j} ψ_k ψ_kᵀ A_j ψ_j /(λ_j − λ_k)
    − ½ ψ_j ψ_jᵀ ∂M ψ_j`` with ``A_j = ∂K − λ_j ∂M``; close pairs (|λ_j − λ_k| < 1e-8 λ_j) are left out of the
    sum.  Vectorised over candidates of the same shape; nothing of the model's size per candidate."""
    e0 = state.e0
    gains = np.full(len(work), -np.inf)
    groups: dict = {}
    for i, (c, (rows, L)) in enumerate(work):
        groups.setdefault((c.matrix, rows.size, L.shape[1]), []).append(i)
    for (matrix, nr, q), members in sorted(groups.items()):
        for chunk in np.array_split(np.asarray(members), max(1, len(members) // 2000)):
            R = np.array([work[i][1][0] for i in chunk])                                # (g, nr)
            Ls = np.array([work[i][1][1] for i in chunk])                               # (g, nr, q)
            J = _jacobians(state, matrix, R, Ls)
            jj = np.einsum("gk,gk->g", J, J)
            je = J @ e0
            upper = np.array([work[i][0].upper for i in chunk], float)
            t = np.clip(-je / np.maximum(jj, 1e-300), 0.0, upper)
            rr = state.r0 + 2 * t * je + t * t * jj
            gains[chunk] = 1.0 - rr / max(state.r0, 1e-300)
    return gains


def _evaluate_exactly(state: _ScreenState, c, rows, L):
    """The candidate at every value of its plausible grid (refined twice near the best) in the subspace
    extended by its own static corrections: ``(value, ‖e‖²)`` of the best, or None (no grid, no effect on
    the paired modes, or not lowering the residual)."""
    resid, mi, ms, kn = state.resid, state.mi, state.ms, state.kn
    grid = _value_grid(c, _local_block(state.K, rows), _local_block(state.M, rows), np.arange(rows.size), L, n=13)
    if grid.size == 0:
        return None
    bp = L.T @ state.paired_rows(rows)                            # (r, n_pairs): the candidate on paired modes
    fa = state.fm0[state.a0]
    if _candidate_effect(resid, fa, None, bp.T, grid[-1], c.matrix) < MIN_OBSERVED_EFFECT:
        return "blind"          # even its largest value leaves every paired mode an exact eigenpair: no evidence
    Wm, Kr, b = _extended_rows(state.basis, rows, L, mi)
    if not np.any(b):
        return None
    Wm = Wm * ms[:, None]
    G = b @ b.T

    def evaluate(thetas):
        if c.matrix == "K":
            w2, Psi = np.linalg.eigh(Kr[None] + thetas[:, None, None] * G[None])
        else:
            Mt = np.eye(Kr.shape[0])[None] + thetas[:, None, None] * G[None]
            Ci = np.linalg.inv(np.linalg.cholesky(Mt))
            A = Ci @ Kr[None] @ Ci.transpose(0, 2, 1)
            w2, Y = np.linalg.eigh(0.5 * (A + A.transpose(0, 2, 1)))
            Psi = Ci.transpose(0, 2, 1) @ Y
        res = np.empty(thetas.size)
        for t in range(thetas.size):
            e = resid.residual(np.sqrt(np.clip(w2[t, :kn], 0, None)) / (2 * np.pi), Wm @ Psi[t][:, :kn])
            res[t] = float(e @ e)
        return res

    t = grid
    rr = evaluate(t)
    for _ in range(2 if rr.min() < 0.95 * state.r0 else 0):   # refine twice between the best value's neighbours
        k = int(np.argmin(rr))
        lo_t, hi_t = t[max(k - 1, 0)], t[min(k + 1, t.size - 1)]
        if hi_t <= lo_t:
            break
        t2 = np.geomspace(lo_t, hi_t, 7)[1:-1]
        t, rr = np.concatenate([t, t2]), np.concatenate([rr, evaluate(t2)])
        o = np.argsort(t, kind="stable")
        t, rr = t[o], rr[o]
    k = int(np.argmin(rr))
    if rr[k] >= state.r0:
        return None
    if _candidate_effect(resid, fa, None, bp.T, t[k], c.matrix) < MIN_OBSERVED_EFFECT:
        log.info("modes: %s would explain %.0f %% of the residual but changes no observed mode; not evidence",
                 c.label, 100 * (1 - rr[k] / max(state.r0, 1e-300)))
        return None
    return float(t[k]), float(rr[k])


def screen_modes(structure, candidates, resid, basis: ModalSubspace | None = None, *,
                 prescreen_above: int | None = None, keep: int | None = None) -> list:
    """Each shared stiffness or mass candidate added alone to ``structure`` at its best value on a plausible
    grid, judged on the modal residual ``resid`` (:class:`~updating.diagnosis.modes.ModalResidual`):
    ``[(candidate, value, gain)]`` best first (gain = relative drop of the residual's squared norm; only
    candidates that lower it).

    No eigen-solution of the full model per value: the candidate ``θ G = θ L Lᵀ`` (rank 1 for a spring,
    3 for a point mass) is added in the subspace of the lowest modes extended by the static corrections of
    its own DOFs (:meth:`ModalSubspace.extended`) — a small ``(m + r)`` eigenproblem per value, batched
    over the grid.  A candidate is kept only if its best value changes a model mode paired with a test
    mode (``L ᵀφ_j ≠ 0``: otherwise every paired mode is an exact eigenpair of the changed model too, and
    any gain would come from a different pairing of modes the sensors cannot see).  With more than
    ``prescreen_above`` (:data:`PRESCREEN_ABOVE`) candidates only the ``keep`` (:data:`PRESCREEN_KEEP`) best
    by :func:`first_order_gains` are evaluated so (module docstring)."""
    prescreen_above = PRESCREEN_ABOVE if prescreen_above is None else prescreen_above
    keep = PRESCREEN_KEEP if keep is None else keep
    state = _ScreenState(structure, resid, basis)
    work = []
    for c in candidates:
        if not c.shared or c.G is None or c.matrix not in ("K", "M"):
            continue
        lr = _low_rank(c.G)
        if lr is not None:
            work.append((c, lr))
    n_work = len(work)
    if n_work > prescreen_above:
        g = first_order_gains(state, work)
        order = sorted(range(n_work), key=lambda i: (-g[i], work[i][0].key))[:keep]
        log.info("modes: first-order pre-screen of %d candidates keeps %d (first-order gain down to %.3g)",
                 n_work, len(order), g[order[-1]] if order else np.nan)
        work = [work[i] for i in sorted(order)]
    out, n_blind = [], 0
    for c, (rows, L) in work:
        res = _evaluate_exactly(state, c, rows, L)
        if isinstance(res, str):
            n_blind += 1
        elif res is not None:
            out.append((c, res[0], 1.0 - res[1] / max(state.r0, 1e-300)))
    out.sort(key=lambda x: (-x[2], x[0].key))
    log.info("modes: screened %d candidates in a %d-vector subspace; %d act on no observed mode", len(candidates),
             state.basis.size, n_blind)
    return out
