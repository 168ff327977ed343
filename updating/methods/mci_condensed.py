"""MCI minimisation on the condensed residual, with line weights from the data's noise model.

The estimator diagnosis uses for the model's own parameters (its "background"): thesis section 3.2.4
with the unmeasured DOFs expanded by the current model at every iteration
(:func:`~updating.correlation.condensation.condensed_residual`, the one Kidder-type expansion that
:class:`~updating.methods.mci.MCIUpdater` and the response-function method use too).  The residual
``r_m = [Z x − f]_m`` is the negative MCI of thesis eq. (3.69) on the measured rows; its first-order change
with a parameter is ``−Tᵀ ∂Z/∂p x`` (:class:`ResidualSystem`), and :func:`mci_update` iterates damped
Gauss–Newton steps on it — in the one iteration loop of the FRF-based updaters
(:func:`updating.methods.iteration.iterate`), which :class:`~updating.methods.mci.MCIUpdater` and the
response-function method run too.

Where it differs from :class:`~updating.methods.mci.MCIUpdater` (in the step it proposes): the lines are
weighted by √coherence / σ of the model (σ the residual a unit relative FRF error would cause), frozen after
the first iteration so that residuals of different models compare; the step is damped (Tikhonov on the normalised step, not on the
departure from the start) and clipped to the bounds; there is no line search and no whitening of the
condensed residual.  Both read the data through :mod:`updating.correlation.receptance`.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from updating.correlation.condensation import condensed_residual
from updating.fe import ParametricFEModel
from updating.methods.iteration import Proposal, iterate

__all__ = ["ResidualSystem", "residual_system", "mci_update", "derivatives"]


def _factor(matrix: str, s: np.ndarray) -> np.ndarray:
    return {"K": np.ones_like(s), "M": s ** 2, "C": s, "D": 1j * np.ones_like(s)}[matrix]


def _column(T, x_full, A, factor, w):
    """−Tᵀ (A·factor) x, weighted, stacked real/imag, for a sparse A (or a diagnosis library's
    :class:`~updating.diagnosis.local_matrix.LocalMatrix`: its block, without an n × n matrix)."""
    n, nq, ns = x_full.shape
    if hasattr(A, "block") and hasattr(A, "rows"):
        rows = A.rows
        if rows.size == 0:
            return None
        v = (A.block @ x_full[rows].reshape(rows.size, -1)).reshape(rows.size, nq, ns) * factor[None, None, :]
    else:
        A = A.tocsr()
        rows = np.unique(A.nonzero()[0])
        if rows.size == 0:
            return None
        v = (A[rows] @ x_full.reshape(n, -1)).reshape(rows.size, nq, ns) * factor[None, None, :]
    if rows.size <= 4:
        c = -np.einsum("smf,sqf->mqf", T[rows], v)
    else:   # one BLAS product per line
        c = -np.matmul(T[rows].transpose(2, 1, 0), v.transpose(2, 0, 1)).transpose(1, 2, 0)
    c = c * w[None]
    return np.concatenate([c.real.ravel(), c.imag.ravel()])


def _stack(r, w):
    y = r * w[None]
    return np.concatenate([y.real.ravel(), y.imag.ravel()])


@dataclass
class ResidualSystem:
    """The weighted, stacked condensed residual ``y`` of a model against data, and what builds its columns."""

    y: np.ndarray
    x_full: np.ndarray
    T: np.ndarray
    w: np.ndarray
    s: np.ndarray
    shape: tuple

    def column(self, A, matrix: str):
        return _column(self.T, self.x_full, A, _factor(matrix, self.s), self.w)

    def derivative_columns(self, derivs) -> np.ndarray:
        cols = []
        for d in derivs:
            parts = [c for c in (self.column(A, k) if A is not None else None
                                 for A, k in ((d.dK, "K"), (d.dM, "M"), (d.dC, "C"), (d.dD, "D"))) if c is not None]
            cols.append(np.sum(parts, axis=0) if parts else np.zeros_like(self.y))
        return np.array(cols).T if cols else np.zeros((self.y.size, 0))


def residual_system(structure, data, weights=None) -> ResidualSystem:
    """Condensed residual of ``structure`` against FRF ``data`` (see :func:`condensed_residual`), weighted.

    ``weights`` (n_r, n_s) fixes the line weights (so that residuals of different models compare); by
    default they are √coherence / σ of this model.
    """
    cols = data.on_model(structure.dofs)
    if data.homogeneous:
        # mode shapes: one vector per "line" (mode), no force (the homogeneous residual Z(iω_j) φ_j)
        F = np.zeros((structure.n_dof, data.H.shape[1]))
    else:
        F = cols.force
    x_full, r, T, sigma = condensed_residual(structure.K, structure.M, structure.C, structure.D, data.s,
                                             cols.measured, cols.theta, F)
    if weights is None:
        coh = np.sqrt(np.mean(data.quality ** 2, axis=0))
        weights = coh / (sigma + 1e-12 * np.max(sigma))
    return ResidualSystem(_stack(r, weights), x_full, T, weights, data.s, r.shape)


_DERIV_CACHE: weakref.WeakKeyDictionary | None = None
_LINEAR_FIELDS = ("E", "rho", "k", "c", "mass", "inertia", "nsm")
#: fields that multiply a linear field's matrices in C or D (C = αM + βK + dampers, D = Σ ge_e K_e + G·K): the
#: derivatives of the linear parameters are affine in their values
_AFFINE_FIELDS = ("ge", "global_ge", "rayleigh_alpha", "rayleigh_beta")


def _split(pmodel) -> tuple[np.ndarray, np.ndarray]:
    """``(lin, aff)`` masks over ``pmodel.parameters``: the parameters whose matrix derivatives do not depend on p
    apart from the damping values (a linear field that no other parameter of the same field also scales: a
    material's E and one property's E on the same elements multiply, and each one's derivative holds the other's
    value), and the damping values those derivatives are affine in."""
    pars = pmodel.parameters
    els = [getattr(pmodel, "_targets", [(None, None)] * len(pars))[i][1] for i in range(len(pars))]
    sets = [None if e is None else {int(getattr(x, "eid", x)) for x in e} for e in els]
    lin = np.array([par.field in _LINEAR_FIELDS for par in pars])
    for i in np.flatnonzero(lin):
        for j in np.flatnonzero(lin):
            if i < j and pars[i].field == pars[j].field and (sets[i] is None or sets[j] is None or sets[i] & sets[j]):
                lin[i] = lin[j] = False
    aff = np.array([par.field in _AFFINE_FIELDS for par in pars])
    return lin, aff


_MATS = ("dK", "dM", "dC", "dD")


def _add(A, dA, a):
    """``A + a·dA`` of two sparse matrices or None (None where zero)."""
    if dA is None:
        return A
    return dA * a if A is None else A + dA * a


class _AffineDerivatives:
    """The derivatives of the linear parameters as ``d(a) = d0 + Σ_j a_j Δd_j`` in the damping values ``a``
    (:data:`_AFFINE_FIELDS`), from ``1 + n_a`` complex-step evaluations (the damping values at 0 and at each unit
    vector, the linear parameters at their nominal values) and checked against a direct evaluation at the first ``p``: exact where the assembly is as
    :mod:`updating.fe.assembly` states, and refused (``ok`` False) where it is not."""

    def __init__(self, pmodel, p, lin, aff, direct):
        self.lin, self.aff = np.flatnonzero(lin), np.flatnonzero(aff)
        # the base and the steps at the damping values 0 and the linear parameters' nominal values: to the bit,
        # complex-step derivatives depend on the values they are taken at, and the form must not depend on the p
        # of its first call (derivatives())
        q = p.copy()
        q[self.lin] = np.asarray(getattr(pmodel, "nominal", p), float)[self.lin]
        q[self.aff] = 0.0
        base = direct if np.array_equal(q, p) else pmodel.derivatives(q)
        self.d0 = {i: base[i] for i in self.lin}
        self.delta = []
        for j in self.aff:
            q1 = q.copy()
            q1[j] = 1.0
            dj = pmodel.derivatives(q1)
            self.delta.append({i: (_diff(dj[i].dC, base[i].dC), _diff(dj[i].dD, base[i].dD)) for i in self.lin})
        self.ok = all(_close(self.at(p)[i], direct[i]) for i in self.lin)

    def at(self, p) -> dict:
        out = {}
        for i in self.lin:
            d = self.d0[i]
            C, D = d.dC, d.dD
            for a, delta in zip(p[self.aff], self.delta):
                if a != 0.0:
                    C, D = (_add(A, dA, a) for A, dA in zip((C, D), delta[i]))
            out[i] = type(d)(dK=d.dK, dM=d.dM, dC=C, dD=D)
        return out


class _AffineDampingDerivatives:
    """The derivatives of the damping values (:data:`_AFFINE_FIELDS`: ∂C/∂α = M, ∂C/∂β = K, ∂D/∂g = K, ∂D/∂g_e =
    K_e) as ``d(p) = d0 + Σ_j (p_j − q_j)/h_j Δd_j`` in the linear parameters, the fields of the matrices they are
    derivatives of (:func:`_split`; they do not depend on the damping values), from ``1 + n_lin`` evaluations at
    ``q`` (the linear parameters' nominal values, the damping values 0) and at one step ``h_j`` in each, and
    checked against the direct evaluation at the first ``p``: refused (``ok`` False) where they differ.  Spares
    the assembly of these derivatives at every step of a fit (the loss factors are parameters of every fit)."""

    def __init__(self, pmodel, p, lin, aff, direct):
        self.lin, self.aff = np.flatnonzero(lin), np.flatnonzero(aff)
        idx = set(int(i) for i in self.aff)
        q = p.copy()
        q[self.lin] = np.asarray(getattr(pmodel, "nominal", p), float)[self.lin]
        q[self.aff] = 0.0
        self.q, self.h = q, np.maximum(1.0, np.abs(q[self.lin]))
        self.d0 = _only(pmodel, q, idx)
        self.delta = []
        for j, h in zip(self.lin, self.h):
            q1 = q.copy()
            q1[j] += h
            self.delta.append([[_diff(getattr(a, k), getattr(b, k)) for k in _MATS]
                               for a, b in zip(_only(pmodel, q1, idx), self.d0)])
        self.ok = all(_close(a, direct[i]) for a, i in zip(self.at(p), self.aff))

    def at(self, p) -> list:
        """The derivatives of the damping values at ``p``, in the order of their indices."""
        out = []
        for n, d in enumerate(self.d0):
            mats = [getattr(d, k) for k in _MATS]
            for j, h, delta in zip(self.lin, self.h, self.delta):
                a = (p[j] - self.q[j]) / h
                if a != 0.0:
                    mats = [_add(A, dA, a) for A, dA in zip(mats, delta[n])]
            out.append(type(d)(**dict(zip(_MATS, mats))))
        return out


def _only(pmodel, p, idx: set) -> list:
    """The derivatives of the parameters ``idx`` at ``p`` (in their order), the others not assembled."""
    ds = pmodel.derivatives(p, only=idx) if isinstance(pmodel, ParametricFEModel) else pmodel.derivatives(p)
    return [ds[i] for i in sorted(idx)]


def _diff(A, B):
    """``A − B`` of two sparse matrices or None (None where zero)."""
    if A is None and B is None:
        return None
    out = sp.csr_matrix(A if B is None else (-B if A is None else A - B))
    out.eliminate_zeros()
    return out if out.nnz else None


def _close(a, b) -> bool:
    """Two :class:`~updating.fe.parametric.Derivative` equal to round-off.  ``dD`` is compared on the scale of
    ``dK`` as well as its own: ``Z = K + iD``, and a derivative of D that is zero in one form is round-off in the
    other where loss factors cancel (a section's loss factor given in all, ``ge = η − G``: its ∂D/∂E is
    ``(G + η − G) K_e``, 0 at η = 0 exactly in the form and ~1e-16·G·K_e assembled — tuning case 2160: 184 of
    578 calls assembled directly because a zero was compared with round-off on its own scale)."""
    def mag(A):
        return 0.0 if A is None else float(abs(A).max())

    k_scale = max(mag(a.dK), mag(b.dK))
    for key in ("dK", "dM", "dC", "dD"):
        x, y = getattr(a, key), getattr(b, key)
        if x is None and y is None:
            continue
        x = sp.csr_matrix(y.shape) if x is None else x
        y = sp.csr_matrix(x.shape) if y is None else y
        scale = max(mag(x), mag(y), k_scale if key == "dD" else 0.0, 1e-300)
        if abs(x - y).max() > 1e-9 * scale:
            return False
    return True


def derivatives(pmodel, p):
    """``pmodel.derivatives(p)``, cached per model when its parameters enter the matrices linearly.

    For fields that scale an element or material matrix (E, ρ, k, c, mass, inertia, nsm; :func:`_split`) the
    derivative depends on p only through the model-wide and element damping values (PARAM G, GE, Rayleigh) that
    multiply K or M, and affinely (:class:`_AffineDerivatives`); the damping values' own derivatives are affine
    in the linear parameters (:class:`_AffineDampingDerivatives`).  Both forms are built once per model, at its
    first call, from the linear parameters' nominal values and the damping values 0, and checked against the
    direct evaluation there.  Saves the complex-step re-assembly (one model per parameter) in iterated MCI
    updates and in the FRF fits of the diagnosis, whose loss factors move at every step.  The first call returns
    the affine form too, not the direct evaluation it was checked against (equal to round-off): the result at
    ``p`` is then the same whatever the model was evaluated at before, so that a fit does not depend on the
    history of its model object (a copy of it in another process fits the same, :mod:`modalab.core.parallel`).

    A model with a non-linear parameter (a thickness, a section dimension, ν, or two parameters scaling the same
    elements' field) is evaluated directly at every call: the forms would depend on that parameter's value, which
    a fit moves at every step, and building them costs ``2 + n_a`` evaluations of every derivative where the
    direct one costs one (the quick demo's diagnosis: 5 500 evaluations for 583 calls, 431 of them at a new
    thickness).
    """
    global _DERIV_CACHE
    if _DERIV_CACHE is None:
        _DERIV_CACHE = weakref.WeakKeyDictionary()
    pars = getattr(pmodel, "parameters", None)
    if pars is None:
        return pmodel.derivatives(p)
    p = np.asarray(p, float)
    lin, aff = _split(pmodel)
    if (~lin & ~aff).any() or not lin.any():
        return pmodel.derivatives(p)
    try:
        form = _DERIV_CACHE.get(pmodel)
    except TypeError:  # pragma: no cover - not weak-referenceable
        return pmodel.derivatives(p)
    if form is None:
        direct = pmodel.derivatives(p)
        form = _AffineDerivatives(pmodel, p, lin, aff, direct)
        if form.ok:
            damping = _AffineDampingDerivatives(pmodel, p, lin, aff, direct) if aff.any() else None
            form.damping = damping if damping is not None and damping.ok else None
        _DERIV_CACHE[pmodel] = form
        if not form.ok:
            # not affine as assembled: this model is evaluated directly from now on
            return list(direct)
    if not form.ok:
        return pmodel.derivatives(p)
    out = [None] * len(pars)
    for i, d in form.at(p).items():
        out[i] = d
    if form.damping is not None:
        for i, d in zip(form.damping.aff, form.damping.at(p)):
            out[i] = d
    elif aff.any():
        # the damping values' derivatives (e.g. PARAM G: ∂D/∂g = K(p)) depend on the linear parameters
        for i, d in zip(np.flatnonzero(aff), _only(pmodel, p, set(int(i) for i in np.flatnonzero(aff)))):
            out[i] = d
    return out


def _solve_ls(B, y, reg):
    """Least squares with normalised columns and a Tikhonov term by the normal equations (small n_col)."""
    nrm = np.maximum(np.linalg.norm(B, axis=0), 1e-300)
    Bn = B / nrm
    N = Bn.T @ Bn + reg * np.eye(B.shape[1])
    dz = np.linalg.solve(N, Bn.T @ y)
    return dz / nrm


def mci_update(pmodel, p, data, lower, upper, *, iters: int = 6, weights=None, tol: float = 1e-3,
               reg: float = 1e-6, free=None):
    """Parameter estimation by minimising the MCI (thesis section 3.2.4): iterate expansion and solution.

    Each iteration expands the measured responses with the current model, solves the weighted linear
    least-squares problem ``r ≈ −Σ Δp_q Tᵀ ∂Z/∂p_q x`` (exact in Δp for parameters that enter the matrices
    linearly), clips the step to the bounds and repeats until the step is below ``tol`` (relative).
    A small Tikhonov term ``reg`` keeps unidentifiable parameters in place (the trivial-solution guard of
    thesis 6.1.2).  Returns the parameters, the final weighted residual norm² and the line weights.
    """
    p = np.asarray(p, float).copy()
    lo, hi = (np.broadcast_to(np.asarray(b, float), p.shape) for b in (lower, upper))
    free = np.ones(p.size, bool) if free is None else np.asarray(free, bool)
    frozen = {"w": weights}

    def propose(p):
        rsys = residual_system(pmodel.structure(p), data, frozen["w"])
        if frozen["w"] is None:
            frozen["w"] = rsys.w
        B = rsys.derivative_columns([d for d, f in zip(derivatives(pmodel, p), free) if f])
        dp = np.zeros(p.size)
        dp[free] = _solve_ls(B, rsys.y, reg)
        return Proposal(dp, float(rsys.y @ rsys.y))

    # every parameter is clipped (the fixed ones too) and the change is relative to the current value
    p = iterate(propose, p, np.arange(p.size), lo, hi, max_iter=iters, tol=tol,
                change_ref=lambda p, p_new: np.maximum(np.abs(p), 1e-12), label="diagnosis MCI").p
    weights = frozen["w"]
    rsys = residual_system(pmodel.structure(p), data, weights)
    return p, float(rsys.y @ rsys.y), weights
