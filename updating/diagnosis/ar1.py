"""The error of an FRF fit along the frequency lines as an AR(1) series: its lag-one correlation and variance
by restricted maximum likelihood (:func:`reml_ar1`), used by :func:`updating.diagnosis.fit.correlated_std`
for the stated standard deviations of the diagnosis' fits when model-form error leaves a residual smooth over
frequency."""
from __future__ import annotations

import numpy as np
import scipy.optimize as so
from scipy.linalg import solve_banded


def _ar1_inv(x: np.ndarray, rho: float) -> np.ndarray:
    """``R⁻¹ x`` along the last axis for the AR(1) correlation ``R_ij = ρ^|i−j|`` (tridiagonal inverse)."""
    y = (1 + rho ** 2) * x
    y[..., 0] = x[..., 0]
    y[..., -1] = x[..., -1]
    y[..., 1:] -= rho * x[..., :-1]
    y[..., :-1] -= rho * x[..., 1:]
    return y / (1 - rho ** 2)


def _ar1_apply(x: np.ndarray, rho: float) -> np.ndarray:
    """``R x`` along the last axis (a banded solve with :func:`_ar1_inv`'s matrix)."""
    n = x.shape[-1]
    ab = np.zeros((3, n))
    ab[0, 1:] = ab[2, :-1] = -rho
    ab[1] = 1 + rho ** 2
    ab[1, 0] = ab[1, -1] = 1.0
    xt = np.moveaxis(x, -1, 0)
    out = solve_banded((1, 1), ab / (1 - rho ** 2), xt.reshape(n, -1))
    return np.moveaxis(out.reshape(xt.shape), 0, -1)


#: range of the lag-one correlation ρ searched by :func:`reml_ar1`
RHO_RANGE = (-0.95, 0.999)


def _column_basis(J: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the column space of ``J`` (rows × columns), of its numerical rank (singular
    values above ``max(shape) ε`` times the largest, as ``numpy.linalg.matrix_rank``)."""
    if J.shape[1] == 0:
        return J
    U, sv, _ = np.linalg.svd(J, full_matrices=False)
    keep = sv > (sv[0] * max(J.shape) * np.finfo(float).eps if sv[0] > 0 else np.inf)
    return U[:, keep]


def reml_ar1(r: np.ndarray, J: np.ndarray) -> tuple[float, float]:
    """Variance σ² and lag-one correlation ρ of an AR(1) error along the last axis of ``r`` (series × lines;
    the series independent, ρ common), from the residual of a least-squares fit with regressors ``J``
    (series × lines × parameters), by restricted maximum likelihood (REML: Patterson & Thompson, Biometrika
    58 (1971) 545-554; for AR(1) regression errors e.g. Cheang & Reinsel, J. Time Ser. Anal. 21 (2000)).

    The fitted residual under-states a slow error (the fit absorbs the part its smooth regressors can follow),
    so ρ and σ² estimated from it directly are biased low; REML accounts for the estimated parameters:
    with the GLS residual's form ``Q(ρ) = rᵀR⁻¹r − bᵀ(JᵀR⁻¹J)⁻¹b`` (``b = JᵀR⁻¹r``, independent of which
    fit gave ``r``), ``ρ̂`` minimises ``(N − p) ln Q + m (n − 1) ln(1 − ρ²) + ln|JᵀR⁻¹J|`` (σ² profiled
    out) and ``σ̂² = Q/(N − p)``.  Both depend on ``J`` only through its column space (``J → JT`` adds the
    constant ``2 ln|T|``), so ``J`` is replaced by an orthonormal basis of that space and ``p`` is its rank: a
    parameter without effect on the FRFs (a zero column) or two acting alike leave ``JᵀR⁻¹J`` regular instead
    of making the objective ``−∞``."""
    r = np.asarray(r, float)
    J = np.asarray(J, float)
    n = r.shape[-1]
    N, m = r.size, r.size // max(n, 1)
    Jf = _column_basis(J.reshape(-1, J.shape[-1]))
    p = Jf.shape[1]
    J = Jf.reshape(J.shape[:-1] + (p,))

    def parts(rho):
        Rr = _ar1_inv(r, rho)
        RJ = np.moveaxis(_ar1_inv(np.moveaxis(J, -1, 0), rho), 0, -1).reshape(-1, p)
        A = Jf.T @ RJ
        b = Jf.T @ Rr.ravel()
        return float(np.sum(r * Rr) - b @ np.linalg.lstsq(A, b, rcond=None)[0]), A

    def objective(rho):
        Q, A = parts(rho)
        ld = np.linalg.slogdet(A)[1] if p else 0.0
        return (N - p) * np.log(max(Q, 1e-300)) + m * (n - 1) * np.log(1 - rho ** 2) + ld

    if n < 3 or N <= p:
        return float(np.sum(r * r)) / max(N - p, 1), 0.0
    rho = float(so.minimize_scalar(objective, bounds=RHO_RANGE, method="bounded",
                                    options={"xatol": 1e-6}).x)
    return parts(rho)[0] / (N - p), rho
