"""Single-point constraints and rigid links by transformation (no penalty).

All DOFs ``u`` of a model are written in terms of the independent, free
DOFs ``u_a`` as ``u = T u_a``:

* a DOF fixed by an SPC has a zero row;
* a DOF made dependent by a rigid link (Nastran RBE2) follows the rigid-body
  motion of the independent node,
  ``u_d = u_i + θ_i × r``, ``θ_d = θ_i`` with ``r = x_d − x_i``, written in the
  nodes' displacement systems: ``u_d,cd = R_dᵀ [[I, −[r]×], [0, I]] R_i u_i,cd``;
* every other DOF maps to itself.

Chains of links (the dependent node of one link being the independent node
of another) are resolved by substitution.  The reduced matrices are
``K_a = Tᵀ K T`` (likewise M, C, D) and results map back by ``u = T u_a``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from modalab.core.dof import Dof
from modalab.core.errors import ModalabValueError

from updating.fe.assembly import Matrices, dof_index

__all__ = ["RBE2", "SPC", "Reduction", "build_reduction", "parse_components"]


def parse_components(components, what: str) -> tuple:
    """'123456' / '1 3' / (1, 3) -> sorted tuple of ints 1..6."""
    if isinstance(components, (int, np.integer)):
        components = str(int(components))
    if isinstance(components, str):
        items = [c for c in components if not c.isspace()]
    else:
        items = list(components)
    try:
        comps = sorted({int(c) for c in items})
    except (TypeError, ValueError):
        raise ModalabValueError(f"{what}: components {components!r}; expected digits 1..6 such as '123456'") from None
    if not comps or comps[0] < 1 or comps[-1] > 6:
        raise ModalabValueError(f"{what}: components {components!r}; expected digits 1..6 such as '123456'")
    return tuple(comps)


@dataclass(frozen=True)
class RBE2:
    """Rigid link: the listed ``components`` of each dependent node follow the independent node."""

    eid: int
    independent: int
    dependents: tuple
    components: tuple = (1, 2, 3, 4, 5, 6)


@dataclass(frozen=True)
class SPC:
    """Single-point constraint: the listed components of ``node`` are zero (in its CD system)."""

    node: int
    components: tuple = (1, 2, 3, 4, 5, 6)


def _skew(r):
    x, y, z = r
    return np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])


def _rot6(R):
    if R is None:
        return np.eye(6)
    B = np.zeros((6, 6))
    B[:3, :3] = R
    B[3:, 3:] = R
    return B


class Reduction:
    """The transformation ``u = T u_a`` from independent free DOFs to all DOFs.

    Attributes: ``T`` (sparse, n_full × n_a), ``full_dofs``, ``dofs`` (the a-set),
    ``fixed`` (DOFs set to zero), ``dependent`` (DOFs slaved by rigid links).
    """

    def __init__(self, T, full_dofs, dofs, fixed, dependent):
        self.T = sp.csr_matrix(T)
        self.full_dofs = list(full_dofs)
        self.dofs = list(dofs)
        self.fixed = list(fixed)
        self.dependent = list(dependent)
        self._identity = (self.T.shape[0] == self.T.shape[1] and not self.fixed and not self.dependent)

    @property
    def n_dof(self) -> int:
        return len(self.dofs)

    def reduce(self, A):
        """``Tᵀ A T`` (None stays None)."""
        if A is None:
            return None
        if self._identity:
            return sp.csr_matrix(A)
        return sp.csr_matrix(self.T.T @ A @ self.T)

    def reduce_matrices(self, m: Matrices) -> Matrices:
        return Matrices(K=self.reduce(m.K), M=self.reduce(m.M), C=self.reduce(m.C), D=self.reduce(m.D),
                        dofs=list(self.dofs))

    def expand(self, x):
        """Full-DOF vectors ``T x`` for a-set vectors x (n_a,) or (n_a, k)."""
        x = np.asarray(x)
        return self.T @ x


def build_reduction(model) -> Reduction:
    """Transformation for the model's SPCs and RBE2 links (see module docstring)."""
    full = model.dofs
    idx = dof_index(full)
    # dependent DOF -> {independent dof key: coefficient}
    relations: dict = {}
    owner: dict = {}
    for link in model.rbe2s.values():
        ni = model.nodes[link.independent]
        Ri = _rot6(ni.cd)
        for d in link.dependents:
            nd = model.nodes[d]
            G = np.eye(6)
            G[:3, 3:] = -_skew(nd.xyz - ni.xyz)
            A = _rot6(nd.cd).T @ G @ Ri
            for c in link.components:
                key = (d, c)
                if key in owner:
                    raise ModalabValueError(
                        f"DOF {Dof(d, c)} is dependent in rigid links {owner[key]} and {link.eid}; a DOF may be "
                        "dependent in one link only — make one of the links use other components")
                owner[key] = link.eid
                row = A[c - 1]
                relations[key] = {(link.independent, j + 1): row[j] for j in range(6) if abs(row[j]) > 1e-14}
    fixed = set()
    for s in model.spcs:
        for c in s.components:
            key = (s.node, c)
            if key in relations:
                raise ModalabValueError(
                    f"SPC on {Dof(s.node, c)}, which is dependent in rigid link {owner[key]}; constrain the "
                    "link's independent node instead")
            if key in idx:
                fixed.add(key)
    # resolve chains
    resolved: dict = {}

    def resolve(key, stack=()):
        if key in resolved:
            return resolved[key]
        if key in stack:
            raise ModalabValueError(f"rigid links form a cycle through {Dof(*key)} (links "
                                    f"{sorted({owner[k] for k in stack})}); break the loop")
        out: dict = {}
        for k, v in relations[key].items():
            if k in relations:
                for k2, v2 in resolve(k, stack + (key,)).items():
                    out[k2] = out.get(k2, 0.0) + v * v2
            else:
                out[k] = out.get(k, 0.0) + v
        resolved[key] = out
        return out

    a_keys = [(d.node, d.axis) for d in full if (d.node, d.axis) not in relations and (d.node, d.axis) not in fixed]
    a_idx = {k: i for i, k in enumerate(a_keys)}
    rows, cols, vals = [], [], []
    for i, d in enumerate(full):
        key = (d.node, d.axis)
        if key in a_idx:
            rows.append(i), cols.append(a_idx[key]), vals.append(1.0)
        elif key in relations:
            for k, v in resolve(key).items():
                if k in a_idx:
                    rows.append(i), cols.append(a_idx[k]), vals.append(v)
                elif k not in fixed:
                    raise ModalabValueError(f"rigid link {owner[key]} refers to {Dof(*k)}, which is not a model "
                                            "DOF; give the independent node elements or all six DOFs")
    T = sp.csr_matrix((vals, (rows, cols)), shape=(len(full), len(a_keys)))
    return Reduction(T, full, [Dof(n, a) for n, a in a_keys], [Dof(*k) for k in sorted(fixed)],
                     [Dof(*k) for k in sorted(relations)])
