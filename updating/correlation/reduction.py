"""Model reduction onto master (primary, measured) DOFs — thesis section 2.1.1.

Every method builds a transformation ``T`` (n × m) from the ``m`` master
coordinates to all ``n`` model coordinates, ``x = T x_p`` (eq. 2.7), and the
reduced matrices ``K_R = Tᵀ K T``, ``M_R = Tᵀ M T`` (eqs. 2.14–2.15, 2.34–2.35).

* :func:`guyan` — static condensation, ``T = [-K_ss⁻¹ K_sp; I]`` (eqs. 2.1–2.17).
  Exact for static loads on the masters and when the masters carry all the mass.
* :func:`irs` — Improved Reduced System (O'Callahan), eq. 2.30, iterated with
  eq. 2.33 until the reduced eigenvalues stop changing (the thesis' 4-step
  procedure).  The iterated IRS converges to the lowest ``m`` eigenvalues of the
  full model (Friswell, Garvey & Penny 1995), so it is never worse than Guyan.
* :func:`serep` — System Equivalent Reduction Expansion Process (eqs. 2.36–2.44),
  ``T = Φ Φ_p⁺``: the reduced model has exactly the retained eigenvalues and the
  retained mode shapes at the masters.

Inputs are dense numpy arrays or scipy.sparse matrices; slave solves use a
sparse LU factorisation of ``K_ss`` (computed once) so large sparse models
reduce without forming dense ``n × n`` matrices.  Masters are given by DOF
label (``"12+Z"``, with ``dofs``) or by integer row index; a master label of
opposite sign to the model DOF flips that reduced coordinate.
:func:`reduce` does the same for a :class:`~modalab.core.structure.Structure` and
also reduces its damping matrices.
"""
from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from modalab.core.dense import use_dense
from modalab.core.dof import Dof, locate, parse_dofs
from modalab.core.errors import ConvergenceError, DofError, ModalabValueError, ShapeError
from modalab.core.modes import ModeSet
from modalab.core.structure import Structure
from updating.fe.solvers import eigen_dense, eigen_sparse
from updating.correlation.dofmap import as_dofmap

__all__ = ["ReducedModel", "guyan", "irs", "serep", "reduce", "master_indices"]

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- helpers
def _square(A, name: str, n: int | None = None):
    if A is None:
        raise ModalabValueError(f"{name} is missing; pass the {name} matrix (numpy array or scipy.sparse)")
    if sp.issparse(A):
        A = sp.csr_matrix(A, dtype=float)
    else:
        try:
            A = np.asarray(A, dtype=float)
        except (TypeError, ValueError):
            raise ModalabValueError(f"{name}: got {type(A).__name__}; expected a real square matrix") from None
        if A.ndim != 2:
            raise ShapeError(f"{name} has shape {A.shape}; expected a square 2-D matrix")
    if A.shape[0] != A.shape[1]:
        raise ShapeError(f"{name} has shape {A.shape}; expected a square matrix")
    if n is not None and A.shape[0] != n:
        raise ShapeError(f"{name} is {A.shape[0]}x{A.shape[1]} but K is {n}x{n}; both must be on the same DOFs")
    return A


def master_indices(masters, n: int, dofs=None) -> tuple[np.ndarray, np.ndarray, list | None]:
    """Row indices, signs and labels of the master DOFs.

    ``masters`` are DOF labels (needs ``dofs``, the labels of the model rows) or
    integer indices.  Returns ``(index, sign, labels or None)``.
    """
    ms = list(masters) if not isinstance(masters, (str, Dof)) else [masters]
    if not ms:
        raise ModalabValueError("no master DOFs given; pass at least one master DOF label or index")
    if all(isinstance(m, (int, np.integer)) and not isinstance(m, bool) for m in ms):
        idx = np.asarray(ms, dtype=int)
        if idx.min() < -n or idx.max() >= n:
            raise DofError(f"master indices {ms[:8]} outside 0..{n - 1}; the model has {n} DOFs")
        idx = idx % n
        sgn = np.ones(idx.size)
        labels = [parse_dofs(dofs)[i] for i in idx] if dofs is not None else None
    else:
        if dofs is None:
            raise DofError(f"master DOFs given as labels ({ms[:3]}...) but the model DOF labels are unknown; "
                           "pass dofs=[...] (one label per matrix row) or give integer indices")
        dl = parse_dofs(dofs)
        if len(dl) != n:
            raise ShapeError(f"{len(dl)} DOF labels for a {n}x{n} model; give one label per row")
        i, s = locate(dl, ms, "master DOF")
        idx, sgn = np.asarray(i, int), np.asarray(s, float)
        labels = parse_dofs(ms)
    if np.unique(idx).size != idx.size:
        raise DofError(f"master DOFs repeat a model DOF ({ms}); list each master once")
    if idx.size >= n:
        raise ModalabValueError(f"{idx.size} masters for a {n}-DOF model; keep fewer masters than DOFs "
                                "(at least one slave) or use the full model")
    return idx, sgn, labels


def _slaves(idx: np.ndarray, n: int) -> np.ndarray:
    mask = np.ones(n, bool)
    mask[idx] = False
    return np.flatnonzero(mask)


def _sub(A, r, c):
    if sp.issparse(A):
        return A[r][:, c]
    return A[np.ix_(r, c)]


def _dense(A):
    return A.toarray() if sp.issparse(A) else np.asarray(A)


class _Factor:
    """Solve with a fixed matrix (sparse LU or dense LU), with a clear error when singular."""

    def __init__(self, A, what: str):
        self.what = what
        try:
            if sp.issparse(A):
                # structural matrices are symmetric: a symmetric fill-reducing ordering beats the COLAMD default
                self._lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A")
                self._solve = self._lu.solve
            else:
                with np.errstate(all="ignore"), warnings.catch_warnings():
                    warnings.simplefilter("ignore", sla.LinAlgWarning)
                    lu = sla.lu_factor(np.asarray(A), check_finite=True)
                d = np.abs(np.diag(lu[0]))
                if d.size and (d.min() <= 1e-13 * max(d.max(), 1e-300)):
                    raise RuntimeError("singular")
                self._solve = lambda b: sla.lu_solve(lu, b)
        except (RuntimeError, ValueError, sla.LinAlgError):
            raise ModalabValueError(f"{what} is singular; the slave DOFs must be restrained when the masters are "
                                    "fixed. Add masters on every free or mechanism slave DOF (e.g. rigid-body "
                                    "directions) or remove massless, stiffness-free DOFs") from None

    def solve(self, b):
        b = np.asarray(b)
        if np.iscomplexobj(b):
            return self.solve(b.real) + 1j * self.solve(b.imag)
        x = self._solve(b)
        if not np.all(np.isfinite(x)):
            raise ModalabValueError(f"{self.what} is singular (non-finite solution); check the masters and "
                                    "the constraints")
        return x


def _project(A, T: np.ndarray) -> np.ndarray:
    AT = A @ T
    R = T.T @ np.asarray(AT)
    return 0.5 * (R + R.T)


# --------------------------------------------------------------------------- result
@dataclass
class ReducedModel:
    """Reduced matrices on the master DOFs and the transformation that produced them.

    Attributes
    ----------
    K, M : (m, m) reduced stiffness and mass, ``Tᵀ K T`` and ``Tᵀ M T``.
    T : (n, m) transformation, ``x_full = T x_masters`` (eq. 2.7).
    master_index : (m,) rows of the masters in the full model.
    masters : master DOF labels, or None when the model had no labels.
    dofs : full-model DOF labels, or None.
    method : 'guyan', 'irs' or 'serep'.
    iterations : IRS iterations performed (0 for the others).
    converged : False only when IRS stopped at ``max_iter`` with ``on_no_convergence='warn'``.
    C, D : reduced viscous and hysteretic damping (from :func:`reduce` on a damped Structure).
    history : relative eigenvalue change per IRS iteration.
    """

    K: np.ndarray
    M: np.ndarray
    T: np.ndarray
    master_index: np.ndarray
    masters: list | None
    dofs: list | None
    method: str
    iterations: int = 0
    converged: bool = True
    C: np.ndarray | None = None
    D: np.ndarray | None = None
    history: list = field(default_factory=list)

    @property
    def n_masters(self) -> int:
        return self.K.shape[0]

    def eig(self, n_modes: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies ω (rad/s) and mass-normalised master shapes of the reduced model (eq. 2.16)."""
        try:
            w2, u = sla.eigh(self.K, self.M)
        except (np.linalg.LinAlgError, ValueError):
            raise ModalabValueError(f"the reduced mass matrix of the {self.method} model is not positive definite; "
                                    "with SEREP keep as many modes as masters, otherwise check the masters") \
                from None
        if n_modes is not None:
            w2, u = w2[:n_modes], u[:, :n_modes]
        return np.sqrt(np.clip(w2, 0, None)), u

    def expand(self, x_masters) -> np.ndarray:
        """Full-model vectors from master vectors: ``T @ x`` (eq. 2.17)."""
        x = np.asarray(x_masters)
        if x.shape[0] != self.n_masters:
            raise ShapeError(f"vectors have {x.shape[0]} rows; expected {self.n_masters} (one per master)")
        return self.T @ x

    def modes(self, n_modes: int | None = None, *, full: bool = False) -> ModeSet:
        """Modes of the reduced model as a :class:`ModeSet` on the masters (``full=True``: expanded by T)."""
        labels = self.dofs if full else self.masters
        if labels is None:
            raise DofError("the reduced model has no DOF labels; reduce with dofs=[...] to get a ModeSet")
        w, u = self.eig(n_modes)
        shapes = self.T @ u if full else u
        return ModeSet(freq_hz=w / (2 * np.pi), shapes=shapes, dofs=labels, scaling="unit_modal_mass",
                       metadata={"source": f"{self.method} reduced model"})

    def structure(self, name: str = "") -> Structure:
        """The reduced model as a :class:`~modalab.core.structure.Structure` on the master labels."""
        if self.masters is None:
            raise DofError("the reduced model has no DOF labels; reduce with dofs=[...] to build a Structure")
        return Structure(M=self.M, K=self.K, C=self.C, D=self.D, dofs=self.masters,
                         name=name or f"{self.method} reduced")


def _build(K, M, masters, dofs):
    K = _square(K, "K")
    n = K.shape[0]
    M = _square(M, "M", n)
    idx, sgn, labels = master_indices(masters, n, dofs)
    return K, M, n, idx, sgn, labels, _slaves(idx, n)


def _static_T(K, n, idx, sgn, s):
    """Static transformation, eq. 2.9 / 2.31, in the full DOF order, columns scaled by the master signs."""
    Kss = _sub(K, s, s)
    Ksp = _dense(_sub(K, s, idx))
    fac = _Factor(Kss, "the slave stiffness K_ss")
    T = np.zeros((n, idx.size))
    T[idx, np.arange(idx.size)] = 1.0
    T[s] = -fac.solve(Ksp)
    return T * sgn[None, :], fac


# --------------------------------------------------------------------------- methods
def guyan(K, M, masters, *, dofs=None) -> ReducedModel:
    """Guyan (static) reduction, eqs. 2.1–2.17.

    ``T = [-K_ss⁻¹ K_sp; I]`` (eq. 2.9, rows in the model's DOF order),
    ``K_GR = Tᵀ K T`` (2.14), ``M_GR = Tᵀ M T`` (2.15).

    Parameters
    ----------
    K, M : (n, n) stiffness and mass, dense or sparse.
    masters : master (primary) DOFs: labels with ``dofs``, or row indices.
    dofs : labels of the model rows (needed for labels).
    """
    K, M, n, idx, sgn, labels, s = _build(K, M, masters, dofs)
    T, _ = _static_T(K, n, idx, sgn, s)
    return ReducedModel(K=_project(K, T), M=_project(M, T), T=T, master_index=idx, masters=labels,
                        dofs=None if dofs is None else parse_dofs(dofs), method="guyan")


def irs(K, M, masters, *, dofs=None, iterate: bool = True, tol: float = 1e-10, max_iter: int = 500,
        on_no_convergence: str = "raise") -> ReducedModel:
    """Improved Reduced System, eqs. 2.18–2.35, iterated to convergence (eq. 2.33).

    The thesis' procedure:

    1. the static transformation ``T_s`` of eq. 2.31;
    2. ``K_irs,i = Tᵢᵀ K Tᵢ``, ``M_irs,i = Tᵢᵀ M Tᵢ`` (eqs. 2.34–2.35), starting from ``T_s``;
    3. ``T_{i+1} = T_s + S M Tᵢ M_irs,i⁻¹ K_irs,i`` (eq. 2.33) with ``S = diag(0, K_ss⁻¹)``
       acting on the slave rows (eq. 2.32);
    4. repeat 2–3 until the reduced eigenvalues change by less than ``tol`` (relative).

    ``iterate=False`` stops after the first correction (O'Callahan's IRS, eq. 2.30).
    The converged model reproduces the lowest ``m`` eigenvalues of the full model;
    convergence is geometric with ratio ≈ λ_m / λ_{m+1}, slow when those are close.

    Parameters
    ----------
    K, M, masters, dofs : as for :func:`guyan`.
    tol : relative change of the reduced eigenvalues that ends the iteration.
    max_iter : iteration limit.
    on_no_convergence : 'raise' (:class:`~modalab.core.errors.ConvergenceError`) or 'warn'
        (log a warning, return the last iterate with ``converged=False``).
    """
    if on_no_convergence not in ("raise", "warn"):
        raise ModalabValueError(f"on_no_convergence {on_no_convergence!r}; expected 'raise' or 'warn'")
    if max_iter < 1:
        raise ModalabValueError(f"max_iter {max_iter}; expected at least 1")
    K, M, n, idx, sgn, labels, s = _build(K, M, masters, dofs)
    Ts, fac = _static_T(K, n, idx, sgn, s)
    T = Ts
    Kr, Mr = _project(K, T), _project(M, T)
    lam_old = _reduced_eigvals(Kr, Mr)
    history, converged, it = [], False, 0
    for it in range(1, max_iter + 1):
        # eq. 2.33: T_{i+1} = T_s + S M T_i M_i^-1 K_i
        try:
            G = sla.solve(Mr, Kr, assume_a="sym")            # M_irs,i^-1 K_irs,i
        except (np.linalg.LinAlgError, ValueError):
            raise ModalabValueError("the reduced mass matrix became singular during IRS; choose masters that "
                                    "carry mass in every low mode") from None
        MT = np.asarray(M @ T)
        T = Ts.copy()
        T[s] += fac.solve(MT[s] @ G)
        Kr, Mr = _project(K, T), _project(M, T)
        lam = _reduced_eigvals(Kr, Mr)
        scale = np.maximum(np.abs(lam), np.abs(lam).max() * 1e-12 + 1e-300)
        change = float(np.max(np.abs(lam - lam_old) / scale))
        history.append(change)
        lam_old = lam
        if not iterate:
            converged = True
            break
        if change < tol:
            converged = True
            break
    if not converged:
        msg = (f"IRS did not converge in {max_iter} iterations (last relative eigenvalue change {history[-1]:.3g}, "
               f"tolerance {tol:g}); the lowest discarded eigenvalue is probably close to the highest retained "
               "one. Increase max_iter, relax tol, or add masters")
        if on_no_convergence == "raise":
            raise ConvergenceError(msg)
        log.warning(msg)
    log.debug("IRS: %d iterations, last change %.3g", it, history[-1] if history else 0.0)
    return ReducedModel(K=Kr, M=Mr, T=T, master_index=idx, masters=labels,
                        dofs=None if dofs is None else parse_dofs(dofs), method="irs", iterations=it,
                        converged=converged, history=history)


def _reduced_eigvals(Kr, Mr):
    try:
        return sla.eigh(Kr, Mr, eigvals_only=True)
    except (np.linalg.LinAlgError, ValueError):
        raise ModalabValueError("the reduced mass matrix is not positive definite; choose masters that carry "
                                "mass in every low mode") from None


def _lowest_modes(K, M, k: int):
    """The lowest ``k`` modes (ω², Φ) by the FE solvers, which handle DOFs without mass (Nastran's default
    lumped mass) and massless mechanisms exactly (:mod:`updating.fe.solvers`)."""
    n = K.shape[0]
    if not sp.issparse(K) and not sp.issparse(M) or use_dense(n, "eigen"):
        w, phi = eigen_dense(_dense(K), _dense(M), k)
        if w.size < k:
            raise ModalabValueError(f"SEREP needs {k} modes but the model has only {w.size} DOFs with mass; "
                                    "keep fewer modes (or masters), or give modes=...")
    else:
        w, phi = eigen_sparse(sp.csr_matrix(K), sp.csr_matrix(M), k)
    return w ** 2, phi


def serep(K, M, masters, *, dofs=None, modes=None, n_modes: int | None = None, rcond: float = 1e-10) -> ReducedModel:
    """SEREP reduction, eqs. 2.36–2.44: ``T = Φ Φ_p⁺`` (eq. 2.44).

    Parameters
    ----------
    K, M, masters, dofs : as for :func:`guyan`.
    modes : (n, r) retained mode shapes (any scaling), a :class:`~modalab.core.modes.ModeSet` on ``dofs``,
        or None to use the lowest ``n_modes`` modes of (K, M).
    n_modes : number of lowest modes when ``modes`` is None (default: the number of masters).
    rcond : cut-off of the pseudo-inverse (eqs. 2.41–2.42).

    With ``r = m`` (as many retained modes as masters) the reduced model has
    exactly the retained eigenvalues and shapes; with ``r < m`` the reduced
    matrices have rank ``r`` (singular mass), with ``r > m`` it is not exact.
    """
    K, M, n, idx, sgn, labels, s = _build(K, M, masters, dofs)
    if modes is None:
        r = idx.size if n_modes is None else int(n_modes)
        if not 1 <= r < n:
            raise ModalabValueError(f"n_modes {n_modes}; expected 1..{n - 1}")
        _, phi = _lowest_modes(K, M, r)
    elif isinstance(modes, ModeSet):
        if dofs is None:
            raise DofError("modes given as a ModeSet but the model DOF labels are unknown; pass dofs=[...]")
        phi = modes.select_dofs(parse_dofs(dofs)).real_shapes
    else:
        phi = np.asarray(modes, dtype=float)
        if phi.ndim == 1:
            phi = phi[:, None]
        if phi.shape[0] != n:
            raise ShapeError(f"modes have {phi.shape[0]} rows; expected {n} (one per model DOF)")
    r = phi.shape[1]
    if r > idx.size:
        log.warning("SEREP with %d modes on %d masters: the least-squares fit does not reproduce the modes "
                    "exactly; use at most as many modes as masters", r, idx.size)
    phi_p = phi[idx] * sgn[:, None]
    rank = np.linalg.matrix_rank(phi_p, tol=rcond * max(np.abs(phi_p).max(), 1e-300) * max(phi_p.shape))
    if rank < min(phi_p.shape):
        raise ModalabValueError(f"the retained modes are linearly dependent at the masters (rank {rank} of "
                                f"{min(phi_p.shape)}); choose masters that see every retained mode")
    T = phi @ np.linalg.pinv(phi_p, rcond=rcond)              # eq. 2.44 with the inverse of eq. 2.41/2.42
    return ReducedModel(K=_project(K, T), M=_project(M, T), T=T, master_index=idx, masters=labels,
                        dofs=None if dofs is None else parse_dofs(dofs), method="serep")


def reduce(structure: Structure, masters, method: str = "guyan", *, dofmap=None, **kw) -> ReducedModel:
    """Reduce a :class:`~modalab.core.structure.Structure` onto labelled masters by ``'guyan'``, ``'irs'`` or ``'serep'``.

    With ``dofmap`` (a :class:`~updating.correlation.dofmap.DofMap`, dict or file), ``masters``
    are *test* DOF labels: each is mapped onto its model DOF (sign and factor
    included) and the reduced model is expressed in the test coordinates, so it
    compares directly with test modes (e.g. :func:`updating.correlation.metrics.mixed_orthogonality`).
    Keyword arguments go to the method.  Viscous (C) and hysteretic (D) damping
    are transformed with the same ``T``.
    """
    if not isinstance(structure, Structure):
        raise ModalabValueError(f"reduce needs a Structure; got {type(structure).__name__}. For bare matrices call "
                                "guyan/irs/serep(K, M, masters, dofs=...)")
    funcs = {"guyan": guyan, "irs": irs, "serep": serep}
    f = funcs.get(str(method).lower())
    if f is None:
        raise ModalabValueError(f"reduction method {method!r}; expected one of {sorted(funcs)}")
    if dofmap is None:
        red = f(structure.K, structure.M, masters, dofs=structure.dofs, **kw)
    else:
        test_labels = parse_dofs(masters)
        idx, fac = as_dofmap(dofmap).selection(test_labels, structure.dofs)
        red = f(structure.K, structure.M, [int(i) for i in idx], dofs=structure.dofs, **kw)
        d = 1.0 / fac                                  # x_model[idx] = x_test / fac
        red.T = red.T * d[None, :]
        red.K = red.K * np.outer(d, d)
        red.M = red.M * np.outer(d, d)
        red.masters = test_labels
    if structure.C is not None:
        red.C = _project(structure.C, red.T)
    if structure.D is not None:
        red.D = _project(structure.D, red.T)
    return red
