"""PolyMAX numerics, part 2: from the reduced normal matrix to poles at one model order.

The denominator coefficients from ``M`` (constraint ``alpha_n = I``, one Cholesky factor for all orders),
the roots of the denominator (block companion eigenvalues, or for one reference and high degree the
certified Aberth-Ehrlich tracking of :func:`denominator_roots`), the participation vectors (left null vectors of the denominator), and the
conversion of z-domain roots to continuous-time poles.

Split out of :mod:`identification.polymax` (which re-exports these names); the model is described there.
"""

from __future__ import annotations

import logging
import numpy as np
from scipy.linalg import solve_triangular
from modalab.core.errors import ModalabValueError

log = logging.getLogger(__name__)


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
