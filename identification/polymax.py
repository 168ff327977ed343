"""Poly-reference least-squares complex-frequency estimator (pLSCF, "PolyMAX").

Model
-----
A right matrix-fraction description on the z-domain, all references at once
(Guillaume et al. 2003, "A poly-reference implementation of the least-squares
complex frequency-domain estimator", IMAC XXI; Peeters et al. 2004, "The
PolyMAX frequency-domain method: a new standard for modal parameter
estimation?", Shock and Vibration 11):

    H_o(ω) ≈ N_o(ω) A(ω)⁻¹,   N_o(ω) = Σ_r Ω_r(ω) β_or,   A(ω) = Σ_r Ω_r(ω) α_r,

with ``Ω_r(ω) = z^r``, ``z = exp(iωΔt)``, ``Δt = 1/(2 f_max)``, real
coefficients ``β_or`` (1 × n_in) and ``α_r`` (n_in × n_in), one numerator row
per output and a common denominator matrix.  The linearised weighted error
``E_o(ω_k) = w_o(ω_k) [Ω(ω_k) β_o − H_o(ω_k) ⊗ Ω(ω_k) α]`` leads to the normal
equations with the blocks

    R_o = Re(Γ_oᴴΓ_o),  S_o = Re(Γ_oᴴΥ_o),  T_o = Re(Υ_oᴴΥ_o),

and, after eliminating every numerator, to the *reduced* normal equations
(Peeters 2004, eq. 6)

    M α = 0,    M = 2 Σ_o (T_o − S_oᵀ R_o⁻¹ S_o).

Because ``Ω_r`` are powers of ``z`` on the unit circle, every block is
Toeplitz in the order index: each is built from 2p+1 "lag" sums, one matrix
product over the frequency lines for all outputs at once.  ``M`` is built
once, for the highest order ``p``; the reduced matrix of a lower order ``n`` is
taken as its leading ``(n+1)·n_in`` block (the denominator of order ``n`` with
the numerators kept at order ``p``), so no order rebuilds anything.  The
constraint ``α_n = I`` (PolyMAX) gives ``α_0..α_{n-1}`` from a linear solve —
for all orders from one Cholesky factor of ``M`` (one triangular solve per order) —,
the poles are the eigenvalues of the block companion matrix and each modal
participation vector ``l`` spans the left null space of ``A(z_pole)``.

With one reference the denominator is a scalar polynomial, and from degree 76 on its
roots are tracked from the previous evaluated order instead (:func:`denominator_roots`):
a simultaneous Aberth–Ehrlich iteration started at the previous roots, whose result is
accepted only when disjoint Newton inclusion discs prove that every root was found once
(else the companion eigenvalues are taken).  It costs O(n²) per order instead of the
O(n³) of the eigenvalues, which dominate a sweep to high orders.

Memory holds the lag sums (accumulated over chunks of lines), one chunk of
``S_o`` blocks (bounded to a few tens of MB) and ``M``: it does not grow with the
order beyond the reduced matrix.
"""
from __future__ import annotations

import logging

import numpy as np

from modalab.core.errors import ModalabValueError, NotFittedError, ShapeError, fmt_error
from modalab.core.frf import FRF
from .stabilisation import mac_vectors
from .stabilisation import StabilisationCriteria, stabilise
from .selection import SelectionOptions, select_poles
from .indicators import mpc
from .lsfd import lsfd, modes_from_poles, pole_uncertainty, refine_poles
from .stabilisation import pole_freq_damping

log = logging.getLogger(__name__)

__all__ = ["PolyMAX", "frequency_weights", "reduced_normal_matrix", "poles_at_order", "denominator_roots",
           "aberth_roots"]

_WEIGHTINGS = (None, "none", "coherence", "variance")


# --------------------------------------------------------------------------- weights
def frequency_weights(frf: FRF, weighting=None, *, normalise: bool = True) -> np.ndarray:
    """Per-output, per-line amplitude weights ``w_o(ω_k)``, shape ``(n_out, n_freq)``.

    ``weighting``
        ``None``/``'none'`` — unit weights;
        ``'coherence'`` — the mean ordinary coherence over the references
        (lines with poor coherence count less);
        ``'variance'`` — ``1/σ_H``, the inverse standard deviation of the FRF
        estimate, from ``frf.variance`` (same shape as ``H``) when
        present, else from coherence and ``n_averages`` with the H1 variance
        ``σ² ≈ (1−γ²)/(2 n_avg γ²)·|H|²`` (Bendat & Piersol, eq. 9.73).

    With ``normalise`` every output is scaled by the RMS of its weighted FRFs,
    so that strong and weak responses count equally (and units cancel).
    """
    if weighting not in _WEIGHTINGS:
        raise ModalabValueError(fmt_error("weighting", weighting, "None, 'coherence' or 'variance'",
                                          "Use 'coherence' when the FRFs carry coherence, else None"))
    H = frf.H
    n_out, n_in, nf = H.shape
    w = np.ones((n_out, nf))
    if weighting == "coherence":
        if frf.coherence is None:
            raise ModalabValueError("weighting='coherence' but the FRF has no coherence; "
                                    "pass weighting=None or estimate the FRFs with coherence")
        w = np.clip(np.nan_to_num(frf.coherence, nan=0.0), 0.0, 1.0).mean(axis=1)
    elif weighting == "variance":
        var = frf.variance
        if var is None:
            if frf.coherence is None:
                raise ModalabValueError("weighting='variance' needs FRF.variance or coherence; "
                                        "neither is present. Use weighting=None")
            n_avg = float(frf.metadata.get("n_averages", 1) or 1)
            g2 = np.clip(frf.coherence, 1e-6, 1 - 1e-9)
            var = (1 - g2) / (2 * n_avg * g2) * np.abs(H) ** 2
        var_o = np.mean(var, axis=1)
        floor = 1e-12 * np.maximum(np.median(var_o, axis=1, keepdims=True), 1e-300)
        w = 1.0 / np.sqrt(np.maximum(var_o, floor))
    if normalise:
        rms = np.sqrt(np.mean(np.abs(H) ** 2 * (w ** 2)[:, None, :], axis=(1, 2)))
        rms[~(rms > 0)] = 1.0
        w = w / rms[:, None]
    return w


# --------------------------------------------------------------------------- reduced matrix
def reduced_normal_matrix(H: np.ndarray, w: np.ndarray, theta: np.ndarray, max_order: int, *,
                          chunk: int = 16, rcond: float = 1e-12) -> np.ndarray:
    """Reduced normal matrix ``M`` of pLSCF for order ``p = max_order``.

    Parameters
    ----------
    H : (n_out, n_in, n_freq) complex FRFs.
    w : (n_out, n_freq) amplitude weights.
    theta : (n_freq,) normalised angular frequencies ``ω_k Δt`` in rad.
    max_order : highest polynomial order ``p``.

    Returns the real symmetric ``((p+1)·n_in, (p+1)·n_in)`` matrix with rows
    and columns ordered (order r, input i), r-major.  Blocks R, S, T are
    Toeplitz in the order index and are formed from lag sums (module docs).
    """
    n_out, n_in, nf = H.shape
    p = int(max_order)
    c = (p + 1) * n_in
    a = (w ** 2).astype(float)                                    # |w|², (n_out, nf)
    D = np.arange(p + 1)[None, :] - np.arange(p + 1)[:, None]     # s - r
    # --- lag sums, accumulated over chunks of lines so that memory does not scale with nf x order.
    #     Only real parts enter R, S, T, so with C_kd = cos(θ_k d), S_kd = sin(θ_k d), d = 0..p:
    #     Re rho_o(±d) = Σ_k a C,  Re sigma_oj(±d) = Σ_k a (Re H_oj C ∓ Im H_oj S),
    #     Re tau_ij(d) = Σ_k (Re G_ij C − Im G_ij S),  G_ij = Σ_o a conj(H_oi) H_oj,  tau_ij(−d) = conj tau_ji(d)
    rho_c = np.zeros((n_out, p + 1))
    sig_c = np.zeros((n_out * n_in, p + 1))
    sig_s = np.zeros((n_out * n_in, p + 1))
    tau_pos = np.zeros((n_in * n_in, p + 1))
    f_chunk = max(16, int(2 ** 17 // max(2 * p + 1, 1)))          # lag matrices of at most ~2 MB
    for k0 in range(0, nf, f_chunk):
        ks = slice(k0, min(k0 + f_chunk, nf))
        E = _powers(np.exp(1j * theta[ks]), p)                     # z_k^d, d = 0..p (chunk, p+1)
        Cm = np.ascontiguousarray(E.real)
        Sm = np.ascontiguousarray(E.imag)
        aH = (a[:, None, ks] * H[:, :, ks]).reshape(n_out * n_in, -1)
        rho_c += a[:, ks] @ Cm
        sig_c += np.ascontiguousarray(aH.real) @ Cm
        sig_s += np.ascontiguousarray(aH.imag) @ Sm
        G = np.einsum("oik,ojk->ijk", H[:, :, ks].conj(), aH.reshape(n_out, n_in, -1), optimize=True)
        G = G.reshape(n_in * n_in, -1)
        tau_pos += np.ascontiguousarray(G.real) @ Cm - np.ascontiguousarray(G.imag) @ Sm
    tau_pos = tau_pos.reshape(n_in, n_in, p + 1)
    tau = np.empty((n_in, n_in, 2 * p + 1))
    tau[:, :, p:] = tau_pos
    tau[:, :, :p] = tau_pos.transpose(1, 0, 2)[:, :, :0:-1]              # Re tau_ij(-d) = Re tau_ji(d)
    T4 = tau[:, :, D + p]                                           # (i, j, r, s)
    M = T4.transpose(2, 0, 3, 1).reshape(c, c).copy()
    del T4, tau, tau_pos
    rho = np.concatenate([rho_c[:, :0:-1], rho_c], axis=1)          # Re rho(d), d = -p..p
    sig_re = np.concatenate([(sig_c + sig_s)[:, :0:-1], sig_c - sig_s], axis=1)   # Re sigma(d), d = -p..p
    # --- R and S per output, eliminated in chunks of outputs (a few tens of MB at most)
    sig_all = sig_re.reshape(n_out, n_in, 2 * p + 1)
    chunk = max(1, min(int(chunk), int(1e6 // (8 * (p + 1) * c))))            # ~1 MB of S per chunk
    same_R = np.allclose(a, a[:1] * (a.sum(1, keepdims=True) / max(a[0].sum(), 1e-300)), rtol=1e-10, atol=0)
    if same_R:
        # R_0⁺ = V Λ⁺ Vᵀ (pseudo-inverse with the same cut-off as pinv): S_oᵀ R_o⁺ S_o = W_oᵀ W_o with
        # W_o = Λ^{-1/2} Vᵀ S_o / sqrt(scale), so the elimination is one product and one symmetric rank-k update
        lam_r, V_r = np.linalg.eigh(rho[0][D + p])
        keep = np.abs(lam_r) > rcond * np.abs(lam_r).max()
        W0 = (V_r[:, keep] / np.sqrt(np.abs(lam_r[keep]))).T
        sgn = np.sign(lam_r[keep])
    for o0 in range(0, n_out, chunk):
        sl = slice(o0, min(o0 + chunk, n_out))
        no = sl.stop - sl.start
        sig = sig_all[sl]
        # S_o[r, (s, j)] = -Re sigma_oj(s - r)
        S = -sig[:, :, D + p]                                       # (no, j, r, s)
        S = S.transpose(0, 2, 3, 1).reshape(no, p + 1, c)
        if same_R:
            scale = rho[0, p] / rho[sl, p]                          # R_o = R_0 * rho_o(0)/rho_0(0)
            W = np.matmul(W0, S) * np.sqrt(scale)[:, None, None]     # (no, k, c)
            if sgn.min() > 0:
                W = W.reshape(-1, c)
                M -= W.T @ W                                        # symmetric rank-k update
            else:                                                   # indefinite R (not from positive weights)
                M -= np.einsum("okc,k,okd->cd", W, sgn, W, optimize=True)
        else:
            R = rho[sl][:, D + p]                                   # (no, p+1, p+1)
            X = np.linalg.pinv(R, rcond=rcond, hermitian=True) @ S
            M -= S.reshape(no * (p + 1), c).T @ X.reshape(no * (p + 1), c)
    M = 0.5 * (M + M.T)
    return 2.0 * M


# --------------------------------------------------------------------------- roots
_EPS = np.finfo(float).eps
_TRACK_MIN_DEGREE = 76          # eigenvalues are cheaper below (LAPACK switches to multishift QR above 75)
_TRACK_MAX_NEW = 8              # at most this many roots more than the starting set (else eigenvalues)


def _powers(b: np.ndarray, n: int) -> np.ndarray:
    """``P[i, k] = b_i**k`` for ``k = 0..n`` by doubling (log2(n) vector products, error O(log n) ulp).

    For a few points and low powers a running product (one call) costs less than the doubling steps.
    """
    P = np.empty((b.size, n + 1), b.dtype)
    P[:, 0] = 1.0
    if b.size <= 32 and n <= 32:
        P[:, 1:] = b[:, None]
        np.cumprod(P[:, 1:], axis=1, out=P[:, 1:])
        return P
    if n:
        P[:, 1] = b
    k = 2
    while k <= n:
        kk = min(k, n + 1 - k)
        np.multiply(P[:, :kk], (P[:, k - 1] * b)[:, None], out=P[:, k:k + kk])     # b^(k+j) = b^j b^k
        k += kk
    return P


def _blocked(CC: np.ndarray) -> np.ndarray:
    """The columns of ``CC`` (n+1 coefficients each) cut into ``B`` blocks of ``m ≈ √(n+1)``: ``(m, B·k)``."""
    n1, k = CC.shape
    m = int(np.ceil(np.sqrt(n1)))
    B = -(-n1 // m)
    C = np.zeros((B * m, k))
    C[:n1] = CC
    return C.reshape(B, m, k).transpose(1, 0, 2).reshape(m, B * k)


def _evaluate(b: np.ndarray, Cb: np.ndarray, k: int) -> np.ndarray:
    """``Σ_j c_j b^j`` for every column of the coefficients blocked by :func:`_blocked`, ``(b.size, k)``.

    ``p(b) = Σ_J (b^m)^J q_J(b)`` with ``q_J`` of degree ``m − 1``: the block polynomials are one matrix
    product with the powers ``b^0..b^(m−1)``, then combined with the powers of ``b^m`` — about
    ``n^(1/2)`` instead of ``n`` complex products per point (|b| <= 1, so no power exceeds one).
    """
    m = Cb.shape[0]
    B = Cb.shape[1] // k
    Pm = _powers(b, m)
    Q = (Pm[:, :m] @ Cb).reshape(b.size, B, k)
    W = _powers(Pm[:, m], B - 1)
    return np.einsum("nb,nbk->nk", W, Q)


def _newton_corrections(CC, rnd, z):
    """Newton corrections ``p(z)/p'(z)``, inclusion radii and a "residual at rounding level" flag.

    ``CC`` holds, in four columns, the coefficients (ascending), their reversal and the derivative
    coefficients of both (``k·c_k`` shifted down by one, zero last row), blocked by :func:`_blocked`
    (``CC[0]``), the moduli of the first two blocked likewise (``CC[1]``, for the rounding bound)
    and the degree (``CC[2]``).  For ``|z| <= 1`` the polynomial is evaluated in powers of ``z``;
    outside the unit circle in powers of ``w = 1/z`` through the reversed polynomial
    ``q(w) = w^n p(1/w)`` (``p/p' = z q / (n q − w q')``), so no power exceeds one in modulus.  The disc ``|ζ − z| ≤ n (|p(z)| + e) / |p'(z)|`` contains a root
    of every polynomial within the rounding error ``e`` of the evaluation (Henrici 1974, Thm 6.4e);
    ``rnd`` is a bound of ``e``.
    """
    Cb, Cabs, n = CC
    az = np.abs(z)
    inside = az <= 1.0
    if inside.all():
        V = _evaluate(z, Cb, 4)
        val, den = V[:, 0], V[:, 2]
        num, b, scl = val, z, 1.0
    else:
        b = np.where(inside, z, 1.0 / np.where(inside, 1.0, z))
        V = _evaluate(b, Cb, 4)
        val = np.where(inside, V[:, 0], V[:, 1])
        den = np.where(inside, V[:, 2], n * V[:, 1] - b * V[:, 3])
        num = np.where(inside, val, z * val)
        scl = np.where(inside, 1.0, az)
    aval = np.abs(val)
    N = num / den                                      # (floating-point errors are silenced by the caller)
    aden = np.abs(den)
    rad = n * (aval + rnd) * scl / aden
    at_round = aval <= rnd
    if at_round.any():
        # sharper rounding bound 4(n+1) eps sum |c_k| |b|^k for the candidates only (also in their radius)
        B = _evaluate(np.abs(b[at_round]), Cabs, 2)
        ins = inside[at_round]
        e = 4 * (n + 1) * _EPS * np.where(ins, B[:, 0], B[:, 1])
        rad[at_round] = n * (aval[at_round] + e) * np.where(ins, 1.0, az[at_round]) / aden[at_round]
        at_round[at_round] = aval[at_round] <= e
    return N, rad, at_round


def _aberth_step(z, upd, N):
    """Aberth corrections ``N_i/(1 − N_i S_i)`` of the roots ``upd`` and ``|S_i|``, ``S_i = Σ_{j≠i} 1/(z_i − z_j)``.

    ``S`` only shapes the step (the fixed point ``p(z_i) = 0`` is set by ``N`` in double precision), so
    it is summed in single precision: twice the throughput, and an error of 1e-7·|S| changes a step
    near convergence by ~1e-7·|N|²|S|.
    """
    zr = z.real.astype(np.float32)
    zi = z.imag.astype(np.float32)
    dr = np.subtract.outer(zr[upd], zr)
    di = np.subtract.outer(zi[upd], zi)
    r2 = dr * dr
    r2 += di * di
    r2[np.arange(upd.size), upd] = np.inf                    # no self term
    np.reciprocal(r2, out=r2)                                 # 1/(z_i − z_j) = conj(z_i − z_j)/|z_i − z_j|²
    dr *= r2
    di *= r2
    S = dr.sum(axis=1).astype(float) - 1j * di.sum(axis=1).astype(float)
    return N / (1.0 - N * S), np.abs(S)


def _aberth_loop(z, CC, rnd, n, tol, max_iter, active, rad):
    """The iteration of :func:`aberth_roots` (updates ``z``, ``active``, ``rad`` in place; ``None`` on overflow)."""
    n_prev = np.full(n, np.inf)                           # |Newton correction| at the previous visit
    s_prev = np.full(n, np.inf)                           # |Σ_j 1/(z_i − z_j)| at the last Aberth step
    for _ in range(int(max_iter)):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        zi = z[idx]
        N, r, at_round = _newton_corrections(CC, rnd, zi)
        scale = np.maximum(np.abs(zi), 1.0)
        aN = np.abs(N)
        # converged: small inclusion radius, or residual at the rounding level and no longer shrinking
        done = (r <= tol * scale) | (at_round & (aN >= 0.5 * n_prev[idx]))
        n_prev[idx] = aN
        rad[idx[done]] = r[done]
        active[idx[done]] = False
        keep = ~done
        upd = idx[keep]
        if upd.size == 0:
            break
        Nk = N[keep]
        # near convergence the Aberth factor 1/(1 − N S) is 1 to within |N S|: a Newton step costs
        # O(n) instead of O(n²) and keeps the quadratic convergence (S from this root's last visit;
        # Newton has no repulsion, so only when |N S| is tiny: at 1e-3 two approximations could
        # settle on one root, which the disc test then rejects)
        newton = np.abs(Nk * s_prev[upd]) < 1e-5
        W = Nk.copy()
        ab = ~newton
        if ab.any():
            W[ab], s_prev[upd[ab]] = _aberth_step(z, upd[ab], Nk[ab])
        z[upd] -= W
        if not np.isfinite(z[upd]).all():
            return None
        small = np.abs(W) <= 1e-8 * scale[keep]
        rad[upd[small]] = r[keep][small] + np.abs(W[small])
        active[upd[small]] = False
    return z


def aberth_roots(coeffs, start, *, max_iter: int = 50, tol: float = 1e-12):
    """Roots of a polynomial by Aberth–Ehrlich iteration from the starting points ``start``, certified.

    ``coeffs`` are the coefficients in ascending powers (``coeffs[-1] != 0``), ``start`` one
    starting point per root (distinct).  All roots are iterated simultaneously,

        z_i ← z_i − N_i / (1 − N_i Σ_{j≠i} 1/(z_i − z_j)),   N_i = p(z_i)/p'(z_i)

    (Aberth 1973; Bini 1996, "Numerical computation of polynomial zeros by means of Aberth's
    method"), and a root stops (is frozen) when its Newton inclusion radius falls below
    ``tol·max(1, |z_i|)`` or its residual has reached the rounding level of the evaluation and
    stopped shrinking; a root whose correction is already below ``1e-8·max(1, |z_i|)`` is frozen
    after that update (the iteration converges cubically, so it is then at rounding level; its
    radius is widened by the step).  Once ``|N_i S_i| < 1e-5`` the step is Newton's (the sum
    ``S_i`` only matters far from convergence).  Real starting points of a real polynomial stay
    real (and conjugate pairs stay pairs) under the iteration, so real and complex roots cannot
    trade places: callers break the symmetry of their starting points (see
    :func:`denominator_roots`).

    Returns ``(z, radius)``: every disc ``|ζ − z_i| ≤ radius_i`` holds a root; the result is
    returned only when these discs are pairwise disjoint, which proves that each holds exactly
    one root and that all ``n`` roots were found.  Returns ``None`` when the iteration does not
    converge in ``max_iter`` steps, produces non-finite values or the discs overlap (multiple or
    very close roots): the caller then falls back to the companion eigenvalues.
    """
    a = np.asarray(coeffs)
    n = a.size - 1
    z = np.array(start, dtype=complex).ravel()
    if n < 1 or z.size != n or not np.isfinite(a).all() or a[-1] == 0 or not np.isfinite(z).all():
        return None
    a = a / a[-1]
    C = np.stack([a, a[::-1]], axis=1)
    CC = np.zeros((n + 1, 4))
    CC[:, :2] = C
    CC[:-1, 2:] = np.arange(1, n + 1)[:, None] * C[1:]
    CC = (_blocked(CC), _blocked(np.abs(C)), n)
    rnd = 4 * (n + 1) * _EPS * np.abs(a).sum()          # |b| <= 1: a bound of the evaluation error
    active = np.ones(n, bool)
    rad = np.full(n, np.inf)
    with np.errstate(all="ignore"):
        z = _aberth_loop(z, CC, rnd, n, tol, max_iter, active, rad)
        if z is None or active.any() or not _discs_disjoint(z, rad):
            return None
    return z, rad


def _discs_disjoint(z, rad) -> bool:
    """``r_i + r_j < |z_i − z_j|`` for every pair, via ``r_i`` < half the nearest-neighbour distance.

    Distances in single precision, less the error of rounding the roots to it (``|δz| <= 2^-24 |z|`` per part).
    """
    zr = z.real.astype(np.float32)
    zi = z.imag.astype(np.float32)
    d2 = np.square(np.subtract.outer(zr, zr))
    d2 += np.square(np.subtract.outer(zi, zi))
    np.fill_diagonal(d2, np.inf)
    nn = np.sqrt(d2.min(axis=1).astype(float)) * (1 - 1e-6) - 4e-7 * np.abs(z).max()
    return bool(np.all(rad < 0.5 * nn))


def _companion_roots(a: np.ndarray) -> np.ndarray:
    """Eigenvalues of the companion matrix of the monic polynomial with ascending coefficients ``a``."""
    n = a.size - 1
    comp = np.zeros((n, n))
    if n > 1:
        comp[np.arange(n - 1), np.arange(1, n)] = 1.0
    comp[-1, :] = -a[:-1] / a[-1]
    return np.linalg.eigvals(comp)


def denominator_roots(coeffs, start=None):
    """Roots of a real polynomial (ascending coefficients), tracked from ``start`` when possible.

    With ``start`` (the roots of a nearby polynomial, e.g. the previous model order) and degree
    at least 76 (below, the eigenvalues cost less than the iteration), the roots are found by
    :func:`aberth_roots` from ``start`` plus one new starting point in each of the widest
    angular gaps for every extra root; the starting points are rotated
    by 1e-4 rad so that real roots may become complex pairs and back (and roots whose inclusion
    disc reaches the real axis are returned exactly real).  Otherwise, or when the
    iteration cannot certify all roots, the eigenvalues of the companion matrix are used.

    Returns ``(z, method)`` with ``method`` ``'tracked'`` or ``'eigvals'``.
    """
    a = np.asarray(coeffs, dtype=float)
    n = a.size - 1
    if start is not None and n >= _TRACK_MIN_DEGREE:
        z0 = np.asarray(start, complex).ravel()
        z0 = z0[np.isfinite(z0)]
        k = n - z0.size
        if 0 <= k <= _TRACK_MAX_NEW and z0.size:
            if k:
                ang = np.sort(np.angle(z0))
                gaps = np.diff(np.append(ang, ang[0] + 2 * np.pi))
                g = np.argsort(-gaps, kind="stable")[:k]
                rad0 = float(np.median(np.abs(z0))) or 1.0
                new = rad0 * np.exp(1j * (ang[g] + gaps[g] * (0.5 + 0.1 * np.arange(g.size) / max(g.size, 1))))
                z0 = np.concatenate([z0, new])
            out = aberth_roots(a, z0 * np.exp(1e-4j))
            if out is not None:
                z, rad = out
                # a real polynomial: a root whose disc reaches the real axis is real (its conjugate would
                # be a second root in the disc); exactly real like the eigenvalues, so that ln z of a
                # negative real root lands on +iπ/Δt and a positive one on the real axis
                real = np.abs(z.imag) <= rad
                z[real] = z[real].real
                return z, "tracked"
            log.debug("root tracking failed at degree %d; companion eigenvalues instead", n)
    return _companion_roots(a), "eigvals"


def _denominator(M: np.ndarray, order: int, n_in: int, chol=None) -> np.ndarray:
    """``α_0..α_{n-1}`` (stacked, ``(n·n_in, n_in)``) of the model of ``order`` with ``α_n = I``.

    ``α = −A11⁻¹ A12`` with ``A11``, ``A12`` the leading blocks of ``M``.  With ``chol``, the lower
    Cholesky factor ``L`` of ``M`` (or of a larger leading block), ``A11 = L_kk L_kkᵀ`` and
    ``A12 = L_kk L_ckᵀ``, so ``α = −L_kk⁻ᵀ L_ckᵀ``: one triangular solve per order instead of a
    factorisation.
    """
    n = int(order)
    if n < 1:
        raise ModalabValueError(f"model order {order} < 1; orders start at 1")
    c = (n + 1) * n_in
    if c > M.shape[0]:
        raise ModalabValueError(f"order {order} needs a reduced matrix of size {c}; got {M.shape[0]}. "
                                "Build M for at least this order")
    k = n * n_in
    if chol is not None and chol.shape[0] >= c:
        from scipy.linalg import solve_triangular

        return -solve_triangular(chol[:k, :k], chol[k:c, :k].T, trans="T", lower=True, check_finite=False)
    Mn = M[:c, :c]
    A11, A12 = Mn[:k, :k], Mn[:k, k:c]
    try:
        return np.linalg.solve(A11, -A12)                           # (k, n_in)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A11, -A12, rcond=None)[0]


def _cholesky(M: np.ndarray):
    """Lower Cholesky factor of ``M``, or ``None`` when ``M`` is not numerically positive definite."""
    try:
        L = np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        return None
    d = np.abs(np.diag(L))
    # a pivot at the rounding level of the largest one: the factor would amplify noise, solve instead
    return L if d.size and d.min() > 1e-7 * d.max() else None


def _roots_at_order(M: np.ndarray, order: int, n_in: int, start=None, chol=None):
    """All roots ``z`` of the denominator of ``order``, participation vectors and the root method."""
    n = int(order)
    alpha = _denominator(M, n, n_in, chol)
    k = n * n_in
    if n_in == 1:
        z, method = denominator_roots(np.append(alpha[:, 0], 1.0), start)
        L = np.ones((1, z.size), complex)
    else:
        comp = np.zeros((k, k))
        if n > 1:
            comp[: k - n_in, n_in:] = np.eye(k - n_in)
        comp[k - n_in:, :] = -np.hstack([alpha[r * n_in:(r + 1) * n_in] for r in range(n)])
        z = np.linalg.eigvals(comp)
        method = "eigvals"
        L = _participation(alpha, n, n_in, z)
    return z, L, method


def _to_poles(z: np.ndarray, L: np.ndarray, dt: float):
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.log(z.astype(complex)) / dt
    ok = np.isfinite(lam)
    return lam[ok], L[:, ok]


def poles_at_order(M: np.ndarray, order: int, n_in: int, dt: float, *, start=None):
    """Poles and participation vectors of the model of ``order`` from the reduced matrix ``M``.

    Uses the leading ``(order+1)·n_in`` block of ``M`` (built for a higher
    order) with the constraint ``α_order = I``.  The poles are the eigenvalues of the block
    companion matrix; with one reference and ``start`` (the z-domain roots ``exp(λ Δt)`` of a
    nearby order) the roots of the scalar denominator are tracked from ``start`` instead
    (:func:`denominator_roots`, certified, falls back to the eigenvalues).

    Returns
    -------
    lam : (n_roots,) complex continuous-time poles ``ln(z)/Δt`` in rad/s, all
        ``order·n_in`` roots (both half-planes, real roots included).
    L : (n_in, n_roots) complex participation vectors (unit norm).
    """
    z, L, _ = _roots_at_order(M, order, n_in, start)
    return _to_poles(z, L, dt)


_SVD_MAX_IN = 8            # up to this many references the null vectors come from a batched SVD
_CHUNK_BYTES = 32 * 2 ** 20   # bound of the (poles, n_in, n_in) work arrays


def duplicate_shapes(freq_hz, psi, cluster_size, distance: float, mac_min: float) -> np.ndarray:
    """True for automatic picks that repeat a nearby pick's shape: within ``distance`` in relative frequency
    and shape MAC >= ``mac_min`` of a pick with a larger cluster (ties: the lower frequency stays)."""

    f = np.asarray(freq_hz, float)
    m = f.size
    dup = np.zeros(m, bool)
    if m < 2:
        return dup
    mac = mac_vectors(psi, psi)
    rank = np.lexsort((f, -np.asarray(cluster_size)))             # larger clusters first, then lower frequency
    for a in rank:
        if dup[a]:
            continue
        near = (np.abs(f - f[a]) < distance * f[a]) & (mac[a] >= mac_min) & ~dup
        near[a] = False
        if near.any():
            log.info("automatic selection: %d pick(s) near %.4g Hz repeat its shape (MAC >= %g): one mode",
                     int(near.sum()), f[a], mac_min)
        dup |= near
    return dup


def combined_std(unc: dict, selected) -> dict:
    """Standard deviations of frequency and damping: FRF noise plus the spread of the pole over orders.

    ``σ² = σ_noise² + s²/n``: ``σ_noise`` from :func:`~identification.lsfd.pole_uncertainty` (the variance
    of the FRF across averages — from ``FRF.variance`` or coherence — propagated to the refined pole), ``s``
    the standard deviation of the mode's stable poles over the upper third of its orders and ``n`` their
    number (:func:`~identification.selection.order_spread`): the standard error of the estimate over the
    model orders, which the noise model does not see (model-order and local-model error, a neighbour's
    leakage).  Treating the orders as independent is an approximation; the coverage of the total is tested
    on synthetic data with known noise (``tests/identification/test_uncertainty_coverage.py``).  A mode
    without an order spread (fewer than two poles) keeps the noise term alone.

    Returns the indicators ``freq_std_hz``, ``damping_std`` (total), ``freq_std_noise_hz``,
    ``damping_std_noise``, ``freq_std_orders_hz``, ``damping_std_orders`` and ``chi2_ratio``.
    """
    n = np.maximum(np.asarray(selected.n_spread, float), 1.0)
    fo = np.where(np.isfinite(selected.freq_spread_hz), selected.freq_spread_hz / np.sqrt(n), 0.0)
    zo = np.where(np.isfinite(selected.damping_spread), selected.damping_spread / np.sqrt(n), 0.0)
    fnz, znz = np.asarray(unc["freq_std_hz"], float), np.asarray(unc["damping_std"], float)
    return {"freq_std_hz": np.hypot(fnz, fo), "damping_std": np.hypot(znz, zo),
            "freq_std_noise_hz": fnz, "damping_std_noise": znz,
            "freq_std_orders_hz": fo, "damping_std_orders": zo, "chi2_ratio": np.asarray(unc["chi2_ratio"])}


def _participation(alpha: np.ndarray, n: int, n_in: int, z: np.ndarray) -> np.ndarray:
    """Left null vectors of the denominator at the poles, unit norm, largest entry real > 0.

    ``H_o = N_o A(z)⁻¹`` and ``A⁻¹ ≈ v wᵀ / (z − z_r)`` near a pole (``A v = 0``, ``wᵀA = 0``), so the
    residue of every output is ∝ ``wᵀ``: the participation vector is the LEFT null vector of ``A(z_r)``.
    With few references it is the last left singular vector (batched SVD); with many (a roving-hammer
    matrix identified as measured, n_in ≫ n_out) two steps of inverse iteration, ``Aᵀ w ← b``, give it
    for ``O(n_in³/3)`` per pole instead of a full SVD, in chunks of poles so memory stays bounded.
    """
    blocks = [alpha[r * n_in:(r + 1) * n_in] for r in range(n)] + [np.eye(n_in)]
    L = np.empty((n_in, z.size), complex)
    chunk = max(1, int(_CHUNK_BYTES // (16 * n_in * n_in)))
    b0 = np.exp(1j * np.arange(n_in))[None, :, None] / np.sqrt(n_in)      # fixed start: deterministic
    for c0 in range(0, z.size, chunk):
        zc = z[c0:c0 + chunk]
        # A(z) = Σ z^r α_r evaluated by Horner for the chunk's poles at once: (m, n_in, n_in)
        Az = np.broadcast_to(blocks[-1], (zc.size, n_in, n_in)).astype(complex)
        for r in range(n - 1, -1, -1):
            Az = Az * zc[:, None, None] + blocks[r][None]
        if n_in <= _SVD_MAX_IN:
            U, _, _ = np.linalg.svd(Az)
            L[:, c0:c0 + zc.size] = U[:, :, -1].conj().T
            continue
        At = np.swapaxes(Az, 1, 2)
        try:
            w = np.linalg.solve(At, np.broadcast_to(b0, (zc.size, n_in, 1)))
            w /= np.linalg.norm(w, axis=1, keepdims=True)
            w = np.linalg.solve(At, w)
        except np.linalg.LinAlgError:
            # A(z) exactly singular in floating point for some pole: its null vector by SVD (exact here)
            U, _, _ = np.linalg.svd(Az)
            L[:, c0:c0 + zc.size] = U[:, :, -1].conj().T
            continue
        L[:, c0:c0 + zc.size] = w[:, :, 0].T
    return _normalise_vectors(L)


def _normalise_vectors(L: np.ndarray) -> np.ndarray:
    nrm = np.linalg.norm(L, axis=0)
    nrm[nrm == 0] = 1.0
    L = L / nrm
    k = np.argmax(np.abs(L), axis=0)
    ph = L[k, np.arange(L.shape[1])]
    ph = np.where(np.abs(ph) > 0, ph / np.abs(ph), 1.0)
    return L / ph[None, :]


# --------------------------------------------------------------------------- estimator
def _keep_consistent_refinement(lam_diagram, lam_refined, max_change: float) -> np.ndarray:
    """The refined poles, except where the local refinement left the stabilisation diagram's estimate: a damping
    ratio changed by more than the factor ``max_change`` (either way) or a frequency moved by more than one
    half-power half-bandwidth (``ζ·f`` of the diagram's pole).  There the diagram's pole, stable over many
    orders, is kept: a local single-pole fit over several close modes merged into one pick converges to a
    compromise (the issue 14 data: 314.35 Hz with ζ 1.07 %, stable over 25 orders, refined to 311.5 Hz with
    ζ 4.4 % where three modes lie at 313.3-314.5 Hz)."""
    lam_d = np.asarray(lam_diagram, complex)
    lam_r = np.array(lam_refined, complex)
    if lam_d.size != lam_r.size or not lam_d.size:
        return lam_r
    fd, zd = pole_freq_damping(lam_d)
    fr, zr = pole_freq_damping(lam_r)
    ratio = zr / np.maximum(zd, 1e-12)
    off = (ratio > max_change) | (ratio < 1.0 / max_change) | (np.abs(fr - fd) > zd * fd)
    for k in np.flatnonzero(off):
        log.info("refinement of %.5g Hz (zeta %.3g %%) to %.5g Hz (zeta %.3g %%) left the stabilisation diagram's "
                 "estimate: the diagram's pole is kept", fd[k], 100 * zd[k], fr[k], 100 * zr[k])
    lam_r[off] = lam_d[off]
    return lam_r


class PolyMAX:
    """Poly-reference LSCF (PolyMAX-style) modal parameter estimator.

    Parameters (stored only; :meth:`fit` does the work)
    ----------
    max_order : int
        Highest polynomial order ``p``; order ``n`` yields ``n·n_in`` poles.
    min_order, order_step : int
        Orders evaluated: ``min_order, min_order+step, ..., max_order``.
    weighting : None, 'coherence' or 'variance'
        Frequency weighting (:func:`frequency_weights`).
    band_hz : (lo, hi) or None
        Frequency band used; the whole FRF by default.
    criteria : :class:`~identification.stabilisation.StabilisationCriteria` or None (defaults).
    select : 'auto', a sequence of frequencies in Hz, or a path to a JSON/TOML selection file.
    selection : :class:`~identification.selection.SelectionOptions` or None (defaults).
    lower_residual, upper_residual : bool
        Residual terms in LSFD.
    refine : bool
        Refine each selected pole by variable-projection least squares on the lines around it
        (:func:`~identification.lsfd.refine_poles`) before the final LSFD.
    refine_max_change : float
        An automatic pick whose refinement changes the damping ratio by more than this factor, or moves the
        frequency by more than a half-power half-bandwidth, keeps the stabilisation diagram's pole (a merge of
        close modes makes the local single-pole fit drift; default 2).
    window_correction : bool
        Remove the exponential window's decay ``frf.window_beta_per_s`` (1/s) from the poles
        (:func:`acquisition.windows.correct_poles`).
    uncertainty : bool
        Standard deviations of the refined frequencies and damping ratios in ``modes_.indicators``:
        ``freq_std_hz``, ``damping_std`` — FRF noise (:func:`~identification.lsfd.pole_uncertainty`,
        first order, one Jacobian per mode) combined with the spread of the pole over the stable orders
        (:func:`combined_std`) —, their parts ``*_noise``/``*_orders`` and ``chi2_ratio``; the noise model
        used is ``modes_.metadata['pole_std_source']``.  NaN with ``refine=False`` (the std describes
        the refined estimate).

    Fitted attributes
    -----------------
    orders_ : (n_orders,) int — the model order of each row of the stabilisation data.
    poles_ : list of (n_k,) complex — upper-half-plane poles (rad/s) of each order, as estimated
        (before window correction).
    participation_ : list of (n_in, n_k) complex — participation vectors of those poles.
    stabilisation_ : :class:`~identification.stabilisation.StabilisationDiagram`.
    selected_ : :class:`~identification.selection.SelectedPoles` (measured poles, linear pLSCF estimates).
    refined_poles_ : (n_modes,) complex — the selected poles after refinement (equal to
        ``selected_.lam`` with ``refine=False``), before window correction.
    lsfd_ : :class:`~identification.lsfd.LSFDResult`.
    modes_ : :class:`modalab.ModeSet` — window-corrected, scaled modes with indicators.
    frf_ : the FRF actually used (band, references), ``dt_`` the z-domain sampling time.
    reduced_matrix_shape_ : shape of the reduced normal matrix (memory diagnostic).
    root_methods_ : dict — how many orders had their roots tracked from the previous order
        (one reference, :func:`denominator_roots`) and how many took companion eigenvalues.

    Example
    -------
    >>> pm = PolyMAX(max_order=40).fit(frf)          # doctest: +SKIP
    >>> pm.modes_.freq_hz, pm.modes_.damping         # doctest: +SKIP
    """

    def __init__(self, max_order: int = 64, *, min_order: int = 1, order_step: int = 1, weighting=None,
                 band_hz=None, criteria=None, select="auto", selection=None, lower_residual: bool = True,
                 upper_residual: bool = True, window_correction: bool = True, refine: bool = True,
                 uncertainty: bool = True, refine_max_change: float = 2.0):
        self.max_order = max_order
        self.min_order = min_order
        self.order_step = order_step
        self.weighting = weighting
        self.band_hz = band_hz
        self.criteria = criteria
        self.select = select
        self.selection = selection
        self.lower_residual = lower_residual
        self.upper_residual = upper_residual
        self.window_correction = window_correction
        self.refine = refine
        self.refine_max_change = refine_max_change
        self.uncertainty = uncertainty

    # ------------------------------------------------------------------ helpers
    def _check_params(self, frf):
        if not isinstance(frf, FRF):
            raise ModalabValueError(fmt_error("frf", type(frf).__name__, "a modalab.FRF",
                                              "Build one with FRF.from_arrays or FRF.from_uff"))
        for name in ("max_order", "min_order", "order_step"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
                raise ModalabValueError(fmt_error(name, v, "a positive integer", "e.g. max_order=64"))
        if self.min_order > self.max_order:
            raise ModalabValueError(f"min_order={self.min_order} > max_order={self.max_order}; "
                                    "give min_order <= max_order")
        if self.weighting not in _WEIGHTINGS:
            raise ModalabValueError(fmt_error("weighting", self.weighting, "None, 'coherence' or 'variance'",
                                              "Use None for unit weights"))

    @staticmethod
    def prepare(frf: FRF, band_hz=None) -> FRF:
        """Band-limit and drop lines at 0 Hz or with non-finite data (coherence and variance with them)."""
        f = frf if band_hz is None else frf.band(*band_hz)
        good = (f.freq_hz > 0) & np.all(np.isfinite(f.H), axis=(0, 1))
        if not good.all():
            f = f.lines(good)
        return f

    # ------------------------------------------------------------------ fit
    def fit(self, frf: FRF) -> "PolyMAX":
        """Estimate poles for every order, stabilise, select, and fit shapes by LSFD."""

        self._check_params(frf)
        data = self.prepare(frf, self.band_hz)
        n_out, n_in, nf = data.shape
        p = int(self.max_order)
        if nf < 2 * p // max(n_in, 1) + 2:
            log.warning("only %d lines for order %d: the problem is barely over-determined", nf, p)
        if nf < p + 2:
            raise ModalabValueError(f"{nf} frequency lines cannot support max_order={p}; "
                                    f"use max_order <= {max(nf - 2, 1)} or a wider band")
        fmax = float(data.freq_hz[-1])
        dt = 1.0 / (2.0 * fmax)
        theta = 2 * np.pi * data.freq_hz * dt
        w = frequency_weights(data, self.weighting)
        M = reduced_normal_matrix(data.H, w, theta, p)
        orders = np.arange(self.min_order, p + 1, self.order_step)
        poles, parts = [], []
        methods = {"tracked": 0, "eigvals": 0}
        z = None
        chol = _cholesky(M)
        for n in orders:
            z, L, how = _roots_at_order(M, int(n), n_in, start=z, chol=chol)
            methods[how] += 1
            lam, L = _to_poles(z, L, dt)
            up = lam.imag > 0
            lam, L = lam[up], L[:, up]
            o = np.argsort(lam.imag)
            poles.append(lam[o])
            parts.append(L[:, o])
        crit = self.criteria if self.criteria is not None else StabilisationCriteria()
        self.frf_ = data
        self.dt_ = dt
        self.reduced_matrix_shape_ = M.shape
        self.root_methods_ = methods
        self.orders_ = orders
        self.poles_ = poles
        self.participation_ = parts
        self.stabilisation_ = stabilise(orders, poles, parts, crit)
        opts = self.selection if self.selection is not None else SelectionOptions()
        band = (float(data.freq_hz[0]), fmax)
        self.selected_ = select_poles(self.stabilisation_, self.select, opts, band_hz=band)
        lam_sel = self.selected_.lam
        if self.refine and lam_sel.size:
            lam_sel = refine_poles(data, lam_sel, self.selected_.participation,
                                   lower_residual=self.lower_residual, upper_residual=self.upper_residual)
        if self.refine and lam_sel.size and self.selected_.source == "auto":
            # refinement can expose a spurious pole: it runs off to unphysical damping
            _, z_ref = pole_freq_damping(lam_sel)
            ok = (z_ref > 0) & (z_ref <= opts.max_damping)
            if not ok.all():
                log.info("refinement rejected %d pole(s) with damping outside (0, %g]", int((~ok).sum()),
                         opts.max_damping)
                sp = self.selected_
                self.selected_ = sp.subset(ok)
                lam_sel = lam_sel[ok]
            lam_sel = _keep_consistent_refinement(self.selected_.lam, lam_sel, self.refine_max_change)
        self.refined_poles_ = lam_sel
        beta = float(data.window_beta_per_s) if self.window_correction else 0.0
        if self.selected_.source == "auto" and opts.min_mpc > 0 and lam_sel.size:
            # noise modes fitted by LSFD have scattered phases: drop automatic picks with a low MPC
            # (MPC is invariant to the complex scaling of a shape: taken on the raw LSFD shapes ψ)
            psi = lsfd(data, lam_sel, self.selected_.participation, lower_residual=self.lower_residual,
                       upper_residual=self.upper_residual).psi
            ok = ~(mpc(psi) < opts.min_mpc)
            # one mode picked twice (two near clusters kept because they coexist at some orders): their
            # shapes agree; a close pair has distinct shapes (MAC between candidate shapes)
            ok &= ~duplicate_shapes(pole_freq_damping(lam_sel)[0], psi, self.selected_.cluster_size,
                                    opts.distance, opts.same_mode_mac)
            if not ok.all():
                log.info("dropped %d automatic pick(s): MPC < %g (noise) or a repeated shape", int((~ok).sum()),
                         opts.min_mpc)
                sp = self.selected_
                self.selected_ = sp.subset(ok)
                lam_sel = lam_sel[ok]
                self.refined_poles_ = lam_sel
        extra = {"cluster_size": self.selected_.cluster_size, "order": self.selected_.order}
        std_source = None
        if self.uncertainty:
            if self.refine:
                unc = pole_uncertainty(data, lam_sel, self.selected_.participation, window_beta=beta)
                std_source = unc["source"]
            else:
                unc = {k: np.full(lam_sel.size, np.nan) for k in ("freq_std_hz", "damping_std", "chi2_ratio")}
                std_source = "not computed (refine=False)"
            extra.update(combined_std(unc, self.selected_))
        self.modes_, self.lsfd_ = modes_from_poles(
            data, lam_sel, self.selected_.participation, lower_residual=self.lower_residual,
            upper_residual=self.upper_residual, window_beta=beta, extra_indicators=extra)
        self.modes_.metadata.update({"method": "pLSCF (PolyMAX-style) + LSFD", "max_order": p,
                                     "band_hz": list(band), "window_beta_per_s": beta,
                                     "weighting": self.weighting or "none"})
        if std_source is not None:
            self.modes_.metadata["pole_std_source"] = std_source
        log.info("PolyMAX: %d outputs x %d references x %d lines, orders %d..%d, %d modes",
                 n_out, n_in, nf, orders[0], orders[-1], self.modes_.n_modes)
        return self

    def __getattr__(self, name):
        if name.endswith("_") and not name.startswith("__"):
            raise NotFittedError(f"PolyMAX.{name} is not available: call fit(frf) first")
        raise AttributeError(name)

    def synthesise(self, freq_hz=None) -> FRF:
        """FRFs synthesised from the fitted modal model (measured poles and residuals)."""
        res = self.lsfd_
        return res.synthesise(self.frf_ if freq_hz is None else np.asarray(freq_hz, float))
