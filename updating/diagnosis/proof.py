"""The proof of a diagnosis (step 5 of :mod:`~updating.diagnosis.workflow`): nominal, parameter-only and
augmented models compared on the held-out FRFs and the test modes, the findings with their values and
standard deviations, the fitted parameters and the FRF overlays.  Split out of ``workflow.py`` as a mixin of
:class:`~updating.diagnosis.workflow.Diagnoser`: the methods read the diagnoser's state."""
from __future__ import annotations

import logging
import time

import numpy as np

from modalab.core.errors import ModalabError
from updating.diagnosis.fit import chi2_per_value, frf_error, model_frf
from updating.diagnosis.screen import residual_map
from updating.diagnosis.priors import AT_PRIOR_Z, SectionLossFactor, loss_factor_totals
from updating.diagnosis.terms import _same_place, _evidence, _upper, PICK_MAX_REDUCED_CHI2
from updating.diagnosis.findings import Finding, Diagnosis, statement
from updating.diagnosis.library import SPRING_LOSS, loss_of
from updating.diagnosis.testmodes import peak_modes, pair_test_modes, _paired_frequencies, _pairing_metrics, \
    say_unpaired

log = logging.getLogger(__name__)

#: the held-out FRFs are at their noise where the parameters alone leave them at most this χ²/N
#: (:meth:`_Proof._held_out_blind`)
HELD_OUT_AT_NOISE = PICK_MAX_REDUCED_CHI2

#: findings whose physical element carries its own loss: a dashpot at the same DOFs is a part of them
_LOSSY_SPRINGS = ("ground_spring",)


def _directions(c) -> set:
    """The directions (``Y``, ``RZ``) of a candidate's DOFs, without their nodes and signs."""
    return {str(d).lstrip("0123456789").lstrip("+-") for d in c.dofs}


def _is_spring_damping(c) -> bool:
    """A dashpot to ground at DOFs (not damping on elements)."""
    return c.physics == "local_damping" and c.matrix == "C" and not c.elements and bool(c.dofs)


def _at_bound(value: float, lower: float, upper: float, std: float, rtol: float = 1e-6) -> bool:
    """Whether a fitted ``value`` lies on its ``lower`` or ``upper`` bound: closer to it than ``rtol`` × the
    larger of the bound's magnitude and the value's finite ``std`` (both in the value's unit, so the test does
    not depend on the unit; a bounded fit's iterates stay strictly inside, a hair from the bound)."""
    s = float(std) if np.isfinite(std) else 0.0
    lo = np.isfinite(lower) and value - lower <= rtol * max(abs(lower), s)
    hi = np.isfinite(upper) and upper - value <= rtol * max(abs(upper), s)
    return bool(lo or hi)


class _Proof:
    """The proof step of :class:`~updating.diagnosis.workflow.Diagnoser` (a mixin)."""

    def prove(self) -> Diagnosis:
        """Nominal, parameter-only and augmented models on the held-out FRFs and the test modes; the findings."""
        cfg = self.config
        self._say("step 6/6: comparing nominal, parameter-only and augmented models on held-out data")
        t1 = time.perf_counter()
        test_modes, modes_source = cfg.test_modes, "given test modes"
        if test_modes is None:
            try:
                test_modes, modes_source = peak_modes(self.measured, band_hz=cfg.band_hz), "peaks of the measured FRFs"
            except ModalabError as e:
                log.info("no test modes: %s", e)
                modes_source = None
        self.test_modes = test_modes

        structures = {"nominal": self.pm.structure(self.p_nomd), "parameters_only": self.pm.structure(self.upd.p),
                      "with_physics": self.best_pm.structure(self.best_fit.p)}
        # each block's models paired with the test modes once (its metrics and its pairing record), and the test
        # modes left without a partner said once for the blocks that leave out the same ones
        paired = ({} if test_modes is None else
                  {key: pair_test_modes(st, test_modes) for key, st in structures.items()})
        if paired:
            say_unpaired(paired, test_modes)

        def metrics(key):
            st = structures[key]
            out = {"frf_error_held_out": frf_error(model_frf(st, self.held), self.held),
                   "frf_error_train": frf_error(model_frf(st, self.train), self.train)}
            out.update(_pairing_metrics(paired.get(key)))
            out["chi2_per_value_held_out"] = chi2_per_value(out["frf_error_held_out"], self.held)
            out["chi2_per_value_train"] = chi2_per_value(out["frf_error_train"], self.train)
            return out

        fit_blocks = {"nominal": metrics("nominal"), "parameters_only": metrics("parameters_only")}
        fit_blocks["with_physics"] = metrics("with_physics") if self.current else dict(fit_blocks["parameters_only"])
        pairing = {}
        if test_modes is not None:
            for key, pr in paired.items():
                pairing[key] = {"pairs": [{"model_hz": fm, "test_hz": float(test_modes.freq_hz[t]), "mac": mc,
                                           "freq_error_pct": fe}
                                          for (fm, t), mc, fe in zip(pr["pairs"], pr["mac"], pr["freq_error_pct"])],
                                "unpaired_test_hz": pr["unpaired_test_hz"], "excluded_test_hz": pr["excluded_test_hz"],
                                "excluded_model_hz": pr["excluded_model_hz"], "cutoff_hz": pr["cutoff_hz"]}
        self._blind_note = None
        if self.current and fit_blocks["with_physics"]["frf_error_held_out"] > \
                fit_blocks["parameters_only"]["frf_error_held_out"] * (1 - cfg.min_holdout_gain) and \
                not self._held_out_blind(fit_blocks):
            log.info("augmentation did not improve held-out data enough; reporting no missing physics")
            self.current, self.best_fit, self.best_pm, self.best_scales = [], self.upd, self.pm, []
            fit_blocks["with_physics"] = dict(fit_blocks["parameters_only"])
        self.timings["6 proof"] = time.perf_counter() - t1
        findings = self._findings()
        steps_modes = {"test_modes": modes_source, "test_freq_hz": [float(x) for x in test_modes.freq_hz]} \
            if modes_source else {}
        st_upd, st_fin = self.pm.structure(self.upd.p), self.best_pm.structure(self.best_fit.p)
        maps = {"freq_hz": self.train.freq_hz, "responses": [str(d) for d in self.train.responses],
                "before": residual_map(st_upd, self.train), "after": residual_map(st_fin, self.train)}
        final_model = self.best_pm.model_at(self.best_fit.p) if hasattr(self.best_pm, "model_at") else self.model0
        try:
            curves, freqs = self._overlays(findings)
        except (ModalabError, np.linalg.LinAlgError) as e:  # pragma: no cover - figures are a by-product
            log.warning("FRF overlays/frequency table not prepared: %s", e)
            curves, freqs = {}, {}
        diag = Diagnosis(findings=findings, parameters=self._parameters(), fit=fit_blocks,
                         statement=statement(findings, fit_blocks, self.held_desc, self.not_evaluated,
                                             self.unobservable, self.mesh_note, blind=self._blind_note,
                                             noise_limit=PICK_MAX_REDUCED_CHI2),
                         model=final_model, not_evaluated=list(self.not_evaluated),
                         unobservable=list(self.unobservable), decisions=list(self.decisions),
                         parametric=self.best_pm, p=self.best_fit.p,
                         steps={"held_out": self.held_desc, "band_hz": self.band, "hot_nodes": self.hot_nodes,
                                "suspension_below_hz": self.suspension_hz, "mesh_correction": self.mesh_note,
                                "n_candidates": self.n_lib, **steps_modes},
                         maps=maps, timings=self.timings, ranking=self.ranking or [], curves=curves, frequencies=freqs,
                         pairing=pairing)
        self.timings["total"] = time.perf_counter() - self._t0
        return diag

    def _held_out_blind(self, fit_blocks: dict) -> bool:
        """Whether the held-out FRFs cannot show the terms' gain and the training FRFs' folds do: the parameters
        alone leave the held-out rows at their noise (χ²/N at most :data:`HELD_OUT_AT_NOISE`), the terms keep
        them there, and the terms predict the training rows' folds that their fits did not see significantly
        better than the parameters alone (:meth:`_cross_validated`).  Then the held-out rows are no evidence
        either way, not evidence against.  Even case 1992 (a joint flexible about RX at a mount of a ladder frame,
        four sensors): the joint took the training FRFs from χ²/N 12.6 to 0.05 while the held-out rows, which
        do not see that joint, stayed at χ²/N 0.06 with the parameters alone, and the 10 % held-out gain the
        proof asked for could not be had: no finding."""
        po, wp = fit_blocks["parameters_only"], fit_blocks["with_physics"]
        if not (po["chi2_per_value_held_out"] <= HELD_OUT_AT_NOISE and wp["chi2_per_value_held_out"] <= HELD_OUT_AT_NOISE):
            return False
        ref, new = (self.pm, self.upd.p, self.lo, self.hi), \
            (self.best_pm, self.best_fit.p, np.r_[self.lo, np.zeros(len(self.current))],
             np.r_[self.hi, _upper(self.current, self.best_scales)])
        ok, why = self._cross_validated(ref, new)
        log.info("the held-out FRFs are at their noise with the parameters alone (χ²/N %.3g) and with the terms "
                 "(%.3g): they cannot show the terms' gain; the training FRFs' folds: %s", po["chi2_per_value_held_out"],
                 wp["chi2_per_value_held_out"], why)
        if ok:
            _, _, c0, c1, n = self._cv_totals(ref, new)          # the folds' fits are cached: no refit
            self._blind_note = (f"The held-out FRFs are at their noise with the parameters alone (χ²/N "
                                f"{po['chi2_per_value_held_out']:.2g}) and cannot show the gain; the evidence is the "
                                f"training FRFs' cross-validation (each fold predicted by fits that did not see it): "
                                f"χ²/N {c0 / n:.3g} -> {c1 / n:.3g}.")
        return ok

    def _findings(self) -> list:
        n_par, findings, ranking = len(self.params), [], self.ranking or []
        m_fin = self.best_pm.model_at(self.best_fit.p) if self.current else self.model0
        for k, (c, scale) in enumerate(zip(self.current, self.best_scales)):
            val = self.best_fit.p[n_par + k] * scale
            std = self.best_fit.std[n_par + k] * scale
            if _at_bound(val, 0.0, getattr(c, "upper", np.inf), std):
                # the fit stopped on the value's bound: the curvature there is not the spread of the estimate
                # (the data would take it past the bound), so no ± is stated
                log.info("%s: %.4g %s lies on its bound (0 or the plausible %.4g): its standard deviation is "
                         "reported as not determined", c.label, val, c.unit, getattr(c, "upper", np.inf))
                std = np.inf
            # a term of the same physics next to an earlier finding refines it (a mass between two nodes is
            # lumped on both): one finding with two parts, not two findings
            if c.label.startswith(SPRING_LOSS):
                # a found spring's own loss factor (library.spring_loss_candidates): a property of its finding
                host = next((f for f in findings if loss_of(c, f.candidate) or
                             any(loss_of(c, o) for o, *_ in f.parts)), None)
            else:
                host = next((f for f in findings if f.candidate.physics == c.physics and
                             _same_place(f.candidate, c, m_fin)), None)
            if host is None and _is_spring_damping(c):
                # a dashpot to ground where a spring to ground was found is the support's own loss (a rubber
                # mount or cord has both): the same finding, not a second piece of missing physics.  Where the
                # spring's place is ambiguous (along an axially stiff member), its loss is as ambiguous: a dashpot
                # in the spring's direction at or next to any of the spring's places is that loss
                host = next((f for f in findings if f.candidate.physics in _LOSSY_SPRINGS and
                             (set(c.dofs) <= set(f.candidate.dofs) or
                              (_directions(c) <= _directions(f.candidate) and
                               any(_same_place(o, c, m_fin) for o in
                                   [f.candidate] + [a for a, *_ in f.alternatives])))), None)
            if host is not None:
                host.parts.append((c, float(val), float(std)))
                continue
            gain, by_mci, same = self._route.get(c.key, (0.0, self.use_mci, None))
            if same is None:
                same = [(o, t, g) for o, t, g in ranking if set(o.nodes) & set(c.nodes) and o.key != c.key]
            findings.append(Finding(c, float(val), float(std), _evidence(c, gain, same, self.band, by_mci) +
                                    self.__dict__.get("_tension_notes", {}).get(c.key, ""), gain or 0.0,
                                    alternatives=list(self.alternatives.get(c.key, []))))
        return findings

    def _parameters(self) -> dict:
        pars, fit, upd = {}, self.best_fit, self.upd
        z_fin, z_upd = self.prior.z(fit.p), self.prior.z(upd.p)
        for k, par in enumerate(self.params):
            pars[par.name] = {"initial": float(self.p_nomd[k]), "updated": float(fit.p[k]),
                              "parameters_only": float(upd.p[k]),
                              "std": float(fit.std[k]) if np.isfinite(fit.std[k]) else None, "mode": par.mode,
                              "prior_std": float(self.psig[k]) if np.isfinite(self.psig[k]) else None,
                              "prior_z": float(z_fin[k]), "at_prior": bool(abs(z_fin[k]) > AT_PRIOR_Z)}
            if isinstance(par, SectionLossFactor):     # an offset: the group's total is what a reader wants
                tot = {key: loss_factor_totals(self.params, pv, self.model0.global_ge)[par.name][1]
                       for key, pv in (("initial", self.p_nomd), ("updated", fit.p), ("parameters_only", upd.p))}
                # never negative: each of the three fits is bounded at 0 in all (nonnegative_loss_factors)
                pars[par.name]["total"] = {**tot, "offset_of": next(
                    (q.name for q in self.params if q.field == "global_ge"), "PARAM G"),
                    "properties": [str(x) for x in par.properties]}
            if abs(z_fin[k]) > AT_PRIOR_Z or abs(z_upd[k]) > AT_PRIOR_Z:
                log.warning("parameter %s runs into its prior (mean %.4g, std %.3g): %.4g in the final fit (%+.1f std), "
                            "%.4g with parameters only (%+.1f std); the model may miss something the candidates do "
                            "not cover", par.name, self.pmean[k], self.psig[k], fit.p[k], z_fin[k], upd.p[k], z_upd[k])
        return pars

    def _overlays(self, findings) -> tuple[dict, dict]:
        """FRF overlays at the located DOFs (findings' measured DOFs, else the worst-fitting nodes) and the
        paired frequencies of the three models, for the report's figures."""
        data, test_modes = self.data, self.test_modes
        st_nom, st_par = self.pm.structure(self.p_nomd), self.pm.structure(self.upd.p)
        st_phys = self.best_pm.structure(self.best_fit.p)
        want = [d for f in findings for d in f.candidate.dofs] + [f"{n}+Z" for n in self.hot_nodes]
        labels = [str(r) for r in data.responses]
        rows = []
        for w in want:
            hit = [i for i, lbl in enumerate(labels) if lbl == w or lbl.split("+")[0].split("-")[0] == w.split("+")[0]]
            rows += [i for i in hit if i not in rows]
        rows = rows[:3] or [0]
        H = {"measured": data.H, "nominal": model_frf(st_nom, data), "parameters_only": model_frf(st_par, data),
             "with_physics": model_frf(st_phys, data)}
        curves = {"freq_hz": data.freq_hz, "pairs": [(f"{labels[i]} / {data.references[0]}",
                                                      {k: v[i, 0] for k, v in H.items()}) for i in rows]}
        nm = len(test_modes.freq_hz) + 2 if test_modes is not None else 8
        freqs = {key: _paired_frequencies(stx, test_modes, nm, self.band)
                 for key, stx in (("nominal", st_nom), ("parameters_only", st_par), ("with_physics", st_phys))}
        freqs["test"] = [float(x) for x in test_modes.freq_hz] if test_modes is not None else []
        return curves, freqs
