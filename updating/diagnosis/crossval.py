"""Cross-validation of a term over the folds of the measured FRFs (:meth:`_CrossValidation._cross_validated`, a
test of :mod:`~updating.diagnosis.acceptance`): the reference model and the model with the term re-fitted without
each fold, their predictions of the held-out folds compared.  Split out of ``acceptance.py`` as a mixin of
:class:`~updating.diagnosis.workflow.Diagnoser`: the methods read and write the diagnoser's state."""
from __future__ import annotations

import numpy as np

from modalab.core.parallel import fork_map
from updating.diagnosis.terms import CV_NFEV, _residual, inflation, significant_gain


class _CrossValidation:

    def _fold_fits(self, *models) -> list:
        """Each model ``(pm, p, lower, upper)`` fitted (from ``p``) on the training part of every
        cross-validation fold (:func:`cv_folds`), its residual on the fold's held-out part (noise units):
        ``[[residual] per fold]`` per model.  The fold of the diagnosis' own split reuses ``p`` (fitted on that
        training part); the others start from ``p`` with :data:`~updating.diagnosis.terms.CV_NFEV` evaluations,
        all of them independent fits on the configured cores (:func:`~modalab.core.parallel.fork_map`: the
        serial result bit for bit).  Cached per model and parameters (the reference is judged against several
        candidates)."""
        cache = self.__dict__.setdefault("_cv_cache", {})
        keys = [(id(pm), np.asarray(p, float).tobytes()) for pm, p, _, _ in models]
        own = [[str(d) for d in he.responses] == [str(d) for d in self.held.responses] and
               [str(d) for d in he.references] == [str(d) for d in self.held.references] and
               he.H.shape == self.held.H.shape for _, he, _ in self._folds]
        todo = [(i, k) for i, key in enumerate(keys) if key not in cache and key not in keys[:i]
                for k in range(len(self._folds)) if not own[k]]

        def fold_fit(i, k):
            pm, p, lo, hi = models[i]
            return self._fit(pm, self._folds[k][0], np.clip(p, lo, hi), lower=lo, upper=hi, max_nfev=CV_NFEV).p
        fitted = dict(zip(todo, fork_map(fold_fit, todo, self.config.jobs)))
        for i, key in enumerate(keys):
            if key not in cache:
                pm, p = models[i][:2]
                cache[key] = (pm, [_residual(pm.structure(fitted.get((i, k), np.asarray(p, float))), he)
                                   for k, (_, he, _) in enumerate(self._folds)])   # the model kept with its key
        return [cache[key][1] for key in keys]

    def _cv_totals(self, ref, new) -> tuple[list, list, float, float, int]:
        """The folds' residuals of ``ref`` and ``new`` (:meth:`_fold_fits`, cached), their χ² summed over the
        folds and the number of observations: ``(r0, r1, c0, c1, n)``."""
        r0, r1 = self._fold_fits(ref, new)
        c0 = float(sum(np.sum(np.abs(r) ** 2) for r in r0))
        c1 = float(sum(np.sum(np.abs(r) ** 2) for r in r1))
        return r0, r1, c0, c1, int(sum(2 * r.size for r in r1))

    def _cross_validated(self, ref, new, penalty: float | None = None) -> tuple[bool, str]:
        """The term of ``new`` against the model ``ref`` (each ``(pm, p, lower, upper)``, fitted on the
        training FRFs) judged by :data:`~updating.diagnosis.terms.CV_FOLDS`-fold cross-validation: both are
        re-fitted without each fold, and the χ² of their predictions of the held-out folds — every held-out
        value predicted once, by a model that did not see it — must fall significantly
        (:func:`significant_gain`, the test of :func:`_term_holds` with the same N).  This replaces one split's
        luck and the former threshold on the training gain of a first term (``min_gain``, 5 %): a term that only
        fits the noise or model-form error of the fitted rows does not predict the rows it did not see."""
        r0, r1, c0, c1, n = self._cv_totals(ref, new)
        infl = float(np.average([inflation(r) for r in r1], weights=[max(np.sum(np.abs(r) ** 2), 1e-300)
                                                                        for r in r1]))
        ok, stat, need = significant_gain(c0, c1, n, infl, self.config.penalty if penalty is None else penalty)
        worse = sum(float(np.sum(np.abs(b) ** 2)) > float(np.sum(np.abs(a) ** 2)) for a, b in zip(r0, r1))
        why = (f"cross-validated over {len(r1)} folds: χ²/N {c0 / n:.3g} -> {c1 / n:.3g} (statistic {stat:.3g}, "
               f"needed {need:.3g}; worse on {worse} fold(s))")
        if not ok:
            return False, why + ": not significant on data the fits did not see"
        return True, why
