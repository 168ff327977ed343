"""The Ritz subspace of the modes-only diagnosis (:mod:`~updating.diagnosis.modes`): the lowest modes of a
structure, extended by static corrections at given DOFs, in which stiffness and mass changes (parameters, a
candidate's ``θ L Lᵀ``) are evaluated by a small eigenproblem instead of an eigen-solution of the full model."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from modalab.core.dense import use_dense
from updating.fe.solvers import DEFAULT_SHIFT_HZ, _drop_mechanisms, eigen_dense, eigen_sparse, factorize

__all__ = ["ModalSubspace"]


def _new_directions(V, S, M) -> np.ndarray:
    """M-orthonormal directions of ``S`` outside the M-orthonormal basis ``V``.  The static correction of a
    DOF beyond the lowest modes has a tiny mass (the high modes' share of a static deflection is weighted by
    1/ω⁴) but matters for a stiff spring or heavy mass there; a direction is dropped only when it is
    numerically inside ``V`` (Euclidean norm after two Gram-Schmidt passes below 1e-10 of its own) or has no
    mass."""
    if S.shape[1] == 0:
        return S
    n0 = np.linalg.norm(S, axis=0)
    for _ in range(2):
        S = S - V @ (V.T @ (M @ S))
    n1 = np.linalg.norm(S, axis=0)
    S = S[:, n1 > 1e-10 * np.maximum(n0, 1e-300)]
    if S.shape[1] == 0:
        return S
    S = S / np.linalg.norm(S, axis=0)
    ms = S.T @ (M @ S)
    mu, U = np.linalg.eigh(0.5 * (ms + ms.T))
    mmax = float(np.abs(M.diagonal()).max(initial=0.0))
    ok = mu > 1e-12 * max(mmax, 1e-300)
    S = S @ (U[:, ok] / np.sqrt(mu[ok]))
    for _ in range(2):                          # re-orthogonalise after the scaling
        S = S - V @ (V.T @ (M @ S))
    return S


class ModalSubspace:
    """A Ritz basis for the lowest modes of a structure and their changes (modes-only screening and fits).

    ``V = [Φ (modes up to ``mode_factor`` × the highest test frequency, at least ``n_min``), K_σ⁻¹ E (static
    corrections at the measured DOFs and the DOFs in ``cols``)]``, M-orthonormal and K-diagonal, on the
    structure's DOFs (a massless mechanism's constrained DOF is zero, see :mod:`updating.fe.solvers`).  The
    modes of a changed structure (new parameters, an added spring or mass) are the Ritz values of ``VᵀKV``,
    ``VᵀMV`` — the modal-truncation-augmentation basis of :class:`~updating.diagnosis.ritz.RitzBasis`,
    whose static corrections make a stiffness or mass added at those DOFs exact at low frequency.
    :meth:`extended` adds the static corrections of one candidate's DOFs (a low-rank update of the basis).
    """

    def __init__(self, structure, cols, f_top_hz: float, n_min: int, *, mode_factor: float = 2.5):
        K, M = sp.csr_matrix(structure.K), sp.csr_matrix(structure.M)
        n = K.shape[0]
        keep, Kk, Mk = _drop_mechanisms(K, M)
        keep = np.arange(n) if keep is None else keep
        fixed = np.setdiff1d(np.arange(n), keep)
        nk = keep.size
        k = min(max(n_min, 24), nk - 2)
        while True:
            w, phi = eigen_dense(Kk, Mk, k) if use_dense(nk, "modes") else eigen_sparse(Kk, Mk, k)
            if w[-1] >= 2 * np.pi * mode_factor * f_top_hz or k >= nk - 2 or k >= 400:
                break
            k = min(2 * k, nk - 2, 400)
        self.sigma = -(2 * np.pi * DEFAULT_SHIFT_HZ) ** 2
        self.factor = factorize(sp.csc_matrix(Kk - self.sigma * Mk), "auto")
        pos = np.full(n, -1)
        pos[keep] = np.arange(nk)
        self.pos, self.keep, self.n, self.Kk, self.Mk = pos, keep, n, Kk, Mk
        self.mechanism_dofs = fixed
        c = pos[np.unique(np.asarray(cols, int))]
        c = c[c >= 0]
        E = np.zeros((nk, c.size))
        E[c, np.arange(c.size)] = 1.0
        R = self.factor.solve(E) if c.size else np.zeros((nk, 0))
        V = _new_directions(np.zeros((nk, 0)), phi, Mk)          # the modes, M-orthonormal
        V = np.hstack([V, _new_directions(V, R, Mk)])
        Kr = V.T @ (Kk @ V)
        w2, Psi = np.linalg.eigh(0.5 * (Kr + Kr.T))
        self.V = np.ascontiguousarray(V @ Psi)                  # on the kept DOFs
        self.w2 = w2
        self.n_modes = int(phi.shape[1])
        self.dofs = list(structure.dofs)

    @property
    def size(self) -> int:
        return self.V.shape[1]

    @property
    def deflation(self):
        """``(MV, VᵀMV)`` on the kept DOFs, computed once (for :func:`_extended_rows`)."""
        if getattr(self, "_deflation", None) is None:
            MV = np.asarray(self.Mk @ self.V)
            self._deflation = (MV, 0.5 * (self.V.T @ MV + MV.T @ self.V))
        return self._deflation

    def full(self, V=None) -> np.ndarray:
        V = self.V if V is None else V
        out = np.zeros((self.n, V.shape[1]))
        out[self.keep] = V
        return out

    def rows_of(self, idx, V=None) -> np.ndarray:
        """Rows ``idx`` (full-DOF indices) of :meth:`full` without forming it (zero at a mechanism's DOF)."""
        V = self.V if V is None else V
        p = self.pos[np.asarray(idx, int)]
        out = np.zeros((p.size, V.shape[1]))
        out[p >= 0] = V[p[p >= 0]]
        return out

    def matches(self, structure) -> bool:
        return list(structure.dofs) == self.dofs

    def project(self, K, M):
        """``VᵀKV``, ``VᵀMV`` of full-size matrices of a structure on the same DOFs."""
        Vf = self.full()
        Kr, Mr = Vf.T @ (K @ Vf), Vf.T @ (M @ Vf)
        return 0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T)

    def extended(self, rows, L):
        """``(W, Kr, b)``: the basis extended by the M-orthonormal static corrections of ``E_rows L``
        (``W`` on the kept DOFs), ``Kr = WᵀKW`` (the nominal stiffness) and ``b = W[rows]ᵀ L`` (so that the
        candidate's ``θ G`` projects to ``θ b bᵀ``).  Rows on a massless mechanism's constrained DOF drop
        out: there the candidate changes no finite mode (a spring fixes the mechanism, an inertia adds only
        its 0 Hz rigid rotation)."""
        p = self.pos[rows]
        on = p >= 0
        Lk = L[on]
        p = p[on]
        V = self.V
        if p.size == 0:
            return V, np.diag(self.w2), np.zeros((V.shape[1], L.shape[1]))
        E = np.zeros((V.shape[0], Lk.shape[1]))
        E[p] = Lk
        S = _new_directions(V, self.factor.solve(E), self.Mk)
        W = np.hstack([V, S])
        KS = self.Kk @ S
        m = V.shape[1]
        Kr = np.zeros((W.shape[1], W.shape[1]))
        Kr[:m, :m] = np.diag(self.w2)
        Kr[:m, m:] = V.T @ KS
        Kr[m:, :m] = Kr[:m, m:].T
        Kr[m:, m:] = S.T @ KS
        return W, 0.5 * (Kr + Kr.T), W[p].T @ Lk


def _extended_rows(basis, rows, L, idx):
    """:meth:`ModalSubspace.extended` with two passes over the basis instead of some ten: ``(W[idx], Kr, b)``,
    ``W[idx]`` the rows ``idx`` (full-DOF indices) of the extended basis; the same Ritz problem up to a
    rotation of the new directions among themselves.

    The static correction is solved for a load with the basis' share removed, ``S₀ = K_σ⁻¹ (E − MV a)``,
    ``a = VᵀE = V[rows]ᵀL`` (``K_σ = K − σM``): for a free-free structure ``K_σ⁻¹E`` is dominated by the
    rigid-body and low modes (the new direction holds ~1e-13 of its mass), which the explicit Gram-Schmidt of
    :meth:`ModalSubspace.extended` removes in repeated passes; the deflated load never creates them, so one
    projection ``c = (MV)ᵀS₀`` makes ``S₁ = S₀ − Vc`` M-orthogonal to the basis.  The stiffness blocks follow
    from ``K = K_σ + σM`` without a product with K: ``VᵀKS₀ = VᵀF + σc``, ``S₀ᵀKS₀ = S₀ᵀF + σS₀ᵀMS₀``
    (``F`` the deflated load), then ``VᵀKS₁ = VᵀKS₀ − ω²c`` and ``S₁ᵀKS₁ = S₀ᵀKS₀ − cᵀVᵀKS₀ − (VᵀKS₀)ᵀc +
    cᵀω²c``.  Only the rows ``idx`` and ``rows`` of ``S₁`` are formed.  A new direction whose mass is not
    clear of the projection (below 1e-6 of ``S₀ᵀMS₀``) falls back to the explicit extension.
    """
    p = basis.pos[rows]
    on = p >= 0
    Lk, p = L[on], p[on]
    V, w2, sg = basis.V, basis.w2, basis.sigma
    m = V.shape[1]
    if p.size == 0:
        return basis.rows_of(idx), np.diag(w2), np.zeros((m, L.shape[1]))
    MV, VMV = basis.deflation
    a = V[p].T @ Lk
    F = -(MV @ a)
    np.add.at(F, p, Lk)
    S0 = np.asarray(basis.factor.solve(F))
    c = MV.T @ S0
    g0 = S0.T @ (basis.Mk @ S0)
    g0 = 0.5 * (g0 + g0.T)
    G = g0 - c.T @ c
    mu, U = np.linalg.eigh(0.5 * (G + G.T))
    if mu.min() < 1e-6 * max(float(np.linalg.eigvalsh(g0).max()), 1e-300):
        W, Kr, b = basis.extended(rows, L)
        return basis.rows_of(idx, W), Kr, b
    T = U / np.sqrt(mu)
    VKS0 = (a - VMV @ a) + sg * c
    k0 = S0[p].T @ Lk - c.T @ a + sg * g0
    SKS1 = 0.5 * (k0 + k0.T) - c.T @ VKS0 - VKS0.T @ c + c.T @ (w2[:, None] * c)
    r = T.shape[1]
    Kr = np.zeros((m + r, m + r))
    Kr[:m, :m] = np.diag(w2)
    Kr[:m, m:] = (VKS0 - w2[:, None] * c) @ T
    Kr[m:, :m] = Kr[:m, m:].T
    Kr[m:, m:] = T.T @ SKS1 @ T
    q = basis.pos[np.asarray(idx, int)]
    Wi = np.zeros((q.size, m + r))
    hit = q >= 0
    Wi[hit, :m] = V[q[hit]]
    Wi[hit, m:] = (S0[q[hit]] - V[q[hit]] @ c) @ T
    Wp = np.hstack([V[p], (S0[p] - V[p] @ c) @ T])
    return Wi, 0.5 * (Kr + Kr.T), Wp.T @ Lk
