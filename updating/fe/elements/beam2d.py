"""Planar Euler–Bernoulli beam (2-D), optionally with axial stiffness.

``plane="xy"``: transverse displacement along +Y and rotation +RZ (θ = v′);
``plane="xz"``: transverse displacement along +Z and rotation +RY, with the
right-hand rule θy = −w′.  Without ``axial`` the element must lie along the
X axis and has 2 DOFs per node (w, θ) — the classic 4×4 beam element; with
``axial`` it may lie anywhere in its plane and has 3 DOFs per node.

Bending inertia: ``Iz`` of the section for the x–y plane, ``Iy`` for x–z.
Mass: consistent cubic (no rotary inertia) or lumped (model.coupled_mass False).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modalab.core.errors import ModalabValueError

from updating.fe.elements._frame import _axial, _bending_K, _bending_M
from updating.fe.elements.base import Element, ElementMatrices
from updating.fe.properties import BeamProperty

__all__ = ["Beam2D"]

_PLANES = {"xy": (1, 2, 6, 1.0), "xz": (1, 3, 5, -1.0)}


@dataclass
class Beam2D(Element):
    """2-D beam between nodes ``n1`` and ``n2`` with property ``pid`` (a BeamProperty)."""

    eid: int
    n1: int
    n2: int
    pid: int
    plane: str = "xy"
    axial: bool = False

    frame = "basic"

    def __post_init__(self):
        if self.plane not in _PLANES:
            raise ModalabValueError(f"element {self.eid}: plane {self.plane!r}; expected 'xy' or 'xz'")

    @property
    def nodes(self) -> tuple:
        return (self.n1, self.n2)

    def dofs(self) -> list:
        ax, tr, rot, _ = _PLANES[self.plane]
        per = (ax, tr, rot) if self.axial else (tr, rot)
        return [(n, a) for n in self.nodes for a in per]

    def matrices(self, ctx) -> ElementMatrices:
        prop = ctx.prop(self.pid)
        if not isinstance(prop, BeamProperty):
            raise ModalabValueError(f"element {self.eid} (Beam2D) refers to property {self.pid}, a "
                                    f"{type(prop).__name__}; a beam needs a BeamProperty")
        mat = ctx.material(prop.mid)
        s = prop.section
        ax, tr, rot, sgn = _PLANES[self.plane]
        d = ctx.xyz(self.n2) - ctx.xyz(self.n1)
        off = [i for i in range(3) if i not in (ax - 1, tr - 1)]
        L = float(np.sqrt(d @ d))
        if L <= 0:
            raise ModalabValueError(f"element {self.eid} has zero length; check its node coordinates")
        if abs(d[off[0]]) > 1e-9 * L:
            raise ModalabValueError(f"element {self.eid} leaves its {self.plane} plane; move the nodes into "
                                    "the plane or use Beam3D")
        c, sn = d[ax - 1] / L, d[tr - 1] / L
        if not self.axial and abs(sn) > 1e-9:
            raise ModalabValueError(f"element {self.eid} is not along X; a Beam2D without axial DOFs must "
                                    "lie on the X axis (use axial=True for inclined members)")
        I = s.Iz if self.plane == "xy" else s.Iy
        m = mat.rho * s.A + prop.nsm
        S = np.diag([1.0, sgn, 1.0, sgn])
        Kb = S @ _bending_K(mat.E * I, L, 0.0) @ S
        if ctx.coupled_mass:
            Mb = S @ _bending_M(m, 0.0, L, 0.0) @ S
        else:
            Mb = np.diag([m * L / 2, 0.0, m * L / 2, 0.0]).astype(np.result_type(m, float))
        ge = prop.ge if prop.ge is not None else mat.ge
        if not self.axial:
            return ElementMatrices(self.dofs(), K=Kb, M=Mb, ge=ge)
        dtype = np.result_type(Kb, Mb)
        Kl = np.zeros((6, 6), dtype)
        Ml = np.zeros((6, 6), dtype)
        ib, ia = [1, 2, 4, 5], [0, 3]
        Kl[np.ix_(ib, ib)] = Kb
        Kl[np.ix_(ia, ia)] = _axial(mat.E * s.A / L)
        Ml[np.ix_(ib, ib)] = Mb
        if ctx.coupled_mass:
            Ml[np.ix_(ia, ia)] = m * L / 6 * np.array([[2, 1], [1, 2]])
        else:
            Ml[0, 0] = Ml[3, 3] = m * L / 2
        R = np.array([[c, sn], [-sn, c]])
        T = np.eye(6)
        T[0:2, 0:2] = R
        T[3:5, 3:5] = R
        return ElementMatrices(self.dofs(), K=T.T @ Kl @ T, M=T.T @ Ml @ T, ge=ge)
