"""The modes-only diagnosis' fit (:mod:`~updating.diagnosis.modes`): bounded least squares of the modal residual
(:class:`~updating.diagnosis.modal_residual.ModalResidual`) over a parametric model's parameters, exactly for
small models and in a :class:`~updating.diagnosis.subspace.ModalSubspace` above :data:`SUBSPACE_ABOVE` DOFs.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.optimize as so
import scipy.sparse as sp

from modalab.core.dof import parse_dofs
from updating.diagnosis.fit import parameter_std
from updating.diagnosis.modal_residual import ModalResidual
from updating.diagnosis.subspace import ModalSubspace

log = logging.getLogger(__name__)
__all__ = ["fit_modal_residual", "SUBSPACE_ABOVE", "LINEAR_FIELDS"]


#: models above this many DOFs are evaluated in a Ritz subspace of their lowest modes (exactly below)
SUBSPACE_ABOVE = 600


#: parameter fields that enter K and M linearly (as a factor or a value: E, ρ, spring stiffness, masses,
#: inertias, non-structural mass); a fit over such parameters only is evaluated from projected derivatives
LINEAR_FIELDS = ("E", "rho", "k", "mass", "inertia", "nsm")


class _ProjectedModel:
    """``VᵀK(p)V``, ``VᵀM(p)V`` of a parametric model whose parameters all enter K and M linearly, from the
    projections at ``p0`` and of the exact derivatives: ``VᵀK(p)V = VᵀK(p₀)V + Σ (p_i − p₀_i) Vᵀ∂K/∂p_i V``.
    No assembly and no product with an n-size matrix per evaluation (at 100k DOFs each was seconds)."""

    def __init__(self, pmodel, basis: ModalSubspace, p0):
        self.p0 = np.asarray(p0, float)
        self.structure = st = pmodel.structure(self.p0)
        self.basis = basis
        self.Kr, self.Mr = basis.project(sp.csr_matrix(st.K), sp.csr_matrix(st.M))
        zero = sp.csr_matrix((st.n_dof, st.n_dof))
        self.dKr, self.dMr = [], []
        for d in pmodel.derivatives(self.p0):
            dK, dM = basis.project(zero if d.dK is None else sp.csr_matrix(d.dK),
                                   zero if d.dM is None else sp.csr_matrix(d.dM))
            self.dKr.append(dK)
            self.dMr.append(dM)

    @staticmethod
    def applies(pmodel) -> bool:
        pars = getattr(pmodel, "parameters", None)
        return bool(pars) and all(getattr(par, "field", None) in LINEAR_FIELDS for par in pars)

    def residual(self, resid: ModalResidual, p) -> np.ndarray:
        dp = np.asarray(p, float) - self.p0
        Kr = self.Kr + sum(x * A for x, A in zip(dp, self.dKr) if x != 0)
        Mr = self.Mr + sum(x * A for x, A in zip(dp, self.dMr) if x != 0)
        return resid.residual(*resid.projected_modes(self.structure, self.basis, Kr, Mr))


def fit_modal_residual(pmodel, resid: ModalResidual, p_start, *, lower, upper, reg: float = 1e-2,
                       max_nfev: int = 60, free=None, cols=(), basis: ModalSubspace | None = None,
                       max_rebuild: int = 2):
    """Bounded least squares of the modal residual (finite-difference Jacobian) over the ``free``
    parameters, with a weak pull ``reg`` towards the start (the common scale of stiffness and mass is not
    observable without a force).  Returns ``(p, std, rss)`` (rss without the pull, from an exact
    eigen-solution).

    Models above ``SUBSPACE_ABOVE`` DOFs are fitted in a :class:`ModalSubspace` (built at the start with
    static corrections at the measured DOFs and the DOF labels ``cols``, or ``basis``); the result is checked
    against the exact modes and the fit repeated in a basis rebuilt there when the two residuals differ by
    more than 2 % (at most ``max_rebuild`` times).  When every parameter enters K and M linearly
    (:data:`LINEAR_FIELDS`) the subspace matrices come from projected derivatives (:class:`_ProjectedModel`).
    """
    p_all = np.asarray(p_start, float)
    free = np.ones(p_all.size, bool) if free is None else np.asarray(free, bool)
    lower = np.asarray(lower, float)[free]
    upper = np.asarray(upper, float)[free]
    big = pmodel.structure(p_all).n_dof > SUBSPACE_ABOVE
    for attempt in range(max_rebuild + 1):
        p0 = p_all[free]
        scale = np.where(np.abs(p0) > 0, np.maximum(np.abs(p0), 1e-12), 1.0)
        if big and (basis is None or attempt > 0):
            st0 = pmodel.structure(p_all)
            where = {(d.node, d.axis): i for i, d in enumerate(st0.dofs)}
            extra = [where[(d.node, d.axis)] for d in parse_dofs(list(cols)) if (d.node, d.axis) in where]
            basis = ModalSubspace(st0, np.concatenate([resid.rows(st0)[0], np.asarray(extra, int)]),
                                  float(resid.f.max()), resid.n_model_modes)

        def full(x, p0=p0, scale=scale):
            p = p_all.copy()
            p[free] = x * scale
            return p

        proj = _ProjectedModel(pmodel, basis, p_all) if big and _ProjectedModel.applies(pmodel) else None

        def fun(x, p0=p0, scale=scale, proj=proj, basis=basis):
            if proj is not None:
                e = proj.residual(resid, full(x))
            else:
                e = resid(pmodel.structure(full(x)), basis=basis if big else None)
            return np.concatenate([e, reg * (x - p0 / scale) * np.sqrt(e.size)])

        lo, hi = lower / scale, upper / scale
        x0 = np.clip(p0 / scale, lo, hi)
        sol = so.least_squares(fun, x0, bounds=(lo, hi), max_nfev=max_nfev, diff_step=1e-4, method="trf")
        p = full(sol.x)
        e = resid(pmodel.structure(p))                      # exact modes
        rss = float(e @ e)
        if not big:
            break
        e_sub = sol.fun[:e.size]
        rss_sub = float(e_sub @ e_sub)
        if abs(rss - rss_sub) <= 0.02 * rss + 1e-9 * resid.n_eq:
            break
        log.info("modes: subspace residual %.4g, exact %.4g: basis rebuilt at the new parameters", rss_sub, rss)
        p_all = p
    std = np.zeros(p.size)
    J = sol.jac[:e.size]
    s2 = rss / max(e.size - int(free.sum()), 1)
    std[free] = parameter_std(J, s2) * scale              # inf where the modes do not determine a parameter
    return p, std, rss
