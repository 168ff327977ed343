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
(:func:`_posterior`; coverage tested in ``tests/updating/test_update_coverage.py``).

**Damped poles.**  Identification reports the modulus of each pole, |s|.  A
model with structural damping (PARAM G, GE) has |s| = ω (1 + η²)^{1/4} above
its undamped ω (η the modal loss factor): the analysis frequency compared with
the test is that modulus (:func:`_pole_factor`), so that data simulated from
the damped model itself leave its parameters unchanged.

Parameter selection: :func:`sensitivity_ranking` (norms of the weighted,
scaled sensitivity columns) and :func:`identifiability` (singular values of
the weighted sensitivity matrix; parameter combinations along singular
vectors with small singular values are not identifiable from the data).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from modalab.core.errors import ModalabValueError, NotFittedError, ShapeError
from modalab.core.modes import ModeSet

from updating.fe.sensitivity import (StackedDerivatives, eigenvalue_sensitivities, eigenvector_sensitivities,
                          solve_modes)

from updating.fe.parametric import parameter_indices
from updating.correlation.metrics import mac, observability, pair_modes
from updating.correlation.dofmap import observation_matrix

log = logging.getLogger(__name__)

__all__ = [
    "SensitivitySystem",
    "sensitivity_system",
    "sensitivity_ranking",
    "identifiability",
    "choose_alpha",
    "InverseEigensensitivity",
]


def _mac_pair(Pa, Px, mac_min, freq_a_hz=None, freq_x_hz=None, phi_full=None, dofs=None, **kw):
    """Pairs by the one pairing rule of modalab (:func:`updating.correlation.metrics.pair_modes`)."""

    Mm = mac(Pa, Px)
    obs = observability(Pa, phi_full, dofs) if phi_full is not None else None
    pr = pair_modes(Mm, freq_a_hz, freq_x_hz, mac_min=mac_min, observability=obs, mode_shapes=(Pa, Px), **kw)
    return [(int(a), int(x)) for a, x in pr.pairs], Mm, pr


def _observation(test: ModeSet, model, dofmap):

    return observation_matrix(test.dofs, model.dofs, dofmap).tocsr()


_param_indices = parameter_indices


@dataclass
class SensitivitySystem:
    """Weighted linearised system at one parameter vector: ``S Δx ≈ r`` with Δx in scaled units (Δp/scale).

    ``rows`` labels each equation ('f3' frequency of test mode 3, 's3:12+Z' shape component);
    ``pairs`` the (analysis, test) mode pairs used; ``scale`` the parameter scaling.
    """

    S: np.ndarray
    r: np.ndarray
    rows: list
    pairs: list
    scale: np.ndarray
    params: np.ndarray
    freq_a_hz: np.ndarray
    freq_x_hz: np.ndarray
    mac: np.ndarray = field(default=None)


def _hysteretic_matrix(model, p):
    """The model's structural (hysteretic) damping matrix D at ``p`` (PARAM G, GE), or None when it has none."""
    D = getattr(model.structure(p), "D", None)
    return D if D is not None and D.nnz > 0 and abs(D).max() > 0 else None


def _pole_factor(D, sol) -> np.ndarray:
    """Per mode of ``sol``, ``|s_r| / ω_r``: the natural frequency identification reports (the
    pole's modulus, :mod:`identification`) over the undamped one, for a model with structural damping D.

    With hysteretic damping the poles solve ``(K + iD − |s|² e^{iθ} M) x = 0``: for D = G·K (PARAM G)
    ``s² = −ω²(1 + iG)`` and ``|s| = ω (1 + G²)^{1/4}``, 1.0001 ω for G = 0.02 — ten times the standard deviation
    of a well-identified frequency, so comparing the undamped ω with the identified |s| moved an exact model's
    parameters.  Here the complex eigenproblem is solved in the subspace of the computed modes
    (``diag(ω²) + i ΦᵀDΦ``: exact for proportional D, and it keeps the coupling of close modes through a
    non-proportional D); each complex mode is matched to the real mode it is made of.  Viscous damping is not
    included (proportional viscous damping leaves |s| = ω)."""
    from scipy.optimize import linear_sum_assignment

    phi = sol.phi
    B = np.asarray(phi.T @ (D @ phi))
    lam = np.clip(sol.lam, 0.0, None)
    mu, V = np.linalg.eig(np.diag(lam).astype(complex) + 1j * 0.5 * (B + B.T))
    _, col = linear_sum_assignment(-np.abs(V))            # row r (real mode) -> its complex mode
    fac = np.ones(lam.size)
    ok = lam > 0
    fac[ok] = np.sqrt(np.abs(mu[col[ok]]) / lam[ok])
    return fac


def _sigmas(test: ModeSet, freq_sigma, shape_sigma):
    nx = test.n_modes
    fs = np.broadcast_to(np.asarray(freq_sigma, float), (nx,)).copy()
    ss = np.asarray(shape_sigma, float)
    ss = np.broadcast_to(ss, (test.n_dof, nx)).copy() if ss.ndim <= 1 and ss.size in (1,) else ss
    if ss.shape != (test.n_dof, nx):
        if ss.shape == (nx,):
            ss = np.broadcast_to(ss[None, :], (test.n_dof, nx)).copy()
        else:
            raise ShapeError(f"shape_sigma has shape {ss.shape}; expected a scalar, ({nx},) or ({test.n_dof}, {nx})")
    if np.any(fs <= 0) or np.any(ss <= 0):
        raise ModalabValueError("freq_sigma and shape_sigma must be positive (relative standard deviations)")
    return fs, ss


def sensitivity_system(model, test_modes: ModeSet, p=None, *, params=None, dofmap=None, n_modes=None,
                       mac_min: float = 0.5, freq_sigma=0.01, shape_sigma=0.05, use_shapes: bool = True,
                       residual: str = "frequency", scale=None, C=None, pairing: dict | None = None,
                       freq_cov=None, only_test=None, fixed_pairs=None, hysteretic=None) -> SensitivitySystem:
    """Build the weighted sensitivity matrix [S] (Eq. 3.50) and residual {Δ} (Eq. 3.51) for paired modes.

    Modes are paired by :func:`updating.correlation.metrics.pair_modes` (``pairing``: its keyword arguments);
    ``only_test`` restricts the pairing to those test modes (0-based), as the updater does after its
    first pairing so that the objective keeps the same test modes at every iteration; ``fixed_pairs``
    (used for frequency-only test sets, where no shape can follow a mode) keeps given (analysis, test) pairs.
    A model with structural damping is compared by the modulus of its poles (:func:`_pole_factor`;
    ``hysteretic`` None: look whether it has any, False: ignore it).
    """
    if residual not in ("frequency", "eigenvalue"):
        raise ModalabValueError(f"residual={residual!r}; expected 'frequency' or 'eigenvalue'")
    p = np.asarray(model.p0 if p is None else p, float)
    idx = _param_indices(model, params)
    scale = np.where(model.p0 != 0, np.abs(model.p0), 1.0)[idx] if scale is None else np.asarray(scale, float)
    C = _observation(test_modes, model, dofmap) if C is None else C
    nx = test_modes.n_modes
    N = len(model.dofs)
    na = min(N, max(2 * nx, nx + 6)) if n_modes is None else int(n_modes)
    sol = solve_modes(model, p, na)
    if n_modes is None and test_modes.n_modes:
        # enough analysis modes to cover the test band and its frequency window (free-free models and local
        # modes can push the partners of the highest test modes beyond 2 x n_test)
        from updating.correlation.metrics import FREQ_WINDOW

        w = (pairing or {}).get("max_freq_error", FREQ_WINDOW) or FREQ_WINDOW
        top = float(np.max(test_modes.freq_hz)) * (1 + w)
        while sol.freq_hz[-1] < top and na < N:
            na = min(N, 2 * na)
            sol = solve_modes(model, p, na)
    X = test_modes.real_shapes
    Pa = np.asarray(C @ sol.phi)
    if use_shapes and not test_modes.has_shapes:
        log.info("the test modes have no shapes: frequencies only")
        use_shapes = False
    cols = np.arange(test_modes.n_modes) if only_test is None else np.array(sorted(int(j) for j in only_test), int)
    if test_modes.has_shapes:
        _, Mm, pr = _mac_pair(Pa, X[:, cols], mac_min, sol.freq_hz, test_modes.freq_hz[cols], sol.phi, model.dofs,
                              **(pairing or {}))
        if only_test is not None:
            from updating.correlation.metrics import mac as _mac

            Mm = _mac(Pa, X)
    elif fixed_pairs is not None:
        pr, Mm = None, None
    else:
        from updating.correlation.metrics import pair_modes

        pr = pair_modes(None, sol.freq_hz, test_modes.freq_hz[cols], **(pairing or {}))
        Mm = None
    pairs = [(int(a), int(x)) for a, x in fixed_pairs] if pr is None else \
        [(int(a), int(cols[x])) for a, x in pr.pairs]
    if not pairs:
        how = pr.method if pr is not None else "fixed pairs"
        raise ModalabValueError(f"no analysis mode pairs with any test mode ({how}); check the DOF "
                                "map (signs, node numbers), the frequency window or mac_min")
    fs, ss = _sigmas(test_modes, freq_sigma, shape_sigma)
    sd = StackedDerivatives(model.derivatives(p), N)
    amodes = np.array([a for a, _ in pairs])
    dl = eigenvalue_sensitivities(model, modes=amodes, solution=sol, derivatives=sd)[:, idx]
    lam_a = sol.lam[amodes]
    fa_all = sol.freq_hz
    D = _hysteretic_matrix(model, p) if hysteretic is not False else None
    if D is not None:
        # the analysis natural frequency as identification measures it, |s| (the pole factor's dependence on p
        # is second order in the loss factor and left out of the sensitivity)
        fac = _pole_factor(D, sol)
        fa_all = fa_all * fac
        lam_a = lam_a * fac[amodes] ** 2
        dl = dl * (fac[amodes] ** 2)[:, None]
    fx = test_modes.freq_hz
    rows, Srows, rvals, frows = [], [], [], []
    if use_shapes:
        used = np.unique(C.indices)
        dphi = eigenvector_sensitivities(model, modes=amodes, solution=sol, derivatives=sd, rows=used)[:, :, idx]
        Cu = C[:, used]
    for k, (a, x) in enumerate(pairs):
        if residual == "frequency":
            wa = np.sqrt(max(lam_a[k], 0.0))
            if wa <= 0:
                raise ModalabValueError(f"analysis mode {a + 1} is a rigid-body mode paired with test mode {x + 1}; "
                                        "remove rigid-body modes from the test set")
            rv = (fx[x] - fa_all[a]) / fx[x]
            srow = dl[k] / (2 * wa) / (2 * np.pi) / fx[x]        # ∂f/∂p = (∂λ/∂p) / (2ω) / 2π
            sig = fs[x]
        else:
            lx = (2 * np.pi * fx[x]) ** 2
            rv = (lx - lam_a[k]) / lx
            srow = dl[k] / lx
            sig = 2 * fs[x]
        rows.append(f"f{x + 1}")
        frows.append((len(rvals), x, 1.0 if residual == "frequency" else 2.0))
        rvals.append(rv / sig)
        Srows.append(srow * scale / sig)
        if use_shapes:
            av = Pa[:, a]
            xv = X[:, x]
            msf = float(av @ xv) / float(xv @ xv)
            na_ = np.linalg.norm(av)
            rms = na_ / np.sqrt(av.size)
            res = (msf * xv - av) / na_
            da = np.asarray(Cu @ dphi[:, k, :])                              # (n_meas, P)
            proj = da - np.outer(xv, xv @ da) / float(xv @ xv)
            sens = proj / na_
            sig_c = ss[:, x] * rms / na_
            rvals.extend(res / sig_c)
            Srows.extend(sens * scale[None, :] / sig_c[:, None])
            rows.extend(f"s{x + 1}:{d}" for d in test_modes.dofs)
    S, r = np.vstack(Srows), np.asarray(rvals, float)
    if freq_cov is not None:
        # whiten the frequency rows with the full covariance of the relative frequencies (Cholesky), so
        # correlated repeats count once; the rows were divided by σ above: undo that first
        cov = np.asarray(freq_cov, float)
        if cov.shape != (test_modes.n_modes, test_modes.n_modes):
            raise ShapeError(f"freq_cov has shape {cov.shape}; expected ({test_modes.n_modes}, {test_modes.n_modes})")
        at = np.array([i for i, _, _ in frows], int)
        xs = np.array([x for _, x, _ in frows], int)
        fac = np.array([c for _, _, c in frows], float)
        sig_used = fac * fs[xs]
        raw_r, raw_S = r[at] * sig_used, S[at] * sig_used[:, None]
        D = 1.0 / fx[xs]
        Sig = fac[:, None] * fac[None, :] * cov[np.ix_(xs, xs)] * np.outer(D, D)
        try:
            L = np.linalg.cholesky(Sig)
        except np.linalg.LinAlgError:
            raise ModalabValueError("the frequency covariance of the paired test modes is singular (a mode with "
                                    "zero variance, or perfectly correlated modes); give positive variances") from None
        r[at] = np.linalg.solve(L, raw_r)
        S[at] = np.linalg.solve(L, raw_S)
    return SensitivitySystem(S=S, r=r, rows=rows, pairs=pairs, scale=scale, params=idx,
                             freq_a_hz=fa_all, freq_x_hz=fx, mac=Mm)


def sensitivity_ranking(model, test_modes: ModeSet, p=None, **kw) -> list:
    """Parameters sorted by the norm of their weighted, scaled sensitivity column: [(name, norm), ...]."""
    sys = sensitivity_system(model, test_modes, p, **kw)
    nrm = np.linalg.norm(sys.S, axis=0)
    names = [model.parameter_names[i] for i in sys.params]
    order = np.argsort(-nrm)
    return [(names[i], float(nrm[i])) for i in order]


def identifiability(model, test_modes: ModeSet, p=None, *, rtol: float = 1e-3, **kw) -> dict:
    """Singular values of the weighted sensitivity matrix and what they imply.

    Returns a dict: ``singular_values`` (descending), ``condition`` (σ_max/σ_min),
    ``rank`` (number of σ > rtol·σ_max), ``directions`` (right singular vectors,
    rows, in scaled parameter units) and ``unidentifiable`` (for each σ ≤ rtol·σ_max
    the parameter names with the largest weights in its direction).
    """
    sys = sensitivity_system(model, test_modes, p, **kw)
    U, s, Vt = np.linalg.svd(sys.S, full_matrices=False)
    names = [model.parameter_names[i] for i in sys.params]
    P = len(names)
    sv = np.zeros(P)
    sv[:s.size] = s
    V = np.zeros((P, P))
    V[:Vt.shape[0]] = Vt
    rank = int(np.sum(sv > rtol * sv[0])) if sv[0] > 0 else 0
    bad = []
    for j in range(rank, P):
        v = V[j]
        top = np.argsort(-np.abs(v))[:3]
        bad.append([(names[t], float(v[t])) for t in top if abs(v[t]) > 0.1])
    return {"singular_values": sv, "condition": float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf,
            "rank": rank, "directions": V, "unidentifiable": bad, "n_equations": sys.S.shape[0],
            "parameters": names}


# ----------------------------------------------------------------------------- regularisation
def choose_alpha(S: np.ndarray, b: np.ndarray, method: str = "lcurve", n_grid: int = 200) -> float:
    """Tikhonov factor α for ``min ‖S y − b‖² + α²‖y‖²`` by L-curve maximum curvature or GCV (via SVD)."""
    U, s, Vt = np.linalg.svd(S, full_matrices=False)
    if s.size == 0 or s[0] == 0:
        return 0.0
    beta = U.T @ b
    perp = max(float(b @ b - beta @ beta), 0.0)
    m = S.shape[0]
    alphas = np.logspace(np.log10(max(s[-1], s[0] * 1e-10) * 1e-2), np.log10(s[0] * 10), n_grid)
    f = s[None, :] ** 2 / (s[None, :] ** 2 + alphas[:, None] ** 2)           # filter factors
    rho2 = np.sum(((1 - f) * beta[None, :]) ** 2, axis=1) + perp
    eta2 = np.sum((f * beta[None, :] / s[None, :]) ** 2, axis=1)
    if method == "gcv":
        den = (m - f.sum(axis=1)) ** 2
        G = rho2 / np.where(den > 0, den, np.inf)
        return float(alphas[int(np.argmin(G))])
    if method != "lcurve":
        raise ModalabValueError(f"regularisation method {method!r}; expected 'lcurve', 'gcv' or a number")
    x = np.log(np.sqrt(np.maximum(rho2, 1e-300)))
    y = np.log(np.sqrt(np.maximum(eta2, 1e-300)))
    t = np.log(alphas)
    dx, dy = np.gradient(x, t), np.gradient(y, t)
    ddx, ddy = np.gradient(dx, t), np.gradient(dy, t)
    kappa = (dx * ddy - dy * ddx) / np.maximum((dx ** 2 + dy ** 2) ** 1.5, 1e-300)
    kappa[:2] = kappa[-2:] = -np.inf
    return float(alphas[int(np.argmax(kappa))])


def _tikhonov(S, b, alpha):
    if alpha == 0:
        return np.linalg.lstsq(S, b, rcond=None)[0]
    P = S.shape[1]
    A = np.vstack([S, alpha * np.eye(P)])
    return np.linalg.lstsq(A, np.concatenate([b, np.zeros(P)]), rcond=None)[0]


# ----------------------------------------------------------------------------- uncertainty
def _group_of(row: str) -> str:
    return "frequency" if row.startswith("f") else "shape"


def _posterior(S: np.ndarray, r: np.ndarray, rows: list, alpha: float = 0.0) -> dict:
    """Covariance of the updated parameters (scaled units) from the weighted system at the solution.

    ``S`` and ``r`` are whitened by the stated standard deviations, so with white residuals the
    linearised estimate has covariance ``(SᵀS)⁻¹``.  With ``alpha`` (Tikhonov on the departure from the initial
    parameters, a Gaussian prior of precision α² on the scaled parameters) the posterior is
    ``(SᵀS + α²I)⁻¹``, prior included.  (Penalising the *step* leaves the converged estimate the plain least-
    squares one: its covariance is ``(SᵀS)⁻¹``; the former sandwich ``(SᵀS+α²I)⁻¹SᵀS(SᵀS+α²I)⁻¹`` was smaller
    than that and did not cover the truth.)

    **Are the stated σ right?**  Per residual group (frequencies, shapes), χ² = Σ r² is compared with its
    degrees of freedom ``n_g − Σ_{i∈g} h_i`` (h the leverages of the fit).  When χ² exceeds its 95 % point the
    stated σ of that group are too small for these data (optimistic identification uncertainties, or what
    the model leaves out, e.g. a damping model); the group's rows are then down-weighted by χ²/dof (the Birge
    ratio) before the covariance is formed.  Otherwise the σ stand as stated (never scaled down).

    Returns ``covariance``, ``covariance_unregularised`` (α = 0; ∞ on the diagonal of parameters that a
    rank-deficient S cannot see), ``groups`` {name: chi2, dof, chi2_95, factor, n}, ``singular_values``
    and ``condition`` (of the weighted S, after the group factors).
    """
    from scipy.stats import chi2 as _chi2

    P = S.shape[1]
    I = np.eye(P)
    names = np.array([_group_of(x) for x in rows]) if len(rows) == S.shape[0] else np.array(["frequency"] * S.shape[0])

    def inverse(H):
        """(H)⁻¹ with ∞ variance for parameters in the null space of a rank-deficient H."""
        w, V = np.linalg.eigh(0.5 * (H + H.T))
        tol = max(w.max(initial=0.0), 0.0) * 1e-12
        good = w > tol
        inv = (V[:, good] / w[good]) @ V[:, good].T
        if not good.all():
            blind = np.any(np.abs(V[:, ~good]) > 1e-8, axis=1)
            inv[blind, :] = np.where(np.eye(P, dtype=bool)[blind, :], np.inf, inv[blind, :])
        return inv

    def fit_leverage(Sw, a):
        H = Sw.T @ Sw + a ** 2 * I
        Hi = np.linalg.pinv(H)
        return np.einsum("ij,jk,ik->i", Sw, Hi, Sw)

    h = fit_leverage(S, alpha) if S.size else np.zeros(0)
    groups, weights = {}, np.ones(S.shape[0])
    for g in ("frequency", "shape"):
        sel = names == g
        if not sel.any():
            continue
        c2 = float(r[sel] @ r[sel])
        dof = float(sel.sum() - h[sel].sum())
        q95 = float(_chi2.ppf(0.95, dof)) if dof >= 0.5 else np.inf
        factor = c2 / dof if c2 > q95 else 1.0
        groups[g] = {"name": g, "n": int(sel.sum()), "chi2": c2, "dof": dof, "chi2_95": q95, "factor": factor}
        weights[sel] = 1.0 / np.sqrt(factor)
    Sw = S * weights[:, None]
    H = Sw.T @ Sw
    cov_u = inverse(H) if S.size else np.full((P, P), np.inf)
    cov = cov_u if alpha == 0 else np.linalg.inv(H + alpha ** 2 * I)
    sv = np.linalg.svd(Sw, compute_uv=False) if Sw.size else np.zeros(0)
    full = sv.size == P and sv.size and sv[-1] > 1e-12 * sv[0]
    return {"covariance": cov, "covariance_unregularised": cov_u, "groups": groups, "singular_values": sv,
            "condition": float(sv[0] / sv[-1]) if full else np.inf}


# ----------------------------------------------------------------------------- the updater
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
        idx = _param_indices(model, self.params)
        p = np.array(model.p0 if p_init is None else p_init, float)
        p0 = p.copy()
        scale = np.where(p0[idx] != 0, np.abs(p0[idx]), 1.0)
        lo, hi = self._bounds(model, idx)
        C = _observation(test_modes, model, dofmap)
        wts = dict(freq_sigma=self.freq_sigma, shape_sigma=self.shape_sigma, use_shapes=self.use_shapes)
        if self.weights is not None:
            unknown = set(self.weights) - set(wts)
            if unknown:
                raise ModalabValueError(f"weights keys {sorted(unknown)}; expected some of {sorted(wts)}")
            wts.update(self.weights)
        fcov = test_modes.freq_cov if isinstance(self.freq_cov, str) and self.freq_cov == "test" else self.freq_cov
        kw = dict(params=idx, n_modes=self.n_modes, mac_min=self.mac_min, residual=self.residual,
                  scale=scale, C=C, pairing=self.pairing, freq_cov=fcov,
                  hysteretic=None if _hysteretic_matrix(model, p) is not None else False, **wts)
        self.history_ = []
        self.converged_ = False
        self.params_ = idx
        change = np.inf
        it = 0
        sysm = sensitivity_system(model, test_modes, p, **kw)
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
        for it in range(1, self.max_iter + 1):
            S, r = sysm.S, sysm.r
            d0 = (p[idx] - p0[idx]) / scale
            if self.tikhonov == "initial":
                b = r + S @ d0
                alpha = self._alpha(S, b)
                y = _tikhonov(S, b, alpha)
                dx = y - d0
            else:
                alpha = self._alpha(S, r)
                dx = _tikhonov(S, r, alpha)
            cost0 = float(r @ r) + (alpha ** 2 * float(d0 @ d0) if self.tikhonov == "initial" else 0.0)
            step = 1.0
            best_tried = np.inf
            for _ls in range(10):
                pn = p.copy()
                pn[idx] = np.clip(p[idx] + step * dx * scale, lo, hi)
                try:
                    new = sensitivity_system(model, test_modes, pn, **kw)
                    dn = (pn[idx] - p0[idx]) / scale
                    cost = float(new.r @ new.r) + (alpha ** 2 * float(dn @ dn) if self.tikhonov == "initial" else 0.0)
                    ok = cost <= cost0 * (1 + 1e-12) and new.r.size >= r.size
                    if new.r.size >= r.size:
                        best_tried = min(best_tried, cost)
                except ModalabValueError:
                    ok = False
                if ok:
                    break
                step *= 0.5
            else:
                # no step lowers the cost: at a stationary point (the Gauss–Newton model predicts almost no
                # decrease) that is convergence; elsewhere the linearisation has failed
                res_lin = r - S @ dx
                pred = float(r @ r) - float(res_lin @ res_lin)
                if pred <= 1e-4 * max(cost0, 1e-300) or best_tried <= cost0 * (1 + 1e-5):
                    log.info("inverse eigensensitivity: stationary at iteration %d (cost %.6g; the steps tried "
                             "reach %.6g, the linear model predicts a decrease of %.3g)", it, cost0, best_tried, pred)
                    self.converged_ = True
                else:
                    log.warning("inverse eigensensitivity: no step decreased the cost at iteration %d", it)
                break
            change = float(np.max(np.abs(pn[idx] - p[idx]) / scale))
            p, sysm = pn, new
            ferr = 100 * (sysm.freq_a_hz[[a for a, _ in sysm.pairs]] - sysm.freq_x_hz[[x for _, x in sysm.pairs]]) \
                / sysm.freq_x_hz[[x for _, x in sysm.pairs]]
            self.history_.append({"iteration": it, "p": p.copy(), "cost": cost, "alpha": alpha,
                                  "pairs": list(sysm.pairs), "freq_error_pct": ferr, "step": step})
            log.debug("IES iteration %d: cost %.4g, alpha %.3g, change %.3g", it, cost, alpha, change)
            if change < self.tol:
                self.converged_ = True
                break
        if not self.converged_:
            log.warning("inverse eigensensitivity did not converge in %d iterations (last change %.3g)",
                        it, change)
        alpha = self.history_[-1]["alpha"] if self.history_ else 0.0
        post = _posterior(sysm.S, sysm.r, sysm.rows, alpha if self.tikhonov == "initial" else 0.0)
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
        self.p_ = p
        self.pairs_ = sysm.pairs
        fa = np.full(test_modes.n_modes, np.nan)
        for a, x in sysm.pairs:
            fa[x] = sysm.freq_a_hz[a]
        self.freq_a_hz_ = fa
        self.n_iter_ = it
        return self

    def _check(self):
        if not hasattr(self, "p_"):
            raise NotFittedError("this InverseEigensensitivity is not fitted yet; call fit(model, test_modes)")

    def parameter_history(self) -> np.ndarray:
        """(n_iter, P) parameter vectors per iteration."""
        self._check()
        return np.vstack([h["p"] for h in self.history_])
