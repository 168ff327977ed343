"""The modal residual of the modes-only diagnosis (:mod:`~updating.diagnosis.modes`): eigenvalue and shape
residuals of a structure against test modes, the pairing of model and test modes, the frequency precision."""
from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla
import scipy.optimize as so
import scipy.sparse as sp

from modalab.core.dense import use_dense
from modalab.core.errors import ModalabValueError
from modalab.core.modes import ModeSet

from modalab.core.dof import locate
from updating.correlation.condensation import condensed_residual
from updating.correlation.metrics import mac as mac_matrix, pair_modes
from updating.diagnosis.fit import FitResult, FRFData
from updating.diagnosis.subspace import ModalSubspace
from updating.fe.solvers import eigen_dense, eigen_sparse, massless_mechanisms

log = logging.getLogger(__name__)
__all__ = ["ModalResidual", "paired_test_modes", "mode_errors", "fit_modes", "modal_force_map"]


def _exact_modes(K, M, k):
    """The lowest ``k`` modes (ω, mass-normalised Φ) with massless DOFs and massless mechanisms handled
    (:mod:`updating.fe.solvers`); dense for small models, shift-invert Lanczos above
    :data:`modalab.core.dense.MODES_LIMIT`."""
    n = K.shape[0]
    if use_dense(n, "modes"):
        return eigen_dense(K, M, min(k, n))
    return eigen_sparse(K, M, min(k, n - 2))


#: a model mode whose measured part is below this fraction of the best observed mode's is unobservable
UNOBSERVABLE = 1e-6
#: model modes beyond the test modes' count that pairing may choose from
EXTRA_MODES = 12
#: ... and at least every model mode up to this factor times the highest test frequency (modes of other
#: planes, unobservable or rigid, interleave with the observed ones)
PAIR_FACTOR = 1.5


def _observed(Vm):
    """Norm of each model mode on the measured DOFs, and whether the sensors see it at all (a mode below
    :data:`UNOBSERVABLE` of the largest has a MAC made of round-off and is never paired)."""
    nrm = np.linalg.norm(Vm, axis=0)
    return nrm, nrm > UNOBSERVABLE * max(nrm.max(initial=0.0), 1e-300)


class ModalResidual:
    """Eigenvalue and shape residuals of a structure against test modes (the modes-only objective).

    ``e = [(f_j − f_test,j)/(σ_f f_test,j) ; (a_j φ_j − φ_test,j)/σ_φ]`` over the test modes ``keep``, each
    paired with the model mode of largest MAC (a model mode used once; clearest test modes first; model
    modes the measured DOFs cannot see are never paired), shapes unit-norm on the measured DOFs and ``a_j``
    the least-squares scale.  Shape residuals in displacement space weigh measurement noise as it is (a
    relative scatter of ``σ_φ``), where the force residual ``Z φ`` amplifies it by the stiffness; ``σ_f`` is
    the frequency precision.  Without shapes (frequency-only data) the model's elastic modes are paired
    by frequency (an assignment on ``|ln f/f_test|``, which keeps their order) and only frequencies enter.

    Modes come from :func:`updating.fe.solvers.eigen_dense` / ``eigen_sparse`` (massless DOFs and
    mechanisms handled), or from a :class:`ModalSubspace` when one is given.
    """

    def __init__(self, test_modes: ModeSet, keep=None, *, sigma_f: float = 0.005, sigma_phi: float = 0.02):
        idx = np.arange(test_modes.n_modes) if keep is None else np.asarray(keep, int)
        phi = np.asarray(test_modes.shapes).reshape(len(test_modes.dofs), test_modes.n_modes)[:, idx]
        phi = np.real(phi) if np.iscomplexobj(phi) else phi
        self.phi = phi / np.maximum(np.linalg.norm(phi, axis=0), 1e-300)
        self.f = np.asarray(test_modes.freq_hz, float)[idx]
        self.dofs = list(test_modes.dofs)
        sf, sphi = np.asarray(sigma_f, float), np.asarray(sigma_phi, float)     # one value, or one per test mode
        self.sigma_f = float(sf) if sf.ndim == 0 else sf[idx]
        self.sigma_phi = float(sphi) if sphi.ndim == 0 else sphi[idx]
        self._loc = None

    @property
    def has_shapes(self) -> bool:
        return self.phi.shape[0] > 0

    @property
    def n_eq(self) -> int:
        return int(self.f.size * (1 + self.phi.shape[0]))

    @property
    def n_model_modes(self) -> int:
        return self.f.size + EXTRA_MODES

    def rows(self, structure):
        if self._loc is None or self._loc[0] is not structure.dofs:
            if self.dofs:
                mi, ms = locate(structure.dofs, self.dofs, "test-mode DOF")
            else:
                mi, ms = [], []
            self._loc = (structure.dofs, np.asarray(mi, int), np.asarray(ms, float))
        return self._loc[1], self._loc[2]

    def model_modes(self, structure, K=None, M=None, basis: ModalSubspace | None = None):
        """Model frequencies (Hz) and shapes on the measured DOFs (n_m, n_modes), mass-normalised."""
        K = structure.K if K is None else K
        M = structure.M if M is None else M
        mi, ms = self.rows(structure)
        if basis is not None and basis.matches(structure):
            return self.projected_modes(structure, basis, *basis.project(sp.csr_matrix(K), sp.csr_matrix(M)))
        Ks, Ms = sp.csr_matrix(K), sp.csr_matrix(M)
        k = self.n_model_modes
        while True:                    # every model mode up to PAIR_FACTOR × the highest test frequency
            w, V = _exact_modes(Ks, Ms, k)
            if w.size < k or w[-1] / (2 * np.pi) > PAIR_FACTOR * self.f.max() or k >= Ks.shape[0] - 2:
                break
            k = min(2 * k, Ks.shape[0] - 2)
        return w / (2 * np.pi), V[mi] * ms[:, None]

    def projected_modes(self, structure, basis, Kr, Mr):
        """Model frequencies (Hz) and measured shapes from the subspace matrices ``Kr = VᵀKV``, ``Mr = VᵀMV``
        of ``basis`` (the Ritz values and vectors)."""
        mi, ms = self.rows(structure)
        w2, Psi = sla.eigh(Kr, Mr)
        k = self.n_pairable(np.sqrt(np.clip(w2, 0, None)) / (2 * np.pi))
        Vm = (basis.rows_of(mi) * ms[:, None]) @ Psi[:, :k]
        return np.sqrt(np.clip(w2[:k], 0, None)) / (2 * np.pi), Vm

    def n_pairable(self, fm) -> int:
        """How many of the ascending model frequencies ``fm`` pairing may choose from: every mode up to
        ``PAIR_FACTOR`` × the highest test frequency, and at least ``n_model_modes``."""
        return int(min(fm.size, max(self.n_model_modes, np.searchsorted(fm, PAIR_FACTOR * self.f.max(), "right"))))

    def pairs(self, fm, Vm):
        """``(a, mac)``: the model mode paired with each test mode and the MAC (NaN without shapes)."""
        nt = self.f.size
        if not self.has_shapes:
            el = np.flatnonzero(fm > 1e-3)
            if el.size < nt:
                raise ModalabValueError(f"the model has {el.size} elastic modes among its lowest {fm.size}; "
                                        f"{nt} test frequencies cannot be paired")
            cost = np.abs(np.log(fm[el][:, None] / self.f[None, :]))
            r, c = so.linear_sum_assignment(cost)
            a = np.empty(nt, int)
            a[c] = el[r]
            return a, np.full(nt, np.nan)
        nrm, seen = _observed(Vm)
        U = Vm / np.maximum(nrm, 1e-300)
        mac = (U.T @ self.phi) ** 2                                           # (model, test)
        # the cost of modalab's one pairing rule (updating.correlation.metrics.pair_modes): (1 − MAC) plus the
        # relative frequency distance, one-to-one by the Hungarian algorithm (deterministic); a mode the
        # sensors cannot see is never paired.  Greedy MAC alone paired an exact model's 37.5 Hz test mode
        # with a model mode far away and moved its parameters by 3-4 %.
        cost = (1.0 - mac) + np.abs(fm[:, None] - self.f[None, :]) / self.f[None, :]
        cost[~seen] = 1e6
        r, c = so.linear_sum_assignment(cost)
        a = np.empty(nt, int)
        a[c] = r
        return a, np.clip(np.einsum("ij,ij->j", U[:, a], self.phi) ** 2, 0.0, 1.0)

    def residual(self, fm, Vm) -> np.ndarray:
        a, _ = self.pairs(fm, Vm)
        ef = (fm[a] - self.f) / (self.sigma_f * self.f)
        if not self.has_shapes:
            return ef
        nrm = np.maximum(np.linalg.norm(Vm[:, a], axis=0), 1e-300)
        V = Vm[:, a] / nrm
        proj = np.einsum("ij,ij->j", V, self.phi)
        es = (V * proj[None, :] - self.phi) / self.sigma_phi
        return np.concatenate([ef, es.ravel()])

    def __call__(self, structure, K=None, M=None, basis: ModalSubspace | None = None) -> np.ndarray:
        return self.residual(*self.model_modes(structure, K, M, basis))


#: relative frequency precision without identified standard deviations (a UFF 55 carries none)
SIGMA_F_DEFAULT = 0.005
#: the smallest relative frequency precision used: an FE model's frequencies are not better than about 0.1 %
#: (mesh, mass lumping), so an identified standard deviation of 1e-5 must not make such a difference significant
SIGMA_F_FLOOR = 1e-3


def _sigma_f(test_modes: ModeSet, sigma_f):
    """The relative frequency precision per test mode (see :func:`diagnose_modes`)."""
    if sigma_f is not None:
        return sigma_f
    std = (test_modes.indicators or {}).get("freq_std_hz")
    if std is None:
        return SIGMA_F_DEFAULT
    rel = np.asarray(std, float).ravel() / np.asarray(test_modes.freq_hz, float)
    if rel.size != test_modes.n_modes or not np.all(np.isfinite(rel) & (rel > 0)):
        log.info("modes: the test modes' freq_std_hz are incomplete; relative frequency sigma %g", SIGMA_F_DEFAULT)
        return SIGMA_F_DEFAULT
    return np.maximum(rel, SIGMA_F_FLOOR)


def paired_test_modes(structure, test_modes: ModeSet):
    """The test modes that pair with a mode of ``structure`` by modalab's one pairing rule
    (:func:`updating.correlation.metrics.pair_modes`: MAC and frequency, modes the sensors cannot see and
    rigid-body modes excluded, a test mode that is a merge of close model modes left out; no frequency window,
    since the physics sought may move a mode far), as ``(indices, {left-out index: reason})``.  The modes-only objective is defined on these modes
    only: a test mode without a counterpart in the nominal model would otherwise pull the parameters
    towards a wrong partner."""
    r = ModalResidual(test_modes)
    fm, Vm = r.model_modes(structure)
    if not r.has_shapes:
        pr = pair_modes(None, fm, r.f, log_unpaired=False)        # the caller says each left-out mode
    else:
        _, seen = _observed(Vm)
        # no frequency window: missing physics may move a mode far (a spring to ground gives a free bar a
        # mode of its own); what must stay out are modes the sensors cannot see and merges of close modes
        pr = pair_modes(mac_matrix(Vm, r.phi), fm, r.f, observability=seen.astype(float), max_freq_error=None,
                        mode_shapes=(Vm, r.phi), log_unpaired=False)
    usable = np.array(sorted(int(x) for _, x in pr.pairs), int)
    left = {int(j): pr.unpaired_reason.get(int(j), "no mode of the nominal model pairs with it")
            for j in range(test_modes.n_modes) if int(j) not in set(usable.tolist())}
    return usable, left


def mode_errors(structure, test_modes: ModeSet, keep=None):
    """Relative frequency errors and MACs (NaN without shapes) of the test modes ``keep``, paired with the
    model's modes as in :class:`ModalResidual`."""
    r = ModalResidual(test_modes, keep)
    fm, Vm = r.model_modes(structure)
    a, mac = r.pairs(fm, Vm)
    return (fm[a] - r.f) / r.f, mac


def fit_modes(pmodel, test_modes: ModeSet, p_start, *, lower, upper, keep=None, w_mac: float = 0.3,
              reg: float = 1e-3, max_nfev: int = 60) -> FitResult:
    """Bounded least squares of eigenvalue and MAC residuals (finite-difference Jacobian).

    A weak pull ``reg`` towards the start keeps the unidentifiable common scale of stiffness and mass put.
    A failing eigen-solution fails the fit (it is never turned into a residual).
    """
    p0 = np.asarray(p_start, float)
    scale = np.where(np.isfinite(upper) & (np.abs(p0) > 0), np.abs(p0), np.maximum(np.abs(p0), 1.0))

    def fun(x):
        p = x * scale
        df, mac = mode_errors(pmodel.structure(p), test_modes, keep)
        mac = np.nan_to_num(mac, nan=1.0)
        return np.concatenate([df, w_mac * (1 - mac), reg * (x - p0 / scale)])

    lo, hi = np.asarray(lower, float) / scale, np.asarray(upper, float) / scale
    x0 = np.clip(p0 / scale, lo, hi)
    sol = so.least_squares(fun, x0, bounds=(lo, hi), max_nfev=max_nfev, diff_step=1e-4, method="trf")
    p = sol.x * scale
    J = sol.jac
    s2 = float(sol.fun @ sol.fun) / max(sol.fun.size - p.size, 1)
    std = np.sqrt(np.clip(np.diag(np.linalg.pinv(J.T @ J)) * s2, 0, None)) * scale
    df, _ = mode_errors(pmodel.structure(p), test_modes, keep)
    return FitResult(p, std, float(np.sqrt(np.mean(df ** 2))), [], bool(sol.success), str(sol.message))


def modal_force_map(structure, data: FRFData) -> np.ndarray:
    """|r| / σ per measured DOF and mode of the homogeneous condensed residual ``[Z(iω_j) x_j]_m`` (the
    modal force residual: thesis eq. 3.89 with f = 0, unmeasured DOFs expanded by the model), (n_m, n_modes).
    A massless mechanism (``K n = M n = 0``) is constrained at one DOF first, exactly as in the eigen-solvers:
    otherwise the expansion ``Z_ss`` is singular at every frequency."""

    mi, ms = locate(structure.dofs, data.responses, "test-mode DOF")
    K, M = sp.csr_matrix(structure.K), sp.csr_matrix(structure.M)
    C = None if structure.C is None else sp.csr_matrix(structure.C)
    D = None if structure.D is None else sp.csr_matrix(structure.D)
    fix, _ = massless_mechanisms(K, M)
    mi = np.asarray(mi, int)
    if fix.size:
        if np.isin(mi, fix).any():
            fix = np.setdiff1d(fix, mi)        # a measured DOF on a mechanism keeps its value (rare)
        keep = np.setdiff1d(np.arange(K.shape[0]), fix)
        pos = np.full(K.shape[0], -1)
        pos[keep] = np.arange(keep.size)
        K, M = K[keep][:, keep], M[keep][:, keep]
        C = None if C is None else C[keep][:, keep]
        D = None if D is None else D[keep][:, keep]
        mi = pos[mi]
    x = data.H * np.asarray(ms, float)[:, None, None]
    F = np.zeros((K.shape[0], 1))
    _, r, _, sigma = condensed_residual(K, M, C, D, data.s, mi, x, F)
    return np.abs(r[:, 0, :]) / (sigma[0][None, :] + 1e-300)
