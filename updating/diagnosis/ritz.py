"""Receptance and its parameter Jacobian in a fixed Ritz basis (fast FRF fits of large models).

A non-linear FRF fit evaluates the model's receptance and ``∂H/∂p`` some tens of times.  On the full
model that is one sparse LU per line and evaluation.  Here the model is projected once on a Ritz basis

    V = [Φ (normal modes up to ``mode_factor`` × the top of the band), K_σ⁻¹ E (static correction at the
         measured and reference DOFs)]

— the modal-truncation-augmentation (residual flexibility) basis, which makes the truncated receptance at
the DOFs in ``E`` exact at low frequency and accurate through the band — M-orthonormalised.  At each
parameter vector the full matrices are projected (``Vᵀ K(p) V`` …), the small undamped problem is solved
(``eigh``), and the receptance follows from the modal form

    H(s) = Q_m G(s) Q_rᵀ,   G(s) = [diag(ω² + s²) + s Qᵀ C Q + i Qᵀ D Q]⁻¹,   Q = V Ψ(p)

(diagonal when the damping is proportional to the modes, e.g. a global loss factor; one small dense solve
per line otherwise), and the Jacobian from ``∂H/∂p = −H ∂Z/∂p H`` (thesis eq. 3.54-3.55 to first order) in the
same basis:
``∂H/∂p = −(G Q_mᵀ)ᵀ (Qᵀ ∂Z/∂p Q) (G Q_rᵀ)``.

The basis is built at one parameter vector and kept while the parameters move; a fit using it
(:func:`~updating.diagnosis.fit.fit_frf`) checks its result against the exact (full) receptance and
rebuilds the basis at the new parameters when they disagree.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from modalab.core.eigen import drop_mechanisms, lanczos_modes, massless_dofs, massless_mechanisms, restore
from modalab.core.dense import use_dense
from modalab.core.errors import ConvergenceError, ModalabValueError

log = logging.getLogger(__name__)
__all__ = ["RitzBasis"]


def _project(V, A):
    return None if A is None else V.T @ (A @ V)


def _lowest_modes(K, M, structure, omega_cut, min_modes, max_modes):
    """Normal modes up to ``omega_cut`` (at least ``min_modes``, at most ``max_modes``): dense for small
    models, shift-invert Lanczos (:func:`modalab.core.eigen.lanczos_modes`: a negative shift so that
    rigid-body modes are found, massless DOFs and mechanisms handled, a fixed start vector) with a growing
    count for large ones."""
    n = K.shape[0]
    if use_dense(n, "modes"):
        return structure.normal_modes(min(n, max(max_modes, min_modes)))
    n_finite = n - massless_dofs(M).size - massless_mechanisms(K, M)[0].size
    k = min(max(min_modes, 24), n_finite, n - 2)
    while True:
        w, phi, _ = lanczos_modes(K, M, k)
        if w[-1] > omega_cut or k >= min(max_modes, n_finite, n - 2):
            return w, phi
        k = min(2 * k, max_modes, n_finite, n - 2)


class RitzBasis:
    """A Ritz basis for the receptance at DOF indices ``cols`` of a structure, band top ``f_max_hz``.

    Parameters
    ----------
    structure : :class:`~modalab.core.structure.Structure` (K, M, C, D on its constrained DOFs).
    cols : indices of the DOFs whose receptance is needed (measured and reference DOFs).
    f_max_hz : top of the frequency band.
    mode_factor : normal modes up to ``mode_factor × f_max_hz`` are kept (at least ``min_modes``).
    """

    def __init__(self, structure, cols, f_max_hz: float, *, mode_factor: float = 3.0, min_modes: int = 12,
                 max_modes: int = 200):
        # (modes: dense up to modalab.core.dense.MODES_LIMIT DOFs, shift-invert Lanczos above)
        K, M = sp.csc_matrix(structure.K), sp.csc_matrix(structure.M)
        n = K.shape[0]
        cols = np.unique(np.asarray(cols, int))
        if not f_max_hz > 0:
            raise ModalabValueError(f"f_max_hz={f_max_hz!r}: the band top must be positive")
        omega, phi = _lowest_modes(K, M, structure, 2 * np.pi * mode_factor * f_max_hz, min_modes, max_modes)
        keep = omega <= 2 * np.pi * mode_factor * f_max_hz
        keep[: min(min_modes, omega.size)] = True
        phi = phi[:, keep]
        # static correction (residual flexibility) at the DOFs of interest, with a small positive shift so
        # that free or suspended structures (singular K) are handled: K_σ = K + σ M, σ = (0.1 · 2π f_max)²
        sigma = (0.2 * np.pi * f_max_hz) ** 2
        # a massless mechanism (no mass, no stiffness: K + σM singular) is constrained as in the modes
        keep, Kk, Mk = drop_mechanisms(K, M)
        E = np.zeros((n, cols.size))
        E[cols, np.arange(cols.size)] = 1.0
        Ek = E if keep is None else E[keep]
        try:
            R = restore(spla.splu(sp.csc_matrix(Kk + sigma * Mk)).solve(Ek), keep, n)
        except RuntimeError as e:
            raise ModalabValueError(f"K + σM is singular ({e}) beyond the massless mechanisms: some motion has "
                                    "neither mass nor stiffness; constrain it (SPC) or give it inertia") from None
        for _ in range(2):                                            # M-orthogonal to the kept modes
            R = R - phi @ (phi.T @ (M @ R))
        mn = np.sqrt(np.abs(np.einsum("ij,ij->j", R, M @ R)))
        R = R[:, mn > 0] / mn[mn > 0]
        V = np.hstack([phi, R])
        # M-orthonormalise the whole basis and diagonalise K on it (drops directions without mass)
        Mr = V.T @ (M @ V)
        Mr = 0.5 * (Mr + Mr.T)
        mu, U = np.linalg.eigh(Mr)
        ok = mu > 1e-10 * mu.max()
        V = V @ (U[:, ok] / np.sqrt(mu[ok]))
        Kr = V.T @ (K @ V)
        w2, Psi = np.linalg.eigh(0.5 * (Kr + Kr.T))
        self.V = np.ascontiguousarray(V @ Psi)
        self.n_modes = int(phi.shape[1])
        self.size = int(self.V.shape[1])
        self.cols = cols
        self.f_max_hz = float(f_max_hz)
        log.debug("Ritz basis: %d modes + %d static corrections -> %d vectors of %d DOFs", self.n_modes, cols.size,
                  self.size, n)

    # ---------------------------------------------------------------------------------------------
    def modal(self, structure):
        """``Q = V Ψ`` (n, m), ω² (m,), and the modal damping matrices ``Qᵀ C Q``, ``Qᵀ D Q`` (or None)."""
        V = self.V
        Kr, Mr = _project(V, structure.K), _project(V, structure.M)
        w2, Psi = sla.eigh(0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T))
        Q = V @ Psi
        Cq = None if structure.C is None else Psi.T @ _project(V, structure.C) @ Psi
        Dq = None if structure.D is None else Psi.T @ _project(V, structure.D) @ Psi
        return Q, Psi, np.clip(w2, 0.0, None), Cq, Dq

    def responses(self, structure, s, rows, refs, want_jac_rows: bool = True):
        """``H`` (n_rows, n_refs, n_s) and the factors of the Jacobian for :meth:`jacobian`.

        Returns ``(H, ctx)``; ``ctx`` holds ``Yr = G Q_refsᵀ`` and ``Ym = G Q_rowsᵀ`` (m, ·, n_s), Ψ and the
        projected basis.
        """
        s = np.asarray(s, complex)
        Q, Psi, w2, Cq, Dq = self.modal(structure)
        Qm, Qr = Q[rows], Q[refs]                                     # (n_m, m), (n_r, m)
        m = w2.size
        diag_only = True
        for A in (Cq, Dq):
            if A is not None and np.abs(A - np.diag(np.diag(A))).max(initial=0.0) > \
                    1e-10 * max(np.abs(np.diag(A)).max(initial=0.0), 1e-300):
                diag_only = False
        if diag_only:
            z = w2[:, None] + (s ** 2)[None, :]                       # (m, n_s)
            if Cq is not None:
                z = z + np.diag(Cq)[:, None] * s[None, :]
            if Dq is not None:
                z = z + 1j * np.diag(Dq)[:, None]
            g = 1.0 / z
            Yr = g[:, None, :] * Qr.T[:, :, None]                      # (m, n_r, n_s)
            Ym = g[:, None, :] * Qm.T[:, :, None] if want_jac_rows else None
        elif Cq is None and (Y := _hysteretic_solve(w2, Dq, s, np.concatenate([Qr.T, Qm.T], axis=1)
                                                    if want_jac_rows else Qr.T)) is not None:
            Yr = Y[:, : Qr.shape[0]]
            Ym = Y[:, Qr.shape[0]:] if want_jac_rows else None
        else:
            Z = np.zeros((s.size, m, m), complex)
            Z[:, np.arange(m), np.arange(m)] = w2[None, :] + (s ** 2)[:, None]
            if Cq is not None:
                Z += s[:, None, None] * Cq[None]
            if Dq is not None:
                Z += 1j * Dq[None]
            rhs = np.concatenate([Qr.T, Qm.T], axis=1) if want_jac_rows else Qr.T
            Y = np.linalg.solve(Z, np.broadcast_to(rhs, (s.size,) + rhs.shape)).transpose(1, 2, 0)
            Yr = Y[:, : Qr.shape[0]]
            Ym = Y[:, Qr.shape[0]:] if want_jac_rows else None
        H = np.einsum("mk,krf->mrf", Qm, Yr, optimize=True)
        return H, (Q, Yr, Ym)

    @staticmethod
    def jacobian(ctx, derivative, s) -> np.ndarray:
        """``∂H/∂p`` (n_rows, n_refs, n_s) for one :class:`~updating.fe.parametric.Derivative`."""
        Q, Yr, Ym = ctx
        m, nr, ns = Yr.shape
        A = np.zeros((m, nr, ns), complex)
        Y2 = np.ascontiguousarray(Yr).reshape(m, nr * ns)             # one product over every line and reference
        for mat, fac in ((derivative.dK, None), (derivative.dM, s ** 2), (derivative.dC, s),
                         (derivative.dD, 1j * np.ones_like(s))):
            if mat is None:
                continue
            P = Q.T @ (mat @ Q)                                       # (m, m)
            # a real P: one real product on the interleaved real and imaginary parts
            PY = (P @ Y2 if np.iscomplexobj(P) else (P @ Y2.view(float)).view(complex)).reshape(m, nr, ns)
            A += PY if fac is None else PY * fac[None, None, :]
        # dH[a, b, f] = −Σ_k Ym[k, a, f] A[k, b, f], one small product per line
        return -np.matmul(Ym.transpose(2, 1, 0), A.transpose(2, 0, 1)).transpose(1, 2, 0)


#: the eigenvector matrix of ``diag(ω²) + i Dq`` may have at most this condition number for
#: :func:`_hysteretic_solve`, which otherwise leaves the lines to a solve each
EIG_COND_LIMIT = 1e6


def _hysteretic_solve(w2, Dq, s, rhs):
    """``(diag(ω²) + i Dq + s_f² I)⁻¹ rhs`` at every line (m, n_rhs, n_s), from one eigen-decomposition
    ``diag(ω²) + i Dq = W Λ W⁻¹`` (the resolvent of one matrix: ``W (Λ + s_f²)⁻¹ W⁻¹``) instead of a solve per
    line; None where ``W`` is too ill-conditioned to invert (:data:`EIG_COND_LIMIT`: near-defective, as
    repeated ω² coupled by ``Dq`` can be)."""
    lam, W = np.linalg.eig(np.diag(w2).astype(complex) + 1j * Dq)
    if not np.all(np.isfinite(lam)) or np.linalg.cond(W) > EIG_COND_LIMIT:
        return None
    B = np.linalg.solve(W, rhs)                                               # (m, n_rhs)
    G = B[:, :, None] / (lam[:, None, None] + (s ** 2)[None, None, :])        # (m, n_rhs, n_s)
    m, nr, ns = G.shape
    return (W @ G.reshape(m, nr * ns)).reshape(m, nr, ns)


class SingularStepError(ConvergenceError, np.linalg.LinAlgError):
    """An FRF fit in a Ritz basis stepped to parameters at which the model's basis cannot be built (K + σM or M
    singular: typically a spring run to a stiffness ~10¹⁶ times the structure's, a rigid connection the
    arithmetic cannot hold beside it).  A :class:`~numpy.linalg.LinAlgError`, so that the diagnosis reports the
    candidate being fitted as not evaluated (:meth:`~updating.diagnosis.workflow.Diagnoser._try`), and a
    :class:`~modalab.core.errors.ConvergenceError` wherever it is not expected."""


def round_basis(structure, cols, f_max_hz: float, pmodel, p_start, p, free, rnd: int) -> RitzBasis:
    """The :class:`RitzBasis` of round ``rnd`` of an FRF fit (:func:`~updating.diagnosis.fit.fit_frf`), at the
    parameters ``p`` its last round reached from ``p_start`` (``structure`` is the model there).  Where it cannot
    be built (K + σM or M singular): at the start a fault of the model (the basis' own error), after a round the
    fit's step (:class:`SingularStepError`, naming the free parameters that moved most by their ratio to the
    start)."""
    try:
        return RitzBasis(structure, cols, f_max_hz)
    except ModalabValueError as e:
        if rnd == 0:
            raise
        ratio = np.abs(p) / np.maximum(np.abs(p_start), 1e-300)
        moved = ", ".join(f"{pmodel.parameter_names[i]} {p_start[i]:.3g} -> {p[i]:.3g}"
                          for i in [i for i in np.argsort(-ratio) if free[i]][:2])
        raise SingularStepError(f"an FRF fit in a Ritz basis stepped to parameters at which the model is singular "
                                f"({moved}), typically a stiffness run far beyond the structure's own (a rigid "
                                f"connection); the fit stops") from e
