"""Parameters of the diagnosis' fits: the default updating parameters of a model, their priors (E and G ±5 %,
density ±3 %, sections ±5 %, damping free; overridable), bounds, the fitted loss factor and the continued
fit.  Split out of :mod:`~updating.diagnosis.workflow`."""
from __future__ import annotations

from collections import Counter
import difflib
import logging

import numpy as np

from modalab.core.errors import ModalabValueError
from modalab.core.parallel import fork_map

from updating.fe import FEModel, Parameter, ParametricFEModel
from updating.diagnosis.fit import FitResult, FRFData, Prior, fit_frf, fit_std, frf_error, model_frf

log = logging.getLogger(__name__)


def default_parameters(model: FEModel) -> list:
    """Stiffness (E) and density multipliers per property group (by property name when named)."""
    params = []
    seen = set()
    for pid, prop in sorted(model.properties.items()):
        name = getattr(prop, "name", "") or f"p{pid}"
        if name in seen:
            continue
        seen.add(name)
        sel = (name,) if getattr(prop, "name", "") else (pid,)
        params.append(Parameter(f"E_{name}", "E", properties=sel))
        params.append(Parameter(f"rho_{name}", "rho", properties=sel))
    return params


#: default prior standard deviations (relative to nominal) by parameter field; fields not listed are free
PRIOR_SIGMA = {"E": 0.05, "G": 0.05, "rho": 0.03, "t": 0.05, "h": 0.05, "b": 0.05, "do": 0.05, "di": 0.05,
               "A": 0.05, "Iy": 0.05, "Iz": 0.05, "J": 0.05}


#: a parameter further than this many prior standard deviations from its nominal has run into its prior
AT_PRIOR_Z = 2.0


#: the fits are bounded at this many prior standard deviations (E ±15 %, density ±9 % by default): with
#: thousands of FRF values against a few parameters, model-form error outweighs any Gaussian prior, and a
#: parameter far outside its physical range is absorbing something else
PRIOR_BOUND = 3.0


def parameter_priors(params: list, p_nom, overrides: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Prior means (the nominal values) and standard deviations of ``params``.

    Defaults (:data:`PRIOR_SIGMA`): E and G ±5 %, density ±3 %, thickness and section ±5 %, damping and
    everything else free.  ``overrides`` maps a parameter name to a relative standard deviation (a number
    > 0) or ``None``/``"free"`` (no prior); for ``mode='value'`` parameters the relative value multiplies
    the nominal value.  An override naming no parameter is an error suggesting the closest name.
    """
    overrides = dict(overrides or {})
    names = [p.name for p in params]
    for k in overrides:
        if k not in names:
            close = difflib.get_close_matches(str(k), names, n=1)
            raise ModalabValueError(f"prior for {k!r}: no such parameter" + (f"; did you mean {close[0]!r}?" if close
                                                                             else f"; parameters: {', '.join(names)}"))
    mean = np.asarray(p_nom, float)[:len(params)].copy()
    sig = np.full(len(params), np.inf)
    for i, par in enumerate(params):
        rel = overrides.get(par.name, PRIOR_SIGMA.get(par.field)) if par.name in overrides else \
            PRIOR_SIGMA.get(par.field)
        if rel in (None, "free") or par.field in ("ge", "global_ge", "c", "rayleigh_alpha", "rayleigh_beta") \
                and par.name not in overrides:
            continue
        if isinstance(rel, str) or not float(rel) > 0:
            raise ModalabValueError(f"prior of {par.name!r}: {rel!r}; expected a relative standard deviation > 0 "
                                    "(0.05 = ±5 %) or 'free'")
        if par.mode != "factor" and mean[i] == 0:
            continue                                   # a relative prior of a zero nominal value: free
        sig[i] = float(rel) * (1.0 if par.mode == "factor" else abs(mean[i]))
    return mean, sig


class SectionLossFactor(Parameter):
    """The background loss factor of one property group relative to the model-wide one (``ge`` of the
    group's properties, in addition to PARAM G): may be negative, the group's total may not (see
    :func:`_with_damping`, :func:`nonnegative_loss_factors`)."""


def loss_factor_totals(params: list, p, model_ge: float | None) -> dict:
    """``{name: (properties, total)}`` for each :class:`SectionLossFactor` among ``params`` at values ``p``: the
    group's loss factor in all, the model-wide one (the ``global_ge`` parameter, else ``model_ge``, PARAM G)
    plus the group's offset."""
    p = np.asarray(p, float)
    g = next((float(p[k]) for k, par in enumerate(params) if par.field == "global_ge"), float(model_ge or 0.0))
    return {par.name: (tuple(par.properties), g + float(p[k])) for k, par in enumerate(params)
            if isinstance(par, SectionLossFactor)}


class _GroupLossFactorTotal(Parameter):
    """A property group's loss factor in all (``mode='value'``): the model keeps PARAM G (applied first) and its
    properties get the GE that adds up to it, ``GE = value − G``.  The coordinates of
    :func:`nonnegative_loss_factors`' refit, where the bound ``value >= 0`` is a box bound."""

    def model_value(self, value, model):
        return value - (model.global_ge or 0.0)

    def parameter_value(self, model_value, model):
        return model_value + (model.global_ge or 0.0)


def nonnegative_loss_factors(pm, data: FRFData, fit: FitResult, lower, upper, *, model_ge: float | None,
                             free=None, prior: Prior | None = None, max_nfev: int = 40) -> tuple[FitResult, list]:
    """``fit`` (of ``pm``) when no property group's loss factor in all is negative; else the fit constrained to
    none negative, and the names of the groups that were.

    A negative loss factor creates energy: no physical section has one.  The fits vary the offsets
    ``eta_<group>`` from ``eta_global`` (a uniform change of damping is one parameter, as the MCI's clipped
    Gauss-Newton steps need), bounded at ±0.2, not at minus the model-wide factor; where that lets a group's
    total fall below 0 (model-form error: the brace of the planar-frame case026 asked for -0.0005, the demo's
    fuselage for -0.02), the fit is repeated from there, with those totals raised to 0, in the coordinates
    (``eta_global``, each group's total), where ``total >= 0`` is a bound, and returned in the offsets again
    (their std from the data at that point).  A total's upper bound there is the offset's upper bound plus
    the fit's ``eta_global``; an offset that still ends above its own bound (``eta_global`` fell in the
    refit) is set to it, so that the result lies in the box every other fit of the offsets uses."""
    params = list(pm.parameters)
    totals = loss_factor_totals(params, fit.p, model_ge)
    low = [name for name, (_, t) in totals.items() if t < 0]
    if not low:
        return fit, []
    ig = next((k for k, par in enumerate(params) if par.field == "global_ge"), None)
    lo, hi = np.array(lower, float), np.array(upper, float)
    g_fit = float(fit.p[ig]) if ig is not None else float(model_ge or 0.0)
    q, qlo, qhi = np.array(fit.p, float), lo.copy(), hi.copy()
    q_params = list(params)
    mean, sig = (np.array(prior.mean, float), np.array(prior.sigma, float)) if prior is not None else (None, None)
    for k, par in enumerate(params):
        if isinstance(par, SectionLossFactor):
            q_params[k] = _GroupLossFactorTotal(par.name, par.field, properties=par.properties, mode="value")
            q[k], qlo[k], qhi[k] = max(totals[par.name][1], 0.0), 0.0, max(g_fit + hi[k], 0.0)
            if mean is not None and k < mean.size and ig is not None:
                mean[k] += mean[ig]                  # a prior on the offset, as one on the total
    pm_q = ParametricFEModel(pm.model, q_params)
    prior_q = Prior(mean, sig, prior.scale) if prior is not None else None
    refit = fit_frf(pm_q, data, q, lower=qlo, upper=qhi, free=free, max_nfev=max_nfev, prior=prior_q)
    p = np.array(refit.p, float)
    g = p[ig] if ig is not None else float(model_ge or 0.0)
    error, clipped = refit.error, False
    for k, par in enumerate(params):
        if isinstance(par, SectionLossFactor):
            p[k] = refit.p[k] - g
            if p[k] > hi[k]:
                p[k], clipped = hi[k], True
            if g + p[k] < 0:                          # rounding of g + (total - g) at a total of 0
                p[k] = -g
    if clipped:
        error = frf_error(model_frf(pm.structure(p), data), data)
    std = fit_std(pm, data, p, free=free, prior=prior)
    log.info("the loss factor in all of %s fitted below 0: refitted with it bounded at 0 (error %.4g -> %.4g)",
             ", ".join(low), fit.error, error)
    return FitResult(p, std, error, fit.history + refit.history, refit.success,
                     refit.message + f" (refitted with the loss factors of {', '.join(low)} bounded at 0)"), low


def _property_groups(model: FEModel) -> list:
    """``[(name, pids, n_elements)]``: the property groups of :func:`default_parameters` (by name when named),
    with the elements they hold; groups without an element are left out."""
    groups: dict = {}
    for pid, prop in sorted(model.properties.items()):
        name = getattr(prop, "name", "") or f"p{pid}"
        groups.setdefault(name, []).append(pid)
    out = []
    for name, pids in groups.items():
        n_el = len(model.elements_with_property(pids))
        if n_el:
            out.append((name, tuple(pids), n_el))
    return out


def _with_damping(model: FEModel, params: list) -> tuple[list, list]:
    """The background damping parameters: the model-wide hysteretic loss factor (PARAM G, ``eta_global``)
    unless declared, and one loss factor per further property group (``eta_<group>``, free, no prior)
    unless a ``ge`` parameter is declared.

    The hysteretic damping matrix is ``D = G·K + Σ_s ge_s K_s`` (the ``i[ΔD]`` part of the updating
    matrix [Δ] of thesis eq. (3.60) in structural form): the group with the most elements carries G alone,
    every other group s carries G + ge_s (ge_s may be negative: bounded at ±0.2, not at -G; a fit whose G + ge_s falls
    below 0 is repeated with it bounded at 0 by :func:`nonnegative_loss_factors`), so that each section has a
    loss factor of its own without a redundant parameter.  Real frames have per-section loss factors
    (welds, coatings, materials); with one global loss factor the difference between sections is left to
    the candidates, and a local damping term on part of a section absorbs it — a false finding on a model
    that misses no physics.  With a loss factor per section, local dissipation has to be local (a part of a
    section) to be a finding.  A free mass-proportional term is not added: it would let the baseline
    smother suspension modes instead of explaining them.  On a model with one property group this is the
    global loss factor alone, as before.
    """
    fields = {p.field for p in params}
    extra = []
    start = []
    if "global_ge" not in fields:
        extra.append(Parameter("eta_global", "global_ge", mode="value"))
        start.append(max(float(model.global_ge or 0.0), 0.01))
    groups = _property_groups(model)
    if "ge" in fields or len(groups) < 2:
        return extra, start
    ref = max(range(len(groups)), key=lambda i: (groups[i][2], -i))      # most elements; the first on a tie
    names = {p.name for p in params}
    for i, (name, pids, _) in enumerate(groups):
        pname = f"eta_{name}"
        if i == ref or pname in names:
            continue
        vals = [model.prop(pid).ge if model.prop(pid).ge is not None else model.material(model.prop(pid).mid).ge
                for pid in pids]
        if not np.allclose(vals, vals[0], rtol=1e-12, atol=0):
            log.info("no background loss factor for property group %s: its properties' loss factors differ %s",
                     name, vals[:5])
            continue
        extra.append(SectionLossFactor(pname, "ge", properties=pids, mode="value"))
        start.append(float(vals[0] or 0.0))
    return extra, start


def _split(data: FRFData, holdout: str | None):
    """Training and held-out parts of ``data`` and a description of the held-out part.

    Response rows are held out by default (every fourth response that is not a driving point: the residual
    needs the response where the force acts; a row whose direction no training row would measure stays in
    training, :func:`_held_rows`); when no such row exists (e.g. every accelerometer is also hit,
    the FRFs stored as accelerometers x hammer points) reference columns are held out, then blocks of lines.
    Neither part is ever empty.
    """
    n_m, n_r, n_s = data.H.shape
    if holdout not in (None, "rows", "columns", "lines"):
        raise ModalabValueError(f"holdout={holdout!r}: expected 'rows', 'columns', 'lines' or None")
    refs = {(d.node, d.axis) for d in data.references}
    cand = [i for i, d in enumerate(data.responses) if (d.node, d.axis) not in refs]
    if holdout in (None, "rows") and n_m >= 4 and cand:
        held = np.asarray(_held_rows(data.responses, cand), int)
        train = np.setdiff1d(np.arange(n_m), held)
        return data.take(rows=train), data.take(rows=held), f"response DOFs {', '.join(str(data.responses[i]) for i in held)}"
    if holdout in (None, "columns") and n_r >= 2:
        held = np.arange(n_r)[1::4] if n_r >= 4 else np.array([n_r - 1])
        train = np.setdiff1d(np.arange(n_r), held)
        return data.take(cols=train), data.take(cols=held), \
            f"reference{'s' if held.size > 1 else ''} {', '.join(str(data.references[i]) for i in held)}"
    if holdout in ("rows", "columns"):
        raise ModalabValueError(f"holdout={holdout!r} needs at least 4 responses that are not driving points "
                                f"(rows) or 2 references (columns); the data have {n_m} x {n_r}")
    lines = np.arange(n_s)
    held = lines[(lines // 8) % 4 == 3]
    train = np.setdiff1d(lines, held)
    return data.take(lines=train), data.take(lines=held), "every fourth block of 8 lines"


def _held_rows(responses, cand: list) -> list:
    """The response rows to hold out: every fourth of the candidate rows ``cand`` (from the second; one when
    fewer than four), except that a row whose direction (axis) no training row would measure is kept for
    training and the next candidate that leaves its direction measured is held out in its place.  Held out, the
    only out-of-plane row of a planar frame leaves the training FRFs blind to every out-of-plane effect (in-
    and out-of-plane motion decouple): tuning case 1710's T-joint, hit once in Z, held that row out, and the
    joint's flexibility about an out-of-plane axis changed no training FRF at any stiffness."""
    want = cand[1::4] if len(cand) >= 4 else cand[:1]
    left = Counter(d.axis for d in responses)
    held = []
    for i in want + [i for i in cand if i not in want]:
        if len(held) == len(want):
            break
        if left[responses[i].axis] >= 2:
            held.append(i)
            left[responses[i].axis] -= 1
    return sorted(held) if held else want


def _bounds(params, p0):
    lo, hi = [], []
    for p, v in zip(params, p0):
        if p.mode == "factor":
            lo.append(0.25)
            hi.append(4.0)
        elif p.field == "global_ge":
            lo.append(0.0)
            hi.append(0.2)
        elif isinstance(p, SectionLossFactor):
            lo.append(-0.2)
            hi.append(0.2)
        else:
            lo.append(0.0)
            hi.append(np.inf)
    return np.array(lo), np.array(hi)


def _fit_continued(pm, train, p_start, damp_mask, lo, hi, max_nfev, *, levels=(0.08,), prior=None, reduced=None,
                   jobs=None):
    """FRF fit with continuation in damping: the parameters are first fitted with the damping raised to
    each of ``levels`` (a smoother error surface: a resonance shifted by more than its half-power
    bandwidth leaves a plain FRF fit in a local minimum), then everything from there with the damping
    back at its start; the better of this and a direct fit is returned.  ``reduced``: as :func:`fit_frf`.
    The two are independent, and run side by side on ``jobs`` processes (:func:`~modalab.core.parallel.fork_map`)."""
    damp_mask = np.asarray(damp_mask, bool)
    kw = dict(lower=lo, upper=hi, max_nfev=max_nfev, prior=prior, reduced=reduced)

    def continued():
        p = np.asarray(p_start, float).copy()
        for level in levels:
            ps = p.copy()
            ps[damp_mask] = np.maximum(ps[damp_mask], level)
            p[~damp_mask] = fit_frf(pm, train, ps, free=~damp_mask, **kw).p[~damp_mask]
        return fit_frf(pm, train, p, **kw)
    if not damp_mask.any():
        return fit_frf(pm, train, p_start, **kw)
    direct, cont = fork_map(lambda f: f(), [(lambda: fit_frf(pm, train, p_start, **kw),), (continued,)], jobs)
    log.info("parameter fit: direct %.4g, with damping continuation %.4g", direct.error, cont.error)
    return cont if cont.error < direct.error else direct
