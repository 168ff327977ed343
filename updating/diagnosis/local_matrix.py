"""A candidate's unit matrix as the few DOFs it touches and a small dense block: :class:`LocalMatrix`.

The diagnosis library (:mod:`~updating.diagnosis.library`) stores every candidate's ``G`` so: a 100k-DOF
model has ~10⁵ candidates, and an n × n sparse matrix each would not fit in memory.  The screenings
(:mod:`~updating.diagnosis.frfscreen`, :mod:`~updating.diagnosis.modes_screen`) read its low-rank factor.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["LocalMatrix"]


class LocalMatrix:
    """A symmetric n × n matrix that is zero outside the block ``rows × rows``: ``G = E_rows B E_rowsᵀ``.

    A candidate's unit matrix touches a few DOFs (1 for a spring, 3 for a point mass, ≤ 18 for an element
    group); stored as an n × n CSR its row pointer alone is 4(n + 1) bytes, ~67 GB for the ~10 candidates per
    grid of a 100k-DOF model.  Here it is the indices and the small dense block.  ``toarray``/``tocsr`` give
    the explicit matrix (for code that wants one); :meth:`low_rank` the factor ``(rows, L)``, ``B = L Lᵀ``
    (PSD part), that the screenings use."""

    __slots__ = ("rows", "block", "n")

    def __init__(self, rows, block, n: int):
        self.rows = np.asarray(rows, int)
        self.block = np.asarray(block, float)
        self.n = int(n)

    @classmethod
    def from_factor(cls, R, n: int):
        """``Rᵀ R`` for a sparse ``R`` (k × n, e.g. rows of the reduction T), kept on its nonzero rows."""
        R = sp.coo_matrix(R)
        return cls._from_triplets(R.row, R.col, R.data, R.shape[0], n)

    @classmethod
    def from_csr_rows(cls, T: sp.csr_matrix, rows, n: int):
        """``Rᵀ R`` with ``R = T[rows]`` read straight from the CSR arrays (no scipy indexing per candidate:
        the library builds one per DOF of a 100k-DOF model)."""
        ip = T.indptr
        lens = np.array([ip[r + 1] - ip[r] for r in rows], int)
        idx = np.concatenate([np.arange(ip[r], ip[r + 1]) for r in rows]) if lens.sum() else np.zeros(0, int)
        return cls._from_triplets(np.repeat(np.arange(len(rows)), lens), T.indices[idx], T.data[idx], len(rows), n)

    @classmethod
    def _from_triplets(cls, row, col, data, k: int, n: int):
        nz = data != 0
        cols = np.unique(col[nz])
        if cols.size == 0:
            return None
        D = np.zeros((k, cols.size))
        np.add.at(D, (row[nz], np.searchsorted(cols, col[nz])), data[nz])
        return cls._trimmed(cols, D.T @ D, n)

    @classmethod
    def _trimmed(cls, rows, B, n):
        """Drop the rows (and columns) of ``B`` that are all zero, as ``G.nonzero()`` would not list them."""
        keep = np.any(B != 0, axis=1)
        if not keep.any():
            return None
        return cls(np.asarray(rows)[keep], B[np.ix_(keep, keep)], n)

    @property
    def shape(self) -> tuple:
        return (self.n, self.n)

    @property
    def nnz(self) -> int:
        return int(np.count_nonzero(self.block))

    def tocsr(self) -> sp.csr_matrix:
        r = np.repeat(self.rows, self.rows.size)
        c = np.tile(self.rows, self.rows.size)
        return sp.csr_matrix((self.block.ravel(), (r, c)), shape=self.shape)

    def tocoo(self):
        return self.tocsr().tocoo()

    def toarray(self) -> np.ndarray:
        return self.tocsr().toarray()

    def nonzero(self):
        return self.tocsr().nonzero()

    def low_rank(self):
        """``(rows, L)`` with ``G = E_rows L Lᵀ E_rowsᵀ`` (the PSD part of the block; None when it has none),
        the same factor as :func:`~updating.diagnosis.frfscreen._low_rank` of the explicit matrix."""
        B = self.block
        w, U = np.linalg.eigh(0.5 * (B + B.T))
        keep = w > 1e-9 * max(np.abs(w).max(), 1e-300)
        if not keep.any():
            return None
        return self.rows, U[:, keep] * np.sqrt(w[keep])


def _group_G(red, blocks, n_red):
    """``Tᵀ (Σ K_e) T`` of element blocks ``[(full rows, K_e)]`` as a :class:`LocalMatrix` (no n × n product)."""
    full = np.unique(np.concatenate([r for r, _ in blocks]))
    Kl = np.zeros((full.size, full.size))
    for r, Ke in blocks:
        p = np.searchsorted(full, r)
        Kl[np.ix_(p, p)] += Ke
    R = sp.coo_matrix(red.T[full])
    nz = R.data != 0
    cols = np.unique(R.col[nz])
    if cols.size == 0:
        return None
    D = np.zeros((full.size, cols.size))
    np.add.at(D, (R.row[nz], np.searchsorted(cols, R.col[nz])), R.data[nz])
    return LocalMatrix._trimmed(cols, D.T @ Kl @ D, n_red)
