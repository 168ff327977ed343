"""A term of missing physics judged and modelled: the effect it has on in-band frequencies and damping
(:func:`term_effect`), the χ² tests on training and held-out FRFs (:func:`_term_holds`), other explanations at
the same place, measured DOFs promoted into the model, and the augmented model with the selected terms
(:func:`_augment`).  Split out of :mod:`~updating.diagnosis.workflow`."""
from __future__ import annotations

import logging

import numpy as np
from scipy.stats import binom

from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF

from updating.fe import FEModel, ParametricFEModel
from updating.diagnosis.fit import FRFData, model_frf
from updating.diagnosis.library import Candidate, _nodes_of
from updating.diagnosis.findings import pct
from modalab.core.dof import parse_dofs

log = logging.getLogger(__name__)


def _same_place(a: Candidate, b: Candidate, model: FEModel) -> bool:
    """Whether two candidates act at the same or neighbouring nodes (sharing a node, or joined by one
    element)."""
    na, nb = set(a.nodes) | _element_nodes(a, model), set(b.nodes) | _element_nodes(b, model)
    if na & nb:
        return True
    return any(na & set(ns) and nb & set(ns) for ns in (_nodes_of(e) for e in model.elements.values()))


def _axes(c: Candidate) -> set:
    """The directions of a candidate's DOFs (``{'Y'}`` for a spring at 9+Y), whatever the node."""
    return {d.split("+")[-1].split("-")[-1] for d in c.dofs}


def _same_kind_nearby(a: Candidate, b: Candidate, model: FEModel) -> bool:
    """Whether ``a`` is ``b``'s kind (physics and value) in the same direction at the same or a neighbouring
    place (:func:`_same_place`): where :data:`NEARBY_PLACES` looks for a better place of ``b``."""
    return a.physics == b.physics and a.value_name == b.value_name and _axes(a) == _axes(b) \
        and _same_place(a, b, model)


#: a fitted candidate's kind in the same direction at this many neighbouring places is fitted too (the screening
#: holds the parameters, which biases the place within a localisation spread): :meth:`_Picks._nearby_options`,
#: :meth:`_Picks._nearby_places`
NEARBY_PLACES = 4


def _is_support(c: Candidate) -> bool:
    """Whether ``c`` releases (part of) a support's constraint."""
    return c.release is not None and c.release[0] == "support"


def _another_explanation(a: Candidate, b: Candidate, model: FEModel) -> bool:
    """Whether ``a`` is a different explanation from ``b``: elsewhere, or the same place with other physics (a
    joint's flexibility and a rotary inertia at one node are two explanations; the same kind one node over is a
    localisation spread, not a second one)."""
    return a.physics != b.physics or not _same_place(a, b, model)


def _element_nodes(c: Candidate, model: FEModel) -> set:
    return {n for e in c.elements if e in model.elements for n in _nodes_of(model.elements[e])}


#: a stiffness or inertia term must move an in-band natural frequency by at least this much (relative): FRF
#: errors near lightly damped resonances grow as Δf/(ζ f), so frequency shifts of the order of an FE model's own
#: discretisation error (0.1-0.4 %) already give large FRF gains that a term would absorb
MIN_FREQ_EFFECT = 0.004


#: competitors of an accepted pick's screening, close to it there, fitted on the FRFs as its alternatives
#: (:meth:`~updating.diagnosis.acceptance._Acceptance._fitted_alternatives`)
CLOSE_COMPETITORS = 2


#: a pick of the exact FRF screening that the MCI did not support is accepted only if it leaves at most this
#: reduced χ² (per observation, :func:`n_obs`, in units of the measurement noise) on the training and the
#: held-out FRFs: a term that leaves the residual well above the noise is reducing model-form error (a coarse
#: mesh, per-element scatter), not explaining a missing effect.  Cross-validation does not replace it: on data
#: simulated from the nominal through the lab simulator, and on a control with per-section material errors,
#: a dashpot or rotary inertia absorbing that error also predicts the held-out folds (measured:
#: ``tests/updating/test_diagnosis_exact.py``, ``examples/concealed/bar_control``)
PICK_MAX_REDUCED_CHI2 = 1.5

#: ... unless the χ² it leaves is at most this share of the current model's on the training and held-out FRFs
#: pooled: a term that removes nearly all of the residual explains it; what is left is the model's form error,
#: which is no reason to reject it
PICK_EXPLAINS = 0.1


#: a damping term must add at least this fraction of the background loss factor to some in-band mode
MIN_DAMPING_EFFECT = 0.25


#: damping on element groups is fitted at the best places of the exact screening, this many distinct ones
DAMPING_PLACES = 3


def _distinct_places(ranked: list, n: int) -> list:
    """The first ``n`` entries of a ranking ``[(candidate, value, gain)]`` at distinct places: an entry sharing
    a node with an earlier one is skipped.

    For local damping the screening's order is the least reliable of all: it adds the term to a model whose
    global loss factor was fitted without it, so the background already carries part of the local
    dissipation (the two trade off against each other, and only a fit that re-fits both sees which place is
    right); the runs of neighbouring element groups at the first place would otherwise fill every slot."""
    out = []
    for t in ranked:
        if len(out) >= n:
            break
        if not any(set(t[0].nodes) & set(o[0].nodes) for o in out):
            out.append(t)
    return out


def term_effect(pm, p, n_par: int, c: Candidate, band) -> tuple[float, float]:
    """The size of the last term of ``pm`` at ``p`` (its value at ``p[-1]``, the other values as they are):
    the largest relative change of an in-band elastic natural frequency between the model with the term and
    without it (value 0; for a joint or support release, 10⁴ times stiffer: the rigid connection), and the
    largest modal loss factor it adds to an in-band mode relative to the background loss factor (first order,
    mass-normalised modes: ``φᵀΔDφ/ω² + φᵀΔCφ/ω``)."""
    p = np.asarray(p, float)
    p0 = p.copy()
    p0[-1] = p[-1] * 1e4 if c.physics in ("joint_flexibility", "boundary_flexibility") else 0.0
    with_, without = pm.structure(p), pm.structure(p0)

    def elastic(st):
        n = st.n_dof
        k = min(n, 40)
        while True:
            w, phi = st.normal_modes(k)
            f = np.atleast_1d(w) / (2 * np.pi)
            if k >= n or f[-1] > 1.2 * band[1]:
                return f, phi
            k = min(n, 2 * k)

    fa, phia = elastic(with_)
    fb, _ = elastic(without)
    m = min(fa.size, fb.size)
    ok = (fb[:m] >= band[0]) & (fb[:m] <= band[1]) & (fb[:m] > 1e-6 * max(band[1], 1.0))
    df = float(np.max(np.abs(fa[:m][ok] - fb[:m][ok]) / fb[:m][ok])) if ok.any() else 0.0
    deta = 0.0
    if c.matrix in ("C", "D"):
        sel = np.flatnonzero((fa >= band[0]) & (fa <= band[1]) & (fa > 0))
        om = 2 * np.pi * fa[sel]
        ph = phia[:, sel]
        add = np.zeros(sel.size)
        for A, B, f in ((with_.D, without.D, lambda x: x / om ** 2), (with_.C, without.C, lambda x: x / om)):
            if A is None:
                continue
            dA = A - B if B is not None else A
            add += f(np.einsum("ij,ij->j", ph, dA @ ph))
        eta_bg = max(float(with_.D.diagonal().sum() / max(with_.K.diagonal().sum(), 1e-300))
                     if with_.D is not None else 0.0, 1e-3)
        deta = float(np.max(np.abs(add))) / eta_bg if add.size else 0.0
    return df, deta


def n_obs(data: FRFData) -> int:
    """The number of observations every test of a term counts: the real and imaginary parts of the complex
    FRF values (``2 × data.H.size``).  :attr:`FRFData.sigma` is the standard error of each part relative to
    ``|H|`` (a complex value has two), so a model that fits to the noise leaves χ² ≈ ``n_obs`` — the
    information criterion of the screening and pick routes, their ambiguity margins and the χ² tests of
    :func:`_term_holds` all use this N."""
    return 2 * int(np.asarray(data.H).size)


def _residual(structure, data: FRFData) -> np.ndarray:
    """The FRF residual in units of the data's noise, (n_m, n_r, n_s) complex: ``(H_model − H)/(den σ)``."""
    return (model_frf(structure, data) - data.H) / (data.den * data.sigma)


def _chi2(structure, data: FRFData) -> tuple[float, int]:
    """χ² of ``structure`` against ``data`` in units of the data's noise (:attr:`FRFData.sigma`: coherence,
    averages, leakage, 1 % floor) and the number of observations (:func:`n_obs`)."""
    r = _residual(structure, data)
    return float(np.sum(np.abs(r) ** 2)), n_obs(data)


def inflation(r: np.ndarray) -> float:
    """Variance inflation of a χ² sum whose terms are correlated from one line to the next (model-form error
    leaves a residual smooth over frequency; measurement noise does not): ``(1 + ρ)/(1 − ρ)`` with ρ the
    lag-one autocorrelation of the residual along the lines (the last axis; real and imaginary parts pooled),
    clipped to [0, 0.999].  The effective number of independent observations is ``N`` / this (Bayley &
    Hammersley, J. R. Stat. Soc. Suppl. 8 (1946) 184-197).  Used for the significance of a term only; the
    parameters' standard deviations come from :func:`~updating.diagnosis.fit.correlated_std` (REML AR(1))."""
    r = np.asarray(r)
    r = np.stack([r.real, r.imag]) if np.iscomplexobj(r) else np.asarray(r, float)
    if r.shape[-1] < 3:
        return 1.0
    den = float(np.sum(r * r))
    if den <= 0:
        return 1.0
    rho = min(max(float(np.sum(r[..., 1:] * r[..., :-1])) / den, 0.0), 0.999)
    return (1 + rho) / (1 - rho)


#: one-sided level of the sign test over FRF rows by which one explanation fits worse than another (:func:`rows_worse`)
ROWS_LEVEL = 0.025


def rows_worse(r_o: np.ndarray, r_c: np.ndarray) -> bool | None:
    """Whether the residual ``r_o`` (noise units, ``(n_m, n_r, n_s)``) fits worse than ``r_c`` of another
    explanation with as many values (a term at another place, or another kind) on more FRF rows than chance
    allows: the exact one-sided sign test (binomial, level :data:`ROWS_LEVEL`) of the rows' χ² differences
    ``D = Σ_lines |r_o|² − |r_c|²``, rows with ``|D|`` below 1e-9 of the largest left out.  ``None`` where the
    rows cannot decide (so few that even all of them worse is not significant, ``0.5^m ≥ ROWS_LEVEL``): then the
    likelihood ratio (:func:`significant_gain`) decides alone.

    The likelihood ratio treats a χ² difference as that of nested models; between two non-nested ones it can be
    large and still carried by a few rows while the others prefer the other place (held-out case 3835, set AZ:
    a planar frame's joint at 8+RZ fitted to χ²/N 1.12 against 1.06 at 16+RZ, χ² 1401 apart, but worse on 19 of
    36 rows, p 0.43: "16 or 8").  Counting rows rather than weighing values keeps the test's power where the
    difference sits at a few resonances (Vuong's z over the values had none there: tuning 3288's local damping,
    χ²/N 0.04, got rotary inertias at 7.5 as alternatives, yet they are worse on 60 of 60 rows) and its size
    where the lines of a row are correlated: the rows' noise is independent."""
    d = (np.abs(r_o) ** 2 - np.abs(r_c) ** 2).reshape(-1, np.shape(r_c)[-1]).sum(axis=1)
    tol = 1e-9 * float(np.max(np.abs(d), initial=0.0))
    k, m = int(np.sum(d > tol)), int(np.sum(np.abs(d) > tol))
    if 0.5 ** m >= ROWS_LEVEL:
        return None
    return float(binom.sf(k - 1, m, 0.5)) < ROWS_LEVEL


def significant_gain(c0: float, c1: float, n: int, infl: float, penalty: float) -> tuple[bool, float, float]:
    """The one significance test of a term on χ² values in noise units (before ``c0``, after ``c1``, over
    ``n`` observations whose residual has the variance inflation ``infl``): the likelihood-ratio statistic
    of nested Gaussian models, with the variance the residual left after the term (the reduced χ², at least
    1: model-form error counts as noise, an F-test) and with ``n / infl`` independent observations, must
    exceed ``penalty`` × ln(``n / infl``) (a Bayesian information criterion, ``penalty`` times BIC's per
    term).  Returns ``(passed, statistic, needed)``."""
    infl = max(float(infl), 1.0)
    n_eff = max(n / infl, 2.0)
    stat = (c0 - c1) / (max(1.0, c1 / max(n, 1)) * infl)
    need = penalty * np.log(n_eff)
    return bool(stat > need), float(stat), float(need)


#: folds of the cross-validation of a term (:func:`cv_folds`)
CV_FOLDS = 4


#: evaluations of a fold's re-fit, which starts from the fit on the whole training part
CV_NFEV = 6


def cv_folds(data: FRFData, holdout: str | None) -> list:
    """``[(train, held, description)]``: the data cut into :data:`CV_FOLDS` disjoint held-out parts along the
    axis the single split of the diagnosis uses (:func:`~updating.diagnosis.priors._split`, whose held-out
    part is the second fold): response rows that are not driving points (every fourth, offset by the fold),
    else reference columns, else blocks of 8 lines.  Every held-out value of the axis is held out exactly
    once; a fold whose training or held-out part would be empty is left out."""
    n_m, n_r, n_s = data.H.shape
    refs = {(d.node, d.axis) for d in data.references}
    cand = [i for i, d in enumerate(data.responses) if (d.node, d.axis) not in refs]
    out = []
    if holdout in (None, "rows") and n_m >= 4 and cand:
        groups = [cand[k::CV_FOLDS] for k in range(CV_FOLDS)] if len(cand) >= CV_FOLDS else [[i] for i in cand]
        for g in groups:
            held = np.asarray(g, int)
            train = np.setdiff1d(np.arange(n_m), held)
            if held.size and train.size:
                out.append((data.take(rows=train), data.take(rows=held), f"rows {list(held)}"))
        return out
    if holdout in (None, "columns") and n_r >= 2:
        groups = [np.arange(n_r)[k::CV_FOLDS] for k in range(CV_FOLDS)] if n_r >= 4 else \
            [np.array([k]) for k in range(n_r)]
        for held in groups:
            train = np.setdiff1d(np.arange(n_r), held)
            if held.size and train.size:
                out.append((data.take(cols=train), data.take(cols=held), f"columns {list(held)}"))
        return out
    lines = np.arange(n_s)
    for k in range(CV_FOLDS):
        held = lines[(lines // 8) % CV_FOLDS == k]
        train = np.setdiff1d(lines, held)
        if held.size and train.size:
            out.append((data.take(lines=train), data.take(lines=held), f"line blocks {k}"))
    return out


def _term_holds(pm_cur, p_cur, pm_new, p_new, train: FRFData, held: FRFData, penalty: float,
                min_holdout_gain: float, folds_decide: bool = False) -> tuple[bool, str]:
    """Whether a term chosen on the training data earns its place on the FRFs: its χ² improvement must be
    significant against the noise (:func:`significant_gain`: scaled by the reduced χ² left when the residual
    is above the noise, and by the residual's correlation over lines) on the training FRFs **and** on the
    held-out FRFs, where the error must also fall by ``min_holdout_gain``.

    ``folds_decide``: the caller cross-validates the term over folds of references and responses next (the
    FRF route).  Held-out rows whose χ² is at the noise before the term (χ²/N at most
    :data:`PICK_MAX_REDUCED_CHI2`) barely see what is missing and cannot show it significantly, whatever the
    term: there, a held-out χ² that falls (by ``min_holdout_gain`` in error) is enough, and the folds — each
    refitted without its rows, every row held out once — decide whether the term holds out of sample."""
    parts = []
    for name, d in (("training", train), ("held-out", held)):
        c0, n = _chi2(pm_cur.structure(p_cur), d)
        r1 = _residual(pm_new.structure(p_new), d)
        c1 = float(np.sum(np.abs(r1) ** 2))
        ok, stat, need = significant_gain(c0, c1, n, inflation(r1), penalty)
        parts.append(f"{name} χ²/N {c0 / n:.3g} -> {c1 / n:.3g} (statistic {stat:.3g}, needed {need:.3g})")
        if not ok and name == "held-out" and folds_decide and c0 / n <= PICK_MAX_REDUCED_CHI2 and c1 < c0:
            parts.append("the held-out rows are at the noise without the term and cannot show it: the folds decide")
            ok = True
        if not ok:
            return False, "; ".join(parts) + f": not significant on the {name} FRFs"
        if name == "held-out" and not np.sqrt(c1 / c0) <= 1 - min_holdout_gain:
            return False, "; ".join(parts) + f": the held-out FRF error falls by less than {100 * min_holdout_gain:.0f} %"
    return True, "; ".join(parts)


def held_out_worse(st_new, st_old, held: FRFData, penalty: float) -> tuple[bool, str]:
    """Whether the structure ``st_new`` fits the held-out FRFs ``held`` significantly worse than ``st_old``
    (:func:`significant_gain` from ``st_new``'s χ² to ``st_old``'s): when ``st_new`` fits the training FRFs better
    than ``st_old``, its gain does not hold out of sample.  Held-out AU 3499, a planar frame's joint at 14+RX:
    the MCI's choice, that joint, left held-out χ²/N 0.45, and a joint at node 8 that fitted the training FRFs
    better (0.23 against 0.30) 2.56 — it replaced the right joint.  Returns ``(worse, why)``."""
    c_n, n = _chi2(st_new, held)
    r_o = _residual(st_old, held)
    c_o = float(np.sum(np.abs(r_o) ** 2))
    worse, stat, need = significant_gain(c_n, c_o, n, inflation(r_o), penalty)
    return worse, f"χ²/N {c_n / n:.3g} against {c_o / n:.3g}, statistic {stat:.3g}, needed {need:.3g}"


def promote_measured(model: FEModel, dofs) -> FEModel:
    """The model with every measured DOF independent and in basic directions.  A measured grid with a
    displacement system of its own (CD) is put in basic (same physics; refused with a clear error when it
    carries constraints in that system).  A one-to-one rigid link (RBE2, all six components)
    whose dependent node is measured and whose independent node is not is reversed — the same constraint,
    written the other way round, so the measured node keeps its own DOFs.  Returns ``model`` itself when
    nothing needs changing; measured DOFs that stay eliminated are reported by the caller's DOF lookup."""
    measured = {d.node for d in parse_dofs(list(dofs))}
    out = model
    # measured directions are basic: a measured grid with its own displacement system is written in basic
    # (the same physics) unless something is constrained in that system
    spc_nodes = {sp_.node for sp_ in model.spcs}
    partial = {n for link in model.rbe2s.values() if set(link.components) != {1, 2, 3, 4, 5, 6}
               for n in (link.independent, *link.dependents)}
    for n in sorted(measured):
        node = model.nodes.get(n)
        if node is None or node.cd is None or np.allclose(node.cd, np.eye(3)):
            continue
        if n in spc_nodes or n in partial:
            raise ModalabValueError(f"measured grid {n} has its own displacement system (CD) and constraints in "
                                    "it; give the measured directions in that system's node or remove the CD")
        if out is model:
            out = model.copy()
        out.nodes[n] = type(node)(node.nid, node.xyz, None)
        log.info("measured grid %d: its displacement system set to basic (measured directions are basic)", n)
    if out is not model:
        out._changed()
    st_dofs = {(d.node, d.axis) for d in out.structure().dofs}
    for link in list(model.rbe2s.values()):
        if len(link.dependents) != 1 or set(link.components) != {1, 2, 3, 4, 5, 6}:
            continue
        dep = link.dependents[0]
        if dep in measured and link.independent not in measured and \
                not any((dep, a) in st_dofs for a in range(1, 7)):
            if out is model:
                out = model.copy()
            del out.rbe2s[link.eid]
            out.add_rbe2(link.eid, dep, (link.independent,), "123456")
            log.info("rigid link %d reversed: measured node %d made independent (node %d follows it)",
                     link.eid, dep, link.independent)
    if out is not model:
        out._changed()
    return out


def _on_model_dofs(model: FEModel, measured: FRF) -> FRF:
    """``measured`` without the response rows whose DOF the model eliminates (both ends of a rigid link
    measured, a constrained component measured), with a warning naming them; a reference the model
    eliminates is an error that says what to do."""
    have = {(d.node, d.axis) for d in model.structure().dofs}
    refs_out = [str(r) for r in measured.references if (r.node, r.axis) not in have]
    if refs_out:
        raise ModalabValueError(f"reference DOF(s) {', '.join(refs_out)} are not independent DOFs of the model "
                                "(constrained, or the dependent end of a rigid link whose other end is measured "
                                "too); remove those columns or model the link with stiff springs")
    keep = [str(d) for d in measured.responses if (d.node, d.axis) in have]
    dropped = [str(d) for d in measured.responses if (d.node, d.axis) not in have]
    if dropped:
        log.warning("measured DOF(s) %s are eliminated in the model (constrained or rigidly linked to another "
                    "measured node) and are left out of the diagnosis", ", ".join(dropped))
        if len(keep) < 2:
            raise ModalabValueError(f"only {len(keep)} measured response DOF(s) are independent DOFs of the model "
                                    f"(left out: {', '.join(dropped)}); check the node numbering")
        return measured.select(responses=keep)
    return measured


def _dof_stiffness(structure, c) -> float:
    """The diagonal stiffness at a candidate's DOF (at its first node, or its partner across a rigid link;
    else the median over DOFs of the same kind, translational or rotational)."""
    d = parse_dofs(c.dofs)[0] if c.dofs else None
    diag = np.abs(structure.K.diagonal())
    if d is not None:
        for n in (d.node,) + tuple(c.nodes):
            for i, x in enumerate(structure.dofs):
                if x.node == n and x.axis == d.axis and diag[i] > 0:
                    return float(diag[i])
        same = [diag[i] for i, x in enumerate(structure.dofs) if (x.axis >= 4) == (d.axis >= 4)]
        if same:
            return float(np.median(same)) or 1.0
    return float(np.median(diag)) or 1.0


def _upper(cands: list, scales: list) -> np.ndarray:
    """Upper bounds of the candidates' parameters (their plausible values over the parameter scales)."""
    return np.array([getattr(c, "upper", np.inf) / sc for c, sc in zip(cands, scales)], float)


def _augment(model: FEModel, cands: list) -> tuple[FEModel, list, list]:
    m = model
    params, scales = [], []
    eid = max(list(m.elements) + list(m.rbe2s) + [0]) + 1000
    for c in cands:
        m, par, scale = c.apply(m, eid)
        eid += 10
        params.append(par)
        scales.append(scale)
    return m, params, scales


class AugmentedModel(ParametricFEModel):
    """A :class:`ParametricFEModel` of a model with candidate terms added (:func:`_augmented`); ``terms`` holds
    the terms' keys in their order, which with the nominal model and its parameters define it."""

    def __init__(self, model: FEModel, parameters, terms: tuple):
        super().__init__(model, parameters)
        self.terms = tuple(terms)


def _augmented(model: FEModel, params: list, lower: np.ndarray, upper: np.ndarray, terms: list):
    """The model with the candidate ``terms`` added (:func:`_augment`), parametrised by ``params`` and the
    terms' values: ``(AugmentedModel, lower, upper, scales)``, the bounds ``lower``, ``upper`` of ``params``
    followed by zero and each term's plausible value (:func:`_upper`), ``scales`` the factors from the terms'
    fitted parameters to their physical values."""
    m_aug, cpar, scales = _augment(model, terms)
    lo = np.concatenate([lower, np.zeros(len(cpar))])
    hi = np.concatenate([upper, _upper(terms, scales)])
    return AugmentedModel(m_aug, list(params) + cpar, [c.key for c in terms]), lo, hi, scales


def _evidence(c: Candidate, gain: float | None, rank_same_place: list, band, use_mci: bool = True) -> str:
    kind = {"K": "real and constant over frequency (a stiffness)", "M": "real and growing as −ω² (an inertia)",
            "C": "imaginary and growing with ω (viscous damping)", "D": "imaginary and constant (hysteretic damping)"}[c.matrix]
    where = ', '.join(c.dofs) or 'node ' + ','.join(map(str, c.nodes))
    if use_mci:
        alt = ", ".join(f"{o.physics.replace('_', ' ')} there explains {pct(100 * g)} %" for o, _, g in rank_same_place[:2])
        s = (f"the dynamic-stiffness residual at {where} is {kind} between {band[0]:.3g} and {band[1]:.3g} Hz; this "
             f"term alone explains {pct(100 * gain)} % of the residual left after parameter updating")
    else:
        alt = ", ".join(f"{o.label} {pct(100 * g)} %" for o, _, g in rank_same_place[:2])
        alone = (f"added alone at its best value, a dynamic stiffness at {where} that is {kind} removes "
                 f"{pct(100 * gain)} % of the FRF error between {band[0]:.3g} and {band[1]:.3g} Hz") \
            if gain is not None else (f"released with the rest of its support (not screened alone), a dynamic "
                                      f"stiffness at {where} that is {kind}")
        s = (alone + "; with the parameters re-fitted it gave the lowest training error of the candidates tried "
             "and passed the information criterion")
    return s + (f" (competing at the same place: {alt})" if alt else "")
