"""PolyMAX numerics, part 1: the frequency weights and the reduced normal matrix ``M`` of the pLSCF
least-squares problem (Peeters 2004, eq. 6), built once for the highest order from Toeplitz lag sums.

Split out of :mod:`identification.polymax` (which re-exports these names); the model is described there.
"""

from __future__ import annotations

import numpy as np
from modalab.core.errors import ModalabValueError, fmt_error
from modalab.core.frf import FRF
from .polymax_roots import _powers


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
def _lag_sums(H: np.ndarray, a: np.ndarray, theta: np.ndarray, p: int):
    """The lag sums of :func:`reduced_normal_matrix` for lags d = 0..p, accumulated over chunks of lines so that
    memory does not scale with n_freq x order: ``rho_c`` (n_out, p+1), ``sig_c``, ``sig_s`` (n_out·n_in, p+1)
    and ``tau_pos`` (n_in, n_in, p+1).

    Only real parts enter R, S, T, so with C_kd = cos(θ_k d), S_kd = sin(θ_k d), d = 0..p:
    Re rho_o(±d) = Σ_k a C,  Re sigma_oj(±d) = Σ_k a (Re H_oj C ∓ Im H_oj S),
    Re tau_ij(d) = Σ_k (Re G_ij C − Im G_ij S),  G_ij = Σ_o a conj(H_oi) H_oj,  tau_ij(−d) = conj tau_ji(d)."""
    n_out, n_in, nf = H.shape
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
    return rho_c, sig_c, sig_s, tau_pos.reshape(n_in, n_in, p + 1)


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
    rho_c, sig_c, sig_s, tau_pos = _lag_sums(H, a, theta, p)
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
