"""The refinement of an accepted support release (part of step 3 of :mod:`~updating.diagnosis.workflow`): a
clamp that is elastic is elastic in all its components, so when the screening accepts the release of a clamp's
rotations (or translations), the complementary group at the same node is fitted too and kept, as a part of the
same finding, when the data support it.  Split out as a mixin of
:class:`~updating.diagnosis.workflow.Diagnoser`: the methods read and write the diagnoser's state."""
from __future__ import annotations

import logging

import numpy as np

from updating.diagnosis.screen import mci_update

log = logging.getLogger(__name__)


def _is_translation(components) -> bool:
    return min(components) <= 3


class _Refine:
    """The support refinement of :class:`~updating.diagnosis.workflow.Diagnoser` (a mixin)."""

    def _refine_supports(self) -> None:
        """For each accepted support release, the release of the other components of the same constraint
        (the largest group: a clamp's translations after its rotations, or the reverse) fitted with the
        parameters and the current terms on the training FRFs, from the screening's value, and judged by
        :meth:`~updating.diagnosis.acceptance._Acceptance._judge_pick` as a supported part: kept when the
        information criterion, the held-out test and the cross-validation pass.  A single physical support then
        comes out as one finding with its translational and rotational stiffness, instead of the rotations
        alone absorbing what the translations miss."""
        for c in list(self.current):
            if c.release is None or c.release[0] != "support":
                continue
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
            free = np.concatenate([self.free_mci, np.ones(len(self.current) + 1, bool)])
            _, self.rss_cur, _ = mci_update(pm_aug, fr.p, self.train, clo, chi, weights=self.W,
                                            iters=3 if self.large else 6, free=free) if self.use_mci else \
                (None, fr.error ** 2, None)
            self.current.append(o)
            self.pm_cur, self.p_cur, self.lo_cur, self.hi_cur = pm_aug, fr.p, clo, chi
            self._frf_cur = (pm_aug, fr)
            self._route[o.key] = (0.0, False, [])
            self._decide("found", o, f"as a part of {c.label}: training FRF error down to {fr.error:.3g}")

    def _complement(self, c):
        """The library's release of the other components of ``c``'s constraint (the largest group of the other
        kind, translations or rotations), not yet accepted; None when the constraint has none."""
        node, comps = c.release[1], set(c.release[2])
        have = {x.key for x in self.current}
        if any(x.release is not None and x.release[0] == "support" and x.release[1] == node and
               _is_translation(x.release[2]) != _is_translation(tuple(comps)) for x in self.current):
            return None                       # the other kind is accepted already
        lib = self._library(self.model0)
        other = [o for o in lib if o.release is not None and o.release[0] == "support" and o.release[1] == node
                 and not set(o.release[2]) & comps and o.key not in have and o.key not in self._hidden
                 and _is_translation(o.release[2]) != _is_translation(tuple(comps))]
        if not other:
            return None
        return max(other, key=lambda o: (len(o.release[2]), -min(o.release[2])))

    def _screened_value(self, o) -> float:
        """``o``'s value in the latest exact screening, else a stiff start (the fit moves it down)."""
        for scr, _ in reversed(self._screens):
            for x, v, _g in scr:
                if x.key == o.key and np.isfinite(v) and v > 0:
                    return float(v)
        return float(min(getattr(o, "upper", np.inf), 1e9))
