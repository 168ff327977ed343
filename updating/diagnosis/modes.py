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
   value; with many candidates (a 100k-DOF model has ~10⁵) a first-order pre-screen by the eigenvalue and
   eigenvector sensitivities of the paired modes chooses the few hundred evaluated so
   (:mod:`~updating.diagnosis.modes_screen`).  A candidate that changes none of the model modes paired with test modes (``Lᵀφ_j = 0``: a
   rotational spring about the vertical axis seen by vertical sensors) has no evidence and is dropped;
3. the best few are fitted jointly with the stiffness parameters (densities stay nominal: a density
   multiplier mimics an added mass, and on suspension modes any grounded stiffness) — in the subspace for
   models above :data:`~updating.diagnosis.modal_fit.SUBSPACE_ABOVE` DOFs (:mod:`~updating.diagnosis.modal_fit`),
   checked against the exact modes; a term is kept if it lowers ``‖e‖²`` by ``min_gain`` and passes an
   information criterion (``penalty`` × ln N); terms are added only while ``‖e‖²`` exceeds the number of
   equations (χ² rule), and backward elimination drops a term whose removal costs less than
   ``min_term_gain``.  Other candidates that fit as well (within 5 %), and are not the same physics at a
   neighbouring node, make the finding ambiguous (:class:`ModesFinding`);
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

from modalab.core.errors import ModalabValueError
from modalab.core.modes import ModeSet

from updating.fe import FEModel, ParametricFEModel
from updating.diagnosis.subspace import ModalSubspace, _extended_rows, _new_directions  # noqa: F401 (re-exported)
from updating.diagnosis.modal_residual import (fit_modes, modal_force_map,  # noqa: F401 (re-exported)
                                              EXTRA_MODES, PAIR_FACTOR, SIGMA_F_DEFAULT, SIGMA_F_FLOOR,  # noqa: F401
                                              UNOBSERVABLE, ModalResidual, _exact_modes, _observed, _sigma_f,
                                              mode_errors, paired_test_modes)
from updating.diagnosis.fit import FitResult, FRFData
from updating.diagnosis.modal_fit import fit_modal_residual
from updating.diagnosis.library import build_library
from updating.diagnosis.priors import _bounds, default_parameters
from updating.diagnosis.terms import _axes, _augment, _augmented, promote_measured
from updating.diagnosis.findings import Diagnosis, Finding, _fmt, from_to, pct, statement
from updating.diagnosis.modes_screen import MIN_OBSERVED_EFFECT, screen_modes  # noqa: F401 (re-exported)
from updating.correlation.dofmap import as_dofmap
from updating.diagnosis.library import _nodes_of
from modalab.core.dof import parse_dofs
from updating.correlation.metrics import shape_noise

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
    return _axes(a) == _axes(b) and any(y == x or y in nb.get(x, ()) for x in a.nodes for y in b.nodes)


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


@dataclass
class _ModesProblem:
    """What the steps of :func:`diagnose_modes` share: the model and its parameters, the test modes split into
    training and held-out modes, the modal residual on the training modes."""

    model: FEModel
    test_modes: ModeSet
    params: list
    pm: ParametricFEModel
    p_nom: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    train: np.ndarray
    held: np.ndarray
    resid: ModalResidual
    dens_free: np.ndarray
    has_shapes: bool
    kinds: tuple
    say: object
    tm: dict = field(default_factory=lambda: {"baseline": 0.0, "screening": 0.0, "fits": 0.0})

    @property
    def n_eq(self) -> int:
        return self.resid.n_eq

    @property
    def n_free(self) -> int:
        return int(self.dens_free.sum())

    @property
    def separable(self) -> bool:
        # without a force the data are n_eq numbers: a physics term and the free parameters must be fewer than
        # half of them, or the data cannot separate the physics from parameter error
        return self.n_eq >= 2 * (self.n_free + 1) + 1


@dataclass
class _State:
    """The model being built: its terms, parametric model, parameters (with the terms' values), uncertainties
    and modal residual."""

    current: list
    pm: ParametricFEModel
    p: np.ndarray
    std: np.ndarray
    rss: float


def _measured_test_modes(model: FEModel, test_modes: ModeSet, say):
    """``(model, test_modes)``: measured nodes that a rigid link eliminates promoted (the link reversed), or
    their DOFs left out with a warning; frequency-only sets pass through."""
    if not len(test_modes.dofs):
        say("modes: frequencies only (no shapes): model modes are paired by frequency order")
        return model, test_modes
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
    return model, test_modes


def _shape_sigma(test_modes: ModeSet, sigma_phi):
    """``sigma_phi`` raised, per mode, to the noise a complex identified shape shows (a weakly excited mode,
    MPC 0.64, is weighted by that noise, as in the update stage; a clean one by ``sigma_phi``)."""
    if not len(test_modes.dofs) or not np.iscomplexobj(test_modes.shapes):
        return sigma_phi
    noise = shape_noise(np.asarray(test_modes.shapes).reshape(len(test_modes.dofs), test_modes.n_modes))
    raised = np.flatnonzero(noise > sigma_phi)
    if raised.size:
        log.info("modes: test mode(s) %s carry more shape noise than %g: sigma %s",
                 ", ".join(str(j + 1) for j in raised), sigma_phi, np.round(noise[raised], 3))
    return np.maximum(float(sigma_phi), noise)


def _modes_problem(model, test_modes, parameters, kinds, sigma_f, sigma_phi, say) -> _ModesProblem:
    """The parameters, the test modes that pair with the nominal model (the others left out, each with its
    reason), every third of them held out (from five on), and the modal residual of the training modes."""
    if test_modes.n_modes < 2:
        raise ModalabValueError(f"{test_modes.n_modes} test mode(s); a modes-only diagnosis needs at least 2")
    model, test_modes = _measured_test_modes(model, test_modes, say)
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
    resid = ModalResidual(test_modes, train, sigma_f=_sigma_f(test_modes, sigma_f),
                          sigma_phi=_shape_sigma(test_modes, sigma_phi))
    dens_free = np.array([par.field not in ("rho", "nsm") for par in params])
    return _ModesProblem(model, test_modes, params, pm, p_nom, lo, hi, train, held, resid, dens_free,
                         len(test_modes.dofs) > 0, kinds, say)


def _screen_options(pb: _ModesProblem, st: _State, first: bool, n_try: int) -> list:
    """``[(candidate, value)]``: the best ``n_try`` of each screening (around the current parameters, and on
    the first pass around the nominal ones too: updating may have bent them to hide the effect) that are not
    terms yet and explain more than 5 % of the residual."""
    t1 = time.perf_counter()
    st_cur = st.pm.structure(st.p)
    lib = _on_independent_dofs(build_library(st.pm.model_at(st.p), kinds=pb.kinds), st_cur)
    pb.say(f"modes: screening {len(lib)} candidates")
    screens = [screen_modes(st_cur, lib, pb.resid)]
    if first:
        st_nom = pb.pm.structure(pb.p_nom)
        screens.append(screen_modes(st_nom, _on_independent_dofs(build_library(pb.pm.model_at(pb.p_nom),
                                                                                kinds=pb.kinds), st_nom), pb.resid))
    pb.tm["screening"] += time.perf_counter() - t1
    have_keys = {c.key for c in st.current}
    options, listed = [], set()
    for scr in screens:
        for c, th, g in scr[:n_try]:
            if c.key not in have_keys and c.key not in listed and g > 0.05:
                options.append((c, th))
                listed.add(c.key)
    return options, screens[0]


def _fit_option(pb: _ModesProblem, st: _State, c, th, first: bool, cols):
    """The candidate ``c`` (screened value ``th``) fitted with the current terms and the stiffness parameters
    (densities stay nominal: without a force a density multiplier mimics an added mass, and on suspension
    modes any grounded stiffness), from the current and on the first pass also the nominal parameters:
    ``(c, rss, pm, p, std)`` of the better, or None when it fits to (nearly) nothing."""
    params, n_par = pb.params, len(pb.params)
    pm_aug, clo, chi, scales = _augmented(pb.model, params, pb.lo, pb.hi, st.current + [c])
    best = None
    for p_par in [st.p] + ([pb.p_nom] if first else []):
        if th <= 0:
            break
        start = np.concatenate([p_par[:n_par], st.p[n_par:], [min(th, c.upper) / scales[-1]]])
        start[:n_par][~pb.dens_free] = pb.p_nom[~pb.dens_free]
        pa, sa, ra = fit_modal_residual(pm_aug, pb.resid, start, lower=clo, upper=chi, cols=cols,
                                        free=np.concatenate([pb.dens_free, np.ones(len(clo) - n_par, bool)]))
        log.info("modes: candidate %s: modal residual %.4g (current %.4g)", c.label, ra, st.rss)
        if pa[-1] * scales[-1] <= 1e-3 * th:      # fitted to (nearly) nothing: not this term
            continue
        if best is None or ra < best[1]:
            best = (c, ra, pm_aug, pa, sa)
    return best


def _forward_selection(pb: _ModesProblem, st: _State, *, max_findings, n_try, min_gain, penalty):
    """Terms added one at a time while the residual exceeds the noise level (χ² rule): the screened options
    fitted, the best kept if it lowers ‖e‖² by ``min_gain`` and passes the information criterion (``penalty``
    × ln N per term); the options that fit as well (within :data:`AMBIGUOUS_RSS`, not the same physics next
    door) are its alternatives.  Returns ``(state, ranking, alternatives)``."""
    ranking, alternatives = None, {}
    nb = _neighbours(pb.model)
    n_eq = pb.n_eq
    for it in range(max_findings):
        if st.rss <= n_eq:
            log.info("modes: residual %.4g within the %d-equation noise level; no further term", st.rss, n_eq)
            break
        if not pb.separable:
            log.info("modes: %d numbers for %d free parameters and a physics term: not separable", n_eq, pb.n_free)
            break
        options, first_screen = _screen_options(pb, st, it == 0, n_try)
        ranking = first_screen if ranking is None else ranking
        t1 = time.perf_counter()
        cols = [d for c, _ in options for d in c.dofs]            # static corrections of the subspace fits
        results = [r for r in (_fit_option(pb, st, c, th, it == 0, cols) for c, th in options) if r is not None]
        results.sort(key=lambda r: (r[1], r[0].key))
        pb.tm["fits"] += time.perf_counter() - t1
        best = results[0] if results else None
        if best is None or not (best[1] < st.rss * (1 - min_gain) and
                                n_eq * np.log(st.rss / max(best[1], 1e-300)) > penalty * np.log(n_eq)):
            break
        c = best[0]
        alternatives[c.key] = [(o[0], float(o[3][-1]) * _augment(pb.model, st.current + [o[0]])[2][-1], o[1])
                               for o in results[1:]
                               if o[1] <= best[1] * (1 + AMBIGUOUS_RSS) + 1.0 and not _same_place(c, o[0], nb)]
        st = _State(st.current + [c], best[2], best[3], best[4], best[1])
        alt = ", ".join(a.label for a, _, _ in alternatives[c.key])
        pb.say(f"  found (modes): {c.label}" + (f" (or, equally well: {alt})" if alt else ""))
    return st, ranking, alternatives


def _backward_elimination(pb: _ModesProblem, st: _State, min_term_gain: float) -> _State:
    """A term whose removal (the rest refitted) costs less than ``min_term_gain`` of the residual has not
    earned its place: dropped, and the test repeated."""
    n_par = len(pb.params)
    while len(st.current) > 1:
        trial = []
        for k in range(len(st.current)):
            rest = st.current[:k] + st.current[k + 1:]
            pm_r, lo_r, hi_r, _ = _augmented(pb.model, pb.params, pb.lo, pb.hi, rest)
            keep_i = np.r_[np.arange(n_par), n_par + np.array([i for i in range(len(st.current)) if i != k], int)]
            pr, sr, rr = fit_modal_residual(pm_r, pb.resid, st.p[keep_i], lower=lo_r, upper=hi_r,
                                            free=np.concatenate([pb.dens_free, np.ones(len(rest), bool)]))
            trial.append((rr, k, _State(rest, pm_r, pr, sr, rr)))
        rr, k, new = min(trial, key=lambda t: (t[0], t[1]))
        if rr > st.rss * (1 + min_term_gain):
            break
        log.info("modes: dropping %s (residual %.4g without it, %.4g with)", st.current[k].label, rr, st.rss)
        st = new
    return st


def _judge(pb: _ModesProblem, upd: FitResult, st: _State, min_gain: float):
    """The terms kept only if they fit the training frequencies better than parameter updating and improve
    the held-out modes.  Returns ``(current, scales, best_fit, best_pm, fit blocks, unproven labels)``."""
    current, best_fit, best_pm, scales = st.current, upd, pb.pm, []
    if current:
        phys_err = _freq_rms(st.pm.structure(st.p), pb.test_modes, pb.train)
        if phys_err < upd.error * (1 - min_gain):
            _, _, scales = _augment(pb.model, current)
            best_fit, best_pm = FitResult(st.p, st.std, phys_err, [], True, ""), st.pm
        else:
            log.info("modes: the augmented model does not fit the test frequencies better; nothing added")
            current = []
    keep_eval = pb.held if pb.held.size else pb.train
    fit = {"nominal": _block(pb.pm.structure(pb.p_nom), pb.test_modes, keep_eval),
           "parameters_only": _block(pb.pm.structure(upd.p), pb.test_modes, keep_eval),
           "with_physics": _block(best_pm.structure(best_fit.p), pb.test_modes, keep_eval)}
    unproven = []
    if current and pb.held.size and \
            fit["with_physics"]["freq_error_rms_pct"] >= fit["parameters_only"]["freq_error_rms_pct"]:
        # the terms fit the training modes but do not predict the held-out ones: not proven, not claimed
        unproven = [c.label for c in current]
        log.info("modes: %s lower the training residual but not the held-out error; nothing added",
                 ", ".join(unproven))
        current, scales, best_fit, best_pm = [], [], upd, pb.pm
        fit["with_physics"] = dict(fit["parameters_only"])
    return current, scales, best_fit, best_pm, fit, unproven


def _modes_findings(pb: _ModesProblem, current, scales, best_fit, ranking, alternatives) -> list:
    n_par = len(pb.params)
    findings = []
    for k, (c, sc) in enumerate(zip(current, scales)):
        gain = next((g for o, _, g in (ranking or []) if o.key == c.key), 0.0)
        alts = alternatives.get(c.key, [])
        ev = (f"the eigenvalue and shape residual of the test modes at {', '.join(c.dofs)} is removed by this term; "
              f"it alone explains {pct(100 * gain)} % of the residual left after parameter updating")
        if not pb.has_shapes:
            ev = ev.replace("eigenvalue and shape residual", "frequency residual")
        if alts:
            ev += ("; AMBIGUOUS: " + ", ".join(f"{a.label} ({_fmt(v, a.unit)})" for a, v, _ in alts)
                   + " explains it as well, and the test modes cannot tell them apart")
        findings.append(ModesFinding(c, float(best_fit.p[n_par + k] * sc), float(best_fit.std[n_par + k] * sc), ev,
                                     gain, alternatives=alts))
    return findings


def _modes_statement(pb: _ModesProblem, findings, fit, unproven) -> tuple[str, str]:
    """``(statement, held-out description)``: what was found and how much it improves the held-out modes;
    a training error is never called held-out."""
    keep_eval = pb.held if pb.held.size else pb.train
    if pb.held.size:
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
                f"held-out RMS frequency error "
                f"{from_to(fit['nominal']['freq_error_rms_pct'], fit['parameters_only']['freq_error_rms_pct'])}.")
    if not pb.separable:
        text = (f"The data cannot separate missing physics from parameter error: {pb.n_eq} numbers "
                f"({pb.resid.f.size} training {'modes' if pb.has_shapes else 'frequencies'}"
                f"{' with shapes' if pb.has_shapes else ', no shapes'}) against {len(pb.params)} "
                f"parameters and a physics term; no physics is claimed. Frequency error after updating the parameters: "
                f"{pct(fit['parameters_only']['freq_error_rms_pct'])} % RMS ({held_desc}).")
    return text, held_desc


#: the kinds of missing physics a diagnosis from identified modes alone judges (the module docstring)
MODES_KINDS = ("ground_spring", "added_mass")


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

    Steps: the problem (:func:`_modes_problem`), parameter-only updating, forward selection of terms
    (:func:`_forward_selection`), backward elimination, the held-out judgement (:func:`_judge`), findings and
    statement.
    """
    other = sorted(set(kinds or ()) - set(MODES_KINDS))
    if other:      # undamped modes cannot show dissipation, and releases are judged on FRFs: never a silent 'nothing'
        raise ModalabValueError(f"kinds {', '.join(other)}: identified modes alone judge {' and '.join(MODES_KINDS)} "
                                "only; give the measured FRFs for the other kinds (modalab diagnose MODEL.bdf "
                                "MEASURED.uff), or leave them out of --kinds")
    t0 = time.perf_counter()
    say = progress or (lambda msg: log.info(msg))
    pb = _modes_problem(model, test_modes, parameters, kinds, sigma_f, sigma_phi, say)
    say("modes: parameter-only updating (baseline)")
    t1 = time.perf_counter()
    p_upd, std_upd, rss_upd = fit_modal_residual(pb.pm, pb.resid, pb.p_nom, lower=pb.lo, upper=pb.hi)
    pb.tm["baseline"] = time.perf_counter() - t1
    upd = FitResult(p_upd, std_upd, _freq_rms(pb.pm.structure(p_upd), pb.test_modes, pb.train), [], True, "")
    st, ranking, alternatives = _forward_selection(pb, _State([], pb.pm, p_upd, std_upd, rss_upd),
                                                   max_findings=max_findings, n_try=n_try, min_gain=min_gain,
                                                   penalty=penalty)
    st = _backward_elimination(pb, st, min_term_gain)
    current, scales, best_fit, best_pm, fit, unproven = _judge(pb, upd, st, min_gain)
    findings = _modes_findings(pb, current, scales, best_fit, ranking, alternatives)
    pars = {par.name: {"initial": float(pb.p_nom[k]), "updated": float(best_fit.p[k]),
                       "parameters_only": float(upd.p[k]),
                       "std": float(best_fit.std[k]) if np.isfinite(best_fit.std[k]) else None, "mode": par.mode}
            for k, par in enumerate(pb.params)}
    text, held_desc = _modes_statement(pb, findings, fit, unproven)
    maps = {}
    if pb.has_shapes:       # localisation for the report: the modal force residual per measured DOF and mode
        mdata = modes_data(pb.test_modes, pb.train)
        maps = {"freq_hz": np.asarray(pb.test_modes.freq_hz, float)[pb.train],
                "responses": [str(d) for d in pb.test_modes.dofs],
                "before": modal_force_map(pb.pm.structure(upd.p), mdata),
                "after": modal_force_map(best_pm.structure(best_fit.p), mdata)}
    return Diagnosis(findings=findings, parameters=pars, fit=fit, statement=text,
                     model=best_pm.model_at(best_fit.p), parametric=best_pm, p=best_fit.p,
                     steps={"held_out": held_desc, "source": "modes", "separable": bool(pb.separable),
                            "n_equations": pb.n_eq, "n_free_parameters": pb.n_free},
                     ranking=ranking or [], maps=maps, timings=dict(pb.tm, total=time.perf_counter() - t0))
