"""Missing-physics diagnosis from identified modes alone (no FRFs: a GVT deliverable).

:func:`diagnose_modes` judges a model against test modes (natural frequencies f_j, real shapes φ_j on the
measured DOFs, or frequencies alone) by the residual of :class:`ModalResidual`

    e = [(f_model,j − f_j)/(σ_f f_j) ;  (a_j φ_model,j − φ_j)/σ_φ]

(modes paired by MAC — model modes the sensors cannot see are never paired — or, without shapes, by
frequency order; shapes unit-norm, ``a_j`` the least-squares scale; σ_f = 0.5 %, σ_φ = 2 % by default): the
eigenvalue residual and the shape residual *in displacement space*.  The homogeneous force residual
``Z(iω_j) φ_j`` (thesis section 3.2.4 with f = 0, the eigen-equation form of eq. 3.89; :func:`modes_data`
still provides it) multiplies the shape scatter by the stiffness and lost the concealed effects at 1 %
scatter; the displacement residual keeps them at 2 %.

Eigen-solutions come from :mod:`updating.fe.solvers`, which handle massless DOFs (Nastran's default lumped
mass) and massless mechanisms exactly; a failing eigen-solution is an error, never a residual.

1. parameter-only updating on ``e`` (a weak pull to the nominal values: without a force the common
   scale of stiffness and mass is not observable) — the baseline;
2. every grounded-spring and added-mass candidate on an independent DOF is added alone at its best value
   on a plausible grid (:func:`screen_modes`), around the updated and the nominal parameters: a low-rank
   update ``θ L Lᵀ`` in the subspace of the lowest modes extended by the static corrections of the
   candidate's DOFs (:class:`ModalSubspace`; the FRF screening's Ritz idea), a small eigenproblem per
   value.  A candidate that changes none of the model modes paired with test modes (``Lᵀφ_j = 0``: a
   rotational spring about the vertical axis seen by vertical sensors) has no evidence and is dropped;
3. the best few are fitted jointly with the stiffness parameters (densities stay nominal: a density
   multiplier mimics an added mass, and on suspension modes any grounded stiffness) — in the subspace for
   models above ``SUBSPACE_ABOVE`` DOFs, checked against the exact modes; a term is kept if it lowers
   ``‖e‖²`` by ``min_gain`` and passes an information criterion (``penalty`` × ln N); terms are added only
   while ``‖e‖²`` exceeds the number of equations (χ² rule), and backward elimination drops a term whose
   removal costs less than ``min_term_gain``.  Other candidates that fit as well (within 5 %), and are not
   the same physics at a neighbouring node, make the finding ambiguous (:class:`ModesFinding`);
4. the comparison uses test modes held out of the fits (every third mode when there are at least five); a
   term that does not improve the held-out modes is not claimed, and without held-out modes the statement
   says the error is a training error.  With too few numbers for the free parameters and a physics term
   (fewer than 2 (n_free + 1) + 1) the statement says the data cannot separate physics from parameters.

Damping cannot be named from real modes.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.optimize as so
import scipy.sparse as sp

from modalab.core.dense import use_dense
from modalab.core.errors import ModalabValueError
from modalab.core.modes import ModeSet

from updating.fe import FEModel, ParametricFEModel
from updating.fe.solvers import eigen_dense, eigen_sparse, massless_mechanisms
from updating.diagnosis.subspace import ModalSubspace, _extended_rows, _new_directions  # noqa: F401 (re-exported)
from updating.diagnosis.fit import FitResult, FRFData, parameter_std
from updating.diagnosis.library import build_library
from updating.diagnosis.workflow import (Diagnosis, Finding, _augment, _bounds, _fmt, _upper, default_parameters,
                       promote_measured, statement)
from updating.diagnosis.modes_screen import MIN_OBSERVED_EFFECT, screen_modes  # noqa: F401 (re-exported)
from updating.correlation.dofmap import as_dofmap
from updating.diagnosis.library import _nodes_of
from modalab.core.dof import parse_dofs
from modalab.core.dof import locate
from updating.correlation.condensation import condensed_residual
from updating.correlation.metrics import mac as mac_matrix, pair_modes, shape_noise

log = logging.getLogger(__name__)
__all__ = ["diagnose_modes", "modes_data", "fit_modes", "mode_errors", "modal_force_map", "ModalResidual",
           "ModalSubspace", "ModesFinding", "screen_modes", "fit_modal_residual", "map_test_modes"]


def modes_data(test_modes: ModeSet, keep=None) -> FRFData:
    """The test modes as homogeneous residual data: one 'line' per mode at s = iω_j, shapes unit-norm."""
    idx = np.arange(test_modes.n_modes) if keep is None else np.asarray(keep, int)
    phi = np.asarray(test_modes.shapes)[:, idx]
    phi = np.real(phi) if np.iscomplexobj(phi) else phi
    phi = phi / np.maximum(np.linalg.norm(phi, axis=0), 1e-300)
    s = 1j * 2 * np.pi * np.asarray(test_modes.freq_hz, float)[idx]
    H = phi[:, None, :].astype(complex)
    return FRFData(s=s, H=H, coherence=np.ones(H.shape), responses=list(test_modes.dofs), references=[],
                   homogeneous=True)


#: models above this many DOFs are evaluated in a Ritz subspace of their lowest modes (exactly below)
SUBSPACE_ABOVE = 600
#: a model mode whose measured part is below this fraction of the best observed mode's is unobservable
UNOBSERVABLE = 1e-6
#: model modes beyond the test modes' count that pairing may choose from
EXTRA_MODES = 12
#: ... and at least every model mode up to this factor times the highest test frequency (modes of other
#: planes, unobservable or rigid, interleave with the observed ones)
PAIR_FACTOR = 1.5


def _exact_modes(K, M, k):
    """The lowest ``k`` modes (ω, mass-normalised Φ) with massless DOFs and massless mechanisms handled
    (:mod:`updating.fe.solvers`); dense for small models, shift-invert Lanczos above
    :data:`modalab.core.dense.MODES_LIMIT`."""
    n = K.shape[0]
    if use_dense(n, "modes"):
        return eigen_dense(K, M, min(k, n))
    return eigen_sparse(K, M, min(k, n - 2))


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
            from modalab.core.dof import locate
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
            Kr, Mr = basis.project(sp.csr_matrix(K), sp.csr_matrix(M))
            w2, Psi = sla.eigh(Kr, Mr)
            k = self.n_pairable(np.sqrt(np.clip(w2, 0, None)) / (2 * np.pi))
            Vm = (basis.rows_of(mi) * ms[:, None]) @ Psi[:, :k]
            return np.sqrt(np.clip(w2[:k], 0, None)) / (2 * np.pi), Vm
        Ks, Ms = sp.csr_matrix(K), sp.csr_matrix(M)
        k = self.n_model_modes
        while True:                    # every model mode up to PAIR_FACTOR × the highest test frequency
            w, V = _exact_modes(Ks, Ms, k)
            if w.size < k or w[-1] / (2 * np.pi) > PAIR_FACTOR * self.f.max() or k >= Ks.shape[0] - 2:
                break
            k = min(2 * k, Ks.shape[0] - 2)
        return w / (2 * np.pi), V[mi] * ms[:, None]

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
        pr = pair_modes(None, fm, r.f)
    else:
        _, seen = _observed(Vm)
        # no frequency window: missing physics may move a mode far (a spring to ground gives a free bar a
        # mode of its own); what must stay out are modes the sensors cannot see and merges of close modes
        pr = pair_modes(mac_matrix(Vm, r.phi), fm, r.f, observability=seen.astype(float), max_freq_error=None,
                        mode_shapes=(Vm, r.phi))
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
    more than 2 % (at most ``max_rebuild`` times)."""
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
            from modalab.core.dof import parse_dofs
            where = {(d.node, d.axis): i for i, d in enumerate(st0.dofs)}
            extra = [where[(d.node, d.axis)] for d in parse_dofs(list(cols)) if (d.node, d.axis) in where]
            basis = ModalSubspace(st0, np.concatenate([resid.rows(st0)[0], np.asarray(extra, int)]),
                                  float(resid.f.max()), resid.n_model_modes)

        def full(x, p0=p0, scale=scale):
            p = p_all.copy()
            p[free] = x * scale
            return p

        def fun(x, p0=p0, scale=scale):
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


def _block(structure, test_modes, keep):
    df, mac = mode_errors(structure, test_modes, keep)
    out = {"frf_error_held_out": None, "freq_error_rms_pct": float(100 * np.sqrt(np.mean(df ** 2))),
           "freq_error_max_pct": float(100 * np.max(np.abs(df)))}
    if not np.all(np.isnan(mac)):
        out["mac_min"] = float(np.min(mac))
    return out


def _freq_rms(structure, test_modes, keep) -> float:
    df, _ = mode_errors(structure, test_modes, keep)
    return float(np.sqrt(np.mean(df ** 2)))


@dataclass
class ModesFinding(Finding):
    """A modes-only finding; ``alternatives`` are other candidates that explain the same residual equally
    well, as ``(Candidate, value, rss)`` (then the finding is ambiguous: the data cannot tell them apart)."""


#: two candidates whose fitted residuals differ by less than this fraction (or by less than 1 in the
#: residual's own χ² units) explain the same residual: one ambiguous finding
AMBIGUOUS_RSS = 0.05


def map_test_modes(test_modes: ModeSet, model: FEModel, dofmap) -> ModeSet:
    """The test modes on the model's DOF labels through a DOF map (``--map``: a TOML/CSV file, a dict or a
    :class:`~updating.correlation.dofmap.DofMap`; test node → model grid, with signs).  Each test DOF must read one
    model DOF (an oblique sensor is refused with a message by :meth:`DofMap.model_labels`)."""
    if not len(test_modes.dofs):
        return test_modes
    labels, scale = as_dofmap(dofmap).model_labels(list(test_modes.dofs), model.reduction().full_dofs)
    shapes = np.asarray(test_modes.shapes) / np.asarray(scale, float)[:, None]
    keys = [(d.node, d.axis) for d in labels]
    if len(set(keys)) != len(keys):
        dup = sorted({str(d) for d, k in zip(labels, keys) if keys.count(k) > 1})
        raise ModalabValueError(f"the DOF map sends several test DOFs to the same model DOF(s) {', '.join(dup)}; "
                                "map each test DOF to its own model DOF")
    out = test_modes.copy()
    out.shapes = shapes
    out.dofs = labels
    return out


def _neighbours(model) -> dict:
    """Nodes sharing an element with each node."""
    nb: dict = {}
    for e in model.elements.values():
        ns = _nodes_of(e)
        for a in ns:
            nb.setdefault(a, set()).update(ns)
    return nb


def _same_place(a, b, nb) -> bool:
    """The same physics in the same direction at the same or a neighbouring node: a localisation spread,
    not a second explanation."""
    if a.physics != b.physics or a.value_name != b.value_name:
        return False
    ax = {d.split("+")[-1].split("-")[-1] for d in a.dofs}
    bx = {d.split("+")[-1].split("-")[-1] for d in b.dofs}
    return ax == bx and any(y == x or y in nb.get(x, ()) for x in a.nodes for y in b.nodes)


def _on_independent_dofs(cands, structure) -> list:
    """Candidates whose every DOF is an independent DOF of the structure (never on a rigid link's dependent
    DOF: a spring or mass there acts through the link on the independent node, where it is a candidate
    of its own)."""
    have = {(d.node, d.axis) for d in structure.dofs}
    out = []
    for c in cands:
        ds = parse_dofs(list(c.dofs)) if c.dofs else []
        if all((d.node, d.axis) in have for d in ds):
            out.append(c)
    return out


def diagnose_modes(model: FEModel, test_modes: ModeSet, *, parameters=None,
                   kinds=("ground_spring", "added_mass"), max_findings: int = 3, penalty: float = 3.0,
                   n_try: int = 4, min_gain: float = 0.3, min_term_gain: float = 0.15, sigma_f=None,
                   sigma_phi: float = 0.02, progress=None) -> Diagnosis:
    """Diagnose stiffness and mass physics from identified modes only (module docstring).

    ``test_modes`` on the model's node numbers (real or complex shapes; complex shapes are used through
    their real part after phase alignment by the identification), or frequencies alone (a mode set without
    DOFs).  Returns a :class:`Diagnosis` whose fit blocks hold ``freq_error_max_pct``,
    ``freq_error_rms_pct`` and ``mac_min`` (with shapes) on the held-out modes (``frf_error_held_out`` is
    None: there are no FRFs).  A numerical failure of an eigen-solution is an error, never a residual.

    ``sigma_f`` (relative frequency precision; one value or one per test mode): by default the standard
    deviations the identification stored with the modes (``freq_std_hz``), not below
    :data:`SIGMA_F_FLOOR`, else :data:`SIGMA_F_DEFAULT`.  Shapes are weighted by ``sigma_phi`` raised to the
    noise each identified shape shows by its complexity.  Test modes that do not pair with the nominal model
    (:func:`paired_test_modes`) are left out, each with its reason.
    """
    t0 = time.perf_counter()
    say = progress or (lambda msg: log.info(msg))
    if test_modes.n_modes < 2:
        raise ModalabValueError(f"{test_modes.n_modes} test mode(s); a modes-only diagnosis needs at least 2")
    has_shapes = len(test_modes.dofs) > 0
    if has_shapes:
        # measured nodes that a rigid link eliminates: reverse the link, or leave the DOF out (with a warning)
        model = promote_measured(model, list(test_modes.dofs))
        have = {(d.node, d.axis) for d in model.structure().dofs}
        dropped = [str(d) for d in test_modes.dofs if (d.node, d.axis) not in have]
        if dropped:
            log.warning("test-mode DOF(s) %s are eliminated in the model and left out", ", ".join(dropped))
            kept = [str(d) for d in test_modes.dofs if (d.node, d.axis) in have]
            if not kept:
                raise ModalabValueError("none of the test modes' DOFs is an independent DOF of the model; check "
                                        "the node numbering (or give --map)")
            test_modes = test_modes.select_dofs(kept)
    else:
        say("modes: frequencies only (no shapes): model modes are paired by frequency order")
    params = list(parameters) if parameters is not None else default_parameters(model)
    pm = ParametricFEModel(model, params)
    p_nom = np.array(pm.p0, float)
    lo, hi = _bounds(params, p_nom)
    usable, left_out = paired_test_modes(pm.structure(p_nom), test_modes)
    for j, why in left_out.items():
        say(f"modes: test mode {j + 1} ({test_modes.freq_hz[j]:.4g} Hz) left out: {why}")
    if usable.size < 2:
        raise ModalabValueError(f"only {usable.size} of {test_modes.n_modes} test modes pair with a mode of the "
                                "nominal model (frequency window, MAC, merged modes); a modes-only diagnosis needs "
                                "at least 2: check the DOF map and the model")
    held = usable[2::3] if usable.size >= 5 else np.array([], int)
    train = np.setdiff1d(usable, held)
    sigma_f = _sigma_f(test_modes, sigma_f)
    if has_shapes and np.iscomplexobj(test_modes.shapes):
        # a shape identified with noise (complexity: a weakly excited mode, MPC 0.64) is weighted by that noise,
        # as in the update stage; a clean one by sigma_phi
        noise = shape_noise(np.asarray(test_modes.shapes).reshape(len(test_modes.dofs), test_modes.n_modes))
        raised = np.flatnonzero(noise > sigma_phi)
        if raised.size:
            log.info("modes: test mode(s) %s carry more shape noise than %g: sigma %s",
                     ", ".join(str(j + 1) for j in raised), sigma_phi, np.round(noise[raised], 3))
        sigma_phi = np.maximum(float(sigma_phi), noise)
    resid = ModalResidual(test_modes, train, sigma_f=sigma_f, sigma_phi=sigma_phi)
    n_eq = resid.n_eq
    dens_free = np.array([par.field not in ("rho", "nsm") for par in params])
    n_free = int(dens_free.sum())
    # without a force the data are n_eq numbers: a physics term and the free parameters must be fewer than
    # half of them, or the data cannot separate the physics from parameter error
    separable = n_eq >= 2 * (n_free + 1) + 1
    say("modes: parameter-only updating (baseline)")
    tm = {"baseline": 0.0, "screening": 0.0, "fits": 0.0}
    t1 = time.perf_counter()
    p_upd, std_upd, rss_upd = fit_modal_residual(pm, resid, p_nom, lower=lo, upper=hi)
    tm["baseline"] = time.perf_counter() - t1
    upd = FitResult(p_upd, std_upd, _freq_rms(pm.structure(p_upd), test_modes, train), [], True, "")
    current, p_cur, pm_cur, rss_cur = [], p_upd, pm, rss_upd
    std_cur = std_upd
    ranking = None
    alternatives: dict = {}
    nb = _neighbours(model)
    for it in range(max_findings):
        if rss_cur <= n_eq:
            # χ² stopping rule: the residual is within what the stated precisions (σ_f, σ_φ) explain
            log.info("modes: residual %.4g within the %d-equation noise level; no further term", rss_cur, n_eq)
            break
        if not separable:
            log.info("modes: %d numbers for %d free parameters and a physics term: not separable", n_eq, n_free)
            break
        st_cur = pm_cur.structure(p_cur)
        lib = _on_independent_dofs(build_library(pm_cur.model_at(p_cur), kinds=kinds), st_cur)
        say(f"modes: screening {len(lib)} candidates")
        t1 = time.perf_counter()
        screens = [screen_modes(st_cur, lib, resid)]
        if it == 0:      # and around the nominal parameters (updating may have bent them to hide the effect)
            st_nom = pm.structure(p_nom)
            screens.append(screen_modes(st_nom, _on_independent_dofs(build_library(pm.model_at(p_nom),
                                                                                    kinds=kinds), st_nom), resid))
        tm["screening"] += time.perf_counter() - t1
        t1 = time.perf_counter()
        if ranking is None:
            ranking = screens[0]
        have_keys = {c.key for c in current}
        options, listed = [], set()
        for scr in screens:
            for c, th, g in scr[:n_try]:
                if c.key not in have_keys and c.key not in listed and g > 0.05:
                    options.append((c, th))
                    listed.add(c.key)
        results = []
        cols = [d for c, _ in options for d in c.dofs]            # static corrections of the subspace fits
        for c, th in options:
            m_aug, cpar, scales = _augment(model, current + [c])
            pm_aug = ParametricFEModel(m_aug, params + cpar)
            clo = np.concatenate([lo, np.zeros(len(cpar))])
            chi = np.concatenate([hi, _upper(current + [c], scales)])
            starts = [p_cur] + ([p_nom] if it == 0 else [])
            best_c = None
            for p_par in starts:
                if th <= 0:
                    break
                start = np.concatenate([p_par[:len(params)], p_cur[len(params):], [min(th, c.upper) / scales[-1]]])
                # without a force a density multiplier mimics an added mass (and, on suspension modes, any
                # grounded stiffness): densities stay nominal while physics terms are fitted
                start[:len(params)][~dens_free] = p_nom[~dens_free]
                pa, sa, ra = fit_modal_residual(pm_aug, resid, start, lower=clo, upper=chi, cols=cols,
                                                free=np.concatenate([dens_free, np.ones(len(cpar), bool)]))
                log.info("modes: candidate %s: modal residual %.4g (current %.4g)", c.label, ra, rss_cur)
                if pa[-1] * scales[-1] <= 1e-3 * th:      # fitted to (nearly) nothing: not this term
                    continue
                if best_c is None or ra < best_c[1]:
                    best_c = (c, ra, pm_aug, pa, sa, clo, chi)
            if best_c is not None:
                results.append(best_c)
        results.sort(key=lambda r: (r[1], r[0].key))
        tm["fits"] += time.perf_counter() - t1
        best = results[0] if results else None
        # an information criterion (``penalty`` × ln N per term) and a relative drop of ``min_gain``
        if best is None or not (best[1] < rss_cur * (1 - min_gain) and
                                n_eq * np.log(rss_cur / max(best[1], 1e-300)) > penalty * np.log(n_eq)):
            break
        c, rss_cur, pm_cur, p_cur, std_cur, _, _ = best
        # other candidates that explain the same residual as well are not a second finding but an ambiguity
        alternatives[c.key] = [(o[0], float(o[3][-1]) * _augment(model, current + [o[0]])[2][-1], o[1])
                               for o in results[1:]
                               if o[1] <= best[1] * (1 + AMBIGUOUS_RSS) + 1.0 and not _same_place(c, o[0], nb)]
        current.append(c)
        alt = ", ".join(a.label for a, _, _ in alternatives[c.key])
        say(f"  found (modes): {c.label}" + (f" (or, equally well: {alt})" if alt else ""))
    # backward elimination: a term whose removal (the rest refitted) costs less than ``min_term_gain`` of the
    # residual has not earned its place
    while len(current) > 1:
        trial = []
        for k in range(len(current)):
            rest = current[:k] + current[k + 1:]
            m_r, cpar_r, sc_r = _augment(model, rest)
            pm_r = ParametricFEModel(m_r, params + cpar_r)
            keep_i = np.r_[np.arange(len(params)), len(params) + np.array([i for i in range(len(current)) if i != k], int)]
            pr, sr, rr = fit_modal_residual(pm_r, resid, p_cur[keep_i], lower=np.concatenate([lo, np.zeros(len(rest))]),
                                            upper=np.concatenate([hi, _upper(rest, sc_r)]),
                                            free=np.concatenate([dens_free, np.ones(len(rest), bool)]))
            trial.append((rr, k, rest, pm_r, pr, sr))
        rr, k, rest, pm_r, pr, sr = min(trial, key=lambda t: (t[0], t[1]))
        if rr > rss_cur * (1 + min_term_gain):
            break
        log.info("modes: dropping %s (residual %.4g without it, %.4g with)", current[k].label, rr, rss_cur)
        current, pm_cur, p_cur, std_cur, rss_cur = rest, pm_r, pr, sr, rr
    best_fit, best_pm, scales = upd, pm, []
    if current:
        phys_err = _freq_rms(pm_cur.structure(p_cur), test_modes, train)
        if phys_err < upd.error * (1 - min_gain):
            _, _, scales = _augment(model, current)
            best_fit = FitResult(p_cur, std_cur, phys_err, [], True, "")
            best_pm = pm_cur
        else:
            log.info("modes: the augmented model does not fit the test frequencies better; nothing added")
            current = []
    keep_eval = held if held.size else train
    fit = {"nominal": _block(pm.structure(p_nom), test_modes, keep_eval),
           "parameters_only": _block(pm.structure(upd.p), test_modes, keep_eval),
           "with_physics": _block(best_pm.structure(best_fit.p), test_modes, keep_eval)}
    unproven = []
    if current and held.size and \
            fit["with_physics"]["freq_error_rms_pct"] >= fit["parameters_only"]["freq_error_rms_pct"]:
        # the terms fit the training modes but do not predict the held-out ones: not proven, not claimed
        unproven = [c.label for c in current]
        log.info("modes: %s lower the training residual but not the held-out error; nothing added",
                 ", ".join(unproven))
        current, scales, best_fit, best_pm = [], [], upd, pm
        fit["with_physics"] = dict(fit["parameters_only"])
    n_par = len(params)
    findings = []
    for k, (c, sc) in enumerate(zip(current, scales)):
        gain = next((g for o, _, g in (ranking or []) if o.key == c.key), 0.0)
        alts = alternatives.get(c.key, [])
        ev = (f"the eigenvalue and shape residual of the test modes at {', '.join(c.dofs)} is removed by this term; "
              f"it alone explains {100 * gain:.0f} % of the residual left after parameter updating")
        if not has_shapes:
            ev = ev.replace("eigenvalue and shape residual", "frequency residual")
        if alts:
            ev += ("; AMBIGUOUS: " + ", ".join(f"{a.label} ({_fmt(v, a.unit)})" for a, v, _ in alts)
                   + " explains it as well, and the test modes cannot tell them apart")
        findings.append(ModesFinding(c, float(best_fit.p[n_par + k] * sc), float(best_fit.std[n_par + k] * sc), ev,
                                     gain, alternatives=alts))
    pars = {par.name: {"initial": float(p_nom[k]), "updated": float(best_fit.p[k]),
                       "parameters_only": float(upd.p[k]),
                       "std": float(best_fit.std[k]) if np.isfinite(best_fit.std[k]) else None, "mode": par.mode}
            for k, par in enumerate(params)}
    if held.size:
        held_desc = f"test modes {', '.join(str(i + 1) for i in keep_eval)}"
        word = "held-out frequency error"
    else:
        held_desc = f"test modes {', '.join(str(i + 1) for i in keep_eval)}, the same modes the fit used"
        word = "training frequency error (no mode could be held out)"
    blocks = {k: dict(v, frf_error_held_out=v["freq_error_rms_pct"] / 100) for k, v in fit.items()}
    text = statement(findings, blocks, held_desc).replace("held-out FRF error", word)
    for f in findings:
        if f.ambiguous:
            text = (f"AMBIGUOUS: {f.candidate.label} or " + " or ".join(a.label for a, _, _ in f.alternatives)
                    + " explain the test modes equally well; the data cannot tell which. ") + text
    if unproven:
        text = (f"Not proven: {' and '.join(unproven)} lowered the error on the training modes but not on the "
                f"held-out ones ({held_desc}), so nothing is added; the model may lack something the candidates "
                f"do not describe (or its mesh is too coarse). Updating the model's own parameters brings the "
                f"held-out frequency error from {fit['nominal']['freq_error_rms_pct']:.3g} % to "
                f"{fit['parameters_only']['freq_error_rms_pct']:.3g} % RMS.")
    if not separable:
        text = (f"The data cannot separate missing physics from parameter error: {n_eq} numbers "
                f"({resid.f.size} training {'modes' if has_shapes else 'frequencies'}"
                f"{' with shapes' if has_shapes else ', no shapes'}) against {len(params)} "
                f"parameters and a physics term; no physics is claimed. Frequency error after updating the parameters: "
                f"{fit['parameters_only']['freq_error_rms_pct']:.3g} % RMS ({held_desc}).")
    maps = {}
    if has_shapes:       # localisation for the report: the modal force residual per measured DOF and mode
        mdata = modes_data(test_modes, train)
        maps = {"freq_hz": np.asarray(test_modes.freq_hz, float)[train],
                "responses": [str(d) for d in test_modes.dofs],
                "before": modal_force_map(pm.structure(upd.p), mdata),
                "after": modal_force_map(best_pm.structure(best_fit.p), mdata)}
    return Diagnosis(findings=findings, parameters=pars, fit=fit, statement=text,
                     model=best_pm.model_at(best_fit.p), parametric=best_pm, p=best_fit.p,
                     steps={"held_out": held_desc, "source": "modes", "separable": bool(separable),
                            "n_equations": n_eq, "n_free_parameters": n_free},
                     ranking=ranking or [], maps=maps, timings=dict(tm, total=time.perf_counter() - t0))


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
