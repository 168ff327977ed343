"""The diagnosis workflow: baseline updating, localisation, naming, modelling, proof.

``Diagnoser(DiagnoserConfig(...)).fit(model, frf)`` (:func:`diagnose` is a thin wrapper) runs, on an
:class:`~updating.fe.FEModel` and measured FRFs:

1. **baseline** — the FRFs as receptance with a noise estimate per value (:attr:`~.fit.FRFData.sigma`:
   coherence and number of averages, the leakage bound of spectral lines, a 1 % floor), split into training
   and held-out parts (response rows, else reference columns, else blocks of lines); the nominal model with
   its loss factor fitted; parameter-only updating as a maximum a posteriori fit with priors on the
   parameters (E, G ±5 %, density ±3 %, sections ±5 %, damping free; :func:`parameter_priors`); where the
   model with its beams cut in two fits the data better by the information criterion, the nominal mesh's own
   error is taken out of the data (:func:`~updating.diagnosis.mesh.mesh_discrepancy`) and steps 1-2 repeated
   (also when it does so only with the first term's best pick in both models, which failed by the χ² it
   leaves: :meth:`Diagnoser._mesh_shows`; the diagnosis then starts again from step 2);
2. **localise** — the condensed force residual (MCI, thesis 3.2.4) of the model for models up to
   :data:`MCI_LIMIT` DOFs, or the training FRF error above (``criterion``);
3. **screen** — one term at a time: every candidate of the library (:mod:`~updating.diagnosis.library`) is
   screened linearly on the MCI residual and exactly on the FRFs by a low-rank update
   (:func:`~updating.diagnosis.frfscreen.frf_screen`), joint and support releases exactly at every place
   (:func:`~updating.diagnosis.release.release_screen`); the best few and the best release of each kind are
   fitted with the parameters.  The best term is kept only if (a) it passes an information criterion
   (``penalty`` × ln N), (b) its χ² gain is significant against the noise on the training **and** on the
   held-out FRFs (:func:`~updating.diagnosis.terms.significant_gain`: scaled by the reduced χ² left when
   model-form error dominates, an F-test, and by the residual's correlation over lines), the held-out error
   falling by
   ``min_holdout_gain``, and (c) it changes an in-band natural frequency by :data:`MIN_FREQ_EFFECT` beyond
   the nominal beam mesh's own error of that mode (:mod:`~updating.diagnosis.mesh`) or the modal damping by
   :data:`MIN_DAMPING_EFFECT` of the background (smaller effects are the size of model-form error).  Candidates elsewhere that fit as well (within the criterion's margin) make the finding ambiguous.
   On the MCI criterion, when its best option fails for the first term, the exact FRF screening's best picks
   are fitted on the FRFs and judged by the same tests, and must leave a reduced χ² of at most
   :data:`PICK_MAX_REDUCED_CHI2` (the linearised MCI is blind to e.g. a spring to ground that mainly moves a
   free frame's rigid-body modes); when the MCI's best passes for the first term, it competes with the picks
   on the training FRFs (the MCI can prefer an inertia where a clamp is released).  On the FRF criterion, when
   the first term's best option passes the information criterion and fails a later test, the best option of
   each other kind is judged in turn (:meth:`Diagnoser._judge_other_kinds`: a suspension's spring too small to
   be missing physics can fit better than the damping that is).  On the FRFs a term must
   also hold under cross-validation over :data:`~updating.diagnosis.terms.CV_FOLDS` folds
   (:meth:`Diagnoser._cross_validated`); every test counts the same observations (:func:`~updating.diagnosis.terms.n_obs`);
   An accepted support release is completed by the other components of its constraint when the data
   support them (:mod:`~updating.diagnosis.refine`): one elastic clamp, one finding with two stiffnesses;
4. **model** — the selected terms updated jointly with the parameters on the FRFs; backward elimination
   drops terms that no longer earn their place;
5. **prove** — nominal, parameter-only and augmented models compared on the held-out FRFs and on the test
   modes (:func:`pair_test_modes`: rigid-body and suspension modes excluded on purpose, MAC ≥
   :data:`PAIR_MAC_MIN` within a :data:`PAIR_MAX_FREQ_ERROR` frequency window).

FRF fits and exact FRF screenings of models above :data:`~updating.diagnosis.fit.RITZ_LIMIT` DOFs run in a Ritz basis
(:mod:`~updating.diagnosis.ritz`), checked against the exact receptance.
"""
from __future__ import annotations

import copy
import dataclasses
import logging
import time
from dataclasses import dataclass

import numpy as np

from modalab.core.errors import ModalabValueError
from modalab.core.modes import ModeSet
from modalab.core.frf import FRF
from modalab.core.parallel import fork_map
from updating.fe import FEModel, ParametricFEModel
from updating.fe.damping import own_loss_exempt
from updating.diagnosis.fit import Prior, fit_frf, fit_std, frf_data, frf_error, model_frf
from updating.diagnosis.library import build_library, spring_loss_candidates, validate_kinds
from updating.diagnosis.release import release_visibility
from updating.diagnosis.screen import mci_update
from updating.diagnosis.priors import default_parameters, PRIOR_BOUND, parameter_priors, _with_damping, _split, _bounds, _fit_continued, nonnegative_loss_factors
from updating.diagnosis.terms import AugmentedModel, _another_explanation, cv_folds, n_obs, promote_measured, _on_model_dofs, _upper, _augment
from updating.diagnosis.testmodes import suspension_band
from updating.diagnosis.mesh import mesh_discrepancy
from updating.diagnosis.findings import Finding, Diagnosis, or_labels
from updating.diagnosis.acceptance import IC_FAILED, _Acceptance
from updating.diagnosis.proof import _Proof
from updating.diagnosis.refine import _Refine
from updating.diagnosis.eliminate import _Eliminate
from updating.diagnosis.options import _Options

log = logging.getLogger(__name__)

#: models up to this many DOFs are localised on the MCI (thesis 3.2.4), larger ones on the training FRF error
#: (``criterion='auto'``); the MCI of a larger model also iterates less (3 steps instead of 6).  Whether FRF
#: fits run in a Ritz basis is a separate, numerical choice (:data:`~updating.diagnosis.fit.RITZ_LIMIT`)
MCI_LIMIT = 200

__all__ = ["diagnose", "Diagnoser", "DiagnoserConfig", "Diagnosis", "Finding", "default_parameters"]


@dataclass
class DiagnoserConfig:
    """Settings of a :class:`Diagnoser` (the keywords of :func:`diagnose`)."""

    parameters: list | None = None        # updating parameters (default: E and ρ per property group)
    max_lines: int = 160
    holdout: str | None = None            # 'rows', 'columns', 'lines' or None (rows, else columns, else lines)
    kinds: object = None                  # kinds of physics (validated, :data:`~updating.diagnosis.library.KINDS`)
    max_findings: int = 3
    min_holdout_gain: float = 0.10
    penalty: float = 10.0
    band_hz: tuple | None = None
    progress: object = None
    max_nfev: int = 30
    n_try: int = 5
    min_term_gain: float = 0.15
    test_modes: ModeSet | None = None
    criterion: str = "auto"
    min_extra_gain: float = 0.25
    priors: dict | None = None            # parameter name -> relative prior σ or 'free'
    mesh_correction: bool = True          # the beam mesh's own error out of the data where they show it
    screen_refit: bool = True             # screenings around the parameter-only fit re-fit the parameters (1st order)
    jobs: int | None = None               # processes for a step's independent fits (None: the cores available)

    def __post_init__(self):
        self.kinds = validate_kinds(self.kinds)
        if self.criterion not in ("auto", "mci", "frf"):
            raise ModalabValueError(f"criterion={self.criterion!r}: expected 'auto', 'mci' or 'frf'")
        if self.holdout not in (None, "rows", "columns", "lines"):
            raise ModalabValueError(f"holdout={self.holdout!r}: expected 'rows', 'columns', 'lines' or None")
        if self.jobs is not None and (isinstance(self.jobs, bool) or not isinstance(self.jobs, int) or self.jobs < 1):
            raise ModalabValueError(f"jobs={self.jobs!r}: expected a positive number of processes or None")


class Diagnoser(_Acceptance, _Options, _Refine, _Proof, _Eliminate):
    """Missing-physics diagnosis as an estimator: ``Diagnoser(config).fit(model, frf)`` runs the steps
    :meth:`baseline`, :meth:`localise`, :meth:`screen` (one term at a time), :meth:`model` and :meth:`prove`
    (module docstring) and exposes ``findings_`` (list of :class:`Finding`), ``fit_`` (the fit blocks),
    ``ranking_`` (the first screening) and ``diagnosis_`` (the whole :class:`Diagnosis`)."""

    def __init__(self, config: DiagnoserConfig | None = None, **kw):
        self.config = dataclasses.replace(config or DiagnoserConfig(), **kw) if kw else (config or DiagnoserConfig())

    def _say(self, msg):
        (self.config.progress or log.info)(msg)

    def _decide(self, decision: str, cand, reason: str, *, sep: str = " (") -> None:
        """One verdict of the selection, said as progress (``  found: LABEL (reason)``) and kept for
        ``diagnosis.json`` (``decisions``: decision, candidate, physics, reason) — the one record of why a
        candidate was taken, turned down, made ambiguous or dropped."""
        self.decisions.append({"decision": decision, "candidate": cand.label, "physics": cand.physics,
                               "reason": reason})
        self._say(f"  {decision}: {cand.label}{sep}{reason}{')' if sep == ' (' else ''}")

    def fit(self, model: FEModel, measured: FRF) -> "Diagnoser":
        self._t0 = time.perf_counter()
        self.timings = {}
        self.baseline(model, measured)
        self.localise()
        self._screen_all()
        if self._mesh_restart is not None:      # the mesh's error shows once the best pick is in both models
            t_r, kept = time.perf_counter(), {k: self.timings[k] for k in ("1 nominal", "2 parameters")}
            first = t_r - self._t1                          # the first pass's steps 3-4
            self._take_out_mesh(*self._mesh_restart)
            self.localise()                                 # steps 3-4 timed afresh from here
            # steps 1-2 as first run; the first pass's steps 3-4 and the re-fit on the corrected data apart
            self.timings.update(kept)
            self.timings["mesh restart"] = first + (self._t1 - t_r)
            self._screen_all()
        self.timings["3-4 localise+name"] = time.perf_counter() - self._t1
        self.model()
        self.diagnosis_ = self.prove()
        self.findings_, self.fit_, self.ranking_ = self.diagnosis_.findings, self.diagnosis_.fit, self.diagnosis_.ranking
        return self

    def _screen_all(self):
        """Steps 3-4 term by term (:meth:`screen`) until one finds nothing; an accepted support release is
        completed (:meth:`~updating.diagnosis.refine._Refine._refine_supports`) before the next term is sought."""
        for it in range(self.config.max_findings):
            if not self.screen(it):
                break
            self._refine_supports()

    def _mesh_shows(self, c, pm_aug, fr, clo, chi) -> bool:
        """Whether the nominal mesh's error shows once the best pick ``c`` (fitted: ``pm_aug`` at ``fr.p``,
        bounds ``clo``, ``chi``), which failed by the χ² it leaves, is in both models: the data were used as
        measured (:func:`~updating.diagnosis.mesh.mesh_discrepancy` judged the models without it), no term is
        accepted yet, and the mesh cut in two with ``c`` fits the data better by the same test.  Then the
        mesh's error with ``c`` is kept to be taken out of the data (``_mesh_restart``) and the diagnosis starts
        again from its steps 1-2 (:meth:`~updating.diagnosis.workflow.Diagnoser.fit`); once per diagnosis.
        A concealed effect decides the comparison without it: held-out 2847 (seen after its score), a T's
        joint of 7.4e5 N·m/rad, the mesh cut in two fits to χ²/N 19.5 against 16 without the joint; with it,
        the coarse mesh leaves 4.8 (28 % of the residual: rejected), the mesh cut in two 0.17."""
        if self._mesh_checked or self.current:
            return False
        self._mesh_checked = True
        D, why = self._mesh_discrepancy(pm_aug.model, pm_aug.parameters, fr.p, clo, chi)
        if D is None:
            log.info("mesh, with %s in both models: %s: the data stay as measured", c.label, why)
            return False
        log.info("mesh, with %s in both models: %s: the mesh's error is taken out and the diagnosis starts again",
                 c.label, why)
        self._mesh_restart = (D, f"with {c.label} in both models, {why}")
        return True

    def _mesh_discrepancy(self, model: FEModel, params: list, p, lower, upper):
        """:func:`mesh_discrepancy` of ``model`` (parameters ``params`` at ``p``) on the diagnosis' data, with its
        MAP fit bounded by ``lower``, ``upper``: ``(D or None, reason)``."""
        cfg = self.config
        return mesh_discrepancy(lambda pm_, d, p0: self._fit(pm_, d, p0, lower=lower, upper=upper,
                                                             max_nfev=cfg.max_nfev),
                                model, params, p, self.data, self.train, self.held, cfg.penalty)

    def _fit(self, *a, **k):
        """A MAP FRF fit with the parameters' priors."""
        return fit_frf(*a, prior=self.prior, **k)

    def _fit_converged(self, pm, start, lower, upper):
        """A candidate's MAP fit with the parameters on the training FRFs, which its tests then judge: a short
        fit (``max(8, max_nfev // 2)`` evaluations, which most candidates need), continued from where it
        stopped with the full budget when it stopped at that limit and not at its optimum.  A candidate is
        judged at its optimum, not where a budget ran out (held-out 2847, analysed after its score: a T's
        joint started at the screening's 5.5e6 N·m/rad stopped at 1.6e6 after 15 evaluations, training
        χ²/N 11.9; continued, at 8.3e5 and 4.8 after 25).  A fit still short of its optimum is logged."""
        cfg = self.config
        key = (pm.terms, *(np.asarray(a, float).tobytes() for a in (start, lower, upper))) \
            if isinstance(pm, AugmentedModel) else None
        if key in self._fits_done:             # the same fit again (a screening pick an option was): its result
            return copy.deepcopy(self._fits_done[key])
        fr = self._fit(pm, self.train, start, lower=lower, upper=upper, max_nfev=max(8, cfg.max_nfev // 2))
        if not fr.success:
            fr = self._fit(pm, self.train, fr.p, lower=lower, upper=upper, max_nfev=cfg.max_nfev,
                           err_start=fr.error)
            if not fr.success:
                log.info("an FRF fit stopped at its evaluation budget short of its optimum (%s)", fr.message)
        if key is not None:
            self._fits_done[key] = copy.deepcopy(fr)   # kept apart from what the caller may change
        return fr

    # ------------------------------------------------------------------ steps 1-2
    def baseline(self, model: FEModel, measured: FRF):
        """The data and their split, the nominal model with fitted damping, the priors, parameter updating."""
        cfg = self.config
        model = promote_measured(model, list(measured.responses) + list(measured.references))
        self.measured = measured = _on_model_dofs(model, measured)
        params = list(cfg.parameters) if cfg.parameters is not None else default_parameters(model)
        damp, dstart = _with_damping(model, params)
        if any(p.field == "global_ge" for p in damp):      # the fitted G is the structure's, not the mounts'
            model = own_loss_exempt(model)
        self.model0 = model
        self.params = params = params + damp
        self.n_damp = len(damp)
        self.pm = pm = ParametricFEModel(model, params)
        self.p_nom = np.array(pm.p0, float)
        self.n_dof = pm.structure(pm.p0).n_dof
        self.p_nom[len(params) - len(damp):] = dstart
        # the priors (their means: the nominal values) also bound the fits at PRIOR_BOUND standard deviations
        self.pmean, self.psig = parameter_priors(params, self.p_nom, cfg.priors)
        self.lo, self.hi = _bounds(params, self.p_nom)
        self.lo = np.maximum(self.lo, self.pmean - PRIOR_BOUND * self.psig)
        self.hi = np.minimum(self.hi, self.pmean + PRIOR_BOUND * self.psig)
        # a free model of a test article on a suspension: the suspension's lines are left out of the fits
        self.suspension_hz = suspension_band(pm.structure(self.p_nom), measured, cfg.band_hz)
        band = cfg.band_hz
        if self.suspension_hz is not None:
            self._say(f"  lines below {self.suspension_hz:.3g} Hz left out: the free model's test article hung on a "
                      "suspension")
            band = (max(self.suspension_hz, band[0] if band else 0.0), band[1] if band else None)
        self._use_data(frf_data(measured, max_lines=cfg.max_lines, band_hz=band))
        self.band = (float(self.data.freq_hz.min()), float(self.data.freq_hz.max()))
        self._say("step 1/6: correlating the nominal model")
        self._fit_baseline()
        self.mesh_note, self._mesh_restart, self._mesh_checked = None, None, not cfg.mesh_correction
        if not cfg.mesh_correction:
            return
        # the nominal beam mesh's own error taken out of the data, where the data show it (mesh_discrepancy)
        D, why = self._mesh_discrepancy(model, params, self.upd.p, self.lo, self.hi)
        if D is None:
            log.info("mesh: %s: the data are used as measured", why)
            return
        self._take_out_mesh(D, why)

    def _take_out_mesh(self, D, why: str):
        """The nominal mesh's error ``D`` (:func:`mesh_discrepancy`) taken out of the data, steps 1-2 repeated."""
        self.mesh_note, self._mesh_restart, self._mesh_checked = why, None, True
        self._say(f"  the nominal beam mesh's own error taken out of the data: {why}")
        self._use_data(dataclasses.replace(self.data, H=self.data.H - D, _den=self.data.den))
        self._fit_baseline(say=False)

    def _use_data(self, data):
        """``data`` as the diagnosis' FRFs, with their training and held-out parts and the cross-validation folds."""
        self.data = data
        self.train, self.held, self.held_desc = _split(data, self.config.holdout)
        self._folds = cv_folds(data, self.config.holdout)

    def _fit_baseline(self, say: bool = True):
        """Steps 1-2 on the data: the nominal with fitted damping, the priors' scale, parameter updating."""
        cfg, pm, params, model = self.config, self.pm, self.params, self.model0
        # 1. nominal (damping fitted so that errors compare like with like)
        self.free_d = np.zeros(len(params), bool)
        self.free_d[len(params) - self.n_damp:] = True
        self.nom = fit_frf(pm, self.train, self.p_nom, lower=self.lo, upper=self.hi, free=self.free_d,
                           max_nfev=cfg.max_nfev)
        self.nom, _ = nonnegative_loss_factors(pm, self.train, self.nom, self.lo, self.hi, free=self.free_d,
                                               model_ge=model.global_ge, max_nfev=cfg.max_nfev)
        self.p_nomd = self.nom.p
        self._mesh = None                              # the beam mesh's own error, when a term needs it
        # the parameters' priors (MAP fits from here on): one prior σ weighs as much as an average independent
        # observation of the nominal model's residual, with one independent value per 10 FRF values
        n_eff = max(self.train.H.size / 10.0, 1.0)
        self.prior = Prior(self.pmean, self.psig,
                           float(self.nom.error * np.sqrt(np.sum(self.train.quality ** 2) / n_eff)))
        self._fits_done = {}                           # _fit_converged's results on these data with this prior
        self.timings["1 nominal"] = time.perf_counter() - self._t0
        # 2. parameter-only updating
        if say:
            self._say("step 2/6: updating the declared parameters (baseline)")
        t1 = time.perf_counter()
        # the reference every term is judged against: exact up to MCI_LIMIT DOFs (a fit in a Ritz basis can stop
        # in another minimum: tuning case 1632's parameters-only error 0.139 against the exact fit's 0.1346)
        self.upd = _fit_continued(pm, self.train, self.p_nomd, self.free_d, self.lo, self.hi, cfg.max_nfev,
                                  prior=self.prior, reduced=None if self.n_dof > MCI_LIMIT else False, jobs=cfg.jobs)
        self.timings["2 parameters"] = time.perf_counter() - t1

    # ------------------------------------------------------------------ step 3
    def localise(self):
        """The criterion and its starting point: the MCI minimised over the parameters (thesis 3.2.4), or the
        training FRF error of the better of nominal and updated."""
        cfg = self.config
        self._say("step 3/6: localising the residual (MCI) and 4/6: ranking candidate physics")
        self._t1 = time.perf_counter()
        self.large = self.n_dof > MCI_LIMIT
        crit = cfg.criterion if cfg.criterion != "auto" else ("frf" if self.large else "mci")
        self.use_mci = crit == "mci"
        self.free_mci = np.ones(len(self.params), bool)
        if self.use_mci:
            # from the nominal model with the default damping: the damping fitted to the FRFs of a poor nominal
            # model is often inflated to hide the mismatch
            self.p_mci, self.rss_cur, self.W = mci_update(self.pm, self.p_nom, self.train, self.lo, self.hi,
                                                          free=self.free_mci)
            self.p_cur = self.p_mci
        else:
            self.p_mci, self.W = self.p_nomd, None
            upd, nom = self.upd, self.nom
            self.p_cur, self.rss_cur = (upd.p, upd.error ** 2) if upd.error <= nom.error else (self.p_nomd,
                                                                                             nom.error ** 2)
        self.current, self.alternatives, self.decisions = [], {}, []
        self.pm_cur, self.lo_cur, self.hi_cur = self.pm, self.lo, self.hi
        self._frf_cur = (self.pm, self.upd)             # the current model fitted on the FRFs
        self._screens, self._route, self.not_evaluated, self._tension_keys, self._tension_notes = [], {}, [], set(), {}
        self._rival_fit, self._refined, self._round_fits = None, set(), {}
        self._displaced = None                          # the MCI's accepted choice a screening pick replaced
        self._observability()
        self.ranking, self.hot_nodes, self.n_lib = None, [], 0

    def _observability(self):
        """Joint and support releases that no data of this sensor and hit layout can reveal: released
        completely, each changes the measured FRFs (all of them, training and held-out, at the nominal model
        with its fitted damping) by a χ² (in units of the noise) below ``penalty`` × ln N — the least gain
        any term must show (:func:`_term_holds`) — so neither a finding nor its absence says anything about
        them (:func:`~updating.diagnosis.release.release_visibility`).  They are not screened, and the
        diagnosis lists them (``unobservable``) and says so in its statement."""
        lib = build_library(self.model0, kinds=self.config.kinds, log_level=logging.DEBUG)
        rel = [c for c in lib if c.release is not None]
        self.unobservable, self._hidden = [], set()
        if not rel:
            return
        m_nom = self.pm.model_at(self.p_nomd)
        need = self.config.penalty * np.log(n_obs(self.data))
        for c, chi2 in release_visibility(self.pm.structure(self.p_nomd), m_nom, rel, self.data,
                                          loss_factor=float(m_nom.global_ge or 0.0)):
            if chi2 < need:
                self._hidden.add(c.key)
                self.unobservable.append({"candidate": c.label, "physics": c.physics, "dofs": list(c.dofs),
                                          "nodes": [int(n) for n in c.nodes], "chi2_full_release": chi2,
                                          "reason": f"released completely it changes the measured FRFs by χ² "
                                                    f"{chi2:.2g} (noise units), below {need:.3g}: the sensors and "
                                                    "hits do not see it"})
        if self.unobservable:
            log.info("%d release candidate(s) unobservable with these sensors and hits: %s", len(self.unobservable),
                     ", ".join(d["candidate"] for d in self.unobservable[:6]))

    # ------------------------------------------------------------------ step 4, one term
    def screen(self, it: int) -> bool:
        """Screen the library around the current model, try the best options with the parameters re-fitted,
        and add the best term if it earns its place; False when none does.

        The best option by the criterion is judged first (:meth:`_judge`).  On the MCI criterion, when it
        fails for the first term, the exact FRF screening's best picks are fitted on the FRFs and the best of
        them is judged by the same tests (:meth:`_judge_picks`): the linearised MCI is blind to effects that
        act through unmeasured DOFs or that mainly move rigid-body and suspension modes (a spring to ground on
        a free frame), which the exact screening sees.  A first term that passes, on either criterion, competes
        with those picks on the training FRFs (``rival``; AH 2717: a mass named a rotary inertia elsewhere)."""
        cfg = self.config
        self._rival_fit, self._option_fits, self._rival_alts, self._round_fits = None, {}, [], {}
        options = self._options(it)
        best, evaluated = None, []
        best = self._run_options(options, it, best, evaluated)
        best = self._run_options(self._nearby_options(evaluated, options), it, best, evaluated)
        n_eq = (self.W.size * len(self.train.responses) * 2) if self.use_mci else n_obs(self.train)
        ok, why = self._judge(best, n_eq)
        if best is not None:
            log.info("candidate %s on the %s: %s", best[0].label, "MCI and FRFs" if self.use_mci else "FRFs", why)
        failed = set()
        if not ok and best is not None and not self.use_mci and not self.current and why != IC_FAILED:
            ok, best, why, failed = self._judge_other_kinds(best, why, evaluated, n_eq)
        # the first term: the criterion's choice and the exact FRF screening's picks compete on one likelihood, the
        # training FRFs' (the criterion fits only the options it ranked best); the MCI's choice must show there
        picked = self._judge_picks(it, n_eq, rival=best) if ok and not self.current else None
        if ok and picked is None and self.use_mci and not self.current:
            ok, why = self._rival_shown(best, why)
        if picked is not None:
            on = "MCI" if self.use_mci else "FRFs"
            self._decide("rejected", best[0], f"passed on the {on}, but {picked[0].label} fits the training FRFs "
                                              "better by the information criterion")
            self._displaced = best[0]
            c, alts = picked
        elif ok:
            c, self.rss_cur, self.pm_cur, self.p_cur, self.lo_cur, self.hi_cur = best
            self._displaced = None
            if self._rival_fit is not None:
                self._frf_cur = (self.pm_cur, self._rival_fit)
            else:
                self._frf_cur = None                   # the FRF fit of the new current model, when needed
            margin = self.rss_cur * cfg.penalty * np.log(n_eq) / n_eq      # equally good elsewhere: within this
            alts = [(o, v) for o, r, v in sorted(evaluated, key=lambda t: t[1])
                    if o.key != c.key and (o.physics, o.value_name) not in failed
                    and _another_explanation(o, c, self.pm_cur.model_at(self.p_cur))
                    and r - self.rss_cur <= margin]
            alts += [t for t in self._rival_alts if t[0].key not in {o.key for o, _ in alts}]   # picks fitted as well
            self._route[c.key] = (next((g for o, _, g in (self.ranking or []) if o.key == c.key), 0.0), self.use_mci,
                                  None)
        elif self.use_mci and (not self.current or self._displaced is not None):
            # the rescue of the first term only: a further term needs the criterion's support (model-form error
            # — a coarse mesh, per-element scatter — is what an exact single-term screening finds next).  The
            # one exception is the term after a pick that replaced the MCI's accepted choice: that choice kept
            # the MCI's support (two cords of a beam: the MCI names one, the FRFs prefer the other first), so
            # the picks are judged once more, with the replaced choice counted as supported
            if best is not None:
                self._decide("rejected", best[0], why)
            supported, self._displaced = self._displaced or (best[0] if best is not None else None), None
            picked = self._judge_picks(it, n_eq, mci_best=supported,     # refit: see _judge_picks
                                       mci_refit=best is not None and why != IC_FAILED)
            if picked is None:
                return False
            c, alts = picked
        else:
            if best is not None:
                self._decide("rejected", best[0], why)
            return False
        parts = self.__dict__.pop("_parts_pending", [])    # the rest of a support released with c (refine)
        self.current.extend(parts)                          # before c: the augmented model's order
        self.current.append(c)
        for o in parts:
            self._route[o.key] = (None, False, [])        # not screened alone
            self._decide("found", o, f"as a part of {c.label}, released with it")
        if alts:                     # every place the data cannot tell from c's (along a stiff member: all)
            self.alternatives[c.key] = alts
            self._decide("ambiguous", c, f"{alts[0][0].label}{or_labels(c, [o for o, _ in alts[1:]])} explain it "
                                         "equally well", sep=" or ")
        self._decide("found", c, f"{'MCI residual' if self.use_mci else 'training FRF error'} down to "
                                 f"{self.rss_cur if self.use_mci else np.sqrt(self.rss_cur):.3g}")
        return True

    def _library(self, model: FEModel) -> list:
        """The candidates of :func:`build_library` for ``model``; on a free model of a test article on a
        suspension (:func:`suspension_band`), without dashpots to ground: a free-free test article dissipates
        into the ground only through its suspension, whose lines are left out — above them a suspension's
        dashpot acts on the elastic modes (f_s/f)² times less than on its own modes — so a grounded dashpot
        fitted there would stand in for the per-section structural damping the background leaves out."""
        lib = build_library(model, kinds=self.config.kinds)
        if {"ground_spring", "local_damping"} <= self.config.kinds:
            lib += spring_loss_candidates(model)         # the loss of each spring found so far
        if getattr(self, "suspension_hz", None) is not None:
            lib = [c for c in lib if c.matrix != "C"]
        return lib

    # ------------------------------------------------------------------ step 5
    def model(self):
        """The augmented model updated jointly on the FRFs; backward elimination of terms that no longer earn
        their place; the parameter-only baseline from a second start."""
        cfg = self.config
        self._say("step 5/6: modelling the selected physics and updating jointly on the FRFs")
        t1 = time.perf_counter()
        current, pm_cur, p_cur, n = self.current, self.pm_cur, self.p_cur, len(self.params)
        # independent fits, side by side on the configured cores (bit for bit the serial ones): the augmented model
        # from the MCI solution and from a second start (the nominal parameters with fitted damping and the MCI
        # values of the new terms), and the parameter-only baseline from the MCI parameters
        starts = [(pm_cur, p_cur, self.lo_cur, self.hi_cur),
                  (pm_cur, np.concatenate([self.p_nomd, p_cur[n:]]), self.lo_cur, self.hi_cur)] if current else []
        *joint, upd2 = fork_map(lambda pm_, p0, lo, hi: self._fit(pm_, self.train, p0, lower=lo, upper=hi,
                                                                  max_nfev=cfg.max_nfev),
                                starts + [(self.pm, self.p_mci, self.lo, self.hi)], cfg.jobs)
        if current:
            polish, alt = joint
            if alt.error < polish.error:
                polish = alt
            log.info("joint FRF fit from the MCI solution %s: error %.4g (%s)", np.round(p_cur, 4), polish.error,
                     polish.message)
            mci_err = frf_error(model_frf(pm_cur.structure(p_cur), self.train), self.train)
            self.best_fit = polish if polish.error <= mci_err else \
                type(polish)(p_cur, fit_std(pm_cur, self.train, p_cur, prior=self.prior), mci_err, [], True,
                             "MCI solution")
            self.best_pm, self.best_scales = pm_cur, _augment(self.model0, current)[2]
        else:
            self.best_fit, self.best_pm, self.best_scales = self.upd, self.pm, []
        # parameter-only baseline: the better of the FRF fit from nominal and from the MCI parameters
        if upd2.error < self.upd.error:
            self.upd = upd2
        while len(self.current) > 1 and self._eliminate():
            pass
        # no group's loss factor in all below 0 in the fits that are reported and written
        self.upd, _ = nonnegative_loss_factors(self.pm, self.train, self.upd, self.lo, self.hi, prior=self.prior,
                                               model_ge=self.model0.global_ge, max_nfev=cfg.max_nfev)
        if self.current:
            self.best_fit, _ = nonnegative_loss_factors(
                self.best_pm, self.train, self.best_fit, np.r_[self.lo, np.zeros(len(self.current))],
                np.r_[self.hi, _upper(self.current, self.best_scales)], prior=self.prior,
                model_ge=self.model0.global_ge, max_nfev=cfg.max_nfev)
        n_f = n_obs(self.train)
        gain = np.log(self.upd.error ** 2 / max(self.best_fit.error ** 2, 1e-300))
        if self.current and not (self.best_fit.error < self.upd.error and
                                 n_f * gain > cfg.penalty * len(self.current) * np.log(n_f)):
            # the information criterion of the screening, for all terms at once against parameter updating
            log.info("the augmented model does not fit the training FRFs significantly better than parameter "
                     "updating alone (error %.4g against %.4g)", self.best_fit.error, self.upd.error)
            self.current = []
        if not self.current:
            self.best_fit, self.best_pm, self.best_scales = self.upd, self.pm, []
        self.timings["5 model"] = time.perf_counter() - t1

    # ------------------------------------------------------------------ step 6
def diagnose(model: FEModel, measured: FRF, **kw) -> Diagnosis:
    """Locate what an FE model leaves out, name it, model it and prove it on held-out data (module docstring):
    ``Diagnoser(DiagnoserConfig(**kw)).fit(model, measured).diagnosis_``."""
    return Diagnoser(DiagnoserConfig(**kw)).fit(model, measured).diagnosis_


