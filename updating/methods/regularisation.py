"""Tikhonov regularisation of a weighted least-squares step and the covariance of its solution.

Used by inverse eigensensitivity (:mod:`updating.methods.eigensensitivity`, thesis 3.2.2 and its section 6.3):
:func:`choose_alpha` picks the factor α by the L-curve (maximum curvature) or GCV, :func:`tikhonov_solve`
solves ``min ‖S y − b‖² + α²‖y‖²``, and :func:`posterior` gives the covariance of the linearised estimate at
the solution with the stated σ checked against the residuals (χ² per residual group).
"""
from __future__ import annotations

import numpy as np
from scipy.stats import chi2 as _chi2

from modalab.core.errors import ModalabValueError

__all__ = ["choose_alpha", "tikhonov_solve", "posterior"]

#: singular values of S below this fraction of the largest are a null direction: the data cannot see that
#: combination of parameters (its unregularised variance is infinite, :func:`_inverse`), and the plain
#: least-squares step does not move along it.  The sensitivities are exact only to the eigen-solution's
#: round-off, so an exactly dependent pair (E and ρ of one material, from frequencies alone: f ∝ √(E/ρ))
#: comes out with a singular value ~1e-10 of the largest, not 0; dividing by it sent both to ~1e19 x nominal.
NULL_RCOND = 1e-6


def choose_alpha(S: np.ndarray, b: np.ndarray, method: str = "lcurve", n_grid: int = 200) -> float:
    """Tikhonov factor α for ``min ‖S y − b‖² + α²‖y‖²`` by L-curve maximum curvature or GCV (via SVD)."""
    U, s, Vt = np.linalg.svd(S, full_matrices=False)
    if s.size == 0 or s[0] == 0:
        return 0.0
    beta = U.T @ b
    perp = max(float(b @ b - beta @ beta), 0.0)
    m = S.shape[0]
    alphas = np.logspace(np.log10(max(s[-1], s[0] * 1e-10) * 1e-2), np.log10(s[0] * 10), n_grid)
    f = s[None, :] ** 2 / (s[None, :] ** 2 + alphas[:, None] ** 2)           # filter factors
    rho2 = np.sum(((1 - f) * beta[None, :]) ** 2, axis=1) + perp
    eta2 = np.sum((f * beta[None, :] / s[None, :]) ** 2, axis=1)
    if method == "gcv":
        den = (m - f.sum(axis=1)) ** 2
        G = rho2 / np.where(den > 0, den, np.inf)
        return float(alphas[int(np.argmin(G))])
    if method != "lcurve":
        raise ModalabValueError(f"regularisation method {method!r}; expected 'lcurve', 'gcv' or a number")
    x = np.log(np.sqrt(np.maximum(rho2, 1e-300)))
    y = np.log(np.sqrt(np.maximum(eta2, 1e-300)))
    t = np.log(alphas)
    dx, dy = np.gradient(x, t), np.gradient(y, t)
    ddx, ddy = np.gradient(dx, t), np.gradient(dy, t)
    kappa = (dx * ddy - dy * ddx) / np.maximum((dx ** 2 + dy ** 2) ** 1.5, 1e-300)
    kappa[:2] = kappa[-2:] = -np.inf
    return float(alphas[int(np.argmax(kappa))])


def tikhonov_solve(S, b, alpha):
    """``argmin ‖S y − b‖² + α²‖y‖²``; for α = 0 the minimum-norm least-squares step with the null directions
    of S (singular values below :data:`NULL_RCOND` of the largest) left out."""
    if alpha == 0:
        return np.linalg.lstsq(S, b, rcond=NULL_RCOND)[0]
    P = S.shape[1]
    A = np.vstack([S, alpha * np.eye(P)])
    return np.linalg.lstsq(A, np.concatenate([b, np.zeros(P)]), rcond=None)[0]


def _group_of(row: str) -> str:
    return "frequency" if row.startswith("f") else "shape"


def _inverse(H):
    """(H)⁻¹ with ∞ variance for parameters in the null space of a rank-deficient H."""
    P = H.shape[0]
    w, V = np.linalg.eigh(0.5 * (H + H.T))
    tol = max(w.max(initial=0.0), 0.0) * NULL_RCOND ** 2     # eigenvalues of H = SᵀS: squared singular values
    good = w > tol
    inv = (V[:, good] / w[good]) @ V[:, good].T
    if not good.all():
        blind = np.any(np.abs(V[:, ~good]) > 1e-8, axis=1)
        inv[blind, :] = np.where(np.eye(P, dtype=bool)[blind, :], np.inf, inv[blind, :])
    return inv


def _leverage(Sw, a):
    """Leverages of the rows of ``Sw`` in the fit with Tikhonov factor ``a``."""
    H = Sw.T @ Sw + a ** 2 * np.eye(Sw.shape[1])
    Hi = np.linalg.pinv(H)
    return np.einsum("ij,jk,ik->i", Sw, Hi, Sw)


def posterior(S: np.ndarray, r: np.ndarray, rows: list, alpha: float = 0.0) -> dict:
    """Covariance of the updated parameters (scaled units) from the weighted system at the solution.

    ``S`` and ``r`` are whitened by the stated standard deviations, so with white residuals the
    linearised estimate has covariance ``(SᵀS)⁻¹``.  With ``alpha`` (Tikhonov on the departure from the initial
    parameters, a Gaussian prior of precision α² on the scaled parameters) the posterior is
    ``(SᵀS + α²I)⁻¹``, prior included.  (Penalising the *step* leaves the converged estimate the plain least-
    squares one: its covariance is ``(SᵀS)⁻¹``; the former sandwich ``(SᵀS+α²I)⁻¹SᵀS(SᵀS+α²I)⁻¹`` was smaller
    than that and did not cover the truth.)

    **Are the stated σ right?**  Per residual group (frequencies, shapes), χ² = Σ r² is compared with its
    degrees of freedom ``n_g − Σ_{i∈g} h_i`` (h the leverages of the fit).  When χ² exceeds its 95 % point the
    stated σ of that group are too small for these data (optimistic identification uncertainties, or what
    the model leaves out, e.g. a damping model); the group's rows are then down-weighted by χ²/dof (the Birge
    ratio) before the covariance is formed.  Otherwise the σ stand as stated (never scaled down).

    Returns ``covariance``, ``covariance_unregularised`` (α = 0; ∞ on the diagonal of parameters that a
    rank-deficient S cannot see), ``groups`` {name: chi2, dof, chi2_95, factor, n}, ``singular_values``
    and ``condition`` (of the weighted S, after the group factors).
    """
    P = S.shape[1]
    I = np.eye(P)
    names = np.array([_group_of(x) for x in rows]) if len(rows) == S.shape[0] else np.array(["frequency"] * S.shape[0])
    h = _leverage(S, alpha) if S.size else np.zeros(0)
    groups, weights = {}, np.ones(S.shape[0])
    for g in ("frequency", "shape"):
        sel = names == g
        if not sel.any():
            continue
        c2 = float(r[sel] @ r[sel])
        dof = float(sel.sum() - h[sel].sum())
        # rows the fit absorbs (dof near 0) leave no residual at a least-squares solution: a χ² there is judged
        # against one degree of freedom, not waved through (a χ² of 8e10 on dof 2e-9 kept σ 1e-6, issue 14)
        q95 = float(_chi2.ppf(0.95, max(dof, 1.0)))
        factor = c2 / max(dof, 1.0) if c2 > q95 else 1.0
        groups[g] = {"name": g, "n": int(sel.sum()), "chi2": c2, "dof": dof, "chi2_95": q95, "factor": factor}
        weights[sel] = 1.0 / np.sqrt(factor)
    Sw = S * weights[:, None]
    H = Sw.T @ Sw
    cov_u = _inverse(H) if S.size else np.full((P, P), np.inf)
    cov = cov_u if alpha == 0 else np.linalg.inv(H + alpha ** 2 * I)
    sv = np.linalg.svd(Sw, compute_uv=False) if Sw.size else np.zeros(0)
    full = sv.size == P and sv.size and sv[-1] > 1e-12 * sv[0]
    return {"covariance": cov, "covariance_unregularised": cov_u, "groups": groups, "singular_values": sv,
            "condition": float(sv[0] / sv[-1]) if full else np.inf}
