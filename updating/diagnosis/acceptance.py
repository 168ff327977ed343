"""The acceptance of a term in the diagnosis (step 3 of :mod:`~updating.diagnosis.workflow`): the tests a
candidate must pass to become a finding — the information criterion and the significance of its gain on the
training and held-out FRFs (:meth:`_Acceptance._judge`), its effect on natural frequencies or damping beyond
model-form error (:meth:`_Acceptance._effect_ok`), the exact FRF screening's picks against the criterion's
choice (:meth:`_Acceptance._judge_picks`), other explanations fitted as alternatives (ambiguity) and the
cross-validation over folds (:meth:`_Acceptance._cross_validated`).  Split out of ``workflow.py`` as a mixin
of :class:`~updating.diagnosis.workflow.Diagnoser`: the methods read and write the diagnoser's state."""
from __future__ import annotations

import logging

import numpy as np

from updating.diagnosis.mesh import mesh_error, shift_beyond_mesh
from updating.diagnosis.screen import mci_update
from updating.diagnosis.picks import _Picks, RUNNERS_UP, closed_under_error, equal_fits
from updating.diagnosis.crossval import _CrossValidation
from updating.diagnosis.terms import _another_explanation, _is_support, MIN_FREQ_EFFECT, CLOSE_COMPETITORS, PICK_EXPLAINS, MIN_DAMPING_EFFECT, term_effect, PICK_MAX_REDUCED_CHI2, _chi2, _term_holds, _residual, inflation, significant_gain, rows_worse, held_out_worse, n_obs, _augmented

log = logging.getLogger(__name__)

#: the reason :meth:`_Acceptance._judge` gives when the criterion's best option fails the information criterion
IC_FAILED = "fails the information criterion"


#: the least shift of an in-band mode beyond the nominal mesh's own error (:func:`shift_beyond_mesh`) that a
#: term with a small effect must show to be kept for the residual it explains (:meth:`_small_effect_kept`)
MESH_MARGIN = MIN_FREQ_EFFECT / 4


def _fits_better(err: float, e_ref: float, n_eq: int, penalty: float) -> bool:
    """Whether training FRF error ``err`` is lower than ``e_ref`` by the information criterion on ``n_eq``
    observations: N ln(e_ref²/err²) > ``penalty`` ln N."""
    return err < e_ref and n_eq * np.log(e_ref ** 2 / max(err ** 2, 1e-300)) > penalty * np.log(n_eq)


class _Acceptance(_Picks, _CrossValidation):
    """The acceptance tests of :class:`~updating.diagnosis.workflow.Diagnoser` (a mixin)."""

    def _judge(self, best, n_eq: int) -> tuple[bool, str]:
        """Whether the criterion's best option earns its place: (a) the information criterion (``penalty`` ×
        ln N per term, ten times BIC's by default, because neighbouring lines and DOFs are far from
        independent) on the criterion, and on the FRF criterion for a further term a drop of the training FRF
        error by ``min_extra_gain`` (model-form error — a finer truth mesh, per-element scatter — is what a
        small second term would otherwise absorb); (b) :func:`_term_holds`; (c) the effect on the frequencies
        or damping (:func:`term_effect`); (d) on the FRF criterion, the cross-validation over folds
        (:meth:`_cross_validated`).  ``n_eq``: the number of observations of the criterion (:func:`n_obs`)."""
        cfg, rss_cur = self.config, self.rss_cur
        if best is None:
            return False, "no candidate could be fitted"
        if not (best[1] < rss_cur and n_eq * np.log(rss_cur / max(best[1], 1e-300)) > cfg.penalty * np.log(n_eq)):
            return False, IC_FAILED
        if not self.use_mci and self.current and np.sqrt(best[1]) > np.sqrt(rss_cur) * (1 - cfg.min_extra_gain):
            return False, (f"a further term lowering the training FRF error by less than "
                           f"{100 * cfg.min_extra_gain:.0f} % ({100 * (1 - np.sqrt(best[1] / rss_cur)):.2g} %)")
        ok, why = _term_holds(self.pm_cur, self.p_cur, best[2], best[3], self.train, self.held, cfg.penalty,
                              cfg.min_holdout_gain, folds_decide=not self.use_mci)
        ok, why = self._effect_ok(ok, why, best[2], best[3], best[0])
        if ok and not self.use_mci:
            ok, cv = self._cross_validated((self.pm_cur, self.p_cur, self.lo_cur, self.hi_cur), best[2:6])
            why += "; " + cv
        return ok, why

    def _judge_other_kinds(self, best, why: str, evaluated: list, n_eq: int):
        """The first term on the FRF criterion, when the best option ``best`` passed the information criterion
        and failed a later test (``why``): its effect the size of model-form error, the held-out rows or the
        folds.  A significant term too small to be missing physics says that something the model leaves out —
        its mesh, the suspension of a free test article — lowers the error more than the missing physics does,
        not that nothing is missing: tuning case 1684's suspended ladder frame, whose loss factor 0.032 on one
        element stands 250 times above the noise, was left without a finding because a spring to ground at a
        cord's node (frequencies 0.11 %) fitted better.  So the best option of each other kind (physics and
        value) that lowered the criterion is judged by the same tests (:meth:`_judge`), in the order of the
        criterion; the first that passes is the term.  Options of the kinds that failed cannot be its
        alternatives (they were judged and rejected).  Returns ``(ok, option or None, reason, failed kinds)``."""
        self._decide("rejected", best[0], why)
        failed = {(best[0].physics, best[0].value_name)}
        for c, crit, _ in sorted(evaluated, key=lambda t: t[1]):
            kind = (c.physics, c.value_name)
            if kind in failed:
                continue
            t = self._option_fits[c.key]
            ok, why = self._judge(t, n_eq)
            log.info("candidate %s (another kind) on the FRFs: %s", c.label, why)
            if ok:
                return True, t, why, failed
            if why == IC_FAILED:                  # the rest fit worse still
                return False, None, why, failed
            self._decide("rejected", c, why)
            failed.add(kind)
        return False, None, why, failed

    def _effect_ok(self, ok: bool, why: str, pm_new, p_new, c) -> tuple[bool, str]:
        """Test (c) of :meth:`_judge`: the term moves an in-band natural frequency by
        :data:`MIN_FREQ_EFFECT` beyond the nominal beam mesh's own error of that mode
        (:func:`~updating.diagnosis.mesh.shift_beyond_mesh`) or adds :data:`MIN_DAMPING_EFFECT` of the
        background modal damping."""
        if not ok:
            return ok, why
        df, deta = term_effect(pm_new, p_new, len(self.params), c, self.band)
        if self._mesh is None:
            self._mesh = mesh_error(self.pm.model, self.params, self.p_nomd, self.band)
        dfx = shift_beyond_mesh(pm_new, p_new, c, self.band, self._mesh) if df >= MIN_FREQ_EFFECT else df
        why += (f"; effect: frequencies {100 * df:.2g} % ({100 * dfx:.2g} % beyond the mesh's own error), damping "
                f"{100 * deta:.2g} % of the background")
        if dfx < MIN_FREQ_EFFECT and deta < MIN_DAMPING_EFFECT:
            return False, why + (f": below {100 * MIN_FREQ_EFFECT:.1f} % in frequency and "
                                 f"{100 * MIN_DAMPING_EFFECT:.0f} % in damping, the size of model-form error")
        return True, why

    def _frf_ref(self):
        """The current model fitted on the training FRFs, ``(pm, FitResult)``: the parameter-only fit before
        any term; after a term accepted on the MCI, its FRF fit from the MCI solution."""
        if self._frf_cur is None:
            fr = self._fit(self.pm_cur, self.train, self.p_cur, lower=self.lo_cur, upper=self.hi_cur,
                           max_nfev=self.config.max_nfev)
            self._frf_cur = (self.pm_cur, fr)
        return self._frf_cur

    def _judge_picks(self, it: int, n_eq_mci: int, rival=None, mci_best=None, mci_refit: bool = False):
        """The exact FRF screening's picks judged on the FRFs (MCI criterion, when the MCI's best failed).

        The best pick of each screening (around the nominal and the updated parameters: updating may have bent
        the parameters to hide the effect; local damping with the parameters re-fitted) and the best pick of
        another kind of physics are fitted with the parameters on the training FRFs from the screening's value;
        the one with the lowest error is judged against the current model's FRF fit by the tests of :meth:`_judge`
        on the FRF criterion.  Candidates of the same screening whose single-term error is
        within the information criterion's margin, elsewhere, make the finding ambiguous.  Returns
        ``(candidate, alternatives)`` with the state updated, or None.

        ``rival``: the criterion's best option (MCI or FRFs), accepted by :meth:`_judge` (``(candidate,
        criterion, pm, p, lower, upper)``).  It is fitted on the training FRFs too (kept as ``_rival_fit``), and
        a pick replaces it only when its training FRF error is lower by the information criterion
        (N ln(e_rival²/e_pick²) > ``penalty`` ln N, N = :func:`n_obs`), it does not fit the held-out FRFs
        significantly worse (:meth:`_held_worse`) and it passes the tests the rival passed
        (:meth:`_judge_pick` with ``supported``); else None (the rival stands).  ``mci_best``: the candidate the
        MCI ranked and fitted best, rejected by :meth:`_judge` (its MCI-optimal value can be far from the
        FRFs'); the same candidate picked here is supported by the MCI too, so it is judged like a supported
        pick.  ``mci_refit``: ``mci_best`` passed the MCI's information criterion and failed a later test with
        its MCI-optimal value; it is fitted on the training FRFs too, from its exact screening's value
        (:meth:`_screened`), as one more pick.

        An alternative that the screening alone (parameters fixed) found within the margin but that was fitted
        on the FRFs as a pick and is worse than the accepted pick by the information criterion is no
        alternative (the fitted comparison decides)."""
        cfg = self.config
        have = {c.key for c in self.current}
        self._rival_fit = None
        if rival is not None:
            have = have | {rival[0].key}
            self._rival_fit = self._fit_converged(rival[2], rival[3], rival[4], rival[5])
            log.info("the criterion's choice %s fitted on the FRFs: error %.4g", rival[0].label,
                     self._rival_fit.error)
        picks = self._screening_picks(have)
        if mci_refit and mci_best is not None and mci_best.key not in {c.key for c, *_ in picks} | have:
            picks += [x for x in [self._screened(mci_best)] if x is not None]
        if not picks:
            return None
        pm_ref, ref = self._frf_ref()
        tried, siblings = self._fitted_picks(picks, have, ref.error)
        tried += self._tension_picks(tried, have)
        err, c, pm_aug, fr, clo, chi, k, _ = min(tried, key=lambda t: t[0])
        n_eq = n_obs(self.train)
        if rival is not None:
            e_r = self._rival_fit.error
            if not _fits_better(err, e_r, n_eq, cfg.penalty):
                log.info("screening pick %s (FRF error %.4g) does not beat the criterion's choice %s (%.4g)", c.label,
                         err, rival[0].label, e_r)
                self._rival_alts = self._tied_with(rival, self._rival_fit, tried)
                return None
            if self._held_worse((c.label, pm_aug, fr.p), (rival[0].label, rival[2], self._rival_fit.p)):
                return None
        supported = rival is not None or (mci_best is not None and c.key == mci_best.key) or self._relieves(c, fr.p)
        judged = self._judge_or_complete((err, c, pm_aug, fr, clo, chi, k), supported, "screening pick")
        if judged is None and rival is None and self._pick_left and self._mesh_shows(c, pm_aug, fr, clo, chi):
            return None
        further = set()
        if judged is None and rival is None and (self._pick_left or self._pick_small):
            judged, tried, further = self._after_residual_left(tried, have, (err, c), ref.error, supported)
        if judged is None and rival is None:
            judged = self._mci_best_fitted(tried, mci_best, c, ref.error) or self._tension_fitted(tried, c, ref.error)
        if judged is None:
            return None

        def supports(o, p) -> bool:            # the support a competitor would have in the pick's place
            return rival is not None or (mci_best is not None and o.key == mci_best.key) or self._relieves(o, p)

        judged, alts = self._settle(judged, tried, siblings | further, have, supports)
        err, c, pm_aug, fr, clo, chi, k = judged
        self.rss_cur = self._criterion_of(pm_aug, fr, clo, chi)
        self.pm_cur, self.p_cur, self.lo_cur, self.hi_cur = pm_aug, fr.p, clo, chi
        self._frf_cur = (pm_aug, fr)
        scr = self._screens[k][0]
        self._record_route(c, fr.p, scr, next((g for o, _, g in scr if o.key == c.key), None))
        return c, alts

    def _held_worse(self, new, old) -> bool:
        """Whether ``new`` (``(label, pm, p)``), better than ``old`` on the training FRFs, fits the held-out FRFs
        significantly worse (:func:`held_out_worse`): then it replaces nothing."""
        worse, why = held_out_worse(new[1].structure(new[2]), old[1].structure(old[2]), self.held, self.config.penalty)
        if worse:
            log.info("%s fits the training FRFs better than %s but the held-out FRFs significantly worse (%s): it "
                     "replaces nothing", new[0], old[0], why)
        return worse

    def _criterion_of(self, pm_aug, fr, clo, chi) -> float:
        """The criterion of an augmented model accepted from its FRF fit ``fr``, the next term's reference: its
        MCI residual (minimised from ``fr``, like every candidate's) on the MCI, its training FRF error² else."""
        if not self.use_mci:
            return fr.error ** 2
        free = np.concatenate([self.free_mci, np.ones(len(fr.p) - len(self.free_mci), bool)])
        return mci_update(pm_aug, fr.p, self.train, clo, chi, weights=self.W, iters=3 if self.large else 6,
                          free=free)[1]

    def _settle(self, judged, tried: list, fitted_for_kind: set, have: set, supports):
        """The accepted pick ``judged`` and its alternatives (:meth:`_alternatives`).  A competitor fitted there
        whose training FRF error is lower than the pick's by the information criterion (N ln(e_pick²/e²) >
        ``penalty`` ln N), and whose held-out FRF error is not significantly higher (:meth:`_held_worse`), is a
        better explanation, not an equal one: it is judged by the pick's tests
        (:meth:`_judge_or_complete`, ``supports(candidate, p)`` telling whether it is supported) and, when it
        passes, replaces the pick, whose alternatives are then named afresh.  Tuning case 2118, a clamped
        portal whose support at node 10 is elastic: the screening pick, a rotary inertia at 12+RX beside the
        support, was accepted at training error 0.1195, and the support's rotations, fitted as its competitor,
        left 0.0462 — listed as an alternative only.  Every clamp released whole (:meth:`_whole_clamps`, two
        values: twice the penalty) competes too.  Returns ``(judged, alternatives)``."""
        alts, comps = self._alternatives(judged, tried, fitted_for_kind, have)
        err, c, n_eq = judged[3].error, judged[1], n_obs(self.train)     # a completed release: its fit's error
        pen = self.config.penalty
        clamps = self._whole_clamps(c, judged[6])                 # two values each: twice the penalty
        better = [t for t in comps if _fits_better(t[0], err, n_eq, pen)] + \
            [t for t in clamps if _fits_better(t[0], err, n_eq, 2 * pen)]
        cur = (c.label, judged[2], judged[3].p)
        better = min([t for t in better if not self._held_worse((t[1].label, t[2], t[3].p), cur)],
                     key=lambda t: t[0], default=None)
        if better is None:
            return judged, alts
        log.info("competitor %s fits the training FRFs better than %s by the information criterion (error %.4g "
                 "against %.4g): judged in its place", better[1].label, c.label, better[0], err)
        pending = self.__dict__.pop("_parts_pending", None)        # set when the pick was a completed release
        sup = supports(better[1], better[3].p)
        new = self._judge_clamp(better, sup) if any(better is t for t in clamps) else \
            self._judge_or_complete(better[:7], sup, "competitor")
        if new is None:
            if pending is not None:
                self._parts_pending = pending
            return judged, alts
        self._decide("rejected", c, f"{better[1].label} fits the training FRFs significantly better (error "
                                    f"{better[0]:.4g} against {err:.4g})")
        return new, self._alternatives(new, tried + comps, fitted_for_kind, have)[0]

    def _alternatives(self, judged, tried: list, fitted_for_kind: set, have: set):
        """The alternatives of the accepted pick ``judged = (error, candidate, pm, FitResult, lower, upper,
        screening index)``: those of its screening (:meth:`_screened_alternatives`) and those fitted
        (:meth:`_fitted_alternatives`).  The screening names alternatives by single-term gains within the margin
        of the pick's own; a support's other components (:meth:`_support_siblings`) and a further pick
        (:meth:`_kind_picks`), ``fitted_for_kind``, were fitted for what they are, not for their screening gain,
        which can be far below the screening's best: there only fitted competitors are alternatives.  Returns
        ``(alternatives, competitors fitted)``, the competitors as ``tried`` holds picks."""
        err, c, pm_aug, fr, clo, chi, k = judged
        scr = self._screens[k][0]
        g_c = next((g for o, _, g in scr if o.key == c.key), None)     # None: a completed group, not screened here
        m_now, margin, n_eq = pm_aug.model_at(fr.p), self._margin(pm_aug, fr), n_obs(self.train)
        alts = self._screened_alternatives(c, g_c, scr, have, tried, m_now, n_eq, margin) \
            if g_c is not None and c.key not in fitted_for_kind else []
        return self._fitted_alternatives(c, fr, k, tried, alts, m_now, n_eq, margin)

    def _after_residual_left(self, tried: list, have: set, best, e_ref: float, supported: bool):
        """The best fitted pick ``best = (error, candidate)`` failed only by the residual it leaves, or by its
        effect after passing every test before it (significant, too small to be missing physics: as on the MCI
        route, :meth:`_judge_other_kinds`, what else the model leaves out may fit better there — set AE's T-joint
        2575, a joint stiff about 7+RZ, frequencies 0.6 %, where a rotary inertia at 13+RZ halved the χ² with
        0.29 % and the joint was never fitted): a support release among the picks that lowered the error
        ``e_ref`` (or the best screened ones, :meth:`_support_picks`) is judged next — a clamp elastic in all its
        components, the best pick an inertia absorbing part of it — then the best of the screenings' further
        candidates of the other kinds (:meth:`_kind_picks`) that leaves less than the best pick.  Returns
        ``(judged or None, tried, keys of the further picks)``."""
        err, c = best
        sup = sorted((t for t in tried + self._support_picks(tried, have) if t[1].key != c.key
                      and _is_support(t[1]) and t[0] < e_ref), key=lambda t: t[0])
        judged = self._judge_or_complete(sup[0][:7], supported, "support pick") if sup else None
        if judged is not None:
            return judged, tried, set()
        deep = self._kind_picks(tried, have, c)
        better = sorted((t for t in deep if t[0] < err), key=lambda t: t[0])
        judged = self._judge_or_complete(better[0][:7], supported, "further pick") if better else None
        return judged, tried + deep, {t[1].key for t in deep}

    def _mci_best_fitted(self, tried: list, mci_best, failed, e_ref: float):
        """When the best fitted pick ``failed``: the candidate the MCI ranked and fitted best (``mci_best``),
        when it is among the fitted picks (``tried``) and lowered the training FRF error below ``e_ref``, judged
        as a supported pick (:meth:`_judge_or_complete`).  The MCI supports it by the modal data; its MCI-optimal
        value can be far from the FRFs' (rejected there), and the fitted pick that leaves the least error can
        be one that fails on the held-out FRFs: even case 1794's 3.5 g mass at node 9 of a clamped post ranked
        first by the MCI (criterion 0.00281 against 0.00301) made the training χ²/N worse at the MCI's value, and
        was fitted fourth among the picks (error 0.0322 against 0.0370) after springs to ground that fit the
        training rows better and the held-out rows by less than 10 %, so nothing was found; fitted on the FRFs
        the mass lowers the held-out χ²/N from 2.01 to 1.32 and passes the cross-validation.  Returns the
        judged tuple or None."""
        if mci_best is None or mci_best.key == failed.key:
            return None
        t = next((t for t in tried if t[1].key == mci_best.key and t[0] < e_ref), None)
        return None if t is None else self._judge_or_complete(t[:7], True, "the MCI's best candidate")

    def _record_route(self, c, p, scr: list, g_c) -> None:
        """The route of an accepted pick ``c`` (fitted at ``p``) for its finding's evidence: its single-term gain
        ``g_c`` in its screening ``scr`` and that screening's candidates at its nodes; a prior-tension pick (no
        screening of its own, ``g_c`` None) takes them from the screening where it gains most
        (:meth:`_tension_route`)."""
        g_r = g_c                 # None: a completed release, not screened alone
        if g_c is None and self._relieves(c, p):
            g_r, scr = self._tension_route(c, p)
        self._route[c.key] = (g_r, False, [(o, v, g) for o, v, g in scr if set(o.nodes) & set(c.nodes)
                                           and o.key != c.key])

    def _tension_fitted(self, tried: list, failed, e_ref: float):
        """When the best fitted pick ``failed``: the best prior-tension pick (:meth:`_tension_picks`) that lowered
        the training FRF error below ``e_ref`` and brings the densities back within their priors, judged as a
        supported pick (:meth:`_judge_or_complete`).  Returns the judged tuple or None."""
        t = min((t for t in tried if t[1].key != failed.key and t[0] < e_ref and self._relieves(t[1], t[3].p)),
                key=lambda t: t[0], default=None)
        return None if t is None else self._judge_or_complete(t[:7], True, "prior-tension pick")

    def _judge_or_complete(self, t, supported: bool, what: str):
        """The pick ``t = (error, candidate, pm, FitResult, lower, upper, screening index)`` judged on the FRFs
        (:meth:`_judge_pick`); a support release that fails after passing the information criterion (on the
        held-out FRFs, by the residual it leaves, its effect or the cross-validation: one component of an
        elastic clamp explains less than the whole) is judged once more completed by the rest of its
        constraint (:meth:`_completed_pick`, its other components placed in ``_parts_pending``).  Returns ``t``
        as accepted (the completed release in it) or None, the rejection recorded."""
        err, c, pm_aug, fr, clo, chi, k = t
        ok, why = self._judge_pick(c, pm_aug, fr, clo, chi, supported=supported)
        log.info("%s %s on the FRFs: %s", what, c.label, why)
        if not ok and self._pick_held and _is_support(c):
            done = self._completed_pick(c, fr)
            if done is not None:
                o, c, pm_aug, fr, clo, chi, why = done
                self._parts_pending = [o]
                return err, c, pm_aug, fr, clo, chi, k
        if not ok:
            self._decide("rejected", c, why)
            return None
        return t

    def _margin(self, pm_aug, fr):
        """The accepted pick's fit (``pm_aug`` at ``fr.p``) as the measure of an equally good explanation: a
        function ``worse(pm_o, p_o) -> bool`` telling whether another explanation, fitted with the parameters,
        fits the training FRFs significantly worse: by the one significance test of a term
        (:func:`~updating.diagnosis.terms.significant_gain` on χ² in noise units: scaled by the reduced χ² the
        pick leaves when above the noise, and by its residual's correlation over lines, as when the pick was
        accepted) and on more FRF rows than chance allows (:func:`~updating.diagnosis.terms.rows_worse`; the
        likelihood ratio alone where the rows are too few to decide).  Where model-form error dominates the
        residual (χ²/N 8 after a right spring on a T-joint, even seed 1598), a fraction of a percent of FRF error
        between two places is no evidence, nor a χ² difference that half the rows contradict: the finding is
        ambiguous between them, not a choice of the first.  Also ``infl``, the pick residual's inflation."""
        r_c = _residual(pm_aug.structure(fr.p), self.train)
        c_c, n, infl = float(np.sum(np.abs(r_c) ** 2)), n_obs(self.train), inflation(r_c)

        def worse(pm_o, p_o) -> bool:
            r_o = _residual(pm_o.structure(p_o), self.train)
            if not significant_gain(float(np.sum(np.abs(r_o) ** 2)), c_c, n, infl, self.config.penalty)[0]:
                return False
            return rows_worse(r_o, r_c) is not False

        worse.infl = infl
        return worse

    def _screened_alternatives(self, c, g_c: float, scr, have: set, tried: list, m_now, n_eq: int, margin) -> list:
        """Equally good single-term explanations elsewhere in ``c``'s screening (χ² within the information
        criterion's margin, parameters fixed), less those fitted on the FRFs as picks (``tried``) and worse there
        than ``c`` by the significance test of a term (``margin``, :meth:`_margin`).  Returns
        ``[(candidate, value)]``."""
        need = self.config.penalty * np.log(n_eq)
        e_c = (1 - g_c) ** 2
        alts = [(o, v) for o, v, g in scr if o.key != c.key and o.key not in have
                and (1 - g) ** 2 - e_c <= e_c * need / n_eq and _another_explanation(o, c, m_now)]
        fitted = {o.key: (e, pm, fr) for e, o, pm, fr, *_ in tried}
        worse = [o for o, _ in alts if o.key in fitted and margin(fitted[o.key][1], fitted[o.key][2].p)]
        for o in worse:
            log.info("%s is no alternative to %s: fitted on the FRFs its error is %.4g, significantly worse", o.label,
                     c.label, fitted[o.key][0])
        return [(o, v) for o, v in alts if o not in worse]

    def _screened(self, c):
        """``(c, value, screening parameters, screening index)`` of ``c`` in the exact FRF screening where it
        gains most, or None when no screening holds it."""
        t = self._best_screened().get(c.key)
        return None if t is None else t[1:]

    def _best_screened(self, floor: float = -np.inf) -> dict:
        """``{key: (gain, candidate, value, screening parameters, screening index)}``: each candidate of the
        exact screenings where it gains most (the first screening on a tie), among gains above ``floor``; in the
        order the candidates first pass ``floor``."""
        best: dict = {}
        for k, (scr, p_scr) in enumerate(self._screens):
            for o, v, g in scr:
                if g > best.get(o.key, (floor,))[0]:
                    best[o.key] = (g, o, v, p_scr, k)
        return best

    def _screening_picks(self, have: set) -> list:
        """``[(candidate, value, screening parameters, screening index)]``: the best of each exact FRF screening
        not in ``have``, then the best of another kind of physics, all kept (a cap of three dropped that one once
        the damping screening's best came: held-out 2857's joint); each with a gain g that alone could pass the
        FRF route's information criterion, N ln(1/(1−g)²) > ``penalty`` × ln N."""
        picks, kinds = [], set()
        g_min = self._g_min()
        for k, (scr, p_scr) in enumerate(self._screens):
            top = [t for t in scr if t[0].key not in have and t[2] > g_min]
            if top and top[0][0].key not in {c.key for c, *_ in picks}:
                picks.append((top[0][0], top[0][1], p_scr, k))
                kinds.add(top[0][0].physics)
        other = sorted(((t, p_scr, k) for k, (scr, p_scr) in enumerate(self._screens) for t in scr
                        if t[0].key not in have and t[2] > g_min and t[0].physics not in kinds),
                       key=lambda x: -x[0][2])
        if other:
            (c, v, _), p_scr, k = other[0]
            picks.append((c, v, p_scr, k))
        return picks

    def _g_min(self) -> float:
        """The least single-term gain g that alone could pass the FRF route's information criterion,
        N ln(1/(1−g)²) > ``penalty`` × ln N (N = :func:`n_obs` of the training FRFs)."""
        n_f = n_obs(self.train)
        return 1.0 - np.exp(-self.config.penalty * np.log(n_f) / (2.0 * n_f))

    def _other_forms(self, c, skip: set) -> list:
        """``[(candidate, value)]``: the best screened candidate (over all screenings, gain above
        :meth:`_g_min`) of each other form of the accepted pick ``c``'s kind — a point mass where ``c`` is a
        rotary inertia, a dashpot where it is a loss factor — best first, none in ``skip``.  The screenings hold
        the parameters, and one form can rank below the other there yet fit better with them: held-out 3111
        (seen after its score), a 3.8 g mass at node 7 of a portal, was named a rotary inertia at 17+RZ
        (χ²/N 1.04) although the mass fits to 0.29.  Fitted as competitors of ``c``
        (:meth:`_fitted_alternatives`), they replace it only when they fit better by the information criterion
        (:meth:`_settle`); added to the screening picks instead they changed which pick was judged first and
        tuning case 1632 lost its mass."""
        g_min, best = self._g_min(), {}
        for scr, _ in self._screens:
            for o, v, g in scr:
                if o.physics == c.physics and o.value_name != c.value_name and o.release is None \
                        and o.key not in skip and g > g_min and g > best.get(o.value_name, (None, None, -np.inf))[2]:
                    best[o.value_name] = (o, v, g)
        return [(o, v) for o, v, _ in sorted(best.values(), key=lambda t: -t[2])]

    def _fitted_alternatives(self, c, fr_c, k: int, tried: list, alts: list, m_now, n_eq: int,
                             margin) -> tuple[list, list]:
        """Explanations elsewhere that fit the FRFs as well as the accepted pick ``c`` once the parameters are
        re-fitted with them (not significantly worse on the training FRFs by the test of a term: ``margin``,
        :meth:`_margin`): the other picks already fitted (``tried``), the screened alternatives ``alts`` not
        fitted yet, at most :data:`~updating.diagnosis.picks.RUNNERS_UP` of them, and the competitors of
        ``c``'s screening whose single-term error (parameters fixed) is within four information-criterion
        margins of ``c``'s (``n_eq`` ln(e_o²/e_c²) ≤ 4 ``penalty`` ln ``n_eq``, both over the residual's
        inflation), at most :data:`CLOSE_COMPETITORS` of them, and the best of each other form of ``c``'s kind
        (:meth:`_other_forms`; at ``c``'s own place a competitor only), fitted like the pick (:meth:`_fitted`).  The
        screening alone cannot tell: parameters re-fitted with a term absorb part of what separated it from its
        neighbours (the same release at the two ends of a symmetric frame's rail differs by a fraction of a
        percent once the moduli are free), and a pick fitted far below its screening's error is not matched by
        what merely screened alike (held-out 2633: a corner joint fitted to 0.0039, rotary inertias screened
        as well as it left 0.0093 fitted).  ``c`` is fitted at ``fr_c``.  Returns ``([(candidate, value)]: the
        alternatives ``alts`` not fitted significantly worse, then the others; competitors fitted)``, the
        competitors as ``tried`` holds picks; also every pick fitted better than one named (closed_under_error)."""
        cfg = self.config
        infl = max(margin.infl, 1.0)
        need = cfg.penalty * np.log(max(n_eq / infl, 2.0))
        seen = {o.key for o, _ in alts} | {c.key} | {x.key for x in self.current}
        out = equal_fits(c, tried, m_now, margin, seen)
        done = {o.key for _, o, *_ in tried}            # fitted once already: not again as a competitor
        seen |= done
        scr = self._screens[k][0]
        g_c = next((g for o, _, g in scr if o.key == c.key), None)     # None: a completed group, not screened here
        close = [] if g_c is None else [
            (o, v) for o, v, g in scr if o.key not in seen and _another_explanation(o, c, m_now)
            and n_eq * np.log(max(1 - g, 1e-300) ** 2 / max(1 - g_c, 1e-300) ** 2) / infl <= 4 * need]
        todo = [(o, v) for o, v in alts if o.key not in done][:RUNNERS_UP] + close[:CLOSE_COMPETITORS]
        queued = {o.key for o, _ in todo}
        forms = [(o, v) for o, v in self._other_forms(c, done | {x.key for x in self.current}) if o.key not in queued]
        todo += forms
        # from the screening's parameters and the current terms' values as c's fit left them
        start = np.concatenate([self._screens[k][1][:len(self.params)], fr_c.p[len(self.params):]])
        comps = self._fitted_each([(o, v, start, k, f"competitor of {c.label} ({fr_c.error:.4g}):") for o, v in todo])
        kept, fitted = {o.key for o, _ in alts}, {}
        own = {o.key for o, _ in forms if not _another_explanation(o, c, m_now)}  # c's place: a competitor only
        for err, o, pm_aug, fr, *_, scale in comps:
            if not margin(pm_aug, fr.p):
                if o.key not in own:
                    fitted[o.key] = (o, float(fr.p[-1] * scale))
            elif o.key in kept:
                kept.discard(o.key)
                log.info("%s is no alternative to %s: fitted on the FRFs its error is %.4g, significantly worse",
                         o.label, c.label, err)
        first = [fitted.pop(o.key, (o, v)) for o, v in alts if o.key in kept]
        return closed_under_error(c, first + out + list(fitted.values()), list(tried) + list(comps), m_now,
                                  own | {c.key} | {x.key for x in self.current}), comps

    def _fit_pick(self, c, v, p_scr):
        """The current terms plus ``c`` fitted with the parameters on the training FRFs, from the parameters
        ``p_scr`` and the value ``v`` (a screening's): ``(pm_aug, FitResult, lower, upper, scale)``, ``scale``
        the factor from ``c``'s fitted parameter (the last) to its physical value.  Values of ``p_scr`` beyond
        the current model's are left out (a competitor starts from the accepted pick's fit, less the pick)."""
        pm_aug, clo, chi, scales = _augmented(self.model0, self.params, self.lo, self.hi, self.current + [c])
        start = np.concatenate([p_scr[:len(clo) - 1], [min(v, getattr(c, "upper", np.inf)) / scales[-1]]])
        fr = self._fit_converged(pm_aug, np.clip(start, clo, chi), clo, chi)
        return pm_aug, fr, clo, chi, scales[-1]

    def _judge_pick(self, c, pm_aug, fr, clo, chi, supported: bool = False, part: bool = False,
                    n_terms: int = 1) -> tuple[bool, str]:
        """The tests of :meth:`_judge` on the FRF criterion for a pick fitted by :meth:`_fit_pick` (bounds
        ``clo``, ``chi``), against the current model's FRF fit: the information criterion, :func:`_term_holds`,
        the reduced χ² the pick must leave (:data:`PICK_MAX_REDUCED_CHI2`), the effect, and the
        cross-validation over folds (:meth:`_cross_validated`).  ``supported``: the MCI accepted a term here
        (the pick competes with it, :meth:`_judge_picks`) or ranked the pick itself best, so the pick is not a
        rescue of an unsupported residual and the reduced-χ² limit, which only guards such rescues, does not apply — the pick passes
        the same tests as the MCI's term it replaces.  ``part``: the pick completes an accepted term at the same
        place (:meth:`~updating.diagnosis.refine._Refine._refine_supports`); its effect on the frequencies may
        be below the model-form threshold when the completed model leaves only noise (reduced χ² at most
        :data:`PICK_MAX_REDUCED_CHI2` on the training and the held-out FRFs): the first term has already shown
        that something is missing there, the part says how much of it.  A pick that leaves at most
        :data:`~updating.diagnosis.terms.PICK_EXPLAINS` of the current model's χ² on the training and the held-out
        FRFs pooled, where that χ² was above the noise (pooled χ²/N above the limit), explains the residual: the reduced-χ² limit does not apply to it, nor the effect limit when it leaves
        noise (what remains is the model's form error; a term absorbing that error cannot remove 90 % of a
        residual that a missing effect dominates).  ``n_terms``: the number of values
        ``pm_aug`` adds to the current model (a support release with the rest of its constraint: 2); every
        penalty counts them.  Sets ``_pick_left`` when the pick failed only by the residual it leaves,
        ``_pick_small`` when it passed every test before the effect and failed by its effect, and ``_pick_held``
        when it passed the information criterion (whatever failed after)."""
        cfg = self.config
        penalty = cfg.penalty * n_terms
        self._pick_left = self._pick_held = self._pick_small = False
        pm_ref, ref = self._frf_ref()
        err, n_eq = fr.error, n_obs(self.train)
        if not _fits_better(err, ref.error, n_eq, penalty):
            return False, "fails the information criterion on the FRFs"
        if self.current and err > ref.error * (1 - cfg.min_extra_gain):
            return False, (f"a further term lowering the training FRF error by less than "
                           f"{100 * cfg.min_extra_gain:.0f} % ({100 * (1 - err / ref.error):.2g} %)")
        self._pick_held = True                 # past the information criterion
        # held-out rows at the noise let the folds decide for a first term (they barely see what is missing) or
        # a term's completion; a further term there has nothing left to explain on them: it must show itself
        # (a T-frame's damping left χ²/N 0.06 held out, and a spring then fitted model-form error below the noise)
        ok, why = _term_holds(pm_ref, ref.p, pm_aug, fr.p, self.train, self.held, penalty, cfg.min_holdout_gain,
                              folds_decide=not self.current or part)
        red = left = np.inf
        red0 = 0.0
        if ok:
            st, st0 = pm_aug.structure(fr.p), pm_ref.structure(ref.p)
            parts = [(_chi2(st, d), _chi2(st0, d)[0]) for d in (self.train, self.held)]
            red = max(c1 / n1 for (c1, n1), _ in parts)
            # the whole residual, training and held-out FRFs pooled: a held-out part that barely sees the effect
            # (χ²/N 1.7 against the training part's 89) says nothing about what the term explains
            n_all = sum(n1 for (_, n1), _ in parts)
            red0 = sum(c0 for _, c0 in parts) / n_all
            left = sum(c1 for (c1, _), _ in parts) / max(sum(c0 for _, c0 in parts), 1e-300)
        # the term removes nearly all of a residual above the noise (twice the noise until control 574's χ²/N 1.9
        # -> 0.14 by a joint flexibility, which the mesh correction now takes out: 0.15 before any term)
        explains = left <= PICK_EXPLAINS and red0 > PICK_MAX_REDUCED_CHI2
        if ok and not supported and red > PICK_MAX_REDUCED_CHI2:
            # a pick the linearised criterion did not support must explain the residual, not only reduce it
            if explains:
                why += (f"; χ²/N {red:.3g} left, above {PICK_MAX_REDUCED_CHI2:g}, but {100 * left:.2g} % of the "
                        f"current model's χ² (at most {100 * PICK_EXPLAINS:g} %): the term explains the residual")
            else:
                ok, self._pick_left = False, True
                why += (f"; χ²/N {red:.3g} left ({100 * left:.2g} % of the current model's), above "
                        f"{PICK_MAX_REDUCED_CHI2:g}: the term reduces a residual that stays far above the noise "
                        "(model-form error it would absorb)")
        ok_h, why_h = ok, why
        ok, why = self._effect_ok(ok, why, pm_aug, fr.p, c)
        if ok_h and not ok and red <= PICK_MAX_REDUCED_CHI2 and (part or explains):
            ok, why = self._small_effect_kept(why, why_h, c, pm_aug, fr.p, red, left, part or n_terms > 1)
        self._pick_small = ok_h and not ok
        if ok:
            lo_ref, hi_ref = (self.lo, self.hi) if pm_ref is self.pm else (self.lo_cur, self.hi_cur)
            ok, cv = self._cross_validated((pm_ref, ref.p, lo_ref, hi_ref), (pm_aug, fr.p, clo, chi), penalty)
            why += "; " + cv
        return ok, why

    def _small_effect_kept(self, why: str, why_h: str, c, pm_aug, p, red: float, left: float,
                           part: bool) -> tuple[bool, str]:
        """The effect limit keeps a term from absorbing model-form error; a term after which the model is exact
        within the noise, having removed nearly all of the residual (or completing an accepted term at its
        place), absorbs none — unless all it does to the frequencies is what the nominal beam mesh's own
        discretisation error does (:func:`~updating.diagnosis.mesh.shift_beyond_mesh` below
        :data:`MESH_MARGIN`): a stiffness or inertia that only lowers modes the coarse mesh puts too high
        cannot be told from the mesh (even control case 1522: a rotary inertia mid-post lowered one bending
        family by 0.02-0.37 % against the mesh's 0.03-0.69 %, leaving χ²/N 0.77).  ``why`` is the verdict of
        the effect limit, ``why_h`` the reason up to it.  ``part``: the term completes an accepted one, or is
        judged with the rest of its support (:meth:`~updating.diagnosis.refine._Refine._completed_pick`): the
        effect is the whole support's, not this group's alone (even case 1190: a clamp's stiff translations
        with its rotations, 0.064 % beyond the mesh alone).  Returns ``(ok, why)``."""
        if part:
            return True, why_h + (f"; a part of an accepted term whose completed model leaves χ²/N {red:.3g} "
                                  f"(at most {PICK_MAX_REDUCED_CHI2:g}: noise)")
        if c.matrix in ("K", "M"):
            if self._mesh is None:
                self._mesh = mesh_error(self.pm.model, self.params, self.p_nomd, self.band)
            dfx = shift_beyond_mesh(pm_aug, p, c, self.band, self._mesh)
            if dfx < MESH_MARGIN:
                return False, why + (f"; it leaves χ²/N {red:.3g} (noise), but it shifts no in-band mode by more "
                                     f"than {100 * MESH_MARGIN:.2g} % beyond the nominal mesh's own error "
                                     f"({100 * dfx:.2g} %): indistinguishable from the mesh's discretisation error")
        return True, why_h + (f"; a small effect on the frequencies, but the model with it leaves χ²/N {red:.3g} "
                              f"(noise), {100 * left:.2g} % of the current model's χ²")
