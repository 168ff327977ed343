"""Missing-physics diagnosis from identified modes alone (no FRFs: a GVT deliverable).

:func:`diagnose_modes` judges a model against test modes (natural frequencies f_j, real shapes φ_j on the
measured DOFs) by the residual of :class:`ModalResidual`

    e = [(f_model,j − f_j)/(σ_f f_j) ;  (a_j φ_model,j − φ_j)/σ_φ]

(modes paired by MAC, shapes unit-norm, ``a_j`` the least-squares scale; σ_f = 0.5 %, σ_φ = 2 % by
default): the eigenvalue residual and the shape residual *in displacement space*.  The homogeneous force
residual ``Z(iω_j) φ_j`` (thesis section 3.2.4 with f = 0, the eigen-equation form of eq. 3.89;
:func:`modes_data` still provides it) multiplies the shape scatter by the stiffness and lost the
concealed effects at 1 % scatter; the displacement residual keeps them at 2 %.

1. parameter-only updating on ``e`` (a weak pull to the nominal values: without a force the common
   scale of stiffness and mass is not observable) — the baseline;
2. every grounded-spring and added-mass candidate is added alone at its best value on a plausible grid
   (:func:`screen_modes`, exact eigensolutions), around the updated and the nominal parameters;
3. the best few are fitted jointly with the stiffness parameters (densities stay nominal: a density
   multiplier mimics an added mass, and on suspension modes any grounded stiffness); a term is kept
   if it lowers ``‖e‖²`` by ``min_gain`` and passes an information criterion (``penalty`` × ln N);
   terms are added only while ``‖e‖²`` exceeds the number of equations (χ² rule: beyond that the model
   already explains the modes to the stated precision), and backward elimination drops a term whose
   removal costs less than ``min_term_gain``;
4. the comparison uses test modes held out of the fits (every third mode when there are at least five).

Damping cannot be named from real modes.
"""
from __future__ import annotations

import logging
import time

import numpy as np
import scipy.optimize as so

from modalab.errors import ModalabError, ModalabValueError
from modalab.modes import ModeSet

from ..fe import FEModel, ParametricFEModel
from .fit import FitResult, FRFData
from .library import build_library
from .workflow import (Diagnosis, Finding, _augment, _bounds, _upper, default_parameters, promote_measured,
                       statement)

log = logging.getLogger(__name__)
__all__ = ["diagnose_modes", "modes_data", "fit_modes", "mode_errors", "modal_force_map", "ModalResidual",
           "screen_modes", "fit_modal_residual"]


def modes_data(test_modes: ModeSet, keep=None) -> FRFData:
    """The test modes as homogeneous residual data: one 'line' per mode at s = iω_j, shapes unit-norm."""
    idx = np.arange(test_modes.n_modes) if keep is None else np.asarray(keep, int)
    phi = np.asarray(test_modes.shapes)[:, idx]
    phi = np.real(phi) if np.iscomplexobj(phi) else phi
    phi = phi / np.maximum(np.linalg.norm(phi, axis=0), 1e-300)
    s = 1j * 2 * np.pi * np.asarray(test_modes.freq_hz, float)[idx]
    H = phi[:, None, :].astype(complex)
    return FRFData(s=s, H=H, coherence=np.ones(H.shape), responses=list(test_modes.dofs), references=[],
                   homogeneous=True)


def mode_errors(structure, test_modes: ModeSet, keep=None):
    """Relative frequency errors and MACs of the test modes ``keep`` paired (by MAC) with the model's modes."""
    from ..correlation import correlate
    sub = test_modes if keep is None else test_modes.select_modes(list(np.asarray(keep, int)))
    # MAC-only pairing as before the one pairing rule (pair_modes); the diagnosis fit block adopts it separately
    c = correlate(structure, sub, mac_min=0.0, max_freq_error=None, freq_weight=0.0)
    df = np.full(sub.n_modes, 1.0)
    mac = np.zeros(sub.n_modes)
    for a, t in c.pairs:
        df[t] = (c.analysis.freq_hz[a] - sub.freq_hz[t]) / sub.freq_hz[t]
        mac[t] = c.mac[a, t]
    return df, mac


class ModalResidual:
    """Eigenvalue and shape residuals of a structure against test modes (the modes-only objective).

    ``e = [(f_j − f_test,j)/(σ_f f_test,j) ; (a_j φ_j − φ_test,j)/σ_φ]`` over the test modes ``keep``, each
    paired with the model mode of largest MAC (a model mode used once), shapes unit-norm on the measured
    DOFs and ``a_j`` the least-squares scale.  Shape residuals in displacement space weigh measurement
    noise as it is (a relative scatter of ``σ_φ``), where the force residual ``Z φ`` amplifies it by the
    stiffness; ``σ_f`` is the frequency precision.  Dense eigensolutions of the lowest modes (small and
    medium models).
    """

    def __init__(self, test_modes: ModeSet, keep=None, *, sigma_f: float = 0.005, sigma_phi: float = 0.02):
        idx = np.arange(test_modes.n_modes) if keep is None else np.asarray(keep, int)
        phi = np.asarray(test_modes.shapes)[:, idx]
        phi = np.real(phi) if np.iscomplexobj(phi) else phi
        self.phi = phi / np.maximum(np.linalg.norm(phi, axis=0), 1e-300)
        self.f = np.asarray(test_modes.freq_hz, float)[idx]
        self.dofs = list(test_modes.dofs)
        self.sigma_f, self.sigma_phi = float(sigma_f), float(sigma_phi)
        self._loc = None

    def _rows(self, structure):
        if self._loc is None or self._loc[0] is not structure.dofs:
            from modalab.dof import locate
            mi, ms = locate(structure.dofs, self.dofs, "test-mode DOF")
            self._loc = (structure.dofs, np.asarray(mi), np.asarray(ms, float))
        return self._loc[1], self._loc[2]

    def __call__(self, structure, K=None, M=None) -> np.ndarray:
        import scipy.linalg as sla
        K = structure.K if K is None else K
        M = structure.M if M is None else M
        Kd = K.toarray() if hasattr(K, "toarray") else np.asarray(K)
        Md = M.toarray() if hasattr(M, "toarray") else np.asarray(M)
        n = Kd.shape[0]
        nm = min(n, self.f.size + 12)
        try:
            w2, V = sla.eigh(Kd, Md, subset_by_index=[0, nm - 1])
        except (np.linalg.LinAlgError, ValueError):
            return np.full(self.f.size * (1 + self.phi.shape[0]), 1e3)
        mi, ms = self._rows(structure)
        Vm = V[mi] * ms[:, None]
        Vm = Vm / np.maximum(np.linalg.norm(Vm, axis=0), 1e-300)
        mac = (Vm.T @ self.phi) ** 2                                          # (model, test)
        fm = np.sqrt(np.clip(w2, 0, None)) / (2 * np.pi)
        used = set()
        ef = np.empty(self.f.size)
        es = np.empty_like(self.phi)
        for j in np.argsort(-mac.max(axis=0)):                              # clearest test modes first
            order = [a for a in np.argsort(-mac[:, j]) if a not in used]
            a = order[0]
            used.add(a)
            ef[j] = (fm[a] - self.f[j]) / (self.sigma_f * self.f[j])
            v = Vm[:, a] * np.sign(Vm[:, a] @ self.phi[:, j] or 1.0)
            es[:, j] = (v * (v @ self.phi[:, j]) - self.phi[:, j]) / self.sigma_phi
        return np.concatenate([ef, es.ravel()])


def screen_modes(structure, candidates, resid: ModalResidual) -> list:
    """Each shared stiffness or mass candidate added alone to ``structure`` at its best value on a plausible
    grid, judged on the modal residual: ``[(candidate, value, gain)]`` best first (gain = relative drop of
    the residual's squared norm; only candidates that lower it)."""
    import scipy.sparse as sp
    from .frfscreen import _low_rank, _value_grid
    K, M = sp.csr_matrix(structure.K), sp.csr_matrix(structure.M)
    e0 = resid(structure)
    r0 = float(e0 @ e0)
    out = []
    for c in candidates:
        if not c.shared or c.G is None or c.matrix not in ("K", "M"):
            continue
        lr = _low_rank(c.G)
        if lr is None:
            continue
        grid = _value_grid(c, K, M, lr[0], lr[1], n=13)
        best = (r0, None)
        for th in grid:
            e = resid(structure, K=K + th * c.G, M=None) if c.matrix == "K" else resid(structure, M=M + th * c.G)
            r = float(e @ e)
            if r < best[0]:
                best = (r, th)
        if best[1] is not None:
            out.append((c, float(best[1]), 1.0 - best[0] / max(r0, 1e-300)))
    out.sort(key=lambda t: -t[2])
    return out


def fit_modal_residual(pmodel, resid: ModalResidual, p_start, *, lower, upper, reg: float = 1e-2,
                       max_nfev: int = 60, free=None):
    """Bounded least squares of the modal residual (finite-difference Jacobian) over the ``free``
    parameters, with a weak pull ``reg`` towards the start (the common scale of stiffness and mass is not
    observable without a force).  Returns ``(p, std, rss)`` (rss without the pull)."""
    p_all = np.asarray(p_start, float)
    free = np.ones(p_all.size, bool) if free is None else np.asarray(free, bool)
    p0 = p_all[free]
    scale = np.maximum(np.abs(p0), 1e-12)
    scale = np.where(np.abs(p0) > 0, scale, 1.0)
    lower = np.asarray(lower, float)[free]
    upper = np.asarray(upper, float)[free]

    def full(x):
        p = p_all.copy()
        p[free] = x * scale
        return p

    def fun(x):
        p = full(x)
        try:
            e = resid(pmodel.structure(p))
        except (ModalabError, np.linalg.LinAlgError):
            e = np.full(resid.f.size * (1 + resid.phi.shape[0]), 1e3)
        return np.concatenate([e, reg * (x - p0 / scale) * np.sqrt(e.size)])

    lo, hi = np.asarray(lower, float) / scale, np.asarray(upper, float) / scale
    x0 = np.clip(p0 / scale, lo, hi)
    sol = so.least_squares(fun, x0, bounds=(lo, hi), max_nfev=max_nfev, diff_step=1e-4, method="trf")
    p = full(sol.x)
    e = resid(pmodel.structure(p))
    std = np.zeros(p.size)
    try:
        J = sol.jac
        s2 = float(e @ e) / max(e.size - int(free.sum()), 1)
        std[free] = np.sqrt(np.clip(np.diag(np.linalg.pinv(J.T @ J)) * s2, 0, None)) * scale
    except (np.linalg.LinAlgError, ValueError):  # pragma: no cover
        pass
    return p, std, float(e @ e)


def fit_modes(pmodel, test_modes: ModeSet, p_start, *, lower, upper, keep=None, w_mac: float = 0.3,
              reg: float = 1e-3, max_nfev: int = 60) -> FitResult:
    """Bounded least squares of eigenvalue and MAC residuals (finite-difference Jacobian).

    A weak pull ``reg`` towards the start keeps the unidentifiable common scale of stiffness and mass put.
    """
    p0 = np.asarray(p_start, float)
    scale = np.where(np.isfinite(upper) & (np.abs(p0) > 0), np.abs(p0), np.maximum(np.abs(p0), 1.0))

    def fun(x):
        p = x * scale
        try:
            df, mac = mode_errors(pmodel.structure(p), test_modes, keep)
        except (ModalabError, np.linalg.LinAlgError):
            return np.full(2 * (len(keep) if keep is not None else test_modes.n_modes) + p.size, 10.0)
        return np.concatenate([df, w_mac * (1 - mac), reg * (x - p0 / scale)])

    lo, hi = np.asarray(lower, float) / scale, np.asarray(upper, float) / scale
    x0 = np.clip(p0 / scale, lo, hi)
    sol = so.least_squares(fun, x0, bounds=(lo, hi), max_nfev=max_nfev, diff_step=1e-4, method="trf")
    p = sol.x * scale
    std = np.zeros(p.size)
    try:
        J = sol.jac
        s2 = float(sol.fun @ sol.fun) / max(sol.fun.size - p.size, 1)
        std = np.sqrt(np.clip(np.diag(np.linalg.pinv(J.T @ J)) * s2, 0, None)) * scale
    except (np.linalg.LinAlgError, ValueError):  # pragma: no cover
        pass
    df, _ = mode_errors(pmodel.structure(p), test_modes, keep)
    return FitResult(p, std, float(np.sqrt(np.mean(df ** 2))), [], bool(sol.success), str(sol.message))


def _block(structure, test_modes, keep):
    df, mac = mode_errors(structure, test_modes, keep)
    return {"frf_error_held_out": None, "freq_error_rms_pct": float(100 * np.sqrt(np.mean(df ** 2))),
            "freq_error_max_pct": float(100 * np.max(np.abs(df))), "mac_min": float(np.min(mac))}


def _freq_rms(structure, test_modes, keep) -> float:
    df, _ = mode_errors(structure, test_modes, keep)
    return float(np.sqrt(np.mean(df ** 2)))


def diagnose_modes(model: FEModel, test_modes: ModeSet, *, parameters=None,
                   kinds=("ground_spring", "added_mass"), max_findings: int = 3, penalty: float = 3.0,
                   n_try: int = 4, min_gain: float = 0.3, min_term_gain: float = 0.15, sigma_f: float = 0.005,
                   sigma_phi: float = 0.02, progress=None) -> Diagnosis:
    """Diagnose stiffness and mass physics from identified modes only (module docstring).

    ``test_modes`` on the model's node numbers (real or complex shapes; complex shapes are used through
    their real part after phase alignment by the identification).  Returns a :class:`Diagnosis` whose fit
    blocks hold ``freq_error_max_pct``, ``freq_error_rms_pct`` and ``mac_min`` on the held-out modes
    (``frf_error_held_out`` is None: there are no FRFs).
    """
    t0 = time.perf_counter()
    say = progress or (lambda msg: log.info(msg))
    if test_modes.n_modes < 2:
        raise ModalabValueError(f"{test_modes.n_modes} test mode(s); a modes-only diagnosis needs at least 2")
    # measured nodes that a rigid link eliminates: reverse the link, or leave the DOF out (with a warning)
    model = promote_measured(model, list(test_modes.dofs))
    have = {(d.node, d.axis) for d in model.structure().dofs}
    dropped = [str(d) for d in test_modes.dofs if (d.node, d.axis) not in have]
    if dropped:
        log.warning("test-mode DOF(s) %s are eliminated in the model and left out", ", ".join(dropped))
        test_modes = test_modes.select_dofs([str(d) for d in test_modes.dofs if (d.node, d.axis) in have])
    params = list(parameters) if parameters is not None else default_parameters(model)
    pm = ParametricFEModel(model, params)
    p_nom = np.array(pm.p0, float)
    lo, hi = _bounds(params, p_nom)
    n = test_modes.n_modes
    held = np.arange(2, n, 3) if n >= 5 else np.array([], int)
    train = np.setdiff1d(np.arange(n), held)
    resid = ModalResidual(test_modes, train, sigma_f=sigma_f, sigma_phi=sigma_phi)
    n_eq = resid.f.size * (1 + resid.phi.shape[0])
    say("modes: parameter-only updating (baseline)")
    p_upd, std_upd, rss_upd = fit_modal_residual(pm, resid, p_nom, lower=lo, upper=hi)
    upd = FitResult(p_upd, std_upd, _freq_rms(pm.structure(p_upd), test_modes, train), [], True, "")
    dens_free = np.array([par.field not in ("rho", "nsm") for par in params])
    current, p_cur, pm_cur, rss_cur = [], p_upd, pm, rss_upd
    clo_cur, chi_cur = lo, hi
    ranking = None
    for it in range(max_findings):
        if rss_cur <= n_eq:
            # χ² stopping rule: the residual is within what the stated precisions (σ_f, σ_φ) explain
            log.info("modes: residual %.4g within the %d-equation noise level; no further term", rss_cur, n_eq)
            break
        lib = build_library(pm_cur.model_at(p_cur), kinds=kinds)
        screens = [screen_modes(pm_cur.structure(p_cur), lib, resid)]
        if it == 0:      # and around the nominal parameters (updating may have bent them to hide the effect)
            screens.append(screen_modes(pm.structure(p_nom), lib, resid))
        if ranking is None:
            ranking = screens[0]
        have = {c.key for c in current}
        options, listed = [], set()
        for scr in screens:
            for c, th, g in scr[:n_try]:
                if c.key not in have and c.key not in listed and g > 0.05:
                    options.append((c, th))
                    listed.add(c.key)
        best = None
        for c, th in options:
            m_aug, cpar, scales = _augment(model, current + [c])
            pm_aug = ParametricFEModel(m_aug, params + cpar)
            clo = np.concatenate([lo, np.zeros(len(cpar))])
            chi = np.concatenate([hi, _upper(current + [c], scales)])
            starts = [p_cur] + ([p_nom] if it == 0 else [])
            for p_par in starts:
                if th <= 0:
                    break
                start = np.concatenate([p_par[:len(params)], p_cur[len(params):], [min(th, c.upper) / scales[-1]]])
                # without a force a density multiplier mimics an added mass (and, on suspension modes, any
                # grounded stiffness): densities stay nominal while physics terms are fitted
                start[:len(params)][~dens_free] = p_nom[~dens_free]
                try:
                    pa, sa, ra = fit_modal_residual(pm_aug, resid, start, lower=clo, upper=chi,
                                                    free=np.concatenate([dens_free, np.ones(len(cpar), bool)]))
                except (np.linalg.LinAlgError, ModalabError) as e:
                    log.info("modes: candidate %s could not be fitted: %s", c.label, e)
                    continue
                log.info("modes: candidate %s: modal residual %.4g (current %.4g)", c.label, ra, rss_cur)
                if pa[-1] * scales[-1] <= 1e-3 * th:      # fitted to (nearly) nothing: not this term
                    continue
                if best is None or ra < best[1]:
                    best = (c, ra, pm_aug, pa, sa, clo, chi)
        # an information criterion (``penalty`` × ln N per term) and a relative drop of ``min_gain``
        if best is None or not (best[1] < rss_cur * (1 - min_gain) and
                                n_eq * np.log(rss_cur / max(best[1], 1e-300)) > penalty * np.log(n_eq)):
            break
        c, rss_cur, pm_cur, p_cur, std_cur, clo_cur, chi_cur = best
        current.append(c)
        say(f"  found (modes): {c.label}")
    # backward elimination: a term whose removal (the rest refitted) costs less than ``min_term_gain`` of the
    # residual has not earned its place
    while len(current) > 1:
        trial = []
        for k in range(len(current)):
            rest = current[:k] + current[k + 1:]
            m_r, cpar_r, sc_r = _augment(model, rest)
            pm_r = ParametricFEModel(m_r, params + cpar_r)
            keep_i = np.r_[np.arange(len(params)), len(params) + np.array([i for i in range(len(current)) if i != k], int)]
            pr, sr, rr = fit_modal_residual(pm_r, resid, p_cur[keep_i], lower=np.concatenate([lo, np.zeros(len(rest))]),
                                            upper=np.concatenate([hi, _upper(rest, sc_r)]),
                                            free=np.concatenate([dens_free, np.ones(len(rest), bool)]))
            trial.append((rr, k, rest, pm_r, pr, sr))
        rr, k, rest, pm_r, pr, sr = min(trial, key=lambda t: t[0])
        if rr > rss_cur * (1 + min_term_gain):
            break
        log.info("modes: dropping %s (residual %.4g without it, %.4g with)", current[k].label, rr, rss_cur)
        current, pm_cur, p_cur, std_cur, rss_cur = rest, pm_r, pr, sr, rr
    best_fit, best_pm, scales = upd, pm, []
    if current:
        phys_err = _freq_rms(pm_cur.structure(p_cur), test_modes, train)
        if phys_err < upd.error * (1 - min_gain):
            _, _, scales = _augment(model, current)
            best_fit = FitResult(p_cur, std_cur, phys_err, [], True, "")
            best_pm = pm_cur
        else:
            log.info("modes: the augmented model does not fit the test frequencies better; nothing added")
            current = []
    keep_eval = held if held.size else train
    fit = {"nominal": _block(pm.structure(p_nom), test_modes, keep_eval),
           "parameters_only": _block(pm.structure(upd.p), test_modes, keep_eval),
           "with_physics": _block(best_pm.structure(best_fit.p), test_modes, keep_eval)}
    n_par = len(params)
    findings = []
    for k, (c, sc) in enumerate(zip(current, scales)):
        gain = next((g for o, _, g in (ranking or []) if o.key == c.key), 0.0)
        ev = (f"the eigenvalue and shape residual of the test modes at {', '.join(c.dofs)} is removed by this term; "
              f"it alone explains {100 * gain:.0f} % of the residual left after parameter updating")
        findings.append(Finding(c, float(best_fit.p[n_par + k] * sc), float(best_fit.std[n_par + k] * sc), ev, gain))
    pars = {par.name: {"initial": float(p_nom[k]), "updated": float(best_fit.p[k]),
                       "parameters_only": float(upd.p[k]), "std": float(best_fit.std[k]), "mode": par.mode}
            for k, par in enumerate(params)}
    held_desc = f"test modes {', '.join(str(i + 1) for i in keep_eval)}" + ("" if held.size else " (not held out)")
    blocks = {k: dict(v, frf_error_held_out=v["freq_error_rms_pct"] / 100) for k, v in fit.items()}
    text = statement(findings, blocks, held_desc).replace("held-out FRF error", "held-out frequency error")
    maps = {}
    try:       # localisation for the report: the modal force residual per measured DOF and mode
        mdata = modes_data(test_modes, train)
        maps = {"freq_hz": np.asarray(test_modes.freq_hz, float)[train],
                "responses": [str(d) for d in test_modes.dofs],
                "before": modal_force_map(pm.structure(upd.p), mdata),
                "after": modal_force_map(best_pm.structure(best_fit.p), mdata)}
    except (ModalabError, np.linalg.LinAlgError) as e:  # pragma: no cover - a figure is a by-product
        log.info("modes: no residual map: %s", e)
    return Diagnosis(findings=findings, parameters=pars, fit=fit, statement=text,
                     model=best_pm.model_at(best_fit.p), parametric=best_pm, p=best_fit.p,
                     steps={"held_out": held_desc, "source": "modes"}, ranking=ranking or [], maps=maps,
                     timings={"total": time.perf_counter() - t0})


def modal_force_map(structure, data: FRFData) -> np.ndarray:
    """|r| / σ per measured DOF and mode of the homogeneous condensed residual ``[Z(iω_j) x_j]_m`` (the
    modal force residual: thesis eq. 3.89 with f = 0, unmeasured DOFs expanded by the model), (n_m, n_modes)."""
    from modalab.dof import locate

    from .dynamics import condensed_residual
    mi, ms = locate(structure.dofs, data.responses, "test-mode DOF")
    x = data.H * np.asarray(ms, float)[:, None, None]
    F = np.zeros((structure.n_dof, 1))
    _, r, _, sigma = condensed_residual(structure.K, structure.M, structure.C, structure.D, data.s, mi, x, F)
    return np.abs(r[:, 0, :]) / (sigma[0][None, :] + 1e-300)
