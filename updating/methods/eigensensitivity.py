"""Inverse eigensensitivity updating, thesis section 3.2.2 (Eq. 3.40–3.53).

The measured natural frequencies and mode shapes are expanded to first
order in the parameters (Eq. 3.44–3.49) and the linearised system
``[S]{Δp} = {Δ}`` (Eq. 3.50–3.52) is solved repeatedly (Gauss–Newton) because
the modal data depend non-linearly on the parameters.  What the thesis did by
hand between Nastran runs is automated here, with the additions its section
6.3 asks for:

**Residuals, for paired modes only.**  At every iteration the analytical modes
are recomputed and paired with the test modes by the one pairing rule of
:func:`updating.correlation.metrics.pair_modes` (MAC and frequency, a frequency window,
unobservable and rigid-body modes excluded), so modes that are out of order
between the models are compared with their true partner.  The objective is
defined on the test modes paired at the start: a test mode without a partner
then stays out at every iteration (re-pairing may follow a mode switch but never
adds a test mode); frequency-only test sets keep their initial partners.  Per pair:

* frequency: ``(f_X − f_A)/f_X`` with sensitivity ``(∂f_A/∂p)/f_X`` from
  ``∂λ/∂p = φᵀ(∂K/∂p − λ∂M/∂p)φ`` (or eigenvalues, ``residual='eigenvalue'``:
  ``(λ_X − λ_A)/λ_X``, Eq. 3.46);
* shape at the measured DOFs: the test shape ``x`` is scaled onto the
  analytical one ``a = Cφ_A`` by the modal scale factor (MSF, Eq. 2.62), and
  the residual ``(MSF·x − a)/‖a‖`` has the sensitivity
  ``(I − x xᵀ/xᵀx) C ∂φ_A/∂p / ‖a‖`` (Eq. 3.47, with the MSF's own
  dependence on p; only the part of ∂φ orthogonal to x matters), with
  eigenvector derivatives by Nelson's method (:mod:`updating.fe.sensitivity`).

**Weighting rule (default).**  Each residual is divided by its standard
deviation (so the weighted residuals are white when the σ are right):
``freq_sigma`` = 1 % of the frequency and ``shape_sigma`` = 5 % of the RMS
shape amplitude per measured component.  Both residual types are relative, so
the orders-of-magnitude gap between raw frequency and shape sensitivities the
thesis reports (6.3) disappears; the ratio 1:5 reflects that identified
frequencies are typically 5–10 times more accurate than individual shape
components, and every measured DOF counts as one equation.  Pass per-mode
``freq_sigma`` (relative) and per-component ``shape_sigma`` arrays (relative
to the RMS of the test shape) to weight by measurement uncertainty, or
``use_shapes=False`` for frequencies only.

**Regularisation.**  Tikhonov with factor α chosen by the L-curve (maximum
curvature) or GCV at each iteration, or fixed; ``tikhonov='step'``
(default) penalises the step (Levenberg–Marquardt-like: stabilises, no bias
at convergence), ``'initial'`` the departure from the initial parameters
(classic Tikhonov: biased towards the initial model, for ill-posed sets).
Parameters are scaled by their initial values (relative changes) first.

**Bounds, convergence, covariance.**  Steps are projected on the bounds and
halved while the weighted cost rises; convergence when the largest relative
parameter change is below ``tol``.  ``covariance_`` (parameter units) is that of
the linearised estimate at the solution: ``(SᵀS)⁻¹`` when the step is
penalised (the converged estimate is the least-squares one), the posterior
``(SᵀS + α²I)⁻¹`` with its prior when the departure from the initial values is
(``tikhonov='initial'``).  The stated σ are checked against the residuals
(χ² per residual group, frequencies and shapes): a group whose χ² exceeds its
95 % point is down-weighted by χ²/dof before the covariance is formed, so a
printed standard deviation is not smaller than the data support
(:func:`updating.methods.regularisation.posterior`; coverage tested in ``tests/updating/test_update_coverage.py``).

**Damped poles.**  Identification reports the modulus of each pole, |s|.  A
model with structural damping (PARAM G, GE) has |s| = ω (1 + η²)^{1/4} above
its undamped ω (η the modal loss factor): the analysis frequency compared with
the test is that modulus
(:func:`updating.methods.eigensensitivity_system.pole_factor`), so that data simulated from
the damped model itself leave its parameters unchanged.

Parameter selection: :func:`sensitivity_ranking` (norms of the weighted,
scaled sensitivity columns) and :func:`identifiability` (singular values of
the weighted sensitivity matrix; parameter combinations along singular
vectors with small singular values are not identifiable from the data).

Where: the linearised system (pairing, residual rows, weights, damped poles) in
:mod:`updating.methods.eigensensitivity_system`; the regularisation and the covariance in
:mod:`updating.methods.regularisation`; the Gauss–Newton iteration here.
"""
from __future__ import annotations

import logging

import numpy as np

from modalab.core.errors import ModalabValueError, NotFittedError, ShapeError
from modalab.core.modes import ModeSet

from updating.fe.parametric import parameter_indices
from updating.methods.eigensensitivity_system import (SensitivitySystem, hysteretic_matrix, identifiability,
                                                      measured_observation, sensitivity_ranking, sensitivity_system)
from updating.methods.regularisation import choose_alpha, posterior, tikhonov_solve

log = logging.getLogger(__name__)

__all__ = [
    "SensitivitySystem",
    "sensitivity_system",
    "sensitivity_ranking",
    "identifiability",
    "choose_alpha",
    "InverseEigensensitivity",
]


class InverseEigensensitivity:
    """Inverse eigensensitivity updater (thesis 3.2.2), ``fit(model, test_modes, dofmap=None)``.

    Parameters
    ----------
    params : names or indices of the parameters to update (default all).
    freq_sigma, shape_sigma, use_shapes, residual : weighting and residual definition (module docstring);
        ``weights`` a dict with any of ``freq_sigma``, ``shape_sigma``, ``use_shapes`` overrides them
        (e.g. measurement uncertainties from identification).
    regularisation : ``'lcurve'``, ``'gcv'``, a fixed α ≥ 0, or None (plain least squares).
    tikhonov : ``'step'`` (default) or ``'initial'`` — what α penalises.
    bounds : (lower, upper) arrays in parameter units (None entries unbounded), for the updated parameters
        or the full vector.
    max_iter, tol : iteration limit; convergence when max |Δp/p_scale| < tol.
    mac_min : MAC threshold for a pair; n_modes : analytical modes computed (default max(2·n_test, n_test + 6)).

    Attributes after fit
    --------------------
    p_ (full vector), params_, std_ and covariance_ (updated parameters, parameter units; see the module
    docstring), std_unregularised_ and covariance_unregularised_ (without any prior), condition_ and
    singular_values_ (of the weighted sensitivity matrix), identifiable_ (condition_ <= condition_max),
    residual_check_ ({'frequency'|'shape': chi2, dof, chi2_95, factor, n}: the stated sigma against the residuals),
    history_ (list of dicts: iteration, p, cost, alpha, pairs, freq_error_pct), initial_pairs_, pairs_,
    freq_a_hz_ (paired analytical frequencies at the solution, per test mode; NaN if unpaired),
    converged_, n_iter_.
    """

    def __init__(self, params=None, *, weights=None, freq_sigma=0.01, shape_sigma=0.05, use_shapes: bool = True,
                 residual: str = "frequency", regularisation="lcurve", tikhonov: str = "step", bounds=None,
                 max_iter: int = 50, tol: float = 1e-6, mac_min: float = 0.5, n_modes: int | None = None,
                 pairing: dict | None = None, freq_cov="test", condition_max: float = 1e3):
        self.pairing = pairing
        self.freq_cov = freq_cov
        self.condition_max = condition_max
        self.weights = weights
        self.params = params
        self.freq_sigma = freq_sigma
        self.shape_sigma = shape_sigma
        self.use_shapes = use_shapes
        self.residual = residual
        self.regularisation = regularisation
        self.tikhonov = tikhonov
        self.bounds = bounds
        self.max_iter = max_iter
        self.tol = tol
        self.mac_min = mac_min
        self.n_modes = n_modes

    def _alpha(self, S, b):
        reg = self.regularisation
        if reg is None:
            return 0.0
        if isinstance(reg, str):
            return choose_alpha(S, b, reg)
        a = float(reg)
        if a < 0:
            raise ModalabValueError(f"regularisation factor {a}; expected >= 0, 'lcurve' or 'gcv'")
        return a

    def _bounds(self, model, idx):
        P = len(model.parameter_names)
        if self.bounds is None:
            return np.full(idx.size, -np.inf), np.full(idx.size, np.inf)
        lo, hi = self.bounds
        out = []
        for v, fill in ((lo, -np.inf), (hi, np.inf)):
            if v is None:
                out.append(np.full(idx.size, fill))
                continue
            v = np.asarray(v, float)
            if v.ndim == 0:
                out.append(np.full(idx.size, float(v)))
            elif v.size == P:
                out.append(v[idx])
            elif v.size == idx.size:
                out.append(v.copy())
            else:
                raise ShapeError(f"bounds of size {v.size}; expected {idx.size} (updated) or {P} (all parameters)")
        if np.any(out[0] > out[1]):
            raise ModalabValueError("some lower bounds exceed the upper bounds")
        return out[0], out[1]

    def fit(self, model, test_modes: ModeSet, dofmap=None, p_init=None) -> "InverseEigensensitivity":
        if not isinstance(test_modes, ModeSet):
            raise ModalabValueError(f"test_modes must be a modalab.core.modes.ModeSet; got {type(test_modes).__name__}")
        if self.tikhonov not in ("step", "initial"):
            raise ModalabValueError(f"tikhonov={self.tikhonov!r}; expected 'step' or 'initial'")
        idx = parameter_indices(model, self.params)
        p = np.array(model.p0 if p_init is None else p_init, float)
        p0 = p.copy()
        scale = np.where(p0[idx] != 0, np.abs(p0[idx]), 1.0)
        lo, hi = self._bounds(model, idx)
        kw = self._system_options(model, test_modes, dofmap, p, idx, scale)
        self.history_ = []
        self.converged_ = False
        self.params_ = idx
        sysm = sensitivity_system(model, test_modes, p, **kw)
        self._keep_initial_pairs(sysm, test_modes, kw)
        p, sysm, it, change = self._iterate(model, test_modes, kw, sysm, p, p0, idx, scale, (lo, hi))
        if not self.converged_:
            log.warning("inverse eigensensitivity did not converge in %d iterations (last change %.3g)",
                        it, change)
        self._set_uncertainty(sysm, scale, idx)
        self.p_ = p
        self.pairs_ = sysm.pairs
        fa = np.full(test_modes.n_modes, np.nan)
        for a, x in sysm.pairs:
            fa[x] = sysm.freq_a_hz[a]
        self.freq_a_hz_ = fa
        self.n_iter_ = it
        return self

    def _system_options(self, model, test_modes: ModeSet, dofmap, p, idx, scale) -> dict:
        """Keyword arguments of :func:`sensitivity_system` for every iteration (weights, pairing, scaling)."""
        C = measured_observation(test_modes, model, dofmap)
        wts = dict(freq_sigma=self.freq_sigma, shape_sigma=self.shape_sigma, use_shapes=self.use_shapes)
        if self.weights is not None:
            unknown = set(self.weights) - set(wts)
            if unknown:
                raise ModalabValueError(f"weights keys {sorted(unknown)}; expected some of {sorted(wts)}")
            wts.update(self.weights)
        fcov = test_modes.freq_cov if isinstance(self.freq_cov, str) and self.freq_cov == "test" else self.freq_cov
        return dict(params=idx, n_modes=self.n_modes, mac_min=self.mac_min, residual=self.residual,
                    scale=scale, C=C, pairing=self.pairing, freq_cov=fcov,
                    hysteretic=None if hysteretic_matrix(model, p) is not None else False, **wts)

    def _keep_initial_pairs(self, sysm: SensitivitySystem, test_modes: ModeSet, kw: dict):
        """Fix the objective to the test modes paired at the start (``kw`` updated in place)."""
        self.initial_pairs_ = list(sysm.pairs)
        # the objective is defined on the test modes paired at the start: re-pairing at later iterations may follow
        # a mode switch (new analysis partner) but never adds a test mode the initial model could not pair
        kw["only_test"] = sorted(x for _, x in sysm.pairs)
        if not test_modes.has_shapes:
            # no shapes to follow a mode: keep the analysis partner (by mode number) found at the start
            kw["fixed_pairs"] = list(sysm.pairs)
        self.unpaired_test_ = [j for j in range(test_modes.n_modes) if j not in kw["only_test"]]
        if self.unpaired_test_:
            log.info("inverse eigensensitivity: test modes %s have no partner and stay out of the objective",
                     [j + 1 for j in self.unpaired_test_])

    def _iterate(self, model, test_modes, kw, sysm, p, p0, idx, scale, bounds):
        """Gauss–Newton iterations with a halving line search; returns (p, system at p, iterations, last change)."""
        change = np.inf
        it = 0
        for it in range(1, self.max_iter + 1):
            S, r = sysm.S, sysm.r
            d0 = (p[idx] - p0[idx]) / scale
            alpha, dx = self._step(S, r, d0)
            cost0 = float(r @ r) + (alpha ** 2 * float(d0 @ d0) if self.tikhonov == "initial" else 0.0)
            # the step that defines convergence: with the step penalised, the undamped Gauss–Newton step (the
            # damped one shrinks as α grows and would stop the iteration short of the least-squares solution,
            # issue 14: a 3-DOF chain stopped at +2 % with its frequencies 1.4 %/2.7 % off, "converged");
            # with the departure penalised, the regularised step itself
            target = tikhonov_solve(S, r, 0.0) if self.tikhonov == "step" else dx
            remaining = _projected_change(p, idx, scale, bounds, target)
            pn = None
            if self.tikhonov == "step":
                # Levenberg–Marquardt order: the Gauss–Newton step first (halved at most twice), the L-curve
                # damped step only when it does not lower the cost
                pn, new, cost, step, best_gn = self._line_search(model, test_modes, kw, p, p0, idx, scale,
                                                                 bounds, target, 0.0, cost0, r.size, tries=3)
                if pn is not None:
                    alpha = 0.0
            if pn is None:
                pn, new, cost, step, best_tried = self._line_search(model, test_modes, kw, p, p0, idx, scale,
                                                                    bounds, dx, alpha, cost0, r.size)
                if self.tikhonov == "step":
                    best_tried = min(best_tried, best_gn)
            if pn is None:
                self.converged_ = _stationary(S, r, target, cost0, best_tried, it)
                break
            change = float(np.max(np.abs(pn[idx] - p[idx]) / scale))
            p, sysm = pn, new
            ferr = 100 * (sysm.freq_a_hz[[a for a, _ in sysm.pairs]] - sysm.freq_x_hz[[x for _, x in sysm.pairs]]) \
                / sysm.freq_x_hz[[x for _, x in sysm.pairs]]
            self.history_.append({"iteration": it, "p": p.copy(), "cost": cost, "alpha": alpha,
                                  "pairs": list(sysm.pairs), "freq_error_pct": ferr, "step": step})
            log.debug("IES iteration %d: cost %.4g, alpha %.3g, change %.3g", it, cost, alpha, change)
            if max(change, remaining) < self.tol:
                self.converged_ = True
                break
            change = max(change, remaining)
        return p, sysm, it, change

    def _step(self, S, r, d0):
        """Tikhonov factor and the Gauss–Newton step (scaled units) from the system at the current point."""
        if self.tikhonov == "initial":
            b = r + S @ d0
            alpha = self._alpha(S, b)
            y = tikhonov_solve(S, b, alpha)
            return alpha, y - d0
        alpha = self._alpha(S, r)
        return alpha, tikhonov_solve(S, r, alpha)

    def _line_search(self, model, test_modes, kw, p, p0, idx, scale, bounds, dx, alpha, cost0, n_res, tries=10):
        """The step, halved at most ``tries`` times, projected on the bounds, until the weighted cost does not rise:
        (p, system, cost, step factor, lowest cost tried), with p None when no step lowered the cost."""
        lo, hi = bounds
        step = 1.0
        best_tried = np.inf
        for _ls in range(tries):
            pn = p.copy()
            pn[idx] = np.clip(p[idx] + step * dx * scale, lo, hi)
            try:
                new = sensitivity_system(model, test_modes, pn, **kw)
                dn = (pn[idx] - p0[idx]) / scale
                cost = float(new.r @ new.r) + (alpha ** 2 * float(dn @ dn) if self.tikhonov == "initial" else 0.0)
                ok = cost <= cost0 * (1 + 1e-12) and new.r.size >= n_res
                if new.r.size >= n_res:
                    best_tried = min(best_tried, cost)
            except ModalabValueError:
                # a trial point where the test modes cannot be paired (or a rigid-body mode pairs) is rejected like
                # one that raises the cost: the step is halved; no cost is invented for it
                ok = False
            if ok:
                return pn, new, cost, step, best_tried
            step *= 0.5
        return None, None, None, step, best_tried

    def _set_uncertainty(self, sysm: SensitivitySystem, scale, idx):
        """Covariances, residual check, condition and identifiability at the solution (parameter units)."""
        alpha = self.history_[-1]["alpha"] if self.history_ else 0.0
        post = posterior(sysm.S, sysm.r, sysm.rows, alpha if self.tikhonov == "initial" else 0.0)
        sc = np.outer(scale, scale)
        self.covariance_ = post["covariance"] * sc
        self.std_ = np.sqrt(np.clip(np.diag(self.covariance_), 0, None))
        self.covariance_unregularised_ = post["covariance_unregularised"] * sc
        self.std_unregularised_ = np.sqrt(np.clip(np.diag(self.covariance_unregularised_), 0, None))
        self.residual_check_ = post["groups"]
        self.singular_values_ = post["singular_values"]
        self.condition_ = post["condition"]
        for g in post["groups"].values():
            if g["factor"] > 1:
                log.warning("inverse eigensensitivity: the %s residuals are %.3g times their stated standard "
                            "deviations (chi2 %.4g for %.3g degrees of freedom, above its 95 %% point %.4g): the "
                            "stated sigma are too small for these data, or the model leaves out physics the "
                            "parameters absorb (then no standard deviation bounds their bias); the parameter "
                            "standard deviations are raised accordingly", g["name"],
                            np.sqrt(g["factor"]), g["chi2"], g["dof"], g["chi2_95"])
        self.identifiable_ = bool(self.condition_ <= self.condition_max)
        if not self.identifiable_:
            log.warning("the parameters are not identifiable from these data: condition number %.3g > %.3g "
                        "(%d equations, %d parameters); unregularised standard deviations %s%s",
                        self.condition_, self.condition_max, sysm.S.shape[0], idx.size,
                        np.array2string(self.std_unregularised_, precision=3),
                        "" if self.tikhonov != "initial" else
                        f" — the posterior values {np.array2string(self.std_, precision=3)} rest on the "
                        "regularisation's prior, not on the data")

    def _check(self):
        if not hasattr(self, "p_"):
            raise NotFittedError("this InverseEigensensitivity is not fitted yet; call fit(model, test_modes)")

    def parameter_history(self) -> np.ndarray:
        """(n_iter, P) parameter vectors per iteration."""
        self._check()
        return np.vstack([h["p"] for h in self.history_])


def _projected_change(p, idx, scale, bounds, dx) -> float:
    """Largest relative parameter change of the step ``dx`` (scaled units) once projected on the bounds."""
    lo, hi = bounds
    return float(np.max(np.abs(np.clip(p[idx] + dx * scale, lo, hi) - p[idx]) / scale, initial=0.0))


def _stationary(S, r, dx, cost0, best_tried, it) -> bool:
    """No step lowered the cost: at a stationary point (the Gauss–Newton model predicts almost no decrease)
    that is convergence (True); elsewhere the linearisation has failed (False, with a warning)."""
    res_lin = r - S @ dx
    pred = float(r @ r) - float(res_lin @ res_lin)
    if pred <= 1e-4 * max(cost0, 1e-300) or best_tried <= cost0 * (1 + 1e-5):
        log.info("inverse eigensensitivity: stationary at iteration %d (cost %.6g; the steps tried "
                 "reach %.6g, the linear model predicts a decrease of %.3g)", it, cost0, best_tried, pred)
        return True
    log.warning("inverse eigensensitivity: no step decreased the cost at iteration %d", it)
    return False
