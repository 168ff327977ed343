"""Analytic eigen-sensitivities of a :class:`~updating.fe.parametric.ParametricModel`.

For the undamped eigenproblem ``K φ_r = λ_r M φ_r`` with mass-normalised modes
(``φ_rᵀ M φ_r = 1``) the derivatives with respect to a parameter ``p_i`` are

* eigenvalue (thesis Eq. 3.44–3.48, the entries ∂(ω_r²)/∂p_i of the
  sensitivity matrix [S] of Eq. 3.50)::

      ∂λ_r/∂p_i = φ_rᵀ (∂K/∂p_i − λ_r ∂M/∂p_i) φ_r

* eigenvector (the entries ∂{φ_r}/∂p_i of Eq. 3.45, 3.49, 3.50), from
  ``(K − λ_r M) ∂φ_r = f_i`` with ``f_i = −(∂K − λ_r ∂M − ∂λ_r M) φ_r`` and the
  normalisation condition ``φ_rᵀ M ∂φ_r = −½ φ_rᵀ ∂M φ_r``:

  - **Nelson's method** (Nelson 1976): the singular ``K − λ_r M`` is made
    regular by fixing the component ``k`` of largest ``|φ_r|``; one
    factorisation per mode, one (multi-right-hand-side) solve per parameter;
    exact for simple eigenvalues, however close.
  - **modal method with static correction**: ``∂φ_r = Σ_s a_s φ_s`` over the
    computed modes plus the quasi-static contribution of the truncated ones,
    ``(K − μM)⁻¹ f − Σ_s φ_s φ_sᵀ f/(λ_s − μ)`` (one factorisation in all).
    Exact when all modes are kept; otherwise an approximation whose error the
    static term reduces by one to two orders of magnitude.

Repeated eigenvalues (a gap below ``repeated_tol``·max|λ|, e.g. the rigid-body
modes of a free-free model or symmetric structures): the eigenvalue
derivatives are the eigenvalues of the g×g matrix ``Φ_Gᵀ(∂K − λ∂M)Φ_G`` of the
group, returned in ascending order — the one-sided derivative of the sorted
eigenvalues for an increase of ``p_i``.  The eigenvectors inside a degenerate
subspace are not unique, so for them only the well-defined part of the
derivative is returned: the component M-orthogonal to the subspace (from the
bordered system ``[K−λM, MΦ_G; (MΦ_G)ᵀ, 0]``) plus the normalisation term; the
rotation inside the subspace is left at zero and a warning is logged.

All sensitivities of all parameters are computed from the stacked non-zeros
of the derivative matrices (:class:`StackedDerivatives`): the cost of the
eigenvalue sensitivities is ``O(nnz(∂K, ∂M) · m)``, independent of the number
of parameters as long as the parameters partition the model.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from modalab.core.eigen import drop_mechanisms, eigsh, massless_dofs, massless_mechanisms, restore
from modalab.core.dense import use_dense
from modalab.core.errors import ModalabValueError, ShapeError

from updating.fe.solvers import _massless, eigen_dense, eigen_sparse

log = logging.getLogger(__name__)

__all__ = [
    "ModalSolution",
    "StackedDerivatives",
    "solve_modes",
    "eigenvalue_sensitivities",
    "frequency_sensitivities",
    "eigenvector_sensitivities",
    "repeated_groups",
]

# ----------------------------------------------------------------------------- stacked derivatives
class StackedDerivatives:
    """The non-zeros of every parameter's derivative matrices in one set of COO arrays.

    ``parts[key] = (rows, cols, vals, pidx)`` for key in ``'K', 'M', 'C', 'D'``:
    entry ``vals[j]`` sits at ``(rows[j], cols[j])`` of ``∂key/∂p_{pidx[j]}``.
    Built once per parameter vector; every vectorised product below works on
    these arrays, so no Python loop runs over elements or parameters.
    """

    KEYS = ("K", "M", "C", "D")

    def __init__(self, derivatives, n: int):
        self.n = int(n)
        self.P = len(derivatives)
        acc = {k: ([], [], [], []) for k in self.KEYS}
        for i, d in enumerate(derivatives):
            for k in self.KEYS:
                A = getattr(d, "d" + k, None)
                if A is None:
                    continue
                A = sp.coo_matrix(A)
                if A.shape != (self.n, self.n):
                    raise ShapeError(f"derivative d{k} of parameter {i} has shape {A.shape}; "
                                     f"expected ({self.n}, {self.n}) like the model")
                if A.nnz == 0:
                    continue
                r, c, v, p = acc[k]
                r.append(A.row)
                c.append(A.col)
                v.append(A.data.astype(float))
                p.append(np.full(A.nnz, i, dtype=np.int64))
        self.parts = {}
        for k, (r, c, v, p) in acc.items():
            if r:
                self.parts[k] = (np.concatenate(r).astype(np.int64), np.concatenate(c).astype(np.int64),
                                 np.concatenate(v), np.concatenate(p))

    def has(self, key: str) -> bool:
        return key in self.parts

    def quadratic(self, key: str, X: np.ndarray, Y: np.ndarray | None = None) -> np.ndarray:
        """``out[i, a] = X[:, a]ᵀ ∂key/∂p_i Y[:, a]`` for every parameter i and column a, shape (P, m)."""
        X = np.asarray(X)
        X2 = X[:, None] if X.ndim == 1 else X
        Y2 = X2 if Y is None else (np.asarray(Y)[:, None] if np.ndim(Y) == 1 else np.asarray(Y))
        out = np.zeros((self.P, X2.shape[1]), dtype=np.result_type(X2, Y2, float))
        if key not in self.parts:
            return out if X.ndim > 1 else out[:, 0]
        r, c, v, p = self.parts[key]
        for a in range(X2.shape[1]):
            w = v * X2[r, a] * Y2[c, a]
            if np.iscomplexobj(w):
                out[:, a] = np.bincount(p, w.real, self.P) + 1j * np.bincount(p, w.imag, self.P)
            else:
                out[:, a] = np.bincount(p, w, self.P)
        return out if X.ndim > 1 else out[:, 0]

    def columns(self, key: str, x: np.ndarray, params=None) -> sp.csc_matrix:
        """Sparse (n, P) matrix whose column i is ``∂key/∂p_i · x`` (optionally only ``params`` columns)."""
        if key not in self.parts:
            P = self.P if params is None else len(params)
            return sp.csc_matrix((self.n, P), dtype=np.result_type(x, float))
        r, c, v, p = self.parts[key]
        if params is None:
            return sp.csc_matrix(sp.coo_matrix((v * x[c], (r, p)), shape=(self.n, self.P)))
        params = np.asarray(params)
        remap = np.full(self.P, -1)
        remap[params] = np.arange(params.size)
        keep = remap[p] >= 0
        return sp.csc_matrix(sp.coo_matrix((v[keep] * x[c[keep]], (r[keep], remap[p[keep]])),
                                           shape=(self.n, params.size)))

    def pair_operators(self, keys=("K", "M", "C", "D")):
        """Pair form for products with many vectors at once.

        Returns ``(pair_param, pair_row, ops)``: the distinct (parameter, row)
        pairs touched by any of ``keys`` and, per key, a sparse
        (n_pairs, n) matrix ``B`` such that ``(B @ X)[q]`` is row ``pair_row[q]``
        of ``∂key/∂p_{pair_param[q]} · X``.  The cost of ``B @ X`` is nnz·(columns of X).
        """
        present = [k for k in keys if k in self.parts]
        if not present:
            return np.zeros(0, int), np.zeros(0, int), {}
        allkey = np.concatenate([self.parts[k][3] * self.n + self.parts[k][0] for k in present])
        uniq, inv = np.unique(allkey, return_inverse=True)
        ops, start = {}, 0
        for k in present:
            r, c, v, p = self.parts[k]
            idx = inv[start:start + r.size]
            start += r.size
            ops[k] = sp.csr_matrix((v, (idx, c)), shape=(uniq.size, self.n))
        return uniq // self.n, uniq % self.n, ops


# ----------------------------------------------------------------------------- eigen-solution
@dataclass
class ModalSolution:
    """Undamped eigen-solution at a parameter vector: ``lam`` (rad²/s², ascending) and mass-normalised ``phi`` (n, m)."""

    lam: np.ndarray
    phi: np.ndarray
    p: np.ndarray
    K: sp.spmatrix
    M: sp.spmatrix

    @property
    def omega(self) -> np.ndarray:
        return np.sqrt(np.clip(self.lam, 0.0, None))

    @property
    def freq_hz(self) -> np.ndarray:
        return self.omega / (2 * np.pi)


def _normalise(phi, M):
    mm = np.einsum("ij,ij->j", phi, M @ phi)
    if np.any(mm <= 0):
        raise ModalabValueError("a mode has zero or negative modal mass; the mass matrix is not positive definite")
    phi = phi / np.sqrt(mm)[None, :]
    k = np.argmax(np.abs(phi), axis=0)
    s = np.sign(phi[k, np.arange(phi.shape[1])])
    s[s == 0] = 1.0
    return phi * s[None, :]


def solve_modes(model, p=None, n_modes: int | None = None, *, sigma: float | None = None) -> ModalSolution:
    """Eigen-solution of ``model`` at ``p``: the lowest ``n_modes`` (all for small dense models).

    Dense ``eigh`` up to :data:`modalab.core.dense.EIGEN_LIMIT` DOFs, otherwise ARPACK shift-invert around
    ``sigma`` (default a small negative shift, safe for free-free models).
    Modes are mass-normalised and signed so that their largest component is positive.
    """
    p = np.asarray(model.p0 if p is None else p, dtype=float)
    st = model.structure(p)
    K, M = st.K.tocsr(), st.M.tocsr()
    n = K.shape[0]
    if n_modes is not None and not (1 <= int(n_modes) <= n):
        raise ModalabValueError(f"n_modes={n_modes}; expected 1..{n} for a model of {n} DOFs")
    if use_dense(n, "eigen") or (n_modes is not None and n_modes >= n - 1):
        # massless DOFs (lumped mass without rotary inertia: Nastran's default without COUPMASS) and massless
        # mechanisms (the rigid torsion of a free-free lumped-mass beam) are handled by the FE solver
        n_finite = n - int(_massless(M).size)
        if n_modes is not None and n_modes > n_finite:
            raise ModalabValueError(f"n_modes={n_modes} but the model has only {n_finite} finite modes; "
                                    f"ask for at most {n_finite} modes")
        w, phi = eigen_dense(K, M, n_modes)
        lam = w ** 2
    elif sigma is None or sigma < 0:
        k = 10 if n_modes is None else int(n_modes)
        if sigma is None:
            scale = abs(K.diagonal()).max() / max(abs(M.diagonal()).max(), 1e-300)
            sigma = -1e-6 * scale
        w, phi = eigen_sparse(K, M, k, shift=sigma)
        lam = w ** 2
    else:
        k = 10 if n_modes is None else int(n_modes)
        # modes nearest a positive shift (K - σM indefinite): plain shift-invert Lanczos from the fixed start
        # vector, on the DOFs left when each massless mechanism is constrained (K - σM is singular otherwise)
        keep, Kk, Mk = drop_mechanisms(K, M)
        n_finite = Kk.shape[0] - massless_dofs(Mk).size
        if k > n_finite:
            raise ModalabValueError(f"n_modes={k} but the model has only {n_finite} finite modes; "
                                    f"ask for at most {n_finite} modes")
        lam, phi = eigsh(sp.csc_matrix(Kk), k, M=sp.csc_matrix(Mk), sigma=sigma, which="LM")
        o = np.argsort(lam)
        lam, phi = lam[o], restore(phi[:, o], keep, n)
    phi = _normalise(phi, M)
    return ModalSolution(lam=np.asarray(lam, float), phi=phi, p=p, K=K, M=M)


def repeated_groups(lam: np.ndarray, repeated_tol: float = 1e-8) -> list:
    """Indices of groups of (numerically) equal eigenvalues: gap ≤ ``repeated_tol``·max|λ|."""
    lam = np.asarray(lam, float)
    if lam.size == 0:
        return []
    tol = repeated_tol * max(np.abs(lam).max(), 1e-300)
    groups, cur = [], [0]
    for j in range(1, lam.size):
        if abs(lam[j] - lam[cur[-1]]) <= tol:
            cur.append(j)
        else:
            groups.append(cur)
            cur = [j]
    groups.append(cur)
    return groups


def _prepare(model, p, modes, solution, derivatives):
    if solution is None:
        nm = None if modes is None else int(np.max(modes)) + 1
        nd = len(model.dofs)
        if nm is not None and not use_dense(nd, "eigen"):
            solution = solve_modes(model, p, nm)
        else:
            solution = solve_modes(model, p)
    if modes is None:
        modes = np.arange(solution.lam.size)
    modes = np.atleast_1d(np.asarray(modes, int))
    if modes.size and (modes.min() < 0 or modes.max() >= solution.lam.size):
        raise ModalabValueError(f"mode indices {modes.tolist()} outside 0..{solution.lam.size - 1} of the solution")
    if not isinstance(derivatives, StackedDerivatives):
        derivs = model.derivatives(solution.p) if derivatives is None else derivatives
        derivatives = StackedDerivatives(derivs, solution.K.shape[0])
    return solution, modes, derivatives


def eigenvalue_sensitivities(model, p=None, modes=None, *, solution: ModalSolution | None = None,
                             derivatives=None, repeated_tol: float = 1e-8) -> np.ndarray:
    """``S[a, i] = ∂λ_{modes[a]}/∂p_i`` (rad²/s² per parameter unit), shape (m, P).

    Eq. (3.48): ``∂λ/∂p = φᵀ(∂K/∂p − λ ∂M/∂p)φ`` from mass-normalised modes;
    repeated groups as described in the module docstring.
    """
    sol, modes, sd = _prepare(model, p, modes, solution, derivatives)
    lam, phi = sol.lam, sol.phi
    S = np.zeros((modes.size, sd.P))
    want = {int(m): a for a, m in enumerate(modes)}
    for g in repeated_groups(lam, repeated_tol):
        hit = [m for m in g if m in want]
        if not hit:
            continue
        if len(g) == 1:
            r = g[0]
            S[want[r]] = sd.quadratic("K", phi[:, r]) - lam[r] * sd.quadratic("M", phi[:, r])
            continue
        # degenerate subspace: eigenvalues of the projected derivative matrix, per parameter
        G = len(g)
        PhiG = phi[:, g]
        lamg = float(np.mean(lam[g]))
        D = np.zeros((sd.P, G, G))
        for a in range(G):
            for b in range(a, G):
                Xa = PhiG[:, a]
                Xb = PhiG[:, b]
                val = _bilinear(sd, "K", Xa, Xb) - lamg * _bilinear(sd, "M", Xa, Xb)
                D[:, a, b] = val
                D[:, b, a] = val
        ev = np.linalg.eigvalsh(D)          # ascending, (P, G)
        for j, m in enumerate(g):
            if m in want:
                S[want[m]] = ev[:, j]
    return S


def _bilinear(sd, key, x, y):
    if not sd.has(key):
        return np.zeros(sd.P)
    r, c, v, p = sd.parts[key]
    return np.bincount(p, v * x[r] * y[c], sd.P)


def frequency_sensitivities(model, p=None, modes=None, *, solution=None, derivatives=None,
                            unit: str = "hz") -> np.ndarray:
    """``∂f_r/∂p_i`` in Hz per parameter unit (``unit='hz'``) or ``∂ω_r/∂p_i`` (``'rad/s'``): ∂λ/(2ω) [/2π]."""
    sol, modes, sd = _prepare(model, p, modes, solution, derivatives)
    S = eigenvalue_sensitivities(model, modes=modes, solution=sol, derivatives=sd)
    w = sol.omega[modes]
    if np.any(w <= 0):
        raise ModalabValueError("frequency sensitivities of rigid-body modes (ω = 0) are undefined; "
                                "use eigenvalue_sensitivities or exclude those modes")
    dw = S / (2 * w[:, None])
    if unit.lower() in ("hz",):
        return dw / (2 * np.pi)
    if unit.lower() in ("rad/s", "omega"):
        return dw
    raise ModalabValueError(f"unit {unit!r}; expected 'hz' or 'rad/s'")


def _factor(A):
    """A solve function for a (sparse) matrix: dense LU for small, SuperLU otherwise."""
    if use_dense(A.shape[0], "eigen"):      # one factorisation per mode (modalab.core.dense)
        lu = sla.lu_factor(A.toarray() if sp.issparse(A) else A, check_finite=False)
        return lambda B: sla.lu_solve(lu, B, check_finite=False)
    f = spla.splu(sp.csc_matrix(A))
    return lambda B: f.solve(np.asarray(B))


def eigenvector_sensitivities(model, p=None, modes=None, *, method: str = "nelson",
                              solution: ModalSolution | None = None, derivatives=None, rows=None,
                              n_modal: int | None = None, shift: float | None = None,
                              repeated_tol: float = 1e-8, chunk: int = 256) -> np.ndarray:
    """``dphi[k, a, i] = ∂φ_{modes[a]}[rows[k]]/∂p_i`` for mass-normalised modes, shape (len(rows), m, P).

    Parameters
    ----------
    method : ``'nelson'`` (exact, one factorisation per mode) or ``'modal'``
        (modal superposition over ``n_modal`` computed modes plus static
        correction with shift ``shift``; exact when all modes are kept).
    rows : DOF row indices to return (default all); the solves use the full model.
    chunk : parameters per multi-right-hand-side solve (memory bound n·chunk).
    """
    sol, modes, sd = _prepare(model, p, modes, solution, derivatives)
    lam, phi, K, M = sol.lam, sol.phi, sol.K, sol.M
    n = K.shape[0]
    rows = np.arange(n) if rows is None else np.asarray(rows, int)
    out = np.zeros((rows.size, modes.size, sd.P))
    groups = repeated_groups(lam, repeated_tol)
    group_of = {m: g for g in groups for m in g}
    # eigen-derivatives needed in the right-hand sides
    dlam = eigenvalue_sensitivities(model, modes=np.arange(lam.size), solution=sol, derivatives=sd,
                                    repeated_tol=repeated_tol)
    # a massless mechanism (no mass, no stiffness: K - λM singular for every λ) stays constrained at the DOFs
    # where the modes were solved with it constrained (zero there, modalab.core.eigen); the derivatives are
    # solved on the other DOFs
    mech, _ = massless_mechanisms(K, M)
    free = np.setdiff1d(np.arange(n), mech)
    if method == "nelson":
        for a, r in enumerate(modes):
            out[:, a, :] = _nelson_mode(sol, sd, int(r), group_of[int(r)], dlam[r], free, rows, chunk)
        return out
    if method != "modal":
        raise ModalabValueError(f"method {method!r}; expected 'nelson' or 'modal'")
    return _modal(sol, sd, modes, group_of, free, rows, n_modal, shift, chunk, out)


def _nelson_mode(sol, sd, r, group, dlam_r, free, rows, chunk):
    """Nelson's method for mode ``r``: ``∂φ_r/∂p = V + c φ_r`` with ``(K − λ_r M) V = F`` solved with the DOF of
    the largest component held (one factorisation per mode), or, for a repeated group, bordered by the
    group's mass-weighted modes (the component outside the degenerate subspace only).  (len(rows), P)."""
    lam, phi, K, M = sol.lam, sol.phi, sol.K, sol.M
    n = K.shape[0]
    x = phi[:, r]
    Mx = M @ x
    A = (K - lam[r] * M).tocsr()
    if len(group) == 1:
        k = int(np.argmax(np.abs(x)))
        keep = free[free != k]
        solve = _factor(A[keep][:, keep])
        border = None
    else:
        log.warning("mode %d belongs to a repeated group %s: returning the eigenvector derivative "
                    "component outside the degenerate subspace only", r, group)
        B = sp.csr_matrix((M @ phi[:, group])[free])
        Ab = sp.bmat([[A[free][:, free], B], [B.T, None]], format="csc")
        solve = _factor(Ab)
        border = len(group)
    out = np.zeros((rows.size, sd.P))
    for s0 in range(0, sd.P, chunk):
        ps = np.arange(s0, min(sd.P, s0 + chunk))
        F = -(sd.columns("K", x, ps) - lam[r] * sd.columns("M", x, ps)).toarray()
        halfm = 0.5 * sd.quadratic("M", x)[ps]
        V = np.zeros((n, ps.size))
        if border is None:
            F += np.outer(Mx, dlam_r[ps])
            V[keep] = solve(F[keep])
        else:
            V[free] = solve(np.vstack([F[free], np.zeros((border, ps.size))]))[:free.size]
        c = -(Mx @ V) - halfm
        out[:, ps] = V[rows] + np.outer(x[rows], c)
    return out


def _modal(sol, sd, modes, group_of, free, rows, n_modal, shift, chunk, out):
    """Modal superposition over ``n_modal`` modes plus the static correction with ``shift`` (exact when all
    modes are kept) into ``out`` (len(rows), len(modes), P)."""
    lam, phi, K, M = sol.lam, sol.phi, sol.K, sol.M
    n = K.shape[0]
    nb = lam.size if n_modal is None else int(n_modal)
    if nb > lam.size:
        raise ModalabValueError(f"n_modal={nb} but the solution holds {lam.size} modes; solve more modes first")
    basis = np.arange(nb)
    complete = nb == n
    if not complete:
        if shift is None:
            elastic = lam[lam > 1e-8 * max(abs(lam).max(), 1e-300)]
            shift = 0.0 if elastic.size == lam.size else -1e-2 * (elastic[0] if elastic.size else 1.0)
        solve_free = _factor((K - shift * M).tocsr()[free][:, free].tocsc())

        def solve(B):
            X = np.zeros((n,) + B.shape[1:])
            X[free] = solve_free(B[free])
            return X
    for a, r in enumerate(modes):
        g = set(group_of[int(r)])
        if len(g) > 1:
            log.warning("mode %d belongs to a repeated group %s: the modal method leaves the rotation "
                        "inside the degenerate subspace at zero", r, sorted(g))
        x = phi[:, r]
        others = np.array([s for s in basis if s not in g], int)
        for s0 in range(0, sd.P, chunk):
            ps = np.arange(s0, min(sd.P, s0 + chunk))
            F = -(sd.columns("K", x, ps) - lam[r] * sd.columns("M", x, ps)).toarray()
            halfm = 0.5 * sd.quadratic("M", x)[ps]
            proj = phi[:, others].T @ F                                     # (s, P)
            coef = proj / (lam[others] - lam[r])[:, None]
            D = phi[rows][:, others] @ coef
            if not complete:
                stat = solve(F)[rows] - phi[rows][:, basis] @ (phi[:, basis].T @ F / (lam[basis] - shift)[:, None])
                D = D + stat
            out[:, a, ps] = D - np.outer(x[rows], halfm)
    return out
