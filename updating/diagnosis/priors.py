"""Parameters of the diagnosis' fits: the default updating parameters of a model, their priors (E and G ±5 %,
density ±3 %, sections ±5 %, damping free; overridable), bounds, the fitted loss factor and the continued
fit.  Split out of :mod:`~updating.diagnosis.workflow`."""
from __future__ import annotations

import difflib
import logging

import numpy as np

from modalab.core.errors import ModalabValueError

from updating.fe import FEModel, Parameter
from updating.diagnosis.fit import FRFData, fit_frf

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
    group's properties, in addition to PARAM G): may be negative (see
    :func:`_with_damping`)."""


def loss_factor_totals(params: list, p, model_ge: float | None) -> dict:
    """``{name: (properties, total)}`` for each :class:`SectionLossFactor` among ``params`` at values ``p``: the
    group's loss factor in all, the model-wide one (the ``global_ge`` parameter, else ``model_ge``, PARAM G)
    plus the group's offset."""
    p = np.asarray(p, float)
    g = next((float(p[k]) for k, par in enumerate(params) if par.field == "global_ge"), float(model_ge or 0.0))
    return {par.name: (tuple(par.properties), g + float(p[k])) for k, par in enumerate(params)
            if isinstance(par, SectionLossFactor)}


def nonnegative_loss_factors(params: list, p, model_ge: float | None) -> tuple[np.ndarray, list]:
    """``p`` with every group offset raised so that no group's total loss factor is negative (a negative
    loss factor creates energy: no physical section has one, and a deck must not say so), and the names of
    the offsets raised.  The fit bounds each offset at ±0.2, not at minus the model-wide factor."""
    q = np.array(p, float, copy=True)
    raised = []
    for name, (_, total) in loss_factor_totals(params, q, model_ge).items():
        if total < 0:
            k = next(i for i, par in enumerate(params) if par.name == name)
            q[k] -= total
            raised.append(name)
    return q, raised


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
    every other group s carries G + ge_s (ge_s may be negative: bounded at ±0.2, not at -G), so that each section has a
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
    needs the response where the force acts); when no such row exists (e.g. every accelerometer is also hit,
    the FRFs stored as accelerometers x hammer points) reference columns are held out, then blocks of lines.
    Neither part is ever empty.
    """
    n_m, n_r, n_s = data.H.shape
    if holdout not in (None, "rows", "columns", "lines"):
        raise ModalabValueError(f"holdout={holdout!r}: expected 'rows', 'columns', 'lines' or None")
    refs = {(d.node, d.axis) for d in data.references}
    cand = [i for i, d in enumerate(data.responses) if (d.node, d.axis) not in refs]
    if holdout in (None, "rows") and n_m >= 4 and cand:
        held = np.asarray(cand[1::4] if len(cand) >= 4 else cand[:1], int)
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


def _fit_continued(pm, train, p_start, damp_mask, lo, hi, max_nfev, *, levels=(0.08,), prior=None):
    """FRF fit with continuation in damping: the parameters are first fitted with the damping raised to
    each of ``levels`` (a smoother error surface: a resonance shifted by more than its half-power
    bandwidth leaves a plain FRF fit in a local minimum), then everything from there with the damping
    back at its start; the better of this and a direct fit is returned."""
    direct = fit_frf(pm, train, p_start, lower=lo, upper=hi, max_nfev=max_nfev, prior=prior)
    damp_mask = np.asarray(damp_mask, bool)
    if not damp_mask.any():
        return direct
    p = np.asarray(p_start, float).copy()
    for level in levels:
        ps = p.copy()
        ps[damp_mask] = np.maximum(ps[damp_mask], level)
        sm = fit_frf(pm, train, ps, lower=lo, upper=hi, free=~damp_mask, max_nfev=max_nfev, prior=prior)
        p[~damp_mask] = sm.p[~damp_mask]
    cont = fit_frf(pm, train, p, lower=lo, upper=hi, max_nfev=max_nfev, prior=prior)
    log.info("parameter fit: direct %.4g, with damping continuation %.4g", direct.error, cont.error)
    return cont if cont.error < direct.error else direct
