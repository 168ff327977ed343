"""Dynamic stiffness, receptance solves and the dynamic expansion of measured responses.

The one implementation of the frequency-domain Kidder expansion (thesis eqs. 2.45–2.48 applied at
every line) and of the condensed residual it leaves — the negative of the MCI of thesis eq. (3.69)
— used by MCI and the response-function method (:mod:`updating.methods.mci`,
:mod:`updating.methods.rfm`) and by diagnosis (:mod:`updating.diagnosis.screen`).

All functions take the structural matrices of a model on its (constrained)
DOFs and complex Laplace variables ``s`` (``s = iω`` for harmonic motion;
``s = iω + β`` reproduces FRFs measured with an exponential window of decay
β: the windowed FRF equals the exact FRF with every pole shifted by β).

The dynamic stiffness is ``Z(s) = K + iD + sC + s²M`` (hysteretic D kept as
``iD``).  Dense batched solves are used for models up to
:data:`modalab.core.dense.SOLVE_LIMIT` DOFs, an LU per line above (the rule and its
reasons: :mod:`modalab.core.dense`): LAPACK's banded LU in the reverse Cuthill-McKee order where the
half band is at most :data:`BAND_LIMIT` (beam frames), SuperLU where it is wider.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg.lapack import zgbsv as _zgbsv, zgbtrf as _zgbtrf, zgbtrs as _zgbtrs
from scipy.sparse.csgraph import reverse_cuthill_mckee

from modalab.core.dense import use_dense

log = logging.getLogger(__name__)

#: the widest half band (after the reverse Cuthill-McKee ordering) solved by LAPACK's banded LU per line
#: (:meth:`_Pattern.factor`); wider ones by SuperLU.  A banded LU costs ~n·b² per line, SuperLU's fill-reducing
#: ordering does better on wide bands (plates, solids) and worse on the beam frames diagnosis works on
BAND_LIMIT = 32

__all__ = ["dynamic_stiffness", "dynamic_stiffness_batch", "solve_columns", "condensed_residual"]


class _Pattern:
    """K, M, C, D on one union sparsity pattern (CSC), so that ``Z(s)`` is a vectorised sum of data arrays."""

    def __init__(self, K, M, C, D):
        n = K.shape[0]
        mats = [A for A in (K, M, C, D)]
        keys = []
        for A in mats:
            if A is None:
                keys.append(None)
                continue
            c = sp.coo_matrix(A)
            keys.append((c.col.astype(np.int64) * n + c.row, c.data))
        union = np.unique(np.concatenate([k[0] for k in keys if k is not None]))
        self.n = n
        self.indices = (union % n).astype(np.int32)
        self.indptr = np.searchsorted(union // n, np.arange(n + 1)).astype(np.int32)
        self.data = []
        for k in keys:
            if k is None:
                self.data.append(None)
                continue
            d = np.zeros(union.size, complex)
            np.add.at(d, np.searchsorted(union, k[0]), k[1])
            self.data.append(d)

        self._band = None

    def values(self, s) -> np.ndarray:
        """The data array of ``Z(s)`` on the union pattern."""
        dK, dM, dC, dD = self.data
        v = dK + (s * s) * dM
        if dC is not None:
            v = v + s * dC
        if dD is not None:
            v = v + 1j * dD
        return v

    def Z(self, s) -> sp.csc_matrix:
        return sp.csc_matrix((self.values(s), self.indices, self.indptr), shape=(self.n, self.n))

    def _banded(self):
        """``(permutation, half band width, flat positions of the pattern's values in LAPACK band storage)``
        after the reverse Cuthill-McKee ordering, or None when the band is wider than :data:`BAND_LIMIT`."""
        if self._band is None:
            cols = np.repeat(np.arange(self.n), np.diff(self.indptr))
            S = sp.csr_matrix((np.ones(self.indices.size), (self.indices, cols)), shape=(self.n, self.n))
            perm = reverse_cuthill_mckee((S + S.T).tocsr(), symmetric_mode=True).astype(np.int64)
            inv = np.empty(self.n, np.int64)
            inv[perm] = np.arange(self.n)
            i, j = inv[self.indices], inv[cols]
            b = int(np.max(np.abs(i - j))) if i.size else 0
            # zgbtrf's storage: A[i, j] at row 2b + i - j (the first b rows are the LU's fill), column j
            self._band = (perm, b, (2 * b + i - j) * self.n + j) if b <= BAND_LIMIT else False
        return self._band or None

    def _band_storage(self, s):
        """``(permutation, half band width, Z(s) in LAPACK band storage)`` for :meth:`factor` and :meth:`solve`,
        or None when the band is too wide."""
        band = self._banded()
        if band is None:
            return None
        perm, b, pos = band
        ab = np.zeros((3 * b + 1) * self.n, complex)
        ab[pos] = self.values(s)
        return perm, b, ab.reshape(3 * b + 1, self.n)

    def factor(self, s):
        """A factorisation of ``Z(s)`` with a ``solve(B)`` method: LAPACK's banded LU (zgbtrf) in the reverse
        Cuthill-McKee order when the band is narrow (a frame: half band width about 20), else SuperLU.  The
        same solution either way, to round-off; the banded one skips SuperLU's symbolic analysis and its
        Python overhead per line, which dominate on the few-hundred-DOF models diagnosis solves at every line.
        A line where the banded LU finds ``Z`` exactly singular is left to SuperLU, which says so as before."""
        band = self._band_storage(s)
        if band is not None:
            perm, b, ab = band
            lu, piv, info = _zgbtrf(ab, b, b)
            if info == 0:
                return _BandLU(lu, piv, b, perm)
        return spla.splu(self.Z(s))

    def solve(self, s, B) -> np.ndarray:
        """``Z(s)⁻¹ B``: :meth:`factor` and its ``solve`` in one LAPACK call (zgbsv) where the band is narrow —
        the same arithmetic, one Python call less per line, which is what the dynamic expansion's per-line loop
        spends most of its overhead on; else SuperLU as :meth:`factor`."""
        band = self._band_storage(s)
        if band is not None:
            perm, b, ab = band
            _, _, x, info = _zgbsv(b, b, ab, np.asarray(B, complex)[perm])
            if info == 0:
                return _unpermute(x, perm)
        return spla.splu(self.Z(s)).solve(np.asarray(B, complex))


class _BandLU:
    """A banded LU of a permuted ``Z`` (:meth:`_Pattern.factor`): ``solve(B)`` is ``Z⁻¹ B``."""

    def __init__(self, lu, piv, b, perm):
        self.lu, self.piv, self.b, self.perm = lu, piv, b, perm

    def solve(self, B):
        B = np.asarray(B, complex)
        x, info = _zgbtrs(self.lu, self.b, self.b, B[self.perm], self.piv)
        return _unpermute(x, self.perm)


def _unpermute(x, perm):
    """The solution in the original DOF order from one in the band's order (row ``k`` is DOF ``perm[k]``)."""
    out = np.empty_like(x)
    out[perm] = x
    return out


def _dense(A):
    return None if A is None else (A.toarray() if sp.issparse(A) else np.asarray(A))


def dynamic_stiffness(K, M, C, D, s):
    """``Z(s)`` for one complex ``s`` (sparse CSC, complex)."""
    Z = sp.csc_matrix(K, dtype=complex) + (s * s) * sp.csc_matrix(M)
    if C is not None:
        Z = Z + s * sp.csc_matrix(C)
    if D is not None:
        Z = Z + 1j * sp.csc_matrix(D)
    return sp.csc_matrix(Z)


def dynamic_stiffness_batch(K, M, C, D, s) -> np.ndarray:
    """``Z(s_f)`` for every ``s_f`` as one dense array (n_s, n, n) (small models, :data:`~modalab.core.dense.SOLVE_LIMIT`)."""
    return _Z_batch(_dense(K), _dense(M), _dense(C), _dense(D), np.atleast_1d(np.asarray(s, dtype=complex)))


def _solve_lines(Z, rhs, s):
    """``Z[f]⁻¹ rhs[f]`` for a batch of lines; a line where ``Z`` is exactly singular (a resonance of the
    model with the measured DOFs held) is solved in the least-squares sense and named in the log."""
    try:
        return np.linalg.solve(Z, rhs)
    except np.linalg.LinAlgError:
        out = np.empty((Z.shape[0], Z.shape[1], rhs.shape[2]), complex)
        bad = []
        for k in range(Z.shape[0]):
            try:
                out[k] = np.linalg.solve(Z[k], rhs[k])
            except np.linalg.LinAlgError:
                out[k] = np.linalg.lstsq(Z[k], rhs[k], rcond=None)[0]
                bad.append(k)
        log.warning("dynamic expansion: Z_ss is singular at %s Hz (a resonance of the model constrained at the "
                    "measured DOFs); least squares used there",
                    ", ".join(f"{abs(complex(s[k]).imag) / (2 * np.pi):.6g}" for k in bad))
        return out


def _Z_batch(Kd, Md, Cd, Dd, s):
    Z = Kd[None, :, :].astype(complex) + (s ** 2)[:, None, None] * Md[None]
    if Cd is not None:
        Z = Z + s[:, None, None] * Cd[None]
    if Dd is not None:
        Z = Z + 1j * Dd[None]
    return Z


def solve_columns(K, M, C, D, s, cols, chunk: int = 64) -> np.ndarray:
    """Receptance columns ``X[:, k, f] = Z(s_f)^{-1} e_{cols[k]}``, shape (n, len(cols), n_s)."""
    s = np.atleast_1d(np.asarray(s, dtype=complex))
    n = K.shape[0]
    cols = list(cols)
    out = np.empty((n, len(cols), s.size), complex)
    if use_dense(n, "solve"):
        Kd, Md, Cd, Dd = _dense(K), _dense(M), _dense(C), _dense(D)
        E = np.zeros((n, len(cols)))
        E[cols, np.arange(len(cols))] = 1.0
        for a in range(0, s.size, chunk):
            Z = _Z_batch(Kd, Md, Cd, Dd, s[a:a + chunk])
            X = np.linalg.solve(Z, np.broadcast_to(E, (Z.shape[0], n, len(cols))))
            out[:, :, a:a + chunk] = X.transpose(1, 2, 0)
        return out
    E = np.zeros((n, len(cols)), complex)
    E[cols, np.arange(len(cols))] = 1.0
    pat = _Pattern(K, M, C, D)
    for f, sf in enumerate(s):
        out[:, :, f] = pat.factor(sf).solve(E)
    return out


def condensed_residual(K, M, C, D, s, meas, x_meas, force, chunk: int = 32):
    """Dynamic (Kidder-type) expansion and the condensed force residual.

    For each line f and measurement vector q (columns of ``x_meas``,
    shape (n_meas, n_q, n_s)), unmeasured DOFs are expanded with the model:
    ``x_s = Z_ss^{-1}(f_s − Z_sm x_m)`` (thesis section 2.1.2.1 applied at
    each frequency), and the residual on the measured DOFs is
    ``r_m = Z_mm x_m + Z_ms x_s − f_m`` — the negative of the thesis' MCI,
    eq. (3.89) ``MCI_r(ω) = δ_ir − Z_r(ω)·θ_i(ω)``.

    Returns ``x_full`` (n, n_q, n_s), ``r_m`` (n_meas, n_q, n_s), the
    dynamic expansion matrices ``T`` (n, n_meas, n_s) with ``T[meas] = I`` and
    ``T[slave] = −Z_ss^{-1} Z_sm``: the first-order change of ``r_m`` caused by
    a change ΔZ of the model is ``−Tᵀ ΔZ x_full`` — which is how a candidate
    at an unmeasured DOF shows at the measured ones.

    ``sigma`` (n_q, n_s) is ‖|Z_red| |x_m|‖, the size of the residual that a
    unit relative error of the measurement would cause (used to weight lines).

    ``force`` is (n, n_q) (the unit force vectors; zero for mode shapes).
    """
    s = np.atleast_1d(np.asarray(s, dtype=complex))
    n = K.shape[0]
    meas = np.asarray(meas, int)
    slave = np.setdiff1d(np.arange(n), meas)
    nq = x_meas.shape[1]
    x_full = np.zeros((n, nq, s.size), complex)
    r = np.zeros((meas.size, nq, s.size), complex)
    T = np.zeros((n, meas.size, s.size), complex)
    T[meas, np.arange(meas.size), :] = 1.0
    sigma = np.zeros((nq, s.size))
    F = np.asarray(force, complex)
    if not use_dense(n, "solve"):
        return _condensed_sparse(K, M, C, D, s, meas, slave, x_meas, F, x_full, r, T, sigma)
    Kd, Md, Cd, Dd = _dense(K), _dense(M), _dense(C), _dense(D)
    for a in range(0, s.size, chunk):
        sl = s[a:a + chunk]
        Z = _Z_batch(Kd, Md, Cd, Dd, sl)
        Zss = Z[:, slave][:, :, slave]
        Zsm = Z[:, slave][:, :, meas]
        xm = x_meas[:, :, a:a + chunk].transpose(2, 0, 1)                  # (b, m, q)
        if slave.size:
            Fs = F[slave][None].repeat(len(sl), 0)
            rhs = np.concatenate([-Zsm, Fs], axis=2)
            sol = _solve_lines(Zss, rhs, sl)
            Tsm = sol[:, :, :meas.size]
            xsF = sol[:, :, meas.size:]
            xs = Tsm @ xm + xsF
            T[slave, :, a:a + chunk] = Tsm.transpose(1, 2, 0)
            # a force on an unmeasured DOF reaches the measured ones through Z_ss^-1: near the resonances of
            # the structure with its measured DOFs held, that path is unreliable, and the weights say so
            force_path = np.linalg.norm(np.abs(Z[:, meas][:, :, slave]) @ np.abs(xsF), axis=1).T
        else:
            xs = np.zeros((len(sl), 0, nq), complex)
            force_path = 0.0
        xf = np.zeros((len(sl), n, nq), complex)
        xf[:, meas] = xm
        xf[:, slave] = xs
        x_full[:, :, a:a + chunk] = xf.transpose(1, 2, 0)
        rr = (Z[:, meas] @ xf) - F[meas][None]
        r[:, :, a:a + chunk] = rr.transpose(1, 2, 0)
        Zred = Z[:, meas][:, :, meas]
        if slave.size:
            Zred = Zred + Z[:, meas][:, :, slave] @ Tsm
        sigma[:, a:a + chunk] = np.linalg.norm(np.abs(Zred) @ np.abs(xm), axis=1).T + force_path
    return x_full, r, T, sigma


class _Blocks:
    """The four blocks of K, M, C, D split into measured (m) and slave (s) DOFs, built once per call.

    ``Z_ss(s)`` is assembled on its own sparse pattern (a vectorised sum of data arrays); the thin blocks
    ``Z_sm``, ``Z_ms`` and ``Z_mm`` are dense (n × n_meas) sums.  Avoids slicing a sparse matrix per line.
    """

    def __init__(self, K, M, C, D, meas, slave):
        mats = [None if A is None else sp.csr_matrix(A) for A in (K, M, C, D)]

        def blk(rows, cols, dense):
            out = []
            for A in mats:
                if A is None:
                    out.append(None)
                    continue
                B = A[rows][:, cols]
                out.append(B.toarray() if dense else B)
            return out
        self.ss = _Pattern(*blk(slave, slave, False)) if slave.size else None
        self.sm = blk(slave, meas, True)
        self.ms = blk(meas, slave, True)
        self.mm = blk(meas, meas, True)

    @staticmethod
    def dense(parts, s):
        """The dense block ``K + s²M + sC + iD`` at every line of ``s`` (1-D): (n_s, rows, cols)."""
        Kb, Mb, Cb, Db = parts
        s2 = (s * s)[:, None, None]
        Z = Kb[None] + s2 * Mb[None]
        if Cb is not None:
            Z = Z + s[:, None, None] * Cb[None]
        if Db is not None:
            Z = Z + 1j * Db[None]
        return Z


def _condensed_sparse(K, M, C, D, s, meas, slave, x_meas, F, x_full, r, T, sigma, chunk: int = 32):
    """:func:`condensed_residual` with one sparse LU of Z_ss per line (large models); the thin dense blocks and
    the products after the solves are formed for ``chunk`` lines at a time (the per-line Python work was as
    costly as the LU itself on the benchmark's frames)."""
    blocks = _Blocks(K, M, C, D, meas, slave)
    Fs = np.ascontiguousarray(F[slave])
    Fm = F[meas]
    nm = meas.size
    for a in range(0, s.size, chunk):
        sl = s[a:a + chunk]
        Zmm = blocks.dense(blocks.mm, sl)                                    # (b, n_m, n_m)
        xm = np.ascontiguousarray(x_meas[:, :, a:a + chunk].transpose(2, 0, 1))   # (b, n_m, n_q)
        if slave.size:
            Zms = blocks.dense(blocks.ms, sl)
            rhs = np.concatenate([-blocks.dense(blocks.sm, sl), np.broadcast_to(Fs, (sl.size,) + Fs.shape)], axis=2)
            sol = np.empty(rhs.shape, complex)
            for k, sf in enumerate(sl):
                sol[k] = blocks.ss.solve(sf, rhs[k])
            Tsm, xsF = sol[:, :, :nm], sol[:, :, nm:]
            xs = Tsm @ xm + xsF
            T[slave, :, a:a + chunk] = Tsm.transpose(1, 2, 0)
            x_full[slave, :, a:a + chunk] = xs.transpose(1, 2, 0)
            force_path = np.linalg.norm(np.abs(Zms) @ np.abs(xsF), axis=1)      # (b, n_q)
            Zred = Zmm + Zms @ Tsm
            rm = Zmm @ xm + Zms @ xs - Fm[None]
        else:
            force_path = 0.0
            Zred = Zmm
            rm = Zmm @ xm - Fm[None]
        r[:, :, a:a + chunk] = rm.transpose(1, 2, 0)
        sigma[:, a:a + chunk] = (np.linalg.norm(np.abs(Zred) @ np.abs(xm), axis=1) + force_path).T
    x_full[meas] = x_meas
    return x_full, r, T, sigma
