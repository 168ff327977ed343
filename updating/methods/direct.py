"""Direct (non-iterative) matrix updating methods, thesis section 3.1.

Each function takes the analytical matrices ``K_A``, ``M_A`` (dense or
sparse, N×N) and measured modal data on *all* N model DOFs (expand first if
the measurement is incomplete): mass-normalised shapes ``phi_X`` (N×m) and
natural frequencies ``omega_X`` in rad/s; it returns a :class:`DirectUpdate`
with the updated and correction matrices.

=====================================  =================================================  ============
method                                  function                                          equations
=====================================  =================================================  ============
Lagrange multipliers, stiffness          :func:`lagrange_stiffness` (Baruch & Bar-Itzhack)  3.1–3.5
Lagrange multipliers, mass               :func:`lagrange_mass` (Berman)                     3.6–3.10
Lagrange multipliers, mass + stiffness   :func:`lagrange_mass_stiffness` (Berman & Nagy)    3.6–3.14
error matrix method                      :func:`error_matrix`                               3.15–3.23
direct matrix updating                   :func:`direct_matrix_updating`                     3.24–3.26
matrix mixing                            :func:`matrix_mixing`                              3.27–3.30
=====================================  =================================================  ============

With a complete modal model (m = N modes on all N DOFs) every method except
the error matrix method reproduces the reference matrices exactly (thesis
5.1.1–5.1.4, 6.1.1); the error matrix method is first order in the error
(Eq. 3.20 drops the quadratic terms), so it is exact only to first order.

Notes on the printed equations (corrected here, following Ewins' *Modal
Testing* and the original papers):

* (3.10) ends with ``[φ]_X [M]_A``; the transpose ``[φ]_Xᵀ [M]_A`` is meant (as in 3.24).
* (3.14) is Berman & Nagy's stiffness correction; it must be evaluated with
  the *updated* mass matrix ``[M]_AU`` of (3.9) wherever ``[M]_A`` appears,
  otherwise it is exact only when the mass matrix was already correct.
* (3.27) prints ``ω_r²``; the flexibility expansion needs ``1/ω_r²`` (as in 3.30),
  and (3.29) gives ``[M]_AU⁻¹`` (not ``[M]_AU``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from modalab.core.errors import ModalabValueError, ShapeError

__all__ = [
    "DirectUpdate",
    "lagrange_stiffness",
    "lagrange_mass",
    "lagrange_mass_stiffness",
    "error_matrix",
    "direct_matrix_updating",
    "matrix_mixing",
    "baruch_orthogonalise",
]


@dataclass
class DirectUpdate:
    """Result of a direct method: updated ``K``, ``M`` and the corrections ``dK = K − K_A``, ``dM = M − M_A``."""

    K: np.ndarray
    M: np.ndarray
    dK: np.ndarray
    dM: np.ndarray
    method: str
    equations: str


def _dense(A, name, n=None):
    A = A.toarray() if sp.issparse(A) else np.asarray(A, dtype=float)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise ShapeError(f"{name} must be a square matrix; got shape {A.shape}")
    if n is not None and A.shape[0] != n:
        raise ShapeError(f"{name} is {A.shape[0]}x{A.shape[0]} but the other matrices are {n}x{n}")
    return A


def _modes(phi, omega, n, name="phi_X"):
    phi = np.asarray(phi)
    if np.iscomplexobj(phi):
        raise ModalabValueError(f"{name} is complex; pass real normal-mode shapes "
                                "(ModeSet.real_shapes) for the direct methods")
    phi = np.asarray(phi, float)
    if phi.ndim == 1:
        phi = phi[:, None]
    if phi.shape[0] != n:
        raise ShapeError(f"{name} has {phi.shape[0]} rows but the model has {n} DOFs; "
                         "expand the measured shapes to all model DOFs first")
    omega = np.atleast_1d(np.asarray(omega, float)) if omega is not None else None
    if omega is not None and omega.shape != (phi.shape[1],):
        raise ShapeError(f"omega has shape {omega.shape}; expected ({phi.shape[1]},), one per mode (rad/s)")
    return phi, omega


def _sym(A):
    return 0.5 * (A + A.T)


def baruch_orthogonalise(phi_X, M_A) -> np.ndarray:
    """Baruch & Bar-Itzhack's optimal M_A-orthonormalisation ``φ (φᵀ M_A φ)^{-1/2}`` of measured shapes."""
    M = _dense(M_A, "M_A")
    phi, _ = _modes(phi_X, None, M.shape[0])
    m = phi.T @ M @ phi
    w, V = np.linalg.eigh(_sym(m))
    if np.any(w <= 0):
        raise ModalabValueError("the measured shapes are linearly dependent (φᵀMφ singular); drop duplicated modes")
    return phi @ (V @ np.diag(w ** -0.5) @ V.T)


def lagrange_stiffness(K_A, M_A, phi_X, omega_X, *, orthogonalise: bool = True) -> DirectUpdate:
    """Baruch & Bar-Itzhack stiffness updating, Eq. (3.1)–(3.5); the mass matrix is taken as correct.

    Minimises ``‖M_A^{-1/2}(K_AU − K_A)M_A^{-1/2}‖`` subject to symmetry (3.2) and
    ``φ_Xᵀ K_AU φ_X = diag(ω_X²)`` (3.3); ``ΔK`` from (3.5).  With
    ``orthogonalise`` the shapes are first made M_A-orthonormal (Baruch's
    reference-basis step), which (3.5) assumes.
    """
    K = _dense(K_A, "K_A")
    M = _dense(M_A, "M_A", K.shape[0])
    phi, w = _modes(phi_X, omega_X, K.shape[0])
    if orthogonalise:
        phi = baruch_orthogonalise(phi, M)
    MP = M @ phi
    PPM = phi @ MP.T                     # φφᵀM
    dK = (-K @ PPM - PPM.T @ K + MP @ (phi.T @ K @ phi) @ MP.T + MP @ np.diag(w ** 2) @ MP.T)
    dK = _sym(dK)
    return DirectUpdate(K=K + dK, M=M.copy(), dK=dK, dM=np.zeros_like(M), method="lagrange_stiffness",
                        equations="3.1-3.5")


def lagrange_mass(M_A, phi_X, K_A=None) -> DirectUpdate:
    """Berman's mass updating, Eq. (3.6)–(3.10); the stiffness matrix ``K_A`` (optional) is returned unchanged.

    ``ΔM = M_A φ m⁻¹ (I − m) m⁻¹ φᵀ M_A`` with ``m = φ_Xᵀ M_A φ_X`` (Eq. 3.10, 3.25),
    the minimum-norm correction that makes the measured shapes M-orthonormal (3.8).
    """
    M = _dense(M_A, "M_A")
    phi, _ = _modes(phi_X, None, M.shape[0])
    m = _sym(phi.T @ M @ phi)
    mi = np.linalg.inv(m)
    MP = M @ phi
    dM = _sym(MP @ mi @ (np.eye(m.shape[0]) - m) @ mi @ MP.T)
    K = _dense(K_A, "K_A", M.shape[0]) if K_A is not None else np.full_like(M, np.nan)
    dKz = np.zeros_like(M) if K_A is not None else np.full_like(M, np.nan)
    return DirectUpdate(K=K.copy(), M=M + dM, dK=dKz, dM=dM,
                        method="lagrange_mass", equations="3.6-3.10")


def lagrange_mass_stiffness(K_A, M_A, phi_X, omega_X) -> DirectUpdate:
    """Berman & Nagy: mass by (3.10), then stiffness by (3.13)–(3.14) with the updated mass.

    ``Δ = ½ M φ (φᵀ K_A φ + diag ω²) φᵀ M − K_A φ φᵀ M`` and ``ΔK = Δ + Δᵀ`` with
    ``M = M_AU`` (see the module notes on 3.14).
    """
    K = _dense(K_A, "K_A")
    M = _dense(M_A, "M_A", K.shape[0])
    phi, w = _modes(phi_X, omega_X, K.shape[0])
    mu = lagrange_mass(M, phi)
    Mu = mu.M
    MP = Mu @ phi
    D = 0.5 * MP @ (phi.T @ K @ phi + np.diag(w ** 2)) @ MP.T - K @ phi @ MP.T
    dK = D + D.T
    return DirectUpdate(K=K + dK, M=Mu, dK=dK, dM=mu.dM, method="lagrange_mass_stiffness",
                        equations="3.6-3.14")


def error_matrix(K_A, M_A, phi_A, omega_A, phi_X, omega_X) -> DirectUpdate:
    """Error matrix method (Sidhu & Ewins), Eq. (3.15)–(3.23): first-order estimates

    ``ΔK ≅ K_A (φ_A Ω_A⁻¹ φ_Aᵀ − φ_X Ω_X⁻¹ φ_Xᵀ) K_A`` (3.22) and
    ``ΔM ≅ M_A (φ_A φ_Aᵀ − φ_X φ_Xᵀ) M_A`` (3.23), with Ω = diag(ω²).

    Exact only to first order in the error: the second-order terms dropped in
    (3.20) remain (thesis 5.1.2: "the obtained results are not exact").  With
    rigid-body modes (ω = 0) the flexibility does not exist; remove them first.

    The sign follows from ``K_X⁻¹ ≅ K_A⁻¹ − K_A⁻¹ ΔK K_A⁻¹`` (3.20): ``ΔK = K_A(K_A⁻¹ − K_X⁻¹)K_A``
    (3.21); for the mass the analogous inverse expansion gives (3.23) with
    ``M⁻¹ = φφᵀ`` (3.17).
    """
    K = _dense(K_A, "K_A")
    M = _dense(M_A, "M_A", K.shape[0])
    pA, wA = _modes(phi_A, omega_A, K.shape[0], "phi_A")
    pX, wX = _modes(phi_X, omega_X, K.shape[0])
    if np.any(wA <= 0) or np.any(wX <= 0):
        raise ModalabValueError("the error matrix method needs flexibilities (1/ω²); remove rigid-body modes")
    dK = _sym(K @ (pA @ np.diag(wA ** -2) @ pA.T - pX @ np.diag(wX ** -2) @ pX.T) @ K)
    dM = _sym(M @ (pA @ pA.T - pX @ pX.T) @ M)
    return DirectUpdate(K=K + dK, M=M + dM, dK=dK, dM=dM, method="error_matrix", equations="3.15-3.23")


def direct_matrix_updating(K_A, M_A, phi_X, omega_X) -> DirectUpdate:
    """Direct matrix updating, Eq. (3.24)–(3.26): mass by (3.24), then stiffness by (3.26) with the updated mass.

    ``ΔM = M_A φ m⁻¹(I − m)m⁻¹ φᵀ M_A`` (3.24, m from 3.25) and
    ``ΔK = Mφφᵀ K_A φφᵀM + MφΩφᵀM − K_A φφᵀM − Mφφᵀ K_A`` (3.26) with M = M_AU.
    Not unique for m < N: nothing constrains the modes above m.
    """
    K = _dense(K_A, "K_A")
    M = _dense(M_A, "M_A", K.shape[0])
    phi, w = _modes(phi_X, omega_X, K.shape[0])
    mu = lagrange_mass(M, phi)
    Mu = mu.M
    MP = Mu @ phi
    PPM = phi @ MP.T
    dK = _sym(MP @ (phi.T @ K @ phi) @ MP.T + MP @ np.diag(w ** 2) @ MP.T - K @ PPM - PPM.T @ K)
    return DirectUpdate(K=K + dK, M=Mu, dK=dK, dM=mu.dM, method="direct_matrix_updating",
                        equations="3.24-3.26")


def matrix_mixing(K_A, M_A, phi_A, omega_A, phi_X, omega_X) -> DirectUpdate:
    """Matrix mixing, Eq. (3.27)–(3.30) (Caesar; Link et al.):

    ``K_AU⁻¹ = K_A⁻¹ + Σ_X φφᵀ/ω² − Σ_A φφᵀ/ω²`` (3.30) and
    ``M_AU⁻¹ = M_A⁻¹ + Σ_X φφᵀ − Σ_A φφᵀ`` (3.29), the measured modes replacing
    their analytical counterparts (the same number m of each, paired).
    Exact with complete modal data (3.27, 3.28).  ``K_A`` must be regular
    (no rigid-body modes).
    """
    K = _dense(K_A, "K_A")
    M = _dense(M_A, "M_A", K.shape[0])
    pA, wA = _modes(phi_A, omega_A, K.shape[0], "phi_A")
    pX, wX = _modes(phi_X, omega_X, K.shape[0])
    if pA.shape[1] != pX.shape[1]:
        raise ShapeError(f"{pX.shape[1]} measured and {pA.shape[1]} analytical modes; matrix mixing replaces "
                         "paired modes, pass the same number of each")
    if np.any(wA <= 0) or np.any(wX <= 0):
        raise ModalabValueError("matrix mixing needs the flexibility (1/ω²); remove rigid-body modes")
    Fk = sla.inv(K) + pX @ np.diag(wX ** -2) @ pX.T - pA @ np.diag(wA ** -2) @ pA.T
    Fm = sla.inv(M) + pX @ pX.T - pA @ pA.T
    Ku, Mu = _sym(sla.inv(_sym(Fk))), _sym(sla.inv(_sym(Fm)))
    return DirectUpdate(K=Ku, M=Mu, dK=Ku - K, dM=Mu - M, method="matrix_mixing", equations="3.27-3.30")
