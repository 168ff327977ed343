"""The FRF error measure and the non-linear FRF fit of diagnosis.

The data are :class:`~updating.correlation.receptance.FRFData` (:func:`frf_data`: the correlation layer's, with
the leakage bound raised where a mode outlives the record, :func:`decay_leakage`).

The fit minimises the coherence-weighted relative complex FRF difference

    e_ijf = √c_ijf · (H_model,ij(s_f) − H_meas,ij(s_f)) / (|H_meas,ij(s_f)| + 0.2·rms_f|H_meas,ij|
                                                           + 10⁻⁴·rms_i,f|H_meas,ij|)

over the parameters of a :class:`~updating.fe.parametric.ParametricModel`
(``scipy.optimize.least_squares``, bounded, with the analytic Jacobian
``∂H/∂p = −H ∂Z/∂p H`` — the first-order limit of the response function method, thesis eq. (3.54)-(3.55)).
The same measure, as an RMS, is the ``frf_error`` reported for training and
held-out data.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.optimize as so
import scipy.sparse as sp

from modalab.core.dof import locate
from modalab.core.errors import ConvergenceError

from updating.correlation.condensation import solve_columns
from updating.correlation.receptance import LOCAL_BAND, FRFData, leakage_bias  # noqa: F401 (re-exported)
from updating.correlation.receptance import frf_data as _frf_data
from updating.diagnosis.ar1 import _ar1_apply, reml_ar1
from updating.diagnosis.ritz import RitzBasis, round_basis
from updating.diagnosis.truncation import RESTORED_SHARE, peak_poles, restore_tails
from updating.methods.mci_condensed import derivatives

log = logging.getLogger(__name__)
__all__ = ["FRFData", "frf_data", "decay_leakage", "leakage_bias", "model_frf", "frf_error", "chi2_per_value",
           "fit_frf", "FitResult", "Prior",
           "parameter_std", "correlated_std", "reml_ar1", "fit_std"]


def _indices(model_dofs, data: FRFData):
    mi, ms = locate(model_dofs, data.responses, "measured response DOF")
    ri, rs = locate(model_dofs, data.references, "measured reference DOF")
    # integer arrays even when empty (``np.asarray([])`` is float and cannot index)
    return (np.asarray(mi, dtype=np.intp), np.asarray(ms, float), np.asarray(ri, dtype=np.intp),
            np.asarray(rs, float))


def model_frf(structure, data: FRFData) -> np.ndarray:
    """Receptance of ``structure`` at the data's DOFs and lines, (n_m, n_r, n_s)."""
    mi, ms, ri, rs = _indices(structure.dofs, data)
    X = solve_columns(structure.K, structure.M, structure.C, structure.D, data.s, ri)
    return X[mi] * ms[:, None, None] * rs[None, :, None]


def frf_error(H_model: np.ndarray, data: FRFData) -> float:
    """Coherence-weighted RMS of the relative complex FRF difference (see the module docstring)."""
    e = np.abs(H_model - data.H) / data.den
    w = data.quality ** 2
    return float(np.sqrt(np.sum(w * e ** 2) / max(np.sum(w), 1e-300)))


#: leakage bound (relative, :func:`decay_leakage`) above which :func:`frf_data` warns that modes outlive the
#: record: the fits count it as noise per line, but it is one bias shared by many lines (on the demo's exact,
#: unwindowed FRFs, 25 % below 14 Hz moved every E and ρ by +0.4..+0.6 %, 8-11 std)
LEAKAGE_WARN = 0.05


def frf_data(frf, **kw) -> FRFData:
    """:func:`updating.correlation.receptance.frf_data` (the same keywords) of ``frf`` with the tails its record
    cut off restored (:func:`~updating.diagnosis.truncation.restore_tails`; the lines of a mode too far from
    decayed to restore left out), the leakage bound of every line raised to :func:`decay_leakage` of the
    measured FRF, and a warning where that bound exceeds :data:`LEAKAGE_WARN`."""
    rest = restore_tails(frf)
    data = _frf_data(rest.frf, **kw)
    if rest.cut_hz > 0:
        data = data.take(lines=np.flatnonzero(data.freq_hz > rest.cut_hz))
    raw = decay_leakage(frf, data.s)
    b = decay_leakage(frf, data.s, restored=rest.poles) if rest.poles.size else raw
    if np.any(b > data.bias):
        data.bias = np.maximum(data.bias, b)
    if np.any(raw > LEAKAGE_WARN):
        _warn_leakage(raw, data.freq_hz[raw > LEAKAGE_WARN], frf, rest)
    return data


def _warn_leakage(b, fl, frf, rest):
    """The warning of :func:`frf_data`: how much leakage, where, and what was done about it."""
    df = np.diff(np.sort(frf.freq_hz))
    done = (f"their tails cut off by the record are restored from the data (modes at "
            f"{', '.join(f'{v:.3g}' for v in rest.poles.imag / (2 * np.pi))} Hz)"
            + (f" and the lines up to {rest.cut_hz:.3g} Hz, too far from decayed, left out" if rest.cut_hz else "")
            + f"; the fits count {RESTORED_SHARE:g} of the bound as noise, but what the restoration misses") \
        if rest.poles.size else "the fits count it as noise, but it"
    log.warning("the FRFs carry leakage of up to %.0f %% at %.3g-%.3g Hz: lightly damped modes outlive the "
                "%.3g s record; %s is one bias shared by those lines and can move the parameters by more than "
                "their standard deviations; measure with an exponential window (modalab frf --exp-end 0.01) or "
                "a longer record", 100 * float(b.max()), float(fl.min()),
                float(fl.max()), 1.0 / float(df[df > 0].min()), done)


def decay_leakage(frf, s: np.ndarray, restored=()) -> np.ndarray:
    """Bound of the relative leakage error of spectral lines at ``s`` left by modes that have not died out at
    the end of the record (length ``T = 1/Δf``).

    A mode of pole λ excited at the record's start and cut at ``T`` is transformed, at the lines
    ``s_k = iω_k + β`` (``e^{−s_k T} = e^{−βT}``), as ``A (1 − e^{(λ − β) T})/(s_k − λ)``: a relative error
    ``e^{−(σ + β) T}`` (σ = −Re λ) wherever that mode dominates — 25 % at a 5 Hz mode with ζ = 1 % in a
    4 s record without a window, ~0 with the usual exponential window (e^{−βT} = 1 %).  The poles are those of
    the peaks of the measured FRFs (:func:`~updating.diagnosis.testmodes.refine_pole`); each line takes the
    errors of the modes weighted by their shares ``|1/(s − λ_r)| / Σ_k |1/(s − λ_k)|``.  The rigid-body tail
    (a mode that never decays, below the first line) is :func:`leakage_bias`.  Data whose metadata name no
    spectral estimator (synthesised FRFs) get none, as for :func:`leakage_bias`.  A mode within 1 % of one of
    the poles ``restored`` (rad/s; its cut tail restored, :func:`~updating.diagnosis.truncation.restore_tails`)
    counts :data:`~updating.diagnosis.truncation.RESTORED_SHARE` of its error."""
    s = np.asarray(s, complex)
    out = np.zeros(s.shape)
    if not frf.metadata.get("estimator") or frf.freq_hz.size < 8:
        return out
    T, beta = 1.0 / float(np.min(np.diff(frf.freq_hz))), float(frf.window_beta_per_s)
    lam = peak_poles(frf, "receptance")
    if not lam.size:
        return out
    leak = np.exp(-(-lam.real + beta) * T)                       # (n_modes,)
    if np.size(restored):
        gap = np.min(np.abs(lam[:, None] - np.asarray(restored)[None, :]), axis=1)
        leak = np.where(gap < 0.01 * np.abs(lam), RESTORED_SHARE * leak, leak)
    share = 1.0 / np.abs(s[:, None] - lam[None, :])
    share /= share.sum(axis=1, keepdims=True)
    return share @ leak


def chi2_per_value(error: float, data: FRFData) -> float:
    """χ²/N of a model whose :func:`frf_error` against ``data`` is ``error``: the squared FRF differences in
    units of each value's noise (:attr:`FRFData.sigma`: coherence and averages, the leakage bound, the 1 %
    floor) per complex FRF value.  About 1 for a model that is exact within that noise model."""
    return float(error * error * np.sum(data.quality ** 2) / data.floor ** 2 / max(data.H.size, 1))


@dataclass
class Prior:
    """Gaussian prior of the first ``len(mean)`` parameters of a fit (further ones, e.g. candidate values, are
    free): the fit is then a maximum a posteriori estimate.  ``sigma`` is the prior standard deviation in
    the parameter's own unit (``inf``: free).  ``scale`` is the weight of one prior standard deviation in
    the units of the FRF residual: with ``scale = √(Σr₀² / N_eff)`` (r₀ the residual at a reference point,
    N_eff the number of independent observations) one prior σ costs as much as an average independent
    observation at the reference point — the data term tempered to N_eff, as its values are far from
    independent across neighbouring lines."""

    mean: np.ndarray
    sigma: np.ndarray
    scale: float = 1.0

    def rows(self, p: np.ndarray, free: np.ndarray):
        """Residual rows of the prior for the free parameters and their (diagonal) Jacobian."""
        n = len(self.mean)
        idx = np.flatnonzero(np.asarray(free[:n], bool) & np.isfinite(self.sigma))
        r = self.scale * (np.asarray(p)[idx] - self.mean[idx]) / self.sigma[idx]
        J = np.zeros((idx.size, int(np.sum(free))))
        col = np.cumsum(free) - 1                           # position of each free parameter among the free
        J[np.arange(idx.size), col[idx]] = self.scale / self.sigma[idx]
        return r, J

    def z(self, p) -> np.ndarray:
        """How many prior standard deviations each parameter lies from its mean (0 where free)."""
        n = len(self.mean)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = (np.asarray(p)[:n] - self.mean) / self.sigma
        return np.where(np.isfinite(self.sigma), z, 0.0)


@dataclass
class FitResult:
    p: np.ndarray
    std: np.ndarray
    error: float
    history: list
    success: bool
    message: str


def _residual(pmodel, p, data: FRFData):
    """Weighted, stacked FRF residual at ``p`` and what the Jacobian needs (the solved columns)."""
    st = pmodel.structure(p)
    mi, ms, ri, rs = _indices(st.dofs, data)
    cols = np.unique(np.concatenate([mi, ri]))
    pos = {c: k for k, c in enumerate(cols)}
    X = solve_columns(st.K, st.M, st.C, st.D, data.s, cols)           # (n, n_cols, n_s)
    Xj = X[:, [pos[c] for c in ri]] * rs[None, :, None]
    Xm = X[:, [pos[c] for c in mi]] * ms[None, :, None]
    H = Xj[mi] * ms[:, None, None]
    w = data.quality / data.den
    e = w * (H - data.H)
    return np.concatenate([e.real.ravel(), e.imag.ravel()]), (Xj, Xm, w)


def _jacobian(pmodel, p, data: FRFData, free, ctx):
    """∂(residual)/∂p for the free parameters: ``∂H/∂p = −H ∂Z/∂p H`` (the first-order limit of the response
    function method, thesis eq. 3.54-3.55)."""
    Xj, Xm, w = ctx
    ders = derivatives(pmodel, p)
    n, nr, ns = Xj.shape
    s = data.s
    flat = Xj.reshape(n, -1)
    XmT = np.ascontiguousarray(Xm.transpose(2, 1, 0))                    # (n_s, n_m, n)
    J = []
    for k in np.flatnonzero(free):
        d = ders[k]
        A = np.zeros((n, nr, ns), complex)
        for mat, fac in ((d.dK, None), (d.dD, "D"), (d.dC, "C"), (d.dM, "M")):
            if mat is None:
                continue
            prod = (mat @ flat).reshape(n, nr, ns)
            if fac is None:
                A += prod
            elif fac == "D":
                A += 1j * prod
            elif fac == "C":
                A += prod * s[None, None, :]
            else:
                A += prod * (s ** 2)[None, None, :]
        # dH[m, r, f] = −Σ_n Xm[n, m, f] A[n, r, f], one BLAS product per line
        dH = -np.matmul(XmT, A.transpose(2, 0, 1)).transpose(1, 2, 0)
        de = w * dH
        J.append(np.concatenate([de.real.ravel(), de.imag.ravel()]))
    return np.array(J).T


def _residual_ritz(pmodel, p, data: FRFData, basis):
    """:func:`_residual` in a fixed :class:`~updating.diagnosis.ritz.RitzBasis`."""
    st = pmodel.structure(p)
    mi, ms, ri, rs = _indices(st.dofs, data)
    H, ctx = basis.responses(st, data.s, mi, ri)
    sign = ms[:, None, None] * rs[None, :, None]
    w = data.quality / data.den
    e = w * (H * sign - data.H)
    return np.concatenate([e.real.ravel(), e.imag.ravel()]), (ctx, sign, w)


def _jacobian_ritz(pmodel, p, data: FRFData, free, ctx):
    rctx, sign, w = ctx
    ders = derivatives(pmodel, p)
    J = []
    for k in np.flatnonzero(free):
        de = w * sign * RitzBasis.jacobian(rctx, ders[k], data.s)
        J.append(np.concatenate([de.real.ravel(), de.imag.ravel()]))
    return np.array(J).T


#: FRF fits and exact FRF screenings of models above this many DOFs run in a checked Ritz basis (was 200: a
#: banded LU per line made 150-200-DOF frames the slowest cases, benchmarks/discovery/RESULTS.md, 25th session)
RITZ_LIMIT = 100
#: a parameter whose matrix derivatives touch at most this many DOFs is local (a spring, a mass, a released
#: joint or support): the Ritz basis of a fit gets the static correction at those DOFs (:func:`fit_frf`)
LOCAL_DOFS = 12


def _local_dofs(pmodel, p, free) -> np.ndarray:
    """The DOF indices that the free local parameters (:data:`LOCAL_DOFS`) act on."""
    out = []
    for k, d in enumerate(derivatives(pmodel, p)):
        if not free[k]:
            continue
        rows = set()
        for A in (d.dK, d.dM, d.dC, d.dD):
            if A is not None:
                A = sp.coo_matrix(A)
                rows.update(int(i) for i in A.row[A.data != 0])
        if 0 < len(rows) <= LOCAL_DOFS:
            out += sorted(rows)
    return np.unique(np.asarray(out, int))


def quick_frf_error(structure, data: FRFData) -> float:
    """:func:`frf_error` of ``structure``, in a Ritz basis built for it when it has more than
    :data:`RITZ_LIMIT` DOFs (for screening many models; exact otherwise)."""
    if structure.n_dof <= RITZ_LIMIT:
        return frf_error(model_frf(structure, data), data)
    mi, ms, ri, rs = _indices(structure.dofs, data)
    basis = RitzBasis(structure, np.concatenate([mi, ri]), float(np.max(np.abs(data.s))) / (2 * np.pi))
    H, _ = basis.responses(structure, data.s, mi, ri, want_jac_rows=False)
    return frf_error(H * ms[:, None, None] * rs[None, :, None], data)


def _rounds_done(rnd: int, err: float, e_red: float, err_prev: float, tol: float) -> bool:
    """Whether a fit in a Ritz basis (:func:`fit_frf`) stops after round ``rnd``: its reduced error ``e_red`` and
    exact error ``err`` agree within ``tol`` (relative), or the round, made in a basis rebuilt at the previous
    round's parameters, left the exact error within ``tol`` of that round's ``err_prev``: then the gap is the
    basis's own bias, not parameters still far from the optimum, and a further round repeats this one (tuning space
    frame 2188: 26 of 69 fits ran three rounds with the two errors 1-4 % apart in every round and the exact one
    moving by at most 0.2 % after the first; 39 s of the diagnosis' 130 s of CPU)."""
    scale = tol * max(err, 1e-12)
    return abs(err - e_red) <= scale or (rnd > 0 and abs(err - err_prev) <= scale)


def fit_frf(pmodel, data: FRFData, p_start, *, lower=None, upper=None, free=None, max_nfev: int = 40,
            x_scale=None, reduced: bool | None = None, rounds: int = 3, tol: float = 0.01,
            prior: Prior | None = None, err_start: float | None = None) -> FitResult:
    """Bounded non-linear least squares of the FRF residual over the free parameters (with a
    :class:`Prior`: the maximum a posteriori estimate; the returned error is that of the data alone).

    ``reduced`` (default: models above :data:`RITZ_LIMIT` DOFs) evaluates the receptance and its Jacobian
    in a Ritz basis built at the start (:class:`~updating.diagnosis.ritz.RitzBasis`: modes to 3× the band
    top plus static corrections at the measured and reference DOFs); the result is checked against the
    exact receptance, and the fit is repeated from there with a basis rebuilt at the new parameters (at most
    ``rounds`` times) until :func:`_rounds_done` (the errors agree, or the exact one no longer moves).  The basis
    also carries the static correction at the DOFs of the free local parameters (:data:`LOCAL_DOFS`).  The
    result is the round with the lowest exact objective, and never worse than the start: when every round
    raised it (the reduced model led the steps astray), the start is returned, with its standard deviations,
    and the message says so.  The returned error is always the exact one.  ``err_start``: the exact error at
    ``p_start`` when the caller has it (a fit continued from another's result: its ``error``), not computed again.
    """
    p_start = np.asarray(p_start, float)
    npar = p_start.size
    free = np.ones(npar, bool) if free is None else np.asarray(free, bool)
    lo = np.full(npar, -np.inf) if lower is None else np.asarray(lower, float)
    hi = np.full(npar, np.inf) if upper is None else np.asarray(upper, float)
    if not free.any():
        H = model_frf(pmodel.structure(p_start), data)
        return FitResult(p_start, np.zeros(npar), frf_error(H, data), [], True, "nothing to fit")
    st0 = pmodel.structure(p_start)
    if reduced is None:
        reduced = st0.n_dof > RITZ_LIMIT
    history: list = []
    p_cur, err_prev = p_start, np.inf
    total_nfev = 0
    # a local parameter (a spring's stiffness, a released joint's) moves the response by the static correction at
    # its own DOFs: with those vectors in the basis, the basis built at the start stays accurate over decades of
    # its value (without them a joint's fit from 2e5 N·m/rad ended at 2e4 with the exact error 4x its start's)
    local = _local_dofs(pmodel, p_start, free) if reduced else None
    best = None
    if reduced:
        # the exact objective at the start: a round whose reduced model misleads it must not leave it worse
        err0 = frf_error(model_frf(st0, data), data) if err_start is None else float(err_start)
        best = (_objective(err0, p_start, data, prior, free), p_start, err0, None)
    for rnd in range(max(int(rounds), 1) if reduced else 1):
        basis = None
        if reduced:
            st = st0 if rnd == 0 else pmodel.structure(p_cur)
            mi, _, ri, _ = _indices(st.dofs, data)
            basis = round_basis(st, np.concatenate([mi, ri, local]), float(np.max(np.abs(data.s))) / (2 * np.pi),
                                pmodel, p_start, p_cur, free, rnd)
        sol = _least_squares(pmodel, data, p_cur, free, lo, hi, max_nfev, x_scale, history, basis, prior)
        total_nfev += sol.nfev
        p = p_cur.copy()
        p[free] = sol.x
        H = model_frf(pmodel.structure(p), data)
        err = frf_error(H, data)
        if not reduced:
            break
        obj = _objective(err, p, data, prior, free)
        if obj < best[0]:
            best = (obj, p, err, sol)
        # the reduced error, in the same measure
        r = sol.fun[:2 * data.H.size]
        e_red = np.sqrt(float(r @ r) / max(float(np.sum(data.quality ** 2)), 1e-300))
        log.debug("Ritz fit round %d: reduced error %.5g, exact %.5g", rnd, e_red, err)
        if _rounds_done(rnd, err, e_red, err_prev, tol):
            break
        p_cur, err_prev = p, err
    fun, jac, message = sol.fun, sol.jac, str(sol.message)
    if reduced and best[3] is None:
        # no round lowered the exact objective: the Ritz model led every step astray; the start is the fit
        log.info("an FRF fit in a Ritz basis ended above its start (exact error %.4g against %.4g): the start is "
                 "kept", err, best[2])
        p, err = best[1], best[2]
        fun, jac = _exact_rows(pmodel, p, data, free, prior)
        message += "; the start kept (every step raised the exact error)"
    elif reduced:
        p, err, sol = best[1], best[2], best[3]
        fun, jac = sol.fun, sol.jac
    std = np.zeros(npar)
    std[free] = correlated_std(fun, jac, data.H.shape, prior_scale=prior.scale if prior is not None else 0.0)
    return FitResult(p, std, err, history, bool(sol.success), message + (
        f" ({total_nfev} evaluations in a Ritz basis)" if reduced else ""))


def _exact_rows(pmodel, p, data: FRFData, free, prior):
    """The exact residual rows of a MAP FRF fit at ``p`` and their Jacobian (the prior's rows appended)."""
    r0, ctx = _residual(pmodel, p, data)
    fun, jac = r0, _jacobian(pmodel, p, data, free, ctx)
    if prior is not None:
        pr, pj = prior.rows(p, free)
        fun, jac = np.concatenate([fun, pr]), np.vstack([jac, pj])
    return fun, jac


def _objective(err: float, p, data: FRFData, prior, free) -> float:
    """The MAP objective of :func:`fit_frf` at a point of exact FRF error ``err``: the data's squared residual
    (``err² Σ quality²``) plus the prior's rows."""
    obj = err * err * float(np.sum(data.quality ** 2))
    if prior is not None:
        obj += float(np.sum(prior.rows(p, free)[0] ** 2))
    return obj


def correlated_std(fun: np.ndarray, jac: np.ndarray, shape: tuple, *, prior_scale: float = 0.0) -> np.ndarray:
    """Standard deviations of the free parameters of an FRF fit whose data residual (the first
    ``2 × prod(shape)`` rows of ``fun``/``jac``: real and imaginary parts of the (n_m, n_r, n_s) values) may be
    correlated from one line to the next, followed by prior rows (:class:`Prior`).

    The least-squares covariance ``s² (JᵀJ)⁻¹`` assumes independent residuals.  Measurement noise is nearly
    independent from line to line, but model-form error — a coarser mesh, another damping model — leaves a
    residual that is smooth over frequency, as are the Jacobian's columns.  The error of every FRF (real and
    imaginary parts apart) is taken as an AR(1) series over the lines with a common ``σ²`` and ρ estimated by
    :func:`reml_ar1`, and the covariance is the sandwich ``A⁻¹ B A⁻¹`` with ``A = JᵀJ`` (data and prior rows:
    the normal matrix of the fit) and ``B = σ² J_dᵀ R(ρ) J_d + prior_scale² J_pᵀ J_p`` (the data rows' error
    covariance; a prior row's value at the truth is ``prior_scale`` × a standard normal).  White residuals give
    back ``s² (JᵀJ)⁻¹``.  Coverage of ±1σ measured on a linear model with smooth regressors and AR(1) error,
    300 seeded trials each (``tests/updating/test_diagnosis_std_correlated.py``): white 0.68/0.68, ρ = 0.9
    0.70/0.68, ρ = 0.99 0.67/0.64 (plain least squares: 0.20/0.15 and 0.14/0.06; the former (1 + ρ̂)/(1 − ρ̂)
    inflation with ρ̂ from the fitted residual: 0.68/0.66 and 0.79/0.57, and 0.59/0.64 and 0.60/0.49 on one
    400-line series: it depends on how the regressors vary over the correlation length, the sandwich does not).
    A MAP fit whose truth is drawn from the prior: 0.63/0.63 (white), 0.62/0.65 (ρ = 0.9); without the prior
    rows' term (the shrinkage towards the prior mean) 0.18/0.09 and 0.47/0.31.  Directions the data do not
    determine get ``inf`` (:func:`parameter_std`)."""
    fun = np.asarray(fun, float)
    jac = np.asarray(jac, float)
    if not np.all(np.isfinite(jac)) or not np.all(np.isfinite(fun)):
        return parameter_std(jac, float(fun @ fun))            # raises, naming the parameters concerned
    # columns of unit norm (scaled back at the end): the REML's normal matrix and the sandwich are then as well
    # conditioned as the problem, whatever the parameters' units (see parameter_std)
    cn = np.linalg.norm(jac, axis=0)
    d = np.where(cn > 0, cn, 1.0)
    jac = jac / d
    nd = 2 * int(np.prod(shape))
    p = jac.shape[1]
    n_s = int(shape[-1])
    r_d = fun[:nd].reshape(-1, n_s)
    J_d = jac[:nd].reshape(-1, n_s, p)
    s2, rho = reml_ar1(r_d, J_d)
    RJ = np.moveaxis(_ar1_apply(np.moveaxis(J_d, -1, 0), rho), 0, -1).reshape(-1, p)
    J_p = jac[nd:]
    meat = s2 * (jac[:nd].T @ RJ) + prior_scale ** 2 * (J_p.T @ J_p)
    log.debug("FRF fit σ: AR(1) error along the lines, ρ = %.3g, σ² = %.3g", rho, s2)
    return parameter_std(jac, 1.0, meat=meat) / d


def fit_std(pmodel, data: FRFData, p, *, free=None, prior: Prior | None = None) -> np.ndarray:
    """:func:`correlated_std` of the parameters ``p`` of ``pmodel`` against ``data`` (the exact receptance and
    its Jacobian at ``p``; with a :class:`Prior`, its rows too), for a solution that did not come out of
    :func:`fit_frf` (e.g. the MCI's): its stated uncertainty is that of the FRF data at that point, not 0."""
    p = np.asarray(p, float)
    free = np.ones(p.size, bool) if free is None else np.asarray(free, bool)
    std = np.zeros(p.size)
    if not free.any():
        return std
    r, ctx = _residual(pmodel, p, data)
    J = _jacobian(pmodel, p, data, free, ctx)
    if prior is not None:
        pr, pj = prior.rows(p, free)
        r, J = np.concatenate([r, pr]), np.vstack([J, pj])
    std[free] = correlated_std(r, J, data.H.shape, prior_scale=prior.scale if prior is not None else 0.0)
    return std


#: a direction of the parameters whose singular value (columns scaled to unit norm) is below this fraction of
#: the largest is not determined by the data
RANK_TOL = 1e-8


def parameter_std(J: np.ndarray, s2: float, *, meat: np.ndarray | None = None) -> np.ndarray:
    """Standard deviations of least-squares parameters: ``√diag(s² (JᵀJ)⁺)`` for the Jacobian ``J`` at the
    solution and the residual variance ``s2``; with ``meat`` (the covariance of ``Jᵀe``), the sandwich
    ``√diag(s² (JᵀJ)⁺ meat (JᵀJ)⁺)``.

    The inverse is taken with the columns of ``J`` scaled to unit norm (and scaled back): parameters in their
    own units differ by many decades (a factor on E near 1, a clamp stiffness near 10⁶ N·m/rad has a column
    ~10⁻⁸ as long), and a pseudo-inverse of the unscaled ``JᵀJ`` cuts the small parameters' directions as if
    they were rank deficient and gives them a standard deviation of ~0 (10⁻¹¹ N·m/rad on 2·10⁶ N·m/rad).
    A parameter the data do not determine — a zero column of ``J``, or a component along a direction whose
    singular value (columns scaled to unit norm) is below :data:`RANK_TOL` of the largest — gets ``inf``,
    not the 0 a pseudo-inverse would give it; the pseudo-inverse drops exactly those directions.  A Jacobian
    with non-finite entries raises :class:`~modalab.core.errors.ConvergenceError` naming the parameters
    concerned.
    """
    J = np.asarray(J, float)
    bad = ~np.all(np.isfinite(J), axis=0)
    if bad.any() or not np.isfinite(s2):
        raise ConvergenceError(
            f"the FRF fit's Jacobian has non-finite entries for free parameter(s) {np.flatnonzero(bad).tolist()} "
            "at the solution (a model resonance exactly on a data line, or parameters at a singular model); "
            "no standard deviation can be given: move the bounds or the frequency band")
    std = np.full(J.shape[1], np.inf)
    cn = np.linalg.norm(J, axis=0)
    seen = cn > 0
    if not seen.any():
        return std
    d = cn[seen]
    Js = J[:, seen] / d
    wide = Js.shape[0] < Js.shape[1]               # fewer equations than parameters: Vt must span them all
    _, sv, Vt = np.linalg.svd(Js, full_matrices=wide)
    sv = np.concatenate([sv, np.zeros(Vt.shape[0] - sv.size)])
    keep = sv >= RANK_TOL * sv[0]
    V = Vt[keep].T
    Ai = (V / sv[keep] ** 2) @ V.T                 # (JsᵀJs)⁺ over the determined directions
    cov = Ai if meat is None else Ai @ (np.asarray(meat, float)[np.ix_(seen, seen)] / np.outer(d, d)) @ Ai
    sd = np.sqrt(np.clip(np.diag(cov) * s2, 0, None)) / d
    null = Vt[~keep]
    if null.size:
        sd[np.max(np.abs(null), axis=0) > np.sqrt(RANK_TOL)] = np.inf
    std[seen] = sd
    return std


def _least_squares(pmodel, data, p_start, free, lo, hi, max_nfev, x_scale, history, basis, prior=None):
    p_fixed = p_start.copy()

    def full(x):
        p = p_fixed.copy()
        p[free] = x
        return p

    cache = {}

    def state(x):
        key = x.tobytes()
        if cache.get("key") != key:
            cache.clear()
            cache["key"] = key
            if basis is None:
                cache["res"], cache["ctx"] = _residual(pmodel, full(x), data)
            else:
                cache["res"], cache["ctx"] = _residual_ritz(pmodel, full(x), data, basis)
        return cache

    def fun(x):
        r = state(x)["res"]
        history.append(float(np.sqrt(np.mean(r ** 2))))
        if prior is not None:
            r = np.concatenate([r, prior.rows(full(x), free)[0]])
        return r

    def jac(x):
        c = state(x)
        if "jac" not in c:
            if basis is None:
                c["jac"] = _jacobian(pmodel, full(x), data, free, c["ctx"])
            else:
                c["jac"] = _jacobian_ritz(pmodel, full(x), data, free, c["ctx"])
            if prior is not None:
                c["jac"] = np.vstack([c["jac"], prior.rows(full(x), free)[1]])
        return c["jac"]

    x0 = np.clip(p_start[free], lo[free] + 1e-12 * np.abs(lo[free]), hi[free])
    xs = "jac" if x_scale is None else np.asarray(x_scale)[free]
    return so.least_squares(fun, x0, jac=jac, bounds=(lo[free], hi[free]), x_scale=xs, max_nfev=max_nfev,
                            method="trf", ftol=1e-6, xtol=1e-8)
