"""The parametric-model protocol every updating method works on.

A parametric model maps a parameter vector ``p`` to structural matrices and
gives their exact derivatives.  FE models (:mod:`updating.fe`) implement it
with non-linear relations (I ∝ t³ ...); :class:`MatrixModel` implements it for
the linear case ``A(p) = A0 + Σ p_i A_i`` that the thesis' lumped case studies
use (section 5.1: each spring, mass or damper is one parameter).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, Sequence, runtime_checkable

import numpy as np
import scipy.sparse as sp

from modalab.core.dof import parse_dofs
from modalab.core.errors import ModalabValueError, ShapeError
from modalab.core.structure import Structure

__all__ = ["ParametricModel", "Derivative", "MatrixModel", "parameter_indices"]


@dataclass
class Derivative:
    """Exact partial derivatives of the structural matrices with respect to one parameter (sparse or None)."""

    dK: sp.spmatrix | None = None
    dM: sp.spmatrix | None = None
    dC: sp.spmatrix | None = None
    dD: sp.spmatrix | None = None


@runtime_checkable
class ParametricModel(Protocol):
    """What updating needs from a model.

    Attributes
    ----------
    dofs : list of :class:`~modalab.core.dof.Dof`, one per matrix row (after constraints).
    parameter_names : names of the updating parameters.
    p0 : nominal parameter values.

    Methods
    -------
    structure(p) -> :class:`~modalab.core.structure.Structure` with M, K (C, D) at ``p``.
    derivatives(p) -> list of :class:`Derivative`, one per parameter, exact at ``p``.
    """

    dofs: list
    parameter_names: list
    p0: np.ndarray

    def structure(self, p=None) -> Structure: ...

    def derivatives(self, p=None) -> list: ...


class MatrixModel:
    """Linear parametric model ``A(p) = A0 + Σ_i p_i A_i`` for A in K, M, C, D.

    Parameters (keyword-only)
    ----------
    dofs : DOF labels.
    K0, M0, C0, D0 : constant parts (None means zero).
    terms : list of (name, Derivative) — the matrices multiplying each parameter.
    p0 : nominal parameter values.
    """

    def __init__(self, *, dofs, terms: Sequence[tuple[str, Derivative]], p0, K0=None, M0=None, C0=None,
                 D0=None, coords=None, name: str = ""):
        self.dofs = parse_dofs(dofs)
        n = len(self.dofs)
        z = sp.csr_matrix((n, n))

        def s(A):
            if A is None:
                return None
            A = sp.csr_matrix(A, dtype=float)
            if A.shape != (n, n):
                raise ShapeError(f"matrix of shape {A.shape} in a model of {n} DOFs")
            return A

        self.K0, self.M0 = s(K0) if K0 is not None else z, s(M0) if M0 is not None else z
        self.C0, self.D0 = s(C0), s(D0)
        self.parameter_names = [t[0] for t in terms]
        self._terms = [Derivative(s(d.dK), s(d.dM), s(d.dC), s(d.dD)) for _, d in terms]
        self.p0 = np.asarray(p0, dtype=float)
        if self.p0.shape != (len(self._terms),):
            raise ShapeError(f"p0 has {self.p0.size} values for {len(self._terms)} parameters")
        self.coords = coords or {}
        self.name = name

    @property
    def n_params(self) -> int:
        return len(self._terms)

    def _check(self, p):
        p = self.p0 if p is None else np.asarray(p, dtype=float)
        if p.shape != self.p0.shape:
            raise ShapeError(f"parameter vector has shape {p.shape}; expected {self.p0.shape} "
                             f"for {self.parameter_names}")
        return p

    def matrices(self, p=None):
        """(K, M, C or None, D or None) at ``p``."""
        p = self._check(p)
        K, M = self.K0.copy(), self.M0.copy()
        C = self.C0.copy() if self.C0 is not None else None
        D = self.D0.copy() if self.D0 is not None else None
        for pi, d in zip(p, self._terms):
            if d.dK is not None:
                K = K + pi * d.dK
            if d.dM is not None:
                M = M + pi * d.dM
            if d.dC is not None:
                C = (C if C is not None else 0) + pi * d.dC
            if d.dD is not None:
                D = (D if D is not None else 0) + pi * d.dD
        return K.tocsr(), M.tocsr(), (None if C is None else sp.csr_matrix(C)), (None if D is None else sp.csr_matrix(D))

    def structure(self, p=None) -> Structure:
        K, M, C, D = self.matrices(p)
        return Structure(M=M, K=K, C=C, D=D, dofs=self.dofs, coords=self.coords, name=self.name)

    def derivatives(self, p=None) -> list:
        self._check(p)
        return list(self._terms)


def parameter_indices(model, params) -> np.ndarray:
    """Indices of ``params`` (names or indices; None = all) among ``model.parameter_names``."""
    names = list(model.parameter_names)
    if params is None:
        return np.arange(len(names))
    out = []
    for q in params:
        if isinstance(q, (int, np.integer)):
            if not 0 <= q < len(names):
                raise ModalabValueError(f"parameter index {q} outside 0..{len(names) - 1}")
            out.append(int(q))
        elif q in names:
            out.append(names.index(q))
        else:
            raise ModalabValueError(f"parameter {q!r} is not in the model; available: {names[:20]}")
    return np.asarray(out, int)
