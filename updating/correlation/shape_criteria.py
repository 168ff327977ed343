"""Mode-shape correlation criteria (thesis section 2.2): MAC (weighted), AutoMAC, MACX, MSF, COMAC,
eCOMAC, cross- and mixed orthogonality, with the shared checks of their shape inputs.

Split out of :mod:`updating.correlation.metrics` (which re-exports these names: import them from there).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from modalab.core.errors import ModalabValueError, ShapeError
from modalab.core.modes import ModeSet


_TINY = 1e-300


# ------------------------------------------------------------------------ inputs
def _shapes(x, name: str) -> np.ndarray:
    if isinstance(x, ModeSet):
        return np.asarray(x.shapes)
    try:
        a = np.asarray(x)
    except (TypeError, ValueError):
        raise ModalabValueError(f"{name}: got {type(x).__name__}; expected an (n_dof, n_modes) array or a ModeSet") \
            from None
    if a.dtype == object or not np.issubdtype(a.dtype, np.number):
        raise ModalabValueError(f"{name}: got an array of {a.dtype}; expected numbers, shape (n_dof, n_modes)")
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise ShapeError(f"{name} has shape {a.shape}; expected (n_dof, n_modes)")
    if not np.all(np.isfinite(a)):
        raise ModalabValueError(f"{name} contains NaN or inf; remove or fill the missing shape values first")
    return a


def _pair_shapes(a, x, na="analysis shapes", nx="test shapes", same_modes=False):
    A, X = _shapes(a, na), _shapes(x, nx)
    if A.shape[0] != X.shape[0]:
        raise ShapeError(f"{na} have {A.shape[0]} DOFs but {nx} have {X.shape[0]}; map both onto the same DOFs "
                         "first (updating.correlation.dofmap.DofMap.apply or correlate(..., dofmap=...))")
    if same_modes and A.shape[1] != X.shape[1]:
        raise ShapeError(f"{na} have {A.shape[1]} modes but {nx} have {X.shape[1]}; pass paired modes column by "
                         "column (e.g. from pair_modes)")
    if isinstance(a, ModeSet) and isinstance(x, ModeSet):
        if [(d.node, d.axis) for d in a.dofs] != [(d.node, d.axis) for d in x.dofs]:
            raise ShapeError("the two mode sets are on different DOF labels; select common DOFs first "
                             "(ModeSet.select_dofs) or use correlate(..., dofmap=...)")
        sg = np.array([da.sign * dx.sign for da, dx in zip(a.dofs, x.dofs)], float)
        X = X * sg[:, None]
    return A, X


def _rescale(P):
    """Divide every column by its largest modulus (for criteria invariant to column scaling; avoids underflow)."""
    m = np.abs(P).max(axis=0, initial=0.0)
    return P / np.where((m > 0) & np.isfinite(m), m, 1.0)[None, :]


def _weight(W, n):
    if W is None:
        return None
    if sp.issparse(W):
        W = sp.csr_matrix(W)
    else:
        W = np.asarray(W)
    if W.shape != (n, n):
        raise ShapeError(f"weighting matrix has shape {W.shape}; expected ({n}, {n}) on the shape DOFs")
    return W


def _inner(A, B, W=None):
    """A^H W B."""
    return A.conj().T @ (B if W is None else np.asarray(W @ B))


# ------------------------------------------------------------------ mode criteria
def mac(phi_a, phi_x, *, weight=None) -> np.ndarray:
    """Modal Assurance Criterion matrix, eq. 2.63.

    ``MAC_ij = |φ_aiᴴ W φ_xj|² / ((φ_aiᴴ W φ_ai)(φ_xjᴴ W φ_xj))`` with ``W = I`` by
    default (a mass matrix gives the mass-weighted MAC).  Complex shapes use the
    conjugate transpose.  Shape (n_analysis_modes, n_test_modes), values in [0, 1];
    a zero vector gives 0.
    """
    A, X = _pair_shapes(phi_a, phi_x)
    A, X = _rescale(A), _rescale(X)
    W = _weight(weight, A.shape[0])
    num = np.abs(_inner(A, X, W)) ** 2
    da = np.real(np.einsum("ij,ij->j", A.conj(), A if W is None else np.asarray(W @ A)))
    dx = np.real(np.einsum("ij,ij->j", X.conj(), X if W is None else np.asarray(W @ X)))
    den = np.outer(da, dx)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0)
    return np.clip(out, 0.0, 1.0)


def automac(phi, *, weight=None) -> np.ndarray:
    """AutoMAC: the MAC of a mode set with itself (symmetric, unit diagonal for non-zero shapes).

    Off-diagonal values near 1 show modes the sensor set cannot tell apart (spatial aliasing).
    """
    P = _shapes(phi, "shapes")
    M = mac(P, P, weight=weight)
    return 0.5 * (M + M.T)


def macx(phi_a, phi_x) -> np.ndarray:
    """Complex MAC (MACX of Vacher, Jacquier & Bucharles 2010) for complex modes.

    ``MACX = (|aᴴx| + |aᵀx|)² / ((aᴴa + |aᵀa|)(xᴴx + |xᵀx|))``.  It equals the MAC
    (eq. 2.63) for real shapes and, unlike the MAC, is insensitive to the
    distinction between a complex mode and its conjugate.
    """
    A, X = _pair_shapes(phi_a, phi_x)
    A, X = _rescale(A), _rescale(X)
    num = (np.abs(A.conj().T @ X) + np.abs(A.T @ X)) ** 2
    da = np.real(np.einsum("ij,ij->j", A.conj(), A)) + np.abs(np.einsum("ij,ij->j", A, A))
    dx = np.real(np.einsum("ij,ij->j", X.conj(), X)) + np.abs(np.einsum("ij,ij->j", X, X))
    den = np.outer(da, dx)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0)
    return np.clip(out, 0.0, 1.0)


def msf(phi_x, phi_a) -> np.ndarray:
    """Modal Scale Factor of paired columns, eq. 2.62: the factor that scales ``φ_a`` onto ``φ_x``.

    ``MSF = φ_aᴴ φ_x / φ_aᴴ φ_a`` (least squares), so ``φ_a * MSF ≈ φ_x``; its modulus is
    eq. 2.62 and its sign (phase for complex shapes) tells whether the shapes are
    inverted.  Shape (n_pairs,); 0 where ``φ_a`` is zero.
    """
    X, A = _pair_shapes(phi_x, phi_a, "shapes phi_x", "shapes phi_a", same_modes=True)
    num = np.einsum("ij,ij->j", A.conj(), X)
    den = np.real(np.einsum("ij,ij->j", A.conj(), A))
    out = np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0)
    return out.real if not np.iscomplexobj(out) or np.all(out.imag == 0) else out


def _unit(P):
    n = np.linalg.norm(P, axis=0)
    return P / np.where(n > _TINY, n, 1.0)[None, :]


def comac(phi_a, phi_x, *, normalize: bool = True) -> np.ndarray:
    """Coordinate MAC per DOF over L paired modes (columns in pair order), eq. 2.64.

    ``COMAC_i = (Σ_r |φ_a,ir φ_x,ir|)² / (Σ_r |φ_a,ir|² Σ_r |φ_x,ir|²)`` (Lieven & Ewins; the
    printed eq. 2.64 omits the square of the numerator, without which the value would not
    be bounded by 1).  ``normalize=True`` scales every mode vector to unit length first, so
    each pair counts equally whatever the test scaling.  Values in [0, 1]; 1 = correlated.
    A DOF that is zero in every mode of both sets (a common node line) counts as 1,
    a DOF zero in only one of them as 0.
    """
    A, X = _pair_shapes(phi_a, phi_x, same_modes=True)
    if normalize:
        A, X = _unit(_rescale(A)), _unit(_rescale(X))
    # COMAC_i is invariant to scaling row i of A or X: divide each row by its largest modulus
    ra, rx = np.abs(A).max(axis=1, initial=0.0), np.abs(X).max(axis=1, initial=0.0)
    A = A / np.where(ra > 0, ra, 1.0)[:, None]
    X = X / np.where(rx > 0, rx, 1.0)[:, None]
    num = np.sum(np.abs(A * X), axis=1) ** 2
    sa, sx = np.sum(np.abs(A) ** 2, axis=1), np.sum(np.abs(X) ** 2, axis=1)
    den = sa * sx
    both_zero = (sa <= _TINY) & (sx <= _TINY)
    out = np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), np.where(both_zero, 1.0, 0.0))
    return np.clip(out, 0.0, 1.0)


def ecomac(phi_a, phi_x) -> np.ndarray:
    """Enhanced COMAC per DOF (Hunt 1992): ``ECOMAC_i = Σ_r |φ_a,ir - φ̃_x,ir| / (2L)``.

    Each analysis mode is scaled to a largest entry of 1 and each test mode is
    scaled onto it with its MSF (eq. 2.62), so the value measures the remaining
    shape difference: 0 for perfect correlation, larger for worse.
    """
    A, X = _pair_shapes(phi_a, phi_x, same_modes=True)
    L = A.shape[1]
    if L == 0:
        return np.zeros(A.shape[0])
    k = np.argmax(np.abs(A), axis=0)
    peak = A[k, np.arange(L)]
    A = A / np.where(np.abs(peak) > _TINY, peak, 1.0)[None, :]
    s = msf(A, X)                                   # scales X onto A
    Xs = X * s[None, :]
    return np.sum(np.abs(A - Xs), axis=1) / (2 * L)


def _ortho(A, M, B):
    Mm = sp.csr_matrix(M) if sp.issparse(M) else np.asarray(M)
    if Mm.shape != (A.shape[0], A.shape[0]):
        raise ShapeError(f"mass matrix has shape {Mm.shape}; expected ({A.shape[0]}, {A.shape[0]}) on the shape "
                         "DOFs (a reduced mass on the test DOFs, or the full mass with expanded test modes)")
    return A.T @ np.asarray(Mm @ B), Mm


def cross_orthogonality(phi_a, phi_x, M, *, normalize: bool = False) -> np.ndarray:
    """Cross orthogonality (Targoff), eq. 2.65: ``COM = Φ_Aᵀ M_A Φ_X``.

    ``M`` is the analytical mass on the shape DOFs (reduced to the test DOFs, or
    the full mass with expanded test shapes).  Identity for well-correlated,
    mass-normalised modes.  ``normalize=True`` divides by
    ``sqrt(|diag(Φ_AᵀMΦ_A)| |diag(Φ_XᵀMΦ_X)|)`` so differently scaled sets compare.
    """
    A, X = _pair_shapes(phi_a, phi_x)
    O, Mm = _ortho(A, M, X)
    if normalize:
        da = np.sqrt(np.abs(np.einsum("ij,ij->j", A, np.asarray(Mm @ A))))
        dx = np.sqrt(np.abs(np.einsum("ij,ij->j", X, np.asarray(Mm @ X))))
        O = O / np.outer(np.where(da > _TINY, da, 1.0), np.where(dx > _TINY, dx, 1.0))
    return O


def mixed_orthogonality(phi_x, M, *, normalize: bool = False) -> np.ndarray:
    """Mixed orthogonality, eq. 2.66: ``MOC = Φ_Xᵀ M_A Φ_X`` (test modes with the analytical mass).

    Identity for mass-normalised modes of a correct model; ``normalize=True``
    divides by ``sqrt(|d_i d_j|)`` with ``d = diag(MOC)`` (unit diagonal).
    """
    X = _shapes(phi_x, "test shapes")
    O, _ = _ortho(X, M, X)
    if normalize:
        d = np.sqrt(np.abs(np.diag(O)))
        d = np.where(d > _TINY, d, 1.0)
        O = O / np.outer(d, d)
    return O
