"""Eigen-solutions and FRF synthesis for assembled FE systems.

Normal modes solve ``K φ = ω² M φ`` (thesis eq. 2.1 and following):

* :func:`eigen_dense` — all (or the lowest) modes of a small model with
  LAPACK, in the same shift-inverted form as the sparse solver so that
  rigid-body modes are accurate; DOFs without mass (lumped-mass rotations)
  drop out exactly (their static condensation).
* Massless mechanisms — motions of the DOFs without mass that need no
  stiffness when the DOFs with mass are held (the rigid torsion of a free-free
  beam with Nastran's default lumped mass, which has no torsional inertia) —
  have neither mass nor stiffness: ``K − σM`` is singular for every σ.  Like
  Nastran's ``PARAM,MECHFIX`` both solvers find them
  (:func:`massless_mechanisms`: the null space of ``K_oo``, the stiffness of
  the massless DOFs) and constrain one DOF per mechanism.  This is exact: a
  massless mechanism ``n`` satisfies ``K n = 0`` and ``M n = 0``, so it may be
  added to any eigenvector, and the constrained DOFs (chosen by pivoted QR so
  that ``n`` restricted to them is well conditioned) only fix that arbitrary
  component (to zero).
* :func:`eigen_sparse` — the lowest modes of a large model by shift-invert
  Lanczos (ARPACK through :func:`scipy.sparse.linalg.eigsh`) about a
  *negative* shift σ: ``K − σM`` is positive definite even for free-free
  models, so rigid-body modes (ω = 0) come out as the eigenvalues nearest σ.
  The factorisation of ``K − σM`` uses SuperLU with the fill-reducing
  ``MMD_AT_PLUS_A`` ordering (4–5× faster than scipy's default COLAMD on a
  100k-DOF frame model, see ``benchmarks/fe_eigen_100k.py``) or, when
  scikit-sparse is importable, CHOLMOD.
* The massless handling and the fixed ARPACK start vector (deterministic modes) live in
  :mod:`modalab.core.eigen`, shared with :class:`~modalab.core.structure.Structure`.
* :func:`normal_modes` picks one; :func:`modes_of` returns a
  :class:`~modalab.core.modes.ModeSet` mapped back to all DOFs.

FRFs (receptance ``H(ω) = (K + iD + iωC − ω²M)⁻¹``, converted to mobility or
accelerance):

* :func:`frf_direct` — one sparse factorisation per frequency line, exact;
* :func:`frf_modal` — modal superposition of the lowest modes with modal
  damping (diagonal projection of C and D, or a ζ(f) table), plus the static
  residual flexibility of the omitted modes evaluated at the shift σ,
  ``R = (K − σM)⁻¹ − Σ_r φ_r φ_rᵀ / (ω_r² − σ)``, valid for free-free models.
"""
from __future__ import annotations

import logging
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from modalab.core.dense import EIGEN_LIMIT, use_dense
from modalab.core.dof import locate, parse_dofs
from modalab.core.eigen import (DEFAULT_SHIFT_HZ, check_definite, dense_modes, drop_mechanisms, lanczos_modes,
                                 massless_dofs, massless_mechanisms, normalise, restore)
from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF, check_window_beta
from modalab.core.modes import ModeSet
from modalab.core.units import QUANTITY_UNITS, check_quantity

log = logging.getLogger(__name__)

__all__ = ["DEFAULT_SHIFT_HZ", "RIGID_HZ", "massless_mechanisms", "eigen_dense", "eigen_sparse", "normal_modes", "modes_of", "factorize",
           "shift_invert_operator", "frf_direct", "frf_modal", "cholmod_available"]

#: modes below this frequency are rigid-body modes (no modal damping, 1/s² term)
RIGID_HZ = 1e-3
_ORDER = {"receptance": 0, "mobility": 1, "accelerance": 2}


def cholmod_available() -> bool:
    """True when scikit-sparse's CHOLMOD can be imported."""
    try:
        import sksparse.cholmod  # noqa: F401  # lazy: optional scikit-sparse
    except Exception:
        return False
    return True


def _shift(shift, shift_hz):
    if shift is not None:
        s = float(shift)
    else:
        s = -(2 * np.pi * (DEFAULT_SHIFT_HZ if shift_hz is None else shift_hz)) ** 2
    if s >= 0:
        raise ModalabValueError(f"shift {s}; a negative shift is required so that K - shift*M is positive "
                                "definite for free-free models. Pass shift < 0 (rad^2/s^2) or shift_hz > 0")
    return s


# massless DOFs, massless mechanisms and the fixed ARPACK start vector: one implementation in the core
_normalise = normalise
_massless = massless_dofs
_drop_mechanisms = drop_mechanisms
_restore = restore
_check_definite = check_definite


# --------------------------------------------------------------------- dense
def eigen_dense(K, M, n_modes: int | None = None, *, shift: float | None = None,
                shift_hz: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``n_modes`` (all by default) natural frequencies ω (rad/s) and mass-normalised shapes.

    Solved in shift-inverted form, ``M φ = μ (K − σM) φ`` with λ = σ + 1/μ and a
    negative shift σ (by default 1e-6 of the stiffness-to-mass scale, see
    :func:`modalab.core.eigen.dense_modes`): ``K − σM`` is positive definite for
    free-free models, rigid-body modes come out ≈ 0 to rounding, and DOFs
    without mass (lumped-mass rotations) simply give μ = 0 — they are dropped,
    which equals their exact static condensation.
    """
    return dense_modes(K, M, n_modes, None if shift is None and shift_hz is None else _shift(shift, shift_hz))


# -------------------------------------------------------------------- sparse
class _Factor:
    """A factorisation of a sparse symmetric matrix with a solve counter."""

    def __init__(self, A, solver: str = "splu", permc_spec: str = "MMD_AT_PLUS_A"):
        A = sp.csc_matrix(A)
        t0 = time.perf_counter()
        try:
            if solver == "cholmod":
                from sksparse.cholmod import cholesky  # lazy: optional scikit-sparse
                self._f = cholesky(A)
                self._solve = self._f
            elif solver == "splu":
                self._f = spla.splu(A, permc_spec=permc_spec, diag_pivot_thresh=0.0,
                                    options={"SymmetricMode": True})
                self._solve = self._f.solve
            else:
                raise ModalabValueError(f"solver {solver!r}; expected 'splu', 'cholmod' or 'auto'")
        except (RuntimeError, ArithmeticError) as e:
            if isinstance(e, ModalabValueError):
                raise
            raise ModalabValueError(f"K - shift*M is singular ({e}): some motion has neither stiffness nor mass, "
                                    "e.g. the rigid torsion of a free-free beam with lumped mass. Constrain it "
                                    "(SPC), give it inertia or use coupled mass") from None
        self.factor_time = time.perf_counter() - t0
        self.n_solves = 0
        self.solve_time = 0.0
        self.shape = A.shape
        self.dtype = A.dtype

    def solve(self, b):
        t0 = time.perf_counter()
        x = self._solve(b)
        self.solve_time += time.perf_counter() - t0
        self.n_solves += 1 if np.ndim(b) == 1 else np.shape(b)[1]
        return x


def factorize(A, solver: str = "auto", permc_spec: str = "MMD_AT_PLUS_A") -> _Factor:
    """Factorise a sparse symmetric positive-definite matrix (CHOLMOD when available with 'auto')."""
    if solver == "auto":
        solver = "cholmod" if cholmod_available() else "splu"
    return _Factor(A, solver, permc_spec)


def shift_invert_operator(K, M, sigma: float, solver: str = "auto", permc_spec: str = "MMD_AT_PLUS_A"):
    """``(K − σM)⁻¹`` as a :class:`~scipy.sparse.linalg.LinearOperator`; ``.factor`` holds timings."""
    A = sp.csc_matrix(K - sigma * M)
    f = factorize(A, solver, permc_spec)
    op = spla.LinearOperator(A.shape, matvec=f.solve, matmat=f.solve, dtype=A.dtype)
    op.factor = f
    return op


def eigen_sparse(K, M, n_modes: int, *, shift: float | None = None, shift_hz: float | None = None,
                 solver: str = "auto", permc_spec: str = "MMD_AT_PLUS_A", tol: float = 0.0,
                 ncv: int | None = None, info: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``n_modes`` modes by shift-invert Lanczos about a negative shift.

    shift : σ in rad²/s² (negative), default −(2π·1 Hz)²; or give ``shift_hz``.
    solver : 'splu' (SuperLU, ordering ``permc_spec``), 'cholmod' or 'auto'.
    info : optional dict filled with timings (factor_time, n_solves, solve_time, total_time).
    Returns ω (rad/s, ascending) and mass-normalised shapes.
    """
    t0 = time.perf_counter()
    n = K.shape[0]
    if not 0 < n_modes < n:
        raise ModalabValueError(f"n_modes = {n_modes}; expected 1..{n - 1} for a sparse solve of {n} DOFs "
                                "(use eigen_dense for all modes)")
    sigma = _shift(shift, shift_hz)
    w, phi, op = lanczos_modes(K, M, n_modes, sigma, tol=tol, ncv=ncv,
                               make_opinv=lambda Kk, Mk, s: shift_invert_operator(Kk, Mk, s, solver, permc_spec))
    if info is not None:
        info.update(factor_time=op.factor.factor_time, n_solves=op.factor.n_solves,
                    solve_time=op.factor.solve_time, total_time=time.perf_counter() - t0, shift=sigma)
    log.debug("eigen_sparse: %d modes of %d DOFs, factor %.3fs, %d solves", n_modes, n,
              op.factor.factor_time, op.factor.n_solves)
    return w, phi


def normal_modes(K, M, n_modes: int | None = None, *, method: str = "auto", dense_limit: int = EIGEN_LIMIT,
                 **kw) -> tuple[np.ndarray, np.ndarray]:
    """ω (rad/s) and mass-normalised Φ: dense for small models or all modes, sparse Lanczos otherwise."""
    n = K.shape[0]
    if method == "auto":
        method = "dense" if (n <= dense_limit or n_modes is None or n_modes >= n - 1) else "sparse"
    if method == "dense":
        return eigen_dense(K, M, n_modes, shift=kw.get("shift"), shift_hz=kw.get("shift_hz"))
    if method == "sparse":
        if n_modes is None:
            raise ModalabValueError("the sparse solver needs n_modes; give the number of modes wanted")
        return eigen_sparse(K, M, n_modes, **kw)
    raise ModalabValueError(f"method {method!r}; expected 'auto', 'dense' or 'sparse'")


def _modal_damping(phi, omega, C, D, table):
    """Per-mode viscous ζ: from a table, else from the diagonal of ΦᵀCΦ and ΦᵀDΦ."""
    z = np.zeros(omega.size)
    el = omega > 2 * np.pi * RIGID_HZ
    if table is not None:
        z[el] = table.zeta(omega[el] / (2 * np.pi))
        return z
    if C is not None:
        z[el] += np.einsum("ij,ij->j", phi[:, el], C @ phi[:, el]) / (2 * omega[el])
    if D is not None:
        z[el] += np.einsum("ij,ij->j", phi[:, el], D @ phi[:, el]) / (2 * omega[el] ** 2)
    return z


def modes_of(system, n_modes: int | None = None, *, full: bool = True, modal_damping=None, **kw) -> ModeSet:
    """Modes of an :class:`~updating.fe.model.FESystem` as a mass-normalised :class:`ModeSet`.

    ``damping`` holds ζ from ``modal_damping`` (a table) or, without one, the
    diagonal projections of C and D (ζ = c/(2ω) + d/(2ω²)).
    ``full`` maps shapes to every model DOF by ``u = T u_a``.
    """
    omega, phi = normal_modes(system.K, system.M, n_modes, **kw)
    zeta = _modal_damping(phi, omega, system.C, system.D, modal_damping)
    if full:
        shapes, dofs = system.reduction.expand(phi), system.reduction.full_dofs
    else:
        shapes, dofs = phi, system.dofs
    return ModeSet(freq_hz=omega / (2 * np.pi), damping=zeta, shapes=np.asarray(shapes), dofs=dofs,
                   scaling="unit_modal_mass", metadata={"source": "updating.fe", "full": full})


# ---------------------------------------------------------------------- FRFs
def _io(system, responses, references):
    """Selection matrices on the a-set for response/reference labels (they may be dependent DOFs)."""
    red = system.reduction
    resp = red.full_dofs if responses is None else parse_dofs(responses)
    refs = red.full_dofs if references is None else parse_dofs(references)
    io, so = locate(red.full_dofs, resp, "response DOF")
    ii, si = locate(red.full_dofs, refs, "reference DOF")
    Tr = sp.csr_matrix(red.T[io].multiply(np.asarray(so, float)[:, None]))
    Tf = sp.csr_matrix(red.T[ii].multiply(np.asarray(si, float)[:, None]))
    return resp, refs, Tr, Tf


def frf_direct(system, freq_hz, responses=None, references=None, quantity: str = "accelerance", *,
               beta: float = 0.0) -> FRF:
    """Exact FRFs by a sparse solve of ``(K + iD + sC + s²M) x = f`` per frequency line, ``s = iω + β``.

    ``beta`` (1/s, default 0): the decay rate of an exponential window ``e^{−βt}`` applied to force and
    response records; the windowed FRF is the transfer function at ``s = iω + β`` (the FRF's
    ``window_beta_per_s``), so a model compared with windowed data is evaluated there.  Response and reference
    DOFs may be any model DOF (dependent DOFs via the rigid links).
    """
    q = check_quantity(quantity)
    freq = np.atleast_1d(np.asarray(freq_hz, float))
    resp, refs, Tr, Tf = _io(system, responses, references)
    F = Tf.T.toarray().astype(complex)
    K = sp.csc_matrix(system.K, dtype=complex)
    if system.D is not None:
        K = K + 1j * system.D
    M = sp.csc_matrix(system.M)
    C = None if system.C is None else sp.csc_matrix(system.C)
    # a massless mechanism is constrained as for the modes (MECHFIX): zero response there, as frf_modal
    keep, _, _ = _drop_mechanisms(system.K, system.M)
    if keep is not None:
        K, M = sp.csc_matrix(K[keep][:, keep]), sp.csc_matrix(M[keep][:, keep])
        C = None if C is None else sp.csc_matrix(C[keep][:, keep])
        F, Tr = F[keep], sp.csr_matrix(Tr[:, keep])
    H = np.empty((len(resp), len(refs), freq.size), complex)
    beta = float(beta)
    for k, f in enumerate(freq):
        sk = 1j * 2 * np.pi * f + beta
        Z = K + sk * sk * M
        if C is not None:
            Z = Z + sk * C
        try:
            X = spla.splu(sp.csc_matrix(Z), permc_spec="MMD_AT_PLUS_A").solve(F)
        except RuntimeError:
            raise ModalabValueError(f"the dynamic stiffness is singular at {f} Hz (an undamped resonance or a "
                                    "rigid-body mode at 0 Hz); avoid that line or add damping") from None
        H[:, :, k] = (Tr @ X) * sk ** _ORDER[q]
    return FRF(freq_hz=freq, H=H, responses=resp, references=refs, quantity=q, units=QUANTITY_UNITS[q],
               metadata={"estimator": "exact", "source": "updating.fe.frf_direct"}, window_beta_per_s=beta)


def frf_modal(system, freq_hz, responses=None, references=None, *, n_modes: int | None = None,
              residual: bool = True, modal_damping=None, quantity: str = "accelerance",
              shift: float | None = None, shift_hz: float | None = None, modes=None,
              window_beta_per_s: float = 0.0) -> FRF:
    """FRFs by modal superposition of the lowest ``n_modes`` modes, optionally with residual flexibility.

    H(ω) = Σ_r φ_r φ_rᵀ / (ω_r² − ω² + i d_r + i ω c_r) + R, where c_r, d_r
    are the diagonal modal damping terms (or 2ζ_rω_r from ``modal_damping``)
    and R the static residual of the omitted modes at the negative shift σ
    (module docstring).  ``modes`` may pass a precomputed (ω, Φ) on the a-set.

    ``window_beta_per_s`` β (1/s, default 0): evaluate at ``s = iω + β`` (``ω_r² + s² + i d_r + s c_r``, the
    quantity's factor ``s^q``), as :func:`frf_direct` does for data taken with an exponential window; the
    result carries β.
    """
    q = check_quantity(quantity)
    freq = np.atleast_1d(np.asarray(freq_hz, float))
    resp, refs, Tr, Tf = _io(system, responses, references)
    sigma = _shift(shift, shift_hz)
    if modes is None:
        omega, phi = normal_modes(system.K, system.M, n_modes, shift=sigma) \
            if not use_dense(system.n_dof, "eigen") else eigen_dense(system.K, system.M, n_modes)
    else:
        omega, phi = modes
    el = omega > 2 * np.pi * RIGID_HZ
    if modal_damping is not None:
        cr = np.where(el, 2 * modal_damping.zeta(omega / (2 * np.pi)) * omega, 0.0)
        dr = np.zeros_like(omega)
    else:
        cr = np.einsum("ij,ij->j", phi, system.C @ phi) if system.C is not None else np.zeros_like(omega)
        dr = np.einsum("ij,ij->j", phi, system.D @ phi) if system.D is not None else np.zeros_like(omega)
    Pr = np.asarray(Tr @ phi)
    Pf = np.asarray(Tf @ phi)
    w = 2 * np.pi * freq
    beta = check_window_beta(window_beta_per_s)
    if beta:                                          # s = iω + β; β = 0 keeps the iω arithmetic below
        s = 1j * w + beta
        den = omega[:, None] ** 2 + s[None, :] ** 2 + 1j * dr[:, None] + s[None, :] * cr[:, None]
    else:
        den = omega[:, None] ** 2 - w[None, :] ** 2 + 1j * dr[:, None] + 1j * w[None, :] * cr[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        H = np.einsum("or,ir,rf->oif", Pr, Pf, 1.0 / den, optimize=True)
    if residual:
        keep, Kk, Mk = _drop_mechanisms(sp.csr_matrix(system.K), sp.csr_matrix(system.M))
        Fk = np.asarray(Tf.T.toarray(), float)
        f = factorize(sp.csc_matrix(Kk - sigma * Mk), "auto")
        X = _restore(f.solve(Fk if keep is None else Fk[keep]), keep, Fk.shape[0])
        R = np.asarray(Tr @ X) - (Pr / (omega ** 2 - sigma)[None, :]) @ Pf.T
        H = H + R[:, :, None]
    H = H * ((1j * w + beta if beta else 1j * w) ** _ORDER[q])[None, None, :]
    return FRF(freq_hz=freq, H=H, responses=resp, references=refs, quantity=q, units=QUANTITY_UNITS[q],
               metadata={"estimator": "exact", "source": "updating.fe.frf_modal", "n_modes": int(omega.size),
                         "residual": bool(residual)}, window_beta_per_s=beta)
