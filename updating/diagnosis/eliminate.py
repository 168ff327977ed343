"""Backward elimination of the diagnosis' terms (part of step 5 of :mod:`~updating.diagnosis.workflow`): after
the joint fit, the term whose removal changes the training FRF error least is refitted away while the error rises
by less than ``min_term_gain``.  Split out of ``workflow.py`` as a mixin of
:class:`~updating.diagnosis.workflow.Diagnoser`: the method reads and writes the diagnoser's state."""
from __future__ import annotations

import logging

import numpy as np

from modalab.core.errors import ModalabValueError
from updating.diagnosis.fit import frf_error, model_frf
from updating.diagnosis.library import loss_of as _loss_of
from updating.diagnosis.screen import mci_update
from updating.diagnosis.terms import _augmented

log = logging.getLogger(__name__)


class _Eliminate:
    """Backward elimination for :class:`~updating.diagnosis.workflow.Diagnoser` (a mixin)."""

    def _eliminate(self) -> bool:
        """Backward elimination: the term whose removal (value 0, the rest as fitted) changes the training FRF
        error least is refitted away; dropped (True) when the error rises by less than ``min_term_gain``."""
        cfg, current, best_fit, n0 = self.config, self.current, self.best_fit, len(self.params)
        worst, worst_err = None, np.inf
        for k in range(len(current)):
            pz = best_fit.p.copy()
            pz[n0 + k] = 0.0
            try:
                ek = frf_error(model_frf(self.best_pm.structure(pz), self.train), self.train)
            except (np.linalg.LinAlgError, ModalabValueError) as e:
                log.info("term %s cannot be removed (%s): kept", current[k].label, e)
                continue
            if ek < worst_err:
                worst, worst_err = k, ek
        if worst is None:
            return False
        # a spring's own loss (library.spring_loss_candidates) goes with its spring
        gone = {worst} | {k for k, t in enumerate(current) if _loss_of(t, current[worst])}
        rest = [t for k, t in enumerate(current) if k not in gone]
        pm_rest, clo_r, chi_r, sc = _augmented(self.model0, self.params, self.lo, self.hi, rest)
        keep = np.r_[np.arange(n0), n0 + np.array([k for k in range(len(current)) if k not in gone], int)]
        refit = self._fit(pm_rest, self.train, best_fit.p[keep], lower=clo_r, upper=chi_r, max_nfev=cfg.max_nfev)
        # also from the MCI solution of the reduced set (the removed term may have dragged the others), and from
        # the nominal parameters
        starts = [np.concatenate([self.p_nomd, best_fit.p[keep][n0:]])]
        if self.use_mci:
            p_r, _, _ = mci_update(pm_rest, np.concatenate([self.p_mci, best_fit.p[keep][n0:]]), self.train,
                                   clo_r, chi_r, weights=self.W)
            starts.insert(0, p_r)
        for s0 in starts:
            r2 = self._fit(pm_rest, self.train, s0, lower=clo_r, upper=chi_r, max_nfev=cfg.max_nfev)
            if r2.error < refit.error:
                refit = r2
        if refit.error > best_fit.error * (1 + cfg.min_term_gain):
            return False
        self._decide("dropped", current[worst], f"backward elimination: without it the training FRF error is "
                                                f"{refit.error:.4g} (with it {best_fit.error:.4g})")
        self.current, self.best_pm, self.best_fit, self.best_scales = rest, pm_rest, refit, sc
        return True
