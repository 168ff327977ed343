"""Undamped normal modes ``K φ = ω² M φ`` with a singular mass matrix (thesis eq. 2.1): the one implementation
shared by :class:`~modalab.core.structure.Structure` and :mod:`updating.fe.solvers`.

With Nastran's default lumped mass (no ``PARAM,COUPMASS``) the rotations of a beam deck have no mass, and a
free-free deck also has rigid-body modes, so neither ``M`` nor ``K`` is positive definite.  Both are handled
exactly:

* **Massless DOFs** (a whole row of ``M`` zero): the problem is solved in shift-inverted form
  ``M φ = μ (K − σM) φ``, ``λ = σ + 1/μ``, about a *negative* shift σ, so that ``K − σM`` is positive definite
  even for a free-free model.  A massless direction gives ``μ = 0`` (an infinite frequency) and is never
  returned; the finite modes equal those of the static condensation of the massless DOFs
  (``K̂ = K_aa − K_ao K_oo⁻¹ K_oa``, as Nastran condenses them), with the massless DOFs recovered from
  ``φ_o = −K_oo⁻¹ K_oa φ_a``.  Rigid-body modes come out ≈ 0 to rounding (the error of λ is relative to
  ``|λ − σ|``, not to the largest eigenvalue).
* **Massless mechanisms** — motions of the massless DOFs that need no stiffness when the DOFs with mass are
  held (the rigid torsion of a free-free beam whose lumped mass has no torsional inertia) — have neither mass
  nor stiffness, so ``K − σM`` is singular for every σ.  Like Nastran's ``PARAM,MECHFIX``
  (:func:`massless_mechanisms`) one DOF per mechanism is constrained.  This is exact: a massless mechanism
  ``n`` has ``K n = 0`` and ``M n = 0``, so it may be added to any eigenvector; the constrained DOFs (chosen
  by pivoted QR so that ``n`` restricted to them is well conditioned) only fix that arbitrary component.
* **Determinism**: every Lanczos (ARPACK) solve starts from the same vector (:func:`start_vector`), so the
  same model gives bit-identical modes run after run.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

from .dense import use_dense
from .errors import ConvergenceError, ModalabValueError

log = logging.getLogger(__name__)

__all__ = ["DEFAULT_SHIFT_HZ", "MASSLESS_TOL", "MECHANISM_TOL", "start_vector", "eigsh", "massless_dofs",
           "massless_mechanisms", "drop_mechanisms", "restore", "check_definite", "normalise", "dense_modes",
           "lanczos_modes", "default_shift"]

#: default negative shift: σ = −(2π · DEFAULT_SHIFT_HZ)²
DEFAULT_SHIFT_HZ = 1.0
#: a DOF whose mass row is below this fraction of the largest diagonal mass has no mass
MASSLESS_TOL = 1e-13
#: an eigenvalue of K_oo below this fraction of its largest diagonal entry is a mechanism
MECHANISM_TOL = 1e-10
#: seed of the fixed ARPACK start vector
_V0_SEED = 20260416


def default_shift() -> float:
    """σ = −(2π · DEFAULT_SHIFT_HZ)² rad²/s²."""
    return -(2 * np.pi * DEFAULT_SHIFT_HZ) ** 2


def start_vector(n: int) -> np.ndarray:
    """The fixed ARPACK start vector of length ``n``: pseudo-random (so that no mode is orthogonal to it by
    symmetry, as a constant vector would be to every antisymmetric mode) but the same on every call."""
    return np.random.default_rng(_V0_SEED).uniform(0.5, 1.5, int(n))


def eigsh(A, k, **kw):
    """:func:`scipy.sparse.linalg.eigsh` with the fixed start vector (``v0``) unless one is given."""
    if kw.get("v0") is None:
        kw["v0"] = start_vector(A.shape[0])
    return spla.eigsh(A, k=k, **kw)


def massless_dofs(M) -> np.ndarray:
    """Indices of the DOFs whose whole mass row is (numerically) zero."""
    Ms = sp.csr_matrix(M)
    scale = np.abs(Ms.diagonal()).max(initial=0.0)
    if scale <= 0:
        raise ModalabValueError("the mass matrix is zero; give the elements density or add lumped masses")
    rowmax = np.zeros(Ms.shape[0])
    A = abs(Ms).tocsr()
    nz = np.diff(A.indptr) > 0
    rowmax[nz] = np.maximum.reduceat(A.data, A.indptr[:-1][nz])
    return np.flatnonzero(rowmax <= MASSLESS_TOL * scale)


def _null_space_psd(A) -> np.ndarray:
    """Orthonormal basis of the (numerical) null space of a symmetric positive semi-definite matrix."""
    n = A.shape[0]
    d = float(np.abs(A.diagonal()).max(initial=0.0))
    if d <= 0:
        return np.eye(n)
    if use_dense(n, "null_space"):              # the one dense/sparse rule (modalab.core.dense)
        w, U = np.linalg.eigh(A.toarray() if sp.issparse(A) else np.asarray(A))
        return U[:, w <= MECHANISM_TOL * d]
    delta = 1e-6 * d
    k = min(8, n - 2)
    while True:
        w, U = eigsh(sp.csc_matrix(A), k, sigma=-delta, which="LM")
        null = w <= MECHANISM_TOL * d
        if not null.all() or k >= n - 2:
            return U[:, null]
        k = min(2 * k, n - 2)


def massless_mechanisms(K, M) -> tuple[np.ndarray, np.ndarray]:
    """Mechanisms of the DOFs without mass, and the DOFs that constrain them (Nastran's MECHFIX).

    Returns ``(dofs, N)``: the indices of one DOF per mechanism to constrain, and the mechanisms as columns
    of ``N`` (on all DOFs).  A mechanism is a null vector of ``K_oo``, the stiffness between the massless
    DOFs o (with the DOFs with mass held); for a positive semi-definite K it satisfies ``K n = 0`` and, being
    massless, ``M n = 0``.  Each connected group of massless DOFs (graph of ``K_oo``) is treated on its own:
    dense eigenvalues up to 300 DOFs, shift-invert Lanczos above.
    """
    n = K.shape[0]
    o = massless_dofs(M)
    empty = (np.zeros(0, int), np.zeros((n, 0)))
    if o.size == 0:
        return empty
    Koo = sp.csr_matrix(K)[o][:, o]
    nc, lab = connected_components(abs(Koo) > 0, directed=False)
    fix, cols = [], []
    for c in range(nc):
        idx = np.flatnonzero(lab == c)
        Nc = _null_space_psd(Koo[idx][:, idx])
        if Nc.shape[1] == 0:
            continue
        _, _, piv = sla.qr(Nc.T, mode="economic", pivoting=True)
        fix.extend(o[idx[piv[:Nc.shape[1]]]])
        for j in range(Nc.shape[1]):
            v = np.zeros(n)
            v[o[idx]] = Nc[:, j]
            cols.append(v)
    if not fix:
        return empty
    log.info("massless mechanisms: %d (constrained at DOF index %s, as Nastran's MECHFIX)", len(fix),
             ", ".join(map(str, fix[:10])) + (" ..." if len(fix) > 10 else ""))
    return np.asarray(fix, int), np.column_stack(cols)


def drop_mechanisms(K, M):
    """``(keep, K_kk, M_kk)`` without one DOF per massless mechanism (``keep`` None when there is none)."""
    fix, _ = massless_mechanisms(K, M)
    if fix.size == 0:
        return None, K, M
    keep = np.setdiff1d(np.arange(K.shape[0]), fix)
    if sp.issparse(K):
        Kc, Mc = sp.csr_matrix(K), sp.csr_matrix(M)
        return keep, Kc[keep][:, keep], Mc[keep][:, keep]
    return keep, np.asarray(K)[np.ix_(keep, keep)], np.asarray(M)[np.ix_(keep, keep)]


def restore(phi, keep, n):
    """Vectors on the kept DOFs back on all ``n`` DOFs (zero on the constrained mechanism DOFs)."""
    if keep is None:
        return phi
    out = np.zeros((n,) + phi.shape[1:], phi.dtype)
    out[keep] = phi
    return out


def check_definite(lam, sigma, K, M):
    """Refuse eigenvalues below zero beyond rounding: the stiffness matrix is indefinite (never clip them).
    Rounding is relative to the shift, the largest eigenvalue found and the stiffness-to-mass scale of the
    diagonals (a very stiff connector next to a small inertia makes rigid-body eigenvalues noisy)."""
    kd = np.abs(K.diagonal()).max(initial=0.0)
    md = max(np.abs(M.diagonal()).max(initial=0.0), 1e-300)
    tol = max(1e-6 * abs(sigma), 1e-10 * float(np.abs(lam).max(initial=0.0)), 1e-12 * kd / md)
    if lam.size and lam.min() < -tol:
        raise ModalabValueError(f"an eigenvalue is negative (ω² = {lam.min():.4g} rad²/s²): the stiffness matrix is "
                                "not positive semi-definite (a negative spring, a buckled or pre-stressed member, or "
                                "a wrong material constant); check the model")


def normalise(phi, M):
    """Unit modal mass, largest component positive.  Components within 1e-6 of the largest count as equal and
    the first of them decides (a symmetric structure has pairs of equal largest components, and rounding
    must not flip the sign of a mode)."""
    mm = np.einsum("ij,ij->j", phi, M @ phi)
    if np.any(mm <= 0):
        raise ModalabValueError("a mode has zero or negative modal mass; the mass matrix is not positive "
                                "semi-definite or a mode lives only on massless DOFs")
    phi = phi / np.sqrt(mm)[None, :]
    a = np.abs(phi)
    k = np.argmax(a >= (1 - 1e-6) * a.max(axis=0, initial=0.0)[None, :], axis=0)
    sg = np.sign(phi[k, np.arange(phi.shape[1])])
    sg[sg == 0] = 1
    return phi * sg[None, :]


def dense_modes(K, M, n_modes: int | None = None, sigma: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``n_modes`` (all finite ones by default) ω (rad/s) and mass-normalised shapes, dense LAPACK.

    Shift-inverted form ``M φ = μ (K − σM) φ`` about the negative shift σ (module docstring): massless DOFs
    give μ = 0 and drop out (their exact static condensation), massless mechanisms are constrained first.
    ``sigma`` None: 1e-6 of the stiffness-to-mass scale ``max K_ii / max M_ii`` (at least (2π · 1 Hz)²), so
    that both the rigid-body modes (error ≈ eps·|σ|) and the highest modes (relative error ≈ eps·λ/|σ|)
    are accurate.
    """
    Kd = K.toarray() if sp.issparse(K) else np.asarray(K, float)
    Md = M.toarray() if sp.issparse(M) else np.asarray(M, float)
    n_all = Kd.shape[0]
    keep, Kd, Md = drop_mechanisms(Kd, Md)
    n = Kd.shape[0]
    scale = np.abs(np.diag(Md)).max(initial=0.0)
    if scale <= 0:
        raise ModalabValueError("the mass matrix is zero; give the elements density or add lumped masses")
    n_finite = n - int(np.all(np.abs(Md) <= MASSLESS_TOL * scale, axis=1).sum())
    k = n_finite if n_modes is None else min(int(n_modes), n_finite)
    if k < 1:
        raise ModalabValueError(f"n_modes = {n_modes}; expected at least 1")
    if sigma is None:
        # the error of λ is about eps·|σ| at the rigid-body modes and eps·λ²/|σ| at the top: a shift far
        # below the stiffness-to-mass scale keeps both small (1e-6 of it, at least (2π · 1 Hz)²)
        sigma = min(default_shift(), -1e-6 * np.abs(np.diag(Kd)).max(initial=0.0) / scale)
    sigma = float(sigma)
    if sigma >= 0:
        raise ModalabValueError(f"shift {sigma}; a negative shift is required so that K - shift*M is positive "
                                "definite for free-free models")
    A = Kd - sigma * Md
    A = (A + A.T) / 2
    try:
        mu, phi = sla.eigh((Md + Md.T) / 2, A, subset_by_index=(n - k, n - 1))
    except np.linalg.LinAlgError as e:
        raise ModalabValueError(f"K - shift*M is not positive definite ({e}): some DOFs have neither mass nor "
                                "stiffness, or the stiffness matrix is indefinite. Constrain unconnected DOFs "
                                "(SPC) or give massless DOFs stiffness") from None
    if mu.min() <= 1e-13 * mu.max():         # μ = 0 to rounding: an infinite frequency, never a mode
        raise ModalabValueError("the mass matrix is singular beyond its massless rows (a combination of DOFs "
                                "without mass that is not a whole zero row); give those DOFs mass (rotary "
                                "inertia, PARAM,COUPMASS) or constrain them")
    lam = sigma + 1.0 / mu
    o = np.argsort(lam)
    lam, phi = lam[o], phi[:, o]
    check_definite(lam, sigma, Kd, Md)
    phi = normalise(phi, Md)
    return np.sqrt(np.clip(lam, 0, None)), restore(phi, keep, n_all)


def _splu_operator(K, M, sigma):
    """``(K − σM)⁻¹`` by SuperLU (fill-reducing MMD_AT_PLUS_A ordering) as a LinearOperator."""
    A = sp.csc_matrix(K - sigma * M)
    try:
        f = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    except RuntimeError as e:
        raise ModalabValueError(f"K - shift*M is singular ({e}): some motion has neither stiffness nor mass "
                                "beyond the massless mechanisms; constrain it (SPC), give it inertia or use "
                                "coupled mass") from None
    return spla.LinearOperator(A.shape, matvec=f.solve, matmat=f.solve, dtype=A.dtype)


def lanczos_modes(K, M, n_modes: int, sigma: float | None = None, *, make_opinv=None, tol: float = 0.0,
                  ncv: int | None = None):
    """Lowest ``n_modes`` modes by shift-invert Lanczos (ARPACK, fixed start vector) about a negative shift.

    Massless mechanisms are constrained first, massless DOFs need nothing (they give μ = 0, never among the
    largest μ).  ``make_opinv(K, M, sigma)`` builds ``(K − σM)⁻¹`` on the kept DOFs (SuperLU by default).
    Returns ``(ω rad/s ascending, mass-normalised Φ on all DOFs, the operator)``.
    """
    n = K.shape[0]
    sigma = default_shift() if sigma is None else float(sigma)
    if sigma >= 0:
        raise ModalabValueError(f"shift {sigma}; a negative shift is required so that K - shift*M is positive "
                                "definite for free-free models")
    keep, Kk, Mk = drop_mechanisms(sp.csr_matrix(K), sp.csr_matrix(M))
    Kk, Mk = sp.csc_matrix(Kk), sp.csc_matrix(Mk)
    nk = Kk.shape[0]
    n_finite = nk - int(massless_dofs(Mk).size)
    if not 0 < n_modes < min(nk, n_finite + 1):
        raise ModalabValueError(f"n_modes = {n_modes}; expected 1..{min(nk - 1, n_finite)} for a Lanczos solve "
                                f"of {nk} DOFs with {n_finite} finite modes (use the dense solver for all modes)")
    op = (make_opinv or _splu_operator)(Kk, Mk, sigma)
    try:
        w2, phi = eigsh(Kk, n_modes, M=Mk, sigma=sigma, which="LM", OPinv=op, tol=tol,
                        ncv=ncv or min(nk, max(2 * n_modes + 1, 20)))
    except spla.ArpackNoConvergence as e:
        raise ConvergenceError(f"Lanczos did not converge for {n_modes} modes ({e}); increase ncv or move the "
                               "shift closer to the wanted frequencies") from None
    o = np.argsort(w2)
    w2, phi = w2[o], phi[:, o]
    check_definite(w2, sigma, Kk, Mk)
    phi = normalise(phi, Mk)
    return np.sqrt(np.clip(w2, 0, None)), restore(phi, keep, n), op
