"""Assembly of the global sparse matrices of an :class:`~updating.fe.model.FEModel`.

The DOFs of a model are the (node, axis) pairs its elements and rigid links
touch, sorted by node then axis, and expressed in each node's displacement
system (Nastran CD).  Elements that work in the basic system are rotated
into the CD systems here: with ``R`` the CD axes in basic (columns),
``u_basic = R u_cd`` per translation/rotation triplet and
``K_cd = Tᵀ K_basic T``.

Damping matrices:

* viscous ``C`` = Σ dampers + Rayleigh ``α M + β K`` (when the model has ``rayleigh``);
* hysteretic ``D`` = Σ_e ge_e K_e + G·K, with ge per material, property or
  spring and G the model's ``global_ge`` (Nastran PARAM G), so that the
  dynamic stiffness is ``K + iD + iωC − ω²M``.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from modalab.core.errors import ModalabValueError

from updating.fe.elements.base import AssemblyContext

log = logging.getLogger(__name__)

__all__ = ["Matrices", "assemble", "dof_index"]


@dataclass
class Matrices:
    """Global K, M, C, D (sparse CSR; C and D None when absent) on ``dofs``."""

    K: sp.csr_matrix
    M: sp.csr_matrix
    C: sp.csr_matrix | None
    D: sp.csr_matrix | None
    dofs: list

    @property
    def n_dof(self) -> int:
        return len(self.dofs)


def dof_index(dofs) -> dict:
    """{(node, axis): row} for a list of positive :class:`Dof`."""
    return {(d.node, d.axis): i for i, d in enumerate(dofs)}


def _cd_transform(model, edofs):
    """T with u_basic(element dofs) = T u_cd, or None when no node of the element has a CD system."""
    nodes = {n for n, _ in edofs}
    if all(model.nodes[n].cd is None for n in nodes if n in model.nodes):
        return None
    pos = {d: i for i, d in enumerate(edofs)}
    T = np.eye(len(edofs))
    for n in nodes:
        R = model.nodes[n].cd
        if R is None:
            continue
        for base in (1, 4):
            trip = [(n, base + k) for k in range(3)]
            present = [d in pos for d in trip]
            if not any(present):
                continue
            if not all(present):
                raise ModalabValueError(
                    f"node {n} has a displacement coordinate system (CD) but an element uses only components "
                    f"{[d[1] for d in trip if d in pos]} of the triplet {[d[1] for d in trip]}; a rotated node "
                    "needs elements that act on all three components (use a 3-D element or CD = basic)")
            idx = [pos[d] for d in trip]
            T[np.ix_(idx, idx)] = R
    return T


def _add_batch(model, cls, group, ctx, idx, parts):
    K, M, ge = cls.batch_matrices(group, ctx)
    nd = K.shape[1]
    keys = [el.dofs() for el in group]
    try:
        rows = np.array([[idx[d] for d in ks] for ks in keys], dtype=np.int64)
    except KeyError as e:
        raise ModalabValueError(f"a {cls.__name__} element uses DOF {e.args[0]} that is not in the model's DOF "
                                "list; this is an internal inconsistency, rebuild the model") from None
    rotated = [k for k, el in enumerate(group) if any(model.nodes[n].cd is not None for n in el.nodes)]
    for k in rotated:
        T = _cd_transform(model, keys[k])
        K[k] = T.T @ K[k] @ T
        M[k] = T.T @ M[k] @ T
    r = np.broadcast_to(rows[:, :, None], (len(group), nd, nd)).ravel()
    c = np.broadcast_to(rows[:, None, :], (len(group), nd, nd)).ravel()
    for key, A in (("K", K), ("M", M)):
        parts[key][0].append(r)
        parts[key][1].append(c)
        parts[key][2].append(A.ravel())
    ge = np.asarray(ge)
    if np.any(ge != 0):
        parts["D"][0].append(r)
        parts["D"][1].append(c)
        parts["D"][2].append((ge[:, None, None] * K).ravel())


def element_stiffness(model, elements, index: dict | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """``[(rows, K_e)]``: each element's stiffness (dense, on the model's DOF indices ``rows``), exactly the block
    :func:`assemble` adds for it, without forming an n × n matrix (the candidate library needs one block per
    element of a 100k-DOF model)."""
    idx = dof_index(model.dofs) if index is None else index
    ctx = AssemblyContext(model)
    els = list(elements)
    out: dict = {}
    batched: dict = {}
    for el in els:
        if hasattr(type(el), "batch_matrices"):
            batched.setdefault(type(el), []).append(el)
            continue
        em = el.matrices(ctx)
        if em.K is None:
            continue
        T = _cd_transform(model, em.dofs) if el.frame == "basic" else None
        out[id(el)] = (np.array([idx[d] for d in em.dofs], int), em.K if T is None else T.T @ em.K @ T)
    for cls, group in batched.items():
        K, _, _ = cls.batch_matrices(group, ctx)
        for k, el in enumerate(group):
            keys = el.dofs()
            Ke = K[k]
            if any(model.nodes[n].cd is not None for n in el.nodes):
                T = _cd_transform(model, keys)
                Ke = T.T @ Ke @ T
            out[id(el)] = (np.array([idx[d] for d in keys], int), Ke)
    return [out[id(el)] for el in els if id(el) in out]


def assemble(model, elements=None, dtype=float, index: dict | None = None,
             include_global: bool = True) -> Matrices:
    """Assemble K, M, C, D of ``model`` (or of the listed ``elements`` only) on ``model.dofs``.

    dtype : float, or complex for complex-step differentiation.
    include_global : add the model-wide terms (PARAM G ``global_ge·K``, Rayleigh ``αM + βK``); G does not damp the
        elements listed in ``model.global_ge_exempt``.
    """
    dofs = model.dofs
    idx = dof_index(dofs) if index is None else index
    ctx = AssemblyContext(model)
    parts = {k: ([], [], []) for k in ("K", "M", "C", "D")}
    els = list(model.elements.values()) if elements is None else list(elements)
    # element classes with a vectorised kernel are assembled in one batch per class
    batched: dict = {}
    single = []
    for el in els:
        if hasattr(type(el), "batch_matrices"):
            batched.setdefault(type(el), []).append(el)
        else:
            single.append(el)
    for cls, group in batched.items():
        _add_batch(model, cls, group, ctx, idx, parts)
    for el in single:
        em = el.matrices(ctx)
        try:
            rows = np.fromiter((idx[d] for d in em.dofs), int, len(em.dofs))
        except KeyError as e:
            raise ModalabValueError(f"element {el.eid} uses DOF {e.args[0]} that is not in the model's DOF "
                                    "list; this is an internal inconsistency, rebuild the model") from None
        T = _cd_transform(model, em.dofs) if el.frame == "basic" else None
        ge = em.ge
        for key, A in (("K", em.K), ("M", em.M), ("C", em.C)):
            if A is None:
                continue
            if T is not None:
                A = T.T @ A @ T
            r, c, v = parts[key]
            r.append(np.repeat(rows, len(rows)))
            c.append(np.tile(rows, len(rows)))
            v.append(np.ravel(A))
            if key == "K" and np.any(ge != 0):
                rd, cd, vd = parts["D"]
                rd.append(r[-1])
                cd.append(c[-1])
                vd.append(ge * np.ravel(A))
    n = len(dofs)

    def build(key):
        r, c, v = parts[key]
        if not r:
            return None
        vals = np.concatenate(v)
        dt = np.result_type(vals.dtype, dtype)
        return sp.csr_matrix((vals.astype(dt, copy=False), (np.concatenate(r), np.concatenate(c))), shape=(n, n))

    K, M, C, D = (build(k) for k in ("K", "M", "C", "D"))
    zero = sp.csr_matrix((n, n), dtype=dtype)
    K = zero if K is None else K
    M = zero if M is None else M
    if include_global:
        g = model.global_ge
        if g:
            GK = g * K
            exempt = [el for el in els if el.eid in model.global_ge_exempt]
            if exempt:         # their own ge is their whole loss factor (updating.fe.damping.own_loss_exempt)
                GK = GK - g * assemble(model, elements=exempt, dtype=dtype, index=idx, include_global=False).K
            D = GK if D is None else D + GK
        if model.rayleigh is not None:
            a, b = model.rayleigh
            R = a * M + b * K
            C = R if C is None else C + R
    return Matrices(K=K, M=M, C=C, D=D, dofs=list(dofs))
