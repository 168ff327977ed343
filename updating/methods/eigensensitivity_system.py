"""The linearised system of inverse eigensensitivity, thesis Eq. 3.44–3.52: ``[S]{Δp} = {Δ}`` at one parameter vector.

:func:`sensitivity_system` pairs the analysis modes with the test modes by the one pairing rule
(:func:`updating.correlation.metrics.pair_modes`) and builds, per pair, the weighted frequency (or eigenvalue)
row and the shape rows at the measured DOFs (residuals, weighting and damped poles as described in
:mod:`updating.methods.eigensensitivity`).  :func:`sensitivity_ranking` and :func:`identifiability` read the
weighted, scaled matrix for parameter selection.  :class:`~updating.methods.eigensensitivity.InverseEigensensitivity`
solves this system at every iteration.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from modalab.core.errors import ModalabValueError, ShapeError
from modalab.core.modes import ModeSet

from updating.fe.parametric import parameter_indices
from updating.fe.sensitivity import (StackedDerivatives, eigenvalue_sensitivities, eigenvector_sensitivities,
                                     solve_modes)
from updating.correlation.dofmap import observation_matrix
from updating.correlation.metrics import FREQ_WINDOW, mac, observability, pair_modes

log = logging.getLogger(__name__)

__all__ = ["SensitivitySystem", "sensitivity_system", "sensitivity_ranking", "identifiability",
           "measured_observation", "hysteretic_matrix", "pole_factor"]


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


def _mac_pair(Pa, Px, mac_min, freq_a_hz=None, freq_x_hz=None, phi_full=None, dofs=None, **kw):
    """Pairs by the one pairing rule of modalab (:func:`updating.correlation.metrics.pair_modes`)."""

    Mm = mac(Pa, Px)
    obs = observability(Pa, phi_full, dofs) if phi_full is not None else None
    pr = pair_modes(Mm, freq_a_hz, freq_x_hz, mac_min=mac_min, observability=obs, mode_shapes=(Pa, Px), **kw)
    return [(int(a), int(x)) for a, x in pr.pairs], Mm, pr


def measured_observation(test: ModeSet, model, dofmap):
    """The observation matrix C (CSR) taking the model's DOFs to the test's measured DOFs."""
    return observation_matrix(test.dofs, model.dofs, dofmap).tocsr()


def hysteretic_matrix(model, p):
    """The model's structural (hysteretic) damping matrix D at ``p`` (PARAM G, GE), or None when it has none."""
    D = getattr(model.structure(p), "D", None)
    return D if D is not None and D.nnz > 0 and abs(D).max() > 0 else None


def pole_factor(D, sol) -> np.ndarray:
    """Per mode of ``sol``, ``|s_r| / ω_r``: the natural frequency identification reports (the
    pole's modulus, :mod:`identification`) over the undamped one, for a model with structural damping D.

    With hysteretic damping the poles solve ``(K + iD − |s|² e^{iθ} M) x = 0``: for D = G·K (PARAM G)
    ``s² = −ω²(1 + iG)`` and ``|s| = ω (1 + G²)^{1/4}``, 1.0001 ω for G = 0.02 — ten times the standard deviation
    of a well-identified frequency, so comparing the undamped ω with the identified |s| moved an exact model's
    parameters.  Here the complex eigenproblem is solved in the subspace of the computed modes
    (``diag(ω²) + i ΦᵀDΦ``: exact for proportional D, and it keeps the coupling of close modes through a
    non-proportional D); each complex mode is matched to the real mode it is made of.  Viscous damping is not
    included (proportional viscous damping leaves |s| = ω)."""
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


def _analysis_modes(model, p, test_modes: ModeSet, n_modes, pairing):
    """The model's lowest modes at ``p``: ``n_modes`` of them, or by default enough to cover the test band."""
    nx = test_modes.n_modes
    N = len(model.dofs)
    na = min(N, max(2 * nx, nx + 6)) if n_modes is None else int(n_modes)
    sol = solve_modes(model, p, na)
    if n_modes is None and test_modes.n_modes:
        # enough analysis modes to cover the test band and its frequency window (free-free models and local
        # modes can push the partners of the highest test modes beyond 2 x n_test)
        w = (pairing or {}).get("max_freq_error", FREQ_WINDOW) or FREQ_WINDOW
        top = float(np.max(test_modes.freq_hz)) * (1 + w)
        while sol.freq_hz[-1] < top and na < N:
            na = min(N, 2 * na)
            sol = solve_modes(model, p, na)
    return sol


def _pairs(model, test_modes: ModeSet, sol, Pa, mac_min, pairing, only_test, fixed_pairs):
    """(analysis, test) pairs (test indices among all test modes) and the MAC matrix (None without shapes)."""
    X = test_modes.real_shapes
    cols = np.arange(test_modes.n_modes) if only_test is None else np.array(sorted(int(j) for j in only_test), int)
    if test_modes.has_shapes:
        _, Mm, pr = _mac_pair(Pa, X[:, cols], mac_min, sol.freq_hz, test_modes.freq_hz[cols], sol.phi, model.dofs,
                              **(pairing or {}))
        if only_test is not None:
            Mm = mac(Pa, X)
    elif fixed_pairs is not None:
        pr, Mm = None, None
    else:
        pr = pair_modes(None, sol.freq_hz, test_modes.freq_hz[cols], **(pairing or {}))
        Mm = None
    pairs = [(int(a), int(x)) for a, x in fixed_pairs] if pr is None else \
        [(int(a), int(cols[x])) for a, x in pr.pairs]
    if not pairs:
        how = pr.method if pr is not None else "fixed pairs"
        raise ModalabValueError(f"no analysis mode pairs with any test mode ({how}); check the DOF "
                                "map (signs, node numbers), the frequency window or mac_min")
    return pairs, Mm


def _frequency_row(residual, a, x, lam_a, fa, fx, dl, fs):
    """Residual, sensitivity row and standard deviation of the frequency (or eigenvalue) of one pair."""
    if residual == "frequency":
        wa = np.sqrt(max(lam_a, 0.0))
        if wa <= 0:
            raise ModalabValueError(f"analysis mode {a + 1} is a rigid-body mode paired with test mode {x + 1}; "
                                    "remove rigid-body modes from the test set")
        rv = (fx - fa) / fx
        srow = dl / (2 * wa) / (2 * np.pi) / fx        # ∂f/∂p = (∂λ/∂p) / (2ω) / 2π
        sig = fs
    else:
        lx = (2 * np.pi * fx) ** 2
        rv = (lx - lam_a) / lx
        srow = dl / lx
        sig = 2 * fs
    return rv, srow, sig


def _shape_rows(av, xv, da, ss_x):
    """Residual, sensitivity rows and standard deviations of the shape components of one pair (Eq. 3.47):
    the test shape ``xv`` scaled onto the analysis one ``av`` by the MSF; ``da`` is C ∂φ/∂p."""
    msf = float(av @ xv) / float(xv @ xv)
    na_ = np.linalg.norm(av)
    rms = na_ / np.sqrt(av.size)
    res = (msf * xv - av) / na_
    proj = da - np.outer(xv, xv @ da) / float(xv @ xv)
    sens = proj / na_
    sig_c = ss_x * rms / na_
    return res, sens, sig_c


def _whiten_frequencies(S, r, frows, freq_cov, fs, fx, n_test):
    """Whiten the frequency rows with the full covariance of the relative frequencies (Cholesky), in place, so
    correlated repeats count once; the rows were divided by σ: that is undone first."""
    cov = np.asarray(freq_cov, float)
    if cov.shape != (n_test, n_test):
        raise ShapeError(f"freq_cov has shape {cov.shape}; expected ({n_test}, {n_test})")
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


def sensitivity_system(model, test_modes: ModeSet, p=None, *, params=None, dofmap=None, n_modes=None,
                       mac_min: float = 0.5, freq_sigma=0.01, shape_sigma=0.05, use_shapes: bool = True,
                       residual: str = "frequency", scale=None, C=None, pairing: dict | None = None,
                       freq_cov=None, only_test=None, fixed_pairs=None, hysteretic=None) -> SensitivitySystem:
    """Build the weighted sensitivity matrix [S] (Eq. 3.50) and residual {Δ} (Eq. 3.51) for paired modes.

    Modes are paired by :func:`updating.correlation.metrics.pair_modes` (``pairing``: its keyword arguments);
    ``only_test`` restricts the pairing to those test modes (0-based), as the updater does after its
    first pairing so that the objective keeps the same test modes at every iteration; ``fixed_pairs``
    (used for frequency-only test sets, where no shape can follow a mode) keeps given (analysis, test) pairs.
    A model with structural damping is compared by the modulus of its poles (:func:`pole_factor`;
    ``hysteretic`` None: look whether it has any, False: ignore it).
    """
    if residual not in ("frequency", "eigenvalue"):
        raise ModalabValueError(f"residual={residual!r}; expected 'frequency' or 'eigenvalue'")
    p = np.asarray(model.p0 if p is None else p, float)
    idx = parameter_indices(model, params)
    scale = np.where(model.p0 != 0, np.abs(model.p0), 1.0)[idx] if scale is None else np.asarray(scale, float)
    C = measured_observation(test_modes, model, dofmap) if C is None else C
    N = len(model.dofs)
    sol = _analysis_modes(model, p, test_modes, n_modes, pairing)
    X = test_modes.real_shapes
    Pa = np.asarray(C @ sol.phi)
    if use_shapes and not test_modes.has_shapes:
        log.info("the test modes have no shapes: frequencies only")
        use_shapes = False
    pairs, Mm = _pairs(model, test_modes, sol, Pa, mac_min, pairing, only_test, fixed_pairs)
    fs, ss = _sigmas(test_modes, freq_sigma, shape_sigma)
    sd = StackedDerivatives(model.derivatives(p), N)
    amodes = np.array([a for a, _ in pairs])
    dl = eigenvalue_sensitivities(model, modes=amodes, solution=sol, derivatives=sd)[:, idx]
    lam_a = sol.lam[amodes]
    fa_all = sol.freq_hz
    D = hysteretic_matrix(model, p) if hysteretic is not False else None
    if D is not None:
        # the analysis natural frequency as identification measures it, |s| (the pole factor's dependence on p
        # is second order in the loss factor and left out of the sensitivity)
        fac = pole_factor(D, sol)
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
        rv, srow, sig = _frequency_row(residual, a, x, lam_a[k], fa_all[a], fx[x], dl[k], fs[x])
        rows.append(f"f{x + 1}")
        frows.append((len(rvals), x, 1.0 if residual == "frequency" else 2.0))
        rvals.append(rv / sig)
        Srows.append(srow * scale / sig)
        if use_shapes:
            res, sens, sig_c = _shape_rows(Pa[:, a], X[:, x], np.asarray(Cu @ dphi[:, k, :]), ss[:, x])
            rvals.extend(res / sig_c)
            Srows.extend(sens * scale[None, :] / sig_c[:, None])
            rows.extend(f"s{x + 1}:{d}" for d in test_modes.dofs)
    S, r = np.vstack(Srows), np.asarray(rvals, float)
    if freq_cov is not None:
        _whiten_frequencies(S, r, frows, freq_cov, fs, fx, test_modes.n_modes)
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
