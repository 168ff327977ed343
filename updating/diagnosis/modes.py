"""Missing-physics diagnosis from identified modes alone (no FRFs: a GVT deliverable).

:func:`diagnose_modes` follows :func:`~updating.diagnosis.diagnose` with the *homogeneous* condensed
residual: for each test mode j (natural frequency ω_j, real shape φ_j on the measured DOFs) the model
should satisfy ``Z(iω_j) φ_j = 0`` (no force), so ``r_j = [Z(iω_j) x_j]_m`` with the unmeasured DOFs
expanded by the model is the modal force residual (thesis section 3.2.4 with f = 0, the eigen-equation
form of eq. 3.89).  Parameters are estimated by iterating expansion and the linear least-squares step
(:func:`~updating.diagnosis.screen.mci_update`); stiffness and mass candidates (grounded springs, added
masses) are ranked by the share of the residual they explain and added greedily under the same
information-criterion gate; the final values are fitted on eigenvalue and MAC residuals

    e = [(f_model,j − f_test,j)/f_test,j ;  w_mac (1 − MAC_j)]

(modes paired by MAC), and the comparison uses the test modes held out of the fits (every third mode
when there are at least five).  Damping cannot be named from real modes, nor absolute mass scale (only
the ratio of stiffness to mass is identifiable without a force): the parameters that fix the scale are
regularised towards their nominal values.
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
from .screen import mci_update, rank_candidates
from .workflow import Diagnosis, Finding, _augment, _bounds, _upper, default_parameters, statement

log = logging.getLogger(__name__)
__all__ = ["diagnose_modes", "modes_data", "fit_modes", "mode_errors"]


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
    c = correlate(structure, sub, mac_min=0.0)
    df = np.full(sub.n_modes, 1.0)
    mac = np.zeros(sub.n_modes)
    for a, t in c.pairs:
        df[t] = (c.analysis.freq_hz[a] - sub.freq_hz[t]) / sub.freq_hz[t]
        mac[t] = c.mac[a, t]
    return df, mac


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


def diagnose_modes(model: FEModel, test_modes: ModeSet, *, parameters=None,
                   kinds=("ground_spring", "added_mass"), max_findings: int = 3, penalty: float = 3.0,
                   n_try: int = 5, min_gain: float = 0.3, progress=None) -> Diagnosis:
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
    params = list(parameters) if parameters is not None else default_parameters(model)
    pm = ParametricFEModel(model, params)
    p_nom = np.array(pm.p0, float)
    lo, hi = _bounds(params, p_nom)
    n = test_modes.n_modes
    held = np.arange(2, n, 3) if n >= 5 else np.array([], int)
    train = np.setdiff1d(np.arange(n), held)
    data = modes_data(test_modes, train)
    say("modes: parameter-only updating (baseline)")
    upd = fit_modes(pm, test_modes, p_nom, lower=lo, upper=hi, keep=train)
    # without a force the common scale of mass and stiffness is not observable, and a density multiplier
    # would mimic any grounded stiffness on the suspension modes: densities stay nominal in the residual steps
    free = np.array([par.field not in ("rho", "nsm") for par in params])
    p_mci, rss_cur, W = mci_update(pm, p_nom, data, lo, hi, reg=1e-3, free=free)
    current, p_cur, pm_cur = [], p_mci, pm
    ranking = None
    for it in range(max_findings):
        lib = build_library(pm_cur.model_at(p_cur), kinds=kinds)
        free_cur = np.concatenate([free, np.ones(len(current), bool)])
        rk, _, _ = rank_candidates(pm_cur, p_cur, lib, data, W, free=free_cur)
        if ranking is None:
            ranking = rk
        have = {c.key for c in current}
        best = None
        for c, th, g in rk[:n_try]:
            if c.key in have:
                continue
            m_aug, cpar, scales = _augment(model, current + [c])
            pm_aug = ParametricFEModel(m_aug, params + cpar)
            clo = np.concatenate([lo, np.zeros(len(cpar))])
            chi = np.concatenate([hi, _upper(current + [c], scales)])
            start = np.concatenate([p_cur, [th / scales[-1]]])
            try:
                pa, ra, _ = mci_update(pm_aug, start, data, clo, chi, weights=W, reg=1e-3,
                                       free=np.concatenate([free, np.ones(len(cpar), bool)]))
            except (np.linalg.LinAlgError, ModalabValueError):
                continue
            if best is None or ra < best[1]:
                best = (c, ra, pm_aug, pa, clo, chi)
        n_eq = 2 * data.H.shape[0] * data.H.shape[2]
        if best is None or not (best[1] < rss_cur and n_eq * np.log(rss_cur / max(best[1], 1e-300))
                                > penalty * np.log(n_eq)):
            break
        c, rss_cur, pm_cur, p_cur, clo_cur, chi_cur = best
        current.append(c)
        say(f"  found (modes): {c.label}")
    best_fit, best_pm, scales = upd, pm, []
    if current:
        _, _, scales = _augment(model, current)
        phys = fit_modes(pm_cur, test_modes, p_cur, lower=clo_cur, upper=chi_cur, keep=train)
        if phys.error < upd.error * (1 - min_gain):
            best_fit, best_pm = phys, pm_cur
        else:
            log.info("modes: the augmented model does not fit the test frequencies better; nothing added")
            current, scales = [], []
    keep_eval = held if held.size else train
    fit = {"nominal": _block(pm.structure(p_nom), test_modes, keep_eval),
           "parameters_only": _block(pm.structure(upd.p), test_modes, keep_eval),
           "with_physics": _block(best_pm.structure(best_fit.p), test_modes, keep_eval)}
    n_par = len(params)
    findings = []
    for k, (c, sc) in enumerate(zip(current, scales)):
        gain = next((g for o, _, g in (ranking or []) if o.key == c.key), 0.0)
        ev = (f"the modal force residual (homogeneous, f = 0) at {', '.join(c.dofs)} is removed by this term; "
              f"it alone explains {100 * gain:.0f} % of the residual left after parameter updating")
        findings.append(Finding(c, float(best_fit.p[n_par + k] * sc), float(best_fit.std[n_par + k] * sc), ev, gain))
    pars = {par.name: {"initial": float(p_nom[k]), "updated": float(best_fit.p[k]),
                       "parameters_only": float(upd.p[k]), "std": float(best_fit.std[k]), "mode": par.mode}
            for k, par in enumerate(params)}
    held_desc = f"test modes {', '.join(str(i + 1) for i in keep_eval)}" + ("" if held.size else " (not held out)")
    blocks = {k: dict(v, frf_error_held_out=v["freq_error_rms_pct"] / 100) for k, v in fit.items()}
    text = statement(findings, blocks, held_desc).replace("held-out FRF error", "held-out frequency error")
    return Diagnosis(findings=findings, parameters=pars, fit=fit, statement=text,
                     model=best_pm.model_at(best_fit.p), parametric=best_pm, p=best_fit.p,
                     steps={"held_out": held_desc, "source": "modes"}, ranking=ranking or [],
                     timings={"total": time.perf_counter() - t0})
