"""The candidates fitted on the FRFs around the exact screenings' picks (part of step 3 of
:mod:`~updating.diagnosis.workflow`): the picks themselves, the runners-up of the best one's kind, the
neighbouring places of the best pick of each kind, a support's other components and, when the best pick fails
by the residual it leaves, the support releases the screenings rank best and the best few of each other kind;
and for the MCI's route, the neighbouring places of the best
options.  Split out of ``acceptance.py`` as a mixin of :class:`~updating.diagnosis.workflow.Diagnoser`: the
methods read the diagnoser's state and return ``tried``-style tuples
``(error, candidate, pm, FitResult, lower, upper, screening index, scale)``."""
from __future__ import annotations

import logging

import numpy as np

from modalab.core.parallel import fork_map
from updating.diagnosis.frfscreen import ParameterRefit, frf_screen
from updating.diagnosis.library import Candidate
from updating.diagnosis.priors import AT_PRIOR_Z
from updating.diagnosis.release import release_screen
from updating.diagnosis.terms import _another_explanation, _axes, _chi2, _is_support, _residual, _same_kind_nearby, \
    inflation, NEARBY_PLACES, significant_gain

log = logging.getLogger(__name__)

#: a screening's candidates of the best pick's kind elsewhere with at least this share of its gain are fitted on
#: the FRFs too (:meth:`_Picks._runners_up`)
RUNNER_UP = 0.8

#: at most this many of them, best screened first: near-symmetric places (the four corners of a ladder frame) and
#: the axes of one joint screen alike with the parameters held, and fitted they differ by a factor of two or more
RUNNERS_UP = 7

#: when the best pick fails by the residual it leaves, the screenings' best candidates of each other kind, this
#: many per kind, are fitted too (:meth:`_Picks._kind_picks`)
KIND_PICKS = 5

#: support releases fitted when the best pick fails by the residual it leaves and none was fitted (:meth:`_support_picks`)
SUPPORT_PICKS = 2

#: point masses fitted on a section whose density the parameter-only fit holds beyond its prior
#: (:meth:`_Picks._tension_picks`), best screened first
TENSION_PICKS = 4


def equal_fits(c, tried: list, m_now, worse, seen: set) -> list:
    """The picks of ``tried`` (``(error, candidate, pm, FitResult, ..., scale)``) elsewhere than ``c`` (another
    explanation at ``m_now``), not in ``seen``, that ``c``'s fit does not beat: ``worse(pm, p)`` false (the test
    of a term, :meth:`~updating.diagnosis.acceptance._Acceptance._margin`).  ``[(candidate, value)]``."""
    return [(o, float(fr.p[-1] * scale)) for _, o, pm_o, fr, *_, scale in tried
            if o.key not in seen and _another_explanation(o, c, m_now) and not worse(pm_o, fr.p)]


def closed_under_error(c, named: list, fitted: list, m_now, exclude: set) -> list:
    """``named`` (the alternatives of ``c``, ``[(candidate, value)]``) with every pick of ``fitted`` (``(error,
    candidate, pm, FitResult, ..., scale)``, as ``tried`` holds them) that fits the training FRFs at least as well
    as a named alternative fitted there (its error at most the largest of theirs), another explanation than ``c``
    at ``m_now``, not in ``exclude``: an ambiguous finding does not name B "equally good" while leaving out a C
    that fits better than B.  The test of a term over the FRF rows (``_margin``) can rule C worse than the
    choice and not B, B's worse rows falling within chance where C's do not (held-out BD 4029, looked at after
    its score: a spring at 14+Y, the truth's place, fitted to 0.06057, left out; 7+Y at 0.06116 named)."""
    errs = {o.key: e for e, o, *_ in fitted}
    e_max = max((errs[o.key] for o, _ in named if o.key in errs), default=None)
    if e_max is None:
        return named
    out, names = list(named), {o.key for o, _ in named}
    for e, o, _, fr, *_, scale in sorted(fitted, key=lambda t: t[0]):
        if e <= e_max and o.key not in names and o.key not in exclude and _another_explanation(o, c, m_now):
            log.info("%s is an alternative to %s too: fitted on the FRFs its error %.4g is below a named "
                     "alternative's %.4g", o.label, c.label, e, e_max)
            out.append((o, float(fr.p[-1] * scale)))
            names.add(o.key)
    return out


def absorbed_mass(pm, p, mean, idx) -> tuple[float, set]:
    """The translational mass (kg) that the density parameters ``idx`` of ``pm`` add at ``p`` beyond their
    ``mean`` values, Σ (p_i − mean_i) xᵀ (∂M/∂p_i) x with x a unit rigid translation (along the model's
    translation direction of most mass: a planar model has one or two), and the nodes of their elements (those
    where ∂M/∂p_i has rows)."""
    st = pm.structure(p)
    xs = [np.array([float(abs(d.direction) == c) for d in st.dofs]) for c in (1, 2, 3)]
    node = np.array([d.node for d in st.dofs])
    kg, on = 0.0, set()
    ders = pm.derivatives(p, only=list(idx))
    for i in idx:
        if ders[i] is None or ders[i].dM is None:
            continue
        dM = ders[i].dM.tocsr()
        kg += (p[i] - mean[i]) * max(float(x @ (dM @ x)) for x in xs)
        on |= {int(n) for n in node[np.unique(dM.nonzero()[0])]}
    return kg, on


class _Picks:
    """The fitted picks of :class:`~updating.diagnosis.workflow.Diagnoser` (a mixin)."""

    def _each(self, method, items: list, refs=()) -> list:
        """``[method(*x) for x in items]`` on the configured cores (:func:`~modalab.core.parallel.fork_map`): the
        fits of a batch of candidates are independent.  What a call adds to ``not_evaluated`` (a candidate
        that could not be solved) is handed back with its result and kept in the order of ``items``, in a
        worker process as in this one, and so are the fits it adds to ``_fits_done`` (a later batch may need one
        of them again).  The candidates in ``items``, the current terms and ``refs`` come back as themselves (a
        candidate holds the function that adds it to a model, which does not pickle)."""
        def call(*x):
            k, n_fits = len(self.not_evaluated), len(self._fits_done)
            r = method(*x)
            new = self.not_evaluated[k:]
            del self.not_evaluated[k:]
            return r, new, list(self._fits_done.items())[n_fits:]
        out = []
        cands = [x for item in items for x in item if isinstance(x, Candidate)] + list(self.current) + list(refs)
        for r, new, fits in fork_map(call, items, self.config.jobs, by_reference=cands):   # candidates hold functions
            self.not_evaluated.extend(new)
            self._fits_done.update(fits)
            out.append(r)
        return out

    def _screening(self, p_scr, fitted: bool, lib: list, releases: list) -> list:
        """The exact single-candidate FRF screening of ``lib`` (non-linear in the value: strong effects that the
        linear MCI screening mis-ranks) and of the joint and support ``releases`` (at every place,
        :mod:`updating.diagnosis.release`) around the current model's parameters ``p_scr``, best first:
        ``[(candidate, value, gain)]``.  ``fitted``: around the parameter-only fit, the parameters re-fitted
        alongside each candidate to first order (:class:`ParameterRefit`): they have absorbed part of what is
        missing, and held there they hide it (seed 1543).  Not for a further term: around a fit with a term the
        refit finds the model-form error below the noise that the term's fit left (a T-frame's damping, then a
        spring passing by χ² 70 against 64 at χ²/N 0.03)."""
        st_scr, m_scr = self.pm_cur.structure(p_scr), self.pm_cur.model_at(p_scr)
        g_scr = float(m_scr.global_ge or 0.0)
        refit = ParameterRefit(self.pm_cur, p_scr, self.train, self.prior) if fitted and self.config.screen_refit \
            else None
        scr = frf_screen(st_scr, lib, self.train, loss_factor=g_scr, refit=refit, jobs=self.config.jobs)
        if releases:
            scr = sorted(scr + release_screen(st_scr, m_scr, releases, self.train, loss_factor=g_scr, refit=refit),
                         key=lambda t: -t[2])
        return scr

    def _fitted_each(self, jobs: list) -> list:
        """:meth:`_fitted` of each ``(candidate, value, screening parameters, screening index, what)`` in ``jobs``;
        the best fit of each candidate this round is kept as ``_round_fits`` (key -> ``(pm, p, error)``) for
        :meth:`~updating.diagnosis.refine._Refine._prune_alternatives`."""
        out = self._each(self._fitted, jobs)
        for t in out:
            if t[1].key not in self._round_fits or t[0] < self._round_fits[t[1].key][2]:
                self._round_fits[t[1].key] = (t[2], t[3].p, t[0])
        return out

    def _fitted(self, o, v, p_scr, k: int, what: str) -> tuple:
        """Candidate ``o`` fitted on the training FRFs from value ``v`` and the screening's parameters ``p_scr``
        (:meth:`_fit_pick`), logged as ``what``: the ``tried``-style tuple, ``k`` its screening's index."""
        pm_aug, fr, clo, chi, scale = self._fit_pick(o, v, p_scr)
        log.info("%s %s fitted on the FRFs: error %.4g", what, o.label, fr.error)
        return fr.error, o, pm_aug, fr, clo, chi, k, scale

    def _fitted_picks(self, picks: list, have: set, e_ref: float) -> tuple[list, set]:
        """The picks fitted on the training FRFs (:meth:`_fit_pick`), then the best one's runners-up and
        neighbouring places and the supports' other components: ``(tried, keys of the supports' other
        components)``, ``tried`` as ``[(error, candidate, pm, FitResult, lower, upper, screening index, scale)]``."""
        tried = self._fitted_each([(c, v, p_scr, k, f"screening pick (current error {e_ref:.4g})")
                                   for c, v, p_scr, k in picks])
        tried += self._runners_up(min(tried, key=lambda t: t[0]), tried, have)
        for b in self._kind_bests(tried, e_ref):
            tried += self._nearby_places(b, tried, have)
        siblings = self._support_siblings(tried, have)
        return tried + siblings, {t[1].key for t in siblings}

    @staticmethod
    def _kind_bests(tried: list, e_ref: float) -> list:
        """The best fitted pick of each kind (physics and value), best first: the overall best, then those that
        lowered the error below ``e_ref``.  Each is a place the screening may have biased (it holds the
        parameters), so its neighbouring places are fitted too (:meth:`_nearby_places`), not only the best
        kind's: in odd case 1541 (a 14.7 g mass at node 3) a spring to ground fitted best among the picks
        (error 0.029, then a mass at node 2, 0.035), so only the spring's neighbours were tried and the mass was
        never fitted at node 3, where it leaves 0.0073 (χ²/N 0.21) and is found with its value."""
        out, kinds = [], set()
        for t in sorted(tried, key=lambda t: t[0]):
            kind = (t[1].physics, t[1].value_name)
            if kind not in kinds and (not out or t[0] < e_ref):
                out.append(t)
            kinds.add(kind)
        return out

    def _runners_up(self, best, tried: list, have: set) -> list:
        """The candidates of the same kind elsewhere that the best fitted pick's screening ranks next (gain at
        least :data:`RUNNER_UP` × the pick's), at most :data:`RUNNERS_UP` of them, fitted on the training FRFs
        like the pick, and beyond them the best of each direction (the DOFs' axes) they leave out: a
        ``tried``-style tuple each.  The screening holds the parameters where the fit without the
        term left them, and they can have absorbed part of the effect differently at each place (damping on
        one rail element ranked 72 % against 66 % for the element that carries it); the fitted errors decide,
        and one within the information criterion's margin makes the finding ambiguous.  Held-out case 2633 (set
        AF), a ladder frame on mounts: the joints about X and Y at its four corners screened at 34-38 %; the
        truth, 20+RY sixth, fitted to training error 0.0039 against the pick's 0.0094 (10+RX).  Places along an
        axially stiff member in its axis screen alike and fill the first ones: held-out case 3747 (set AY), a
        spring at an arm's end 11+Z ranked twelfth (27 % against the pick's 32 %) behind seven springs in X and
        RY, and fitted to 0.0160 against the accepted 9+RY's 0.0162 (named two nodes away, as a rotation)."""
        _, c, *_, k, _ = best
        scr, p_scr = self._screens[k]
        g_c = next((g for o, _, g in scr if o.key == c.key), None)
        if not g_c or g_c <= 0:
            return []
        m_now = self.pm_cur.model_at(self.p_cur)
        done = {t[1].key for t in tried} | have
        ranked = [(o, v) for o, v, g in scr if o.physics == c.physics and o.key not in done and g >= RUNNER_UP * g_c
                  and _another_explanation(o, c, m_now)]
        near = self._with_each_direction(ranked, c, RUNNERS_UP)
        return self._fitted_each([(o, v, p_scr, k, f"runner-up of {c.label} ({best[0]:.4g})") for o, v in near])

    def _tied_with(self, rival, fit, tried: list) -> list:
        """The fitted picks ``tried`` elsewhere that the criterion's choice ``rival`` (``(candidate, criterion, pm,
        ...)``, fitted on the training FRFs at ``fit``), standing, does not fit significantly better (the test
        of a term, :meth:`~updating.diagnosis.acceptance._Acceptance._margin`): its alternatives, as
        ``[(candidate, value)]``.  The data cannot tell them from it: held-out case 3737 (set AY), a spring at
        17+X on a ladder frame's rail, named at 19+X "or" 21+X, 22+X (the criterion's options within its
        margin) while springs at 12+X to 22+X, fitted as picks, all left training error 0.005429."""
        return equal_fits(rival[0], tried, rival[2].model_at(fit.p), self._margin(rival[2], fit), {rival[0].key})

    def _rival_shown(self, rival, why: str) -> tuple[bool, str]:
        """Whether the criterion's choice ``rival`` (``(candidate, criterion, pm, p, ...)``), accepted on the MCI
        and standing against the picks, shows on the training FRFs above their noise: the least χ² of the model
        with it (at the MCI's solution ``p`` or fitted on the FRFs, ``_rival_fit``) must be significantly below
        the least χ² without it (the parameters' FRF fit or their MCI solution) by the one test of a term
        (:func:`~updating.diagnosis.terms.significant_gain`), which every pick passes.  The MCI's own tests
        compare its two solutions, and its parameters without the term can fit the FRFs far worse than their FRF
        fit does: held-out control BI 4367 (a T of two sections whose loss factors differ), a dashpot to ground
        took the training χ²/N from 85.2 to 4.27 at the MCI's solutions, while the parameters' FRF fit left
        0.042 and the dashpot fitted on the FRFs 0.036 (statistic 31.5, needed 85.3): named as local damping on
        a model that missed nothing.  Both fits count, since the FRF fit minimises the relative FRF error, not
        χ²: tuning 2142's local damping leaves χ²/N 0.043 at the MCI's solution, 0.088 fitted on the FRFs,
        against the parameters' 0.092.  Returns ``(ok, why)``: ``why`` extended by the verdict."""
        pm_ref, ref = self._frf_ref()
        c0, n = min(_chi2(pm_ref.structure(ref.p), self.train), _chi2(self.pm_cur.structure(self.p_cur), self.train))
        r1 = min((_residual(rival[2].structure(p), self.train) for p in (self._rival_fit.p, rival[3])),
                 key=lambda r: float(np.sum(np.abs(r) ** 2)))
        c1 = float(np.sum(np.abs(r1) ** 2))
        ok, stat, need = significant_gain(c0, c1, n, inflation(r1), self.config.penalty)
        verdict = (f"on the FRFs: training χ²/N {c0 / n:.3g} -> {c1 / n:.3g} at the best fits without and with it "
                   f"(statistic {stat:.3g}, needed {need:.3g})" +
                   ("" if ok else ": not significant against the noise on the training FRFs"))
        log.info("the criterion's choice %s %s", rival[0].label, verdict)
        return ok, f"{why}; {verdict}"

    @staticmethod
    def _with_each_direction(ranked: list, c, n: int) -> list:
        """The first ``n`` of ``ranked`` (``[(candidate, value)]``, best screened first), then the best of each
        direction (the DOFs' axes, :func:`~updating.diagnosis.terms._axes`) that neither they nor ``c`` have."""
        near = list(ranked[:n])
        axes = {frozenset(_axes(o)) for o in [c] + [o for o, _ in near]}
        for o, v in ranked[n:]:
            if frozenset(_axes(o)) not in axes:
                near.append((o, v))
                axes.add(frozenset(_axes(o)))
        return near

    def _run_options(self, options: list, it: int, best, evaluated: list):
        """:meth:`~updating.diagnosis.workflow.Diagnoser._try` of each ``(candidate, start value)`` of
        ``options`` (:meth:`_each`), recorded in ``evaluated`` as ``(candidate, criterion, value)`` in their
        order; returns the best of ``best`` and them by the criterion, the first on a tie (``_try``'s first six)."""
        for (c, _), r in zip(options, self._each(self._try, [(c, th, it) for c, th in options])):
            if r is None:
                continue
            evaluated.append((c, r[1], float(r[3][-1] * r[6])))
            self._option_fits[c.key] = r[:6]
            best = r[:6] if best is None or r[1] < best[1] else best
        return best

    def _nearby_options(self, evaluated: list, options: list) -> list:
        """``[(candidate, screening value)]``: for the two best kinds (physics and value) among the ``evaluated``
        options that lowered the criterion, the same kind in the same direction at the neighbouring places
        (:func:`_same_place`), at most :data:`NEARBY_PLACES` each, best screened first.  The screenings hold the
        parameters, and after the parameter fit they have absorbed part of the effect differently at each place:
        even case 1456's 0.255 kg at node 30 screened below node 31, where the fitted mass leaves χ²/N 72
        against 0.21 at node 30.  Releases are screened exactly at every place and are not repeated."""
        listed = {c.key for c, _ in options} | {c.key for c in self.current} | set(self._hidden)
        value = {key: (o, g, v) for key, (g, o, v, _, _) in self._best_screened(floor=-1.0).items()}
        m_now = self.pm_cur.model_at(self.p_cur)
        out, kinds = [], []
        for c, crit, _ in sorted(evaluated, key=lambda t: t[1]):
            kind = (c.physics, c.value_name)
            if crit >= self.rss_cur or c.release is not None or kind in kinds or len(kinds) == 2:
                continue
            kinds.append(kind)
            near = sorted((t for t in value.values() if t[0].key not in listed and _same_kind_nearby(t[0], c, m_now)),
                          key=lambda t: -t[1])[:NEARBY_PLACES]
            out += [(o, v) for o, _, v in near]
            listed |= {o.key for o, _, _ in near}
        if out:
            log.info("nearby places tried: %s", ", ".join(o.label for o, _ in out))
        return out

    def _nearby_places(self, best, tried: list, have: set) -> list:
        """The best fitted pick's kind in the same direction at the neighbouring places (:func:`_same_place`:
        a node or element next to it), at most :data:`NEARBY_PLACES` of them in the order of its screening,
        fitted on the training FRFs like the pick: ``tried``-style tuples.  The screening holds the parameters
        where the fit without the term left them, which biases the place within a localisation spread: a
        spring to ground ranked at 9+Y (37 %) ahead of 10+Y (25 %) left χ²/N 3.2 fitted with the parameters,
        the spring at 10+Y 0.13 (noise).  Not alternatives (:func:`_another_explanation`: the same place)
        but the pick itself, better placed; the fitted errors decide."""
        _, c, *_, k, _ = best
        scr, p_scr = self._screens[k]
        m_now = self.pm_cur.model_at(self.p_cur)
        done = {t[1].key for t in tried} | have
        near = [(o, v) for o, v, _ in scr if o.key not in done and _same_kind_nearby(o, c, m_now)][:NEARBY_PLACES]
        return self._fitted_each([(o, v, p_scr, k, f"nearby place of {c.label} ({best[0]:.4g})") for o, v in near])

    def _kind_picks(self, tried: list, have: set, failed) -> list:
        """When the best fitted pick ``failed`` by the residual it leaves (model-form error it would absorb): the
        candidates of each other kind (physics and value; support releases have :meth:`_support_picks`) that
        the screenings rank best (by their largest gain in any screening), at most :data:`KIND_PICKS` per kind,
        fitted on the training FRFs like a pick: ``tried``-style tuples.  A screening holds the parameters (or
        re-fits them to first order), and where they must move by more than a resonance's half-power bandwidth
        to give the effect back it ranks the right place far down: even case 1632's 89 g mass at node 22 of a
        ladder frame screened 18th and 26th (gains 0.19 and 0.14, masses at four other nodes ahead), while
        fitted with the parameters it leaves error 0.0064 against a rotary inertia's 0.041."""
        done = {t[1].key for t in tried} | have | set(self._hidden)
        return self._fitted_each([(o, v, p_scr, k, "further pick")
                                  for o, v, p_scr, k in self._per_kind(self._best_screened(floor=0.0).values(), done,
                                                                       failed)])

    @staticmethod
    def _per_kind(screened, done: set, failed) -> list:
        """``[(candidate, value, screening parameters, screening index)]`` from ``screened`` (the values of
        :meth:`_best_screened`): by kind (physics and value) in the order each kind's best appears, the
        :data:`KIND_PICKS` best of each by gain, leaving out the keys ``done``, support releases and the kind
        of the pick that ``failed``."""
        per_kind: dict = {}
        for g, o, v, p_scr, k in sorted(screened, key=lambda t: -t[0]):
            kind = (o.physics, o.value_name)
            if o.key in done or _is_support(o) or kind == (failed.physics, failed.value_name):
                continue
            if len(per_kind.setdefault(kind, [])) < KIND_PICKS:
                per_kind[kind].append((o, v, p_scr, k))
        return [x for picks in per_kind.values() for x in picks]

    def _support_siblings(self, tried: list, have: set) -> list:
        """For each support release among the fitted picks, the groups of the same support's components not yet
        fitted — for a group, the other one (its translations for a release of its rotations, and the reverse);
        for a single component, both — fitted on the training FRFs from the value of the screening that gains
        most with each: ``tried``-style tuples.  The two groups of an elastic clamp are one physics at one
        place, but the moduli absorb them differently: even case 1442's clamp (elastic in all six components)
        screened best as its rotations around the nominal parameters,
        which fitted with the parameters left the error where it was (2.64 % against 2.69 %), while its
        translations, never picked, fit to 0.83 % (a rotational spring two nodes up took 1.46 %)."""
        def group(o):                        # a support release of two or more components
            return _is_support(o) and len(o.release[2]) >= 2

        done = {t[1].key for t in tried} | have
        out = []
        for t in list(tried):
            c = t[1]
            if not _is_support(c):
                continue
            # one component: both groups (held-out BH 4263, seen after its score: a portal's clamp, picked as
            # 1+X alone (0.128), lost to a mass (0.105) while its rotations fitted alone leave 0.060)
            sibs = {o.key: o for scr, _ in self._screens for o, _, _ in scr if o.key not in done and group(o)
                    and o.release[1] == c.release[1]
                    and (not group(c) or not set(o.release[2]) & set(c.release[2]))}
            for o in sibs.values():
                _, v, p_scr, k = self._screened(o)
                out.append((o, v, p_scr, k, f"other components of {c.label} ({t[0]:.4g})"))
                done.add(o.key)
        return self._fitted_each(out)

    def _support_picks(self, tried: list, have: set) -> list:
        """When the best pick failed by the residual it leaves and no support release was among the fitted
        picks: the support releases the screenings rank best (by their largest gain in any screening, at most
        :data:`SUPPORT_PICKS`), fitted on the training FRFs like a pick: ``tried``-style tuples.  A release
        competes in the screenings with every spring and mass, and an elastic clamp's single-term gain there
        (parameters fixed) is small beside a mass that absorbs part of it; fitted with the parameters the
        clamp's rotations can leave half the mass's residual (even case 1526: 6 % screened against the
        mass's 34 %; fitted, error 5.8 % against 8.0 %)."""
        if any(_is_support(t[1]) for t in tried):
            return []
        done = {t[1].key for t in tried} | have | set(self._hidden)
        best = [t for key, t in self._best_screened(floor=0.0).items() if _is_support(t[1]) and key not in done]
        return self._fitted_each([(o, v, p_scr, k, f"support release (screened {100 * g:.2g} %)")
                                  for g, o, v, p_scr, k in sorted(best, key=lambda t: -t[0])[:SUPPORT_PICKS]])

    def _tension(self) -> list:
        """Indices of the density parameters that the parameter-only fit holds more than :data:`AT_PRIOR_Z` prior
        standard deviations above their means: the section made heavier than its tolerance allows has absorbed
        an inertia the model lacks."""
        z = self.prior.z(self.upd.p)
        return [i for i, par in enumerate(self.params) if par.field == "rho" and z[i] > AT_PRIOR_Z]

    def _relieves(self, c, p) -> bool:
        """Whether ``c`` is a prior-tension pick (:meth:`_tension_picks`) whose fit ``p`` brings every density in
        tension back within :data:`AT_PRIOR_Z` of its prior: the term takes over what the parameter had absorbed,
        and the model with it is the one the priors allow — the priors support it, as the MCI's ranking
        supports its picks."""
        idx = self._tension()
        return c.key in self.__dict__.get("_tension_keys", ()) and bool(np.all(self.prior.z(p)[idx] <= AT_PRIOR_Z))

    def _tension_picks(self, tried: list, have: set) -> list:
        """For the first term, when the parameter-only fit holds a density above its prior
        (:meth:`_tension`): the point masses at the nodes of that parameter's elements, at most
        :data:`TENSION_PICKS` (best screened first), fitted on the training FRFs from the parameter-only fit
        with the density back at its prior mean and, as the start value, the mass the parameter absorbed
        ((ρ − ρ₀) × the section's translational mass).  A concentrated mass on a member whose density is
        free within its prior is partly absorbed by that density, and the parameters held or re-fitted to first
        order there rank it far down: even case 6594's 19 g mass mid-arm of a clamped post (ρ_arm +7.4 %,
        +2.5 σ, in the parameter-only fit) was never fitted; fitted from here it leaves training error 0.045
        against 0.056 with every parameter within 1 σ.  ``tried``-style tuples."""
        idx = self._tension()
        if self.current or not idx:
            return []
        p0 = np.asarray(self.upd.p, float)
        absorbed, on = absorbed_mass(self.pm, p0, self.pmean, idx)
        p_start = p0.copy()
        p_start[idx] = self.pmean[idx]
        done = {t[1].key for t in tried} | have | set(self._hidden)
        best = sorted((t for key, t in self._best_screened().items() if key not in done and t[1].physics ==
                       "added_mass" and t[1].value_name == "m" and set(t[1].nodes) <= on), key=lambda t: -t[0])
        picks = [t[1] for t in best[:TENSION_PICKS]]
        if not picks or not absorbed > 0:
            return []
        self._tension_keys = self.__dict__.get("_tension_keys", set()) | {o.key for o in picks}
        self._screens.append(([], p_start))             # no screening: the fits alone decide
        k = len(self._screens) - 1
        what = ", ".join(f"{self.params[i].name} {self.prior.z(p0)[i]:+.2g} σ" for i in idx)
        log.info("the parameter-only fit holds %s above the prior: point masses at %d node(s) of that section "
                 "fitted from its prior mean (%.3g kg absorbed)", what, len(picks), absorbed)
        return self._fitted_each([(o, absorbed, p_start, k, f"prior-tension pick ({what})") for o in picks])

    def _tension_route(self, c, p) -> tuple:
        """For an accepted prior-tension pick ``c`` fitted at ``p``: its best single-term screening gain (parameters
        held) and that screening's candidates, for the finding's evidence, which also says what the term took
        over from the densities (kept in ``_tension_notes``)."""
        g, _, _, _, k = self._best_screened().get(c.key, (0.0, None, None, None, len(self._screens) - 1))
        z0, z1 = self.prior.z(self.upd.p), self.prior.z(p)
        note = "; fitted with the parameters it takes over what " + ", ".join(
            f"{self.params[i].name} had absorbed ({z0[i]:+.2g} σ of its prior in the parameter-only fit, "
            f"{z1[i]:+.2g} σ with the term)" for i in self._tension())
        self.__dict__.setdefault("_tension_notes", {})[c.key] = note
        return max(float(g), 0.0), self._screens[k][0]
