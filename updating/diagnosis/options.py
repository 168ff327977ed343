"""The options of one step of the diagnosis' screening (step 3 of :mod:`~updating.diagnosis.workflow`): the
candidates to fit and their start values (:meth:`_Options._options`: the best of the linear MCI ranking, of the
exact FRF and damping screenings, joints near the located nodes and every support release) and the fit of the
current terms plus one of them with the parameters (:meth:`_Options._try`).  Split out of ``workflow.py`` as a
mixin of :class:`~updating.diagnosis.workflow.Diagnoser`: the methods read and write the diagnoser's state."""
from __future__ import annotations

import logging

import numpy as np

from updating.diagnosis.dampscreen import damping_screen
from updating.diagnosis.fit import quick_frf_error
from updating.diagnosis.library import _nodes_of
from updating.diagnosis.screen import mci_update, rank_candidates, residual_system
from updating.diagnosis.terms import DAMPING_PLACES, _distinct_places, _dof_stiffness, _augmented

log = logging.getLogger(__name__)

#: a release whose stiffness is this many times the structure's own at its DOF is the rigid connection of the
#: nominal (its flexibility changes the local compliance by a millionth): the bound of its MCI fit
RIGID_RELEASE = 1e6


class _Options:

    def _options(self, it: int) -> list:
        """[(candidate, start value or None)] to try: the best of the linear MCI ranking and of the exact FRF
        screening, joints near the located nodes and every support release."""
        cfg = self.config
        pm_cur, p_cur = self.pm_cur, self.p_cur
        lib = self._library(pm_cur.model_at(p_cur))
        self.n_lib = max(self.n_lib, len(lib))
        have = {c.key for c in self.current}
        # exact single-candidate FRF screening (non-linear in the value; strong effects that the linear MCI
        # screening mis-ranks), around the nominal parameters first (parameter updating may have bent them
        # to hide the effect), then around the current model
        # joint and support releases are screened exactly too, at every place (updating.diagnosis.release)
        releases = [c for c in lib if c.release is not None and c.key not in have and c.key not in self._hidden]
        at = [(self.p_nomd, False), (self.upd.p, True)] if it == 0 else [(p_cur, False)]
        screens = self._each(self._screening, [(p_scr, fitted, lib, releases) for p_scr, fitted in at], refs=lib)
        self._screens = [(scr, np.asarray(p_scr, float)) for scr, (p_scr, _) in zip(screens, at)]
        if self.use_mci:
            rk, _, energy = rank_candidates(pm_cur, p_cur, lib, self.train, self.W)
            if it == 0:
                # also rank around the nominal parameters: after parameter-only updating the parameters have
                # often absorbed part of what is missing, which hides it from a linear look
                rk0, _, _ = rank_candidates(self.pm, self.p_nom, lib, self.train, self.W)
                seen_keys = {c.key for c, _, _ in rk[:4]}
                rk = rk[:4] + [t for t in rk0[:4] if t[0].key not in seen_keys] + rk[4:]
            node_e: dict = {}
            for d, e in zip(self.train.responses, energy):
                node_e[d.node] = node_e.get(d.node, 0.0) + float(e) ** 2
            hot = [n for n, _ in sorted(node_e.items(), key=lambda kv: -kv[1])[:2]]
        else:
            rk = screens[0] if screens else []
            hot = list(dict.fromkeys(n for c, _, _ in rk[:4] for n in c.nodes))[:2]
        if self.ranking is None:
            self.ranking, self.hot_nodes = rk, hot
        options = [(c, th) for c, th, g in rk[:cfg.n_try if self.use_mci else 0] if c.key not in have and g > 0.02]
        # FRF-screen picks: the best two overall, the best of each kind of matrix and the best release of each
        # kind (joint, support): a release changes the DOF set, which no other candidate can imitate exactly
        listed = {c.key for c, _ in options}
        # local damping ranked with the parameters (loss factors among them) re-fitted: updating.diagnosis.dampscreen.
        # It measures the training FRF error, so it starts from the current model's FRF fit, as its picks do: the
        # MCI's minimiser can sit at the parameters' bounds with a negative loss factor (seed 1305: E -15 %,
        # ρ -9 %), where the linear re-fit ranks well but the pick's fit from there stops in a poor optimum
        pm_d, fr_d = self._frf_ref()
        dscr = damping_screen(pm_d, fr_d.p, [c for c in lib if c.key not in have], self.train, self.config.jobs)
        self._screens.append((dscr, np.asarray(fr_d.p, float)))        # its best is a pick too (_judge_picks)
        for scr in screens + [dscr]:
            by_kind: dict = {}
            for c, v, g in scr:
                by_kind.setdefault(c.matrix, []).append((c, v, g))
                if c.release is not None:
                    by_kind.setdefault(c.physics, []).append((c, v, g))
            for c, v, g in scr[:2 if self.use_mci else 3] + [lst[0] for lst in by_kind.values()] + \
                    _distinct_places(by_kind.get("D", []), DAMPING_PLACES)[1:]:
                if c.key not in listed and c.key not in have and g > 0.05:
                    options.append((c, v))
                    listed.add(c.key)
        near = set(hot) | {n for c, _, _ in rk[:1] for n in c.nodes}
        # joints without an exact release form (rigid links softened) near the located nodes (within one element)
        near |= {b for e in pm_cur.model_at(p_cur).elements.values()
                 if near & set(_nodes_of(e)) for b in _nodes_of(e)}
        options += [(c, None) for c in lib if not c.shared and c.release is None and c.physics == "joint_flexibility"
                    and near & set(c.nodes) and c.key not in have][:cfg.n_try]
        options += [(c, None) for c in lib if c.release is None and c.physics == "boundary_flexibility"
                    and c.key not in have]
        return [(c, th) for c, th in options if c.key not in self._hidden]

    def _rigid_bound(self, c, chi, scale) -> np.ndarray:
        """``chi`` with the released stiffness of ``c`` bounded at :data:`RIGID_RELEASE` times the larger of the
        structure's median and its own DOF's diagonal stiffness (:func:`_dof_stiffness`): stiffer, the release is
        the rigid connection of the nominal.  Unbounded, the MCI iteration of a release the data do not want
        runs its stiffness up by decades per step (control CT 2242: a joint of a post's arm at 1.4e107, where
        the derivative columns overflow)."""
        structure = self.pm_cur.structure(self.p_cur)
        kd = max(float(np.median(np.abs(structure.K.diagonal()))), _dof_stiffness(structure, c))
        out = np.array(chi, float)
        out[-1] = min(out[-1], RIGID_RELEASE * kd / scale)
        return out

    def _start_value(self, c, pm_aug, p_par, prev) -> float:
        """A start value for a candidate without one: on the MCI, the best of six decades around the median
        stiffness; on the FRFs, the error (in a Ritz basis when large) over six decades around the stiffness
        of the DOF concerned, then refined — a joint or support spring's error is far from convex in it."""
        p_cur, n = self.p_cur, len(self.params)
        if self.use_mci:
            kd = float(np.median(np.abs(self.pm_cur.structure(p_cur).K.diagonal())) or 1.0)
            trials = []
            for v in kd * np.logspace(-3, 2, 6):
                y = residual_system(pm_aug.structure(np.concatenate([p_cur[:n], prev, [v]])), self.train, self.W).y
                trials.append((float(y @ y), v))
            return min(trials, key=lambda t: t[0])[1]

        def qerr(v):
            return quick_frf_error(pm_aug.structure(np.concatenate([p_par, prev, [v]])), self.train)
        kd = _dof_stiffness(self.pm_cur.structure(p_cur), c)
        grid = kd * np.logspace(-4, 2, 21)           # steps of 2: a resonance's basin is narrow
        errs = [qerr(v) for v in grid]
        k = int(np.argmin(errs))
        fine = np.geomspace(grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)], 7)
        errs_f = [qerr(v) for v in fine]
        return float(fine[int(np.argmin(errs_f))]) if min(errs_f) < errs[k] else float(grid[k])

    def _try(self, c, th, it: int):
        """The current terms plus ``c`` fitted with the parameters (MCI or FRF fit, from one or two starts):
        (c, criterion, pm, p, lower, upper, value scale), or None when the candidate cannot be evaluated."""
        n = len(self.params)
        pm_aug, clo, chi, scales = _augmented(self.model0, self.params, self.lo, self.hi, self.current + [c])
        prev = list(self.p_cur[n:])
        if self.use_mci and c.release is not None:
            chi = self._rigid_bound(c, chi, scales[-1])
        p_aug, rss_aug = None, np.inf
        try:
            values = [th]
            if self.use_mci and (th is None or c.release is not None):
                # a release's value from the exact FRF screening, and the MCI's own best decade: the MCI of a
                # release is far from linear in its stiffness (the expansion of the DOFs it frees depends on it)
                values = [v for v in (th, self._start_value(c, pm_aug, None, prev)) if v is not None]
            if self.use_mci:
                starts = (self.p_cur[:n], self.p_nom[:n]) if it == 0 and not self.large else (self.p_cur[:n],)
            else:
                starts = (self.p_cur[:n], self.p_nomd) if it == 0 else (self.p_cur[:n],)
            for p_par, v0 in ((a, b) for a in starts for b in values):
                v = v0 if v0 is not None else self._start_value(c, pm_aug, p_par, prev)
                v = min(v, getattr(c, "upper", np.inf))
                start = np.concatenate([p_par, prev, [v / scales[-1]]])
                if self.use_mci:
                    pa, ra, _ = mci_update(pm_aug, start, self.train, clo, chi, weights=self.W,
                                           iters=3 if self.large else 6,
                                           free=np.concatenate([self.free_mci, np.ones(len(clo) - n, bool)]))
                    if c.release is not None:
                        # the iteration may leave the start for a worse value (see above): the start is a solution
                        y0 = residual_system(pm_aug.structure(start), self.train, self.W).y
                        if float(y0 @ y0) < ra:
                            pa, ra = start, float(y0 @ y0)
                else:
                    fr = self._fit_converged(pm_aug, start, clo, chi)
                    pa, ra = fr.p, fr.error ** 2
                if ra < rss_aug:
                    p_aug, rss_aug = pa, ra
        except np.linalg.LinAlgError as e:
            # the augmented model cannot be solved at some line: the candidate is not judged, and the diagnosis
            # says so (``not_evaluated`` in diagnosis.json and the statement) instead of passing over it
            log.warning("candidate %s could not be evaluated (%s): it is left out of the comparison", c.label, e)
            self.not_evaluated.append({"candidate": c.label, "physics": c.physics, "reason": str(e)})
            return None
        if self.use_mci and c.release is not None and p_aug is not None and p_aug[-1] >= chi[-1] * (1 - 1e-9):
            log.info("candidate %s: the MCI fit holds it rigid (%.3g, %.0e times the stiffness at its DOF): "
                     "no release", c.label, p_aug[-1] * scales[-1], RIGID_RELEASE)
        log.info("candidate %s: %s %.4g (current %.4g)", c.label, "MCI residual" if self.use_mci else
                 "FRF error²", rss_aug, self.rss_cur)
        return None if p_aug is None else (c, rss_aug, pm_aug, p_aug, clo, chi, scales[-1])
