"""Issue 15: one documented dense/sparse rule, :mod:`modalab.core.dense`.  Every switch goes through
:func:`~modalab.core.dense.use_dense` with a limit the module documents; the null space of the massless part
(:mod:`modalab.core.eigen`, formerly its own ``_DENSE_NULL = 300``) is one of them, and both of its paths give
the same null space."""
import numpy as np
import scipy.sparse as sp

import modalab.core.dense as dense
from modalab.core import eigen


def test_every_limit_is_documented_and_used_through_use_dense():
    doc = dense.__doc__
    for op, name in dense._LIMITS.items():
        assert f"``{name}`` ({getattr(dense, name)})" in doc, name
        assert dense.use_dense(getattr(dense, name), op) and not dense.use_dense(getattr(dense, name) + 1, op)
    assert not hasattr(eigen, "_DENSE_NULL")


def _null_basis(n_null_limit):
    # a chain of 40 springs free at both ends plus two loose DOFs: null space = rigid translation + 2 loose DOFs
    n = 42
    K = sp.diags([np.r_[1.0, 2 * np.ones(38), 1.0], -np.ones(39), -np.ones(39)], [0, 1, -1], shape=(40, 40))
    K = sp.block_diag([K, sp.csr_matrix((2, 2))]).tocsc()
    old = dense.NULL_SPACE_LIMIT
    dense.NULL_SPACE_LIMIT = n_null_limit
    try:
        return eigen._null_space_psd(K), n
    finally:
        dense.NULL_SPACE_LIMIT = old


def test_null_space_dense_and_sparse_paths_agree():
    (Ud, n), (Us, _) = _null_basis(1000), _null_basis(1)
    assert Ud.shape == Us.shape == (n, 3)
    # the same subspace: each basis is reproduced by projecting on the other
    np.testing.assert_allclose(Us @ (Us.T @ Ud), Ud, atol=1e-6)
