"""Rod element (Nastran CROD): axial and torsional stiffness between two nodes.

Works in the basic system on 6 DOFs per node.  Stiffness ``EA/L`` along the
rod axis e and ``GJ/L`` about it.  Mass: consistent translational mass
``ρAL/6 [[2I, I], [I, 2I]]`` in all three directions (Nastran's coupled rod
mass) or lumped ``ρAL/2`` per node; no rotational inertia.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modalab.core.errors import ModalabValueError

from updating.fe.elements.base import Element, ElementMatrices, six_dofs
from updating.fe.properties import BeamProperty, RodProperty

__all__ = ["Rod"]


@dataclass
class Rod(Element):
    """Rod between ``n1`` and ``n2`` with a RodProperty (or a BeamProperty: its A and J are used)."""

    eid: int
    n1: int
    n2: int
    pid: int

    frame = "basic"

    @property
    def nodes(self) -> tuple:
        return (self.n1, self.n2)

    def dofs(self) -> list:
        return six_dofs(self.nodes)

    def matrices(self, ctx) -> ElementMatrices:
        prop = ctx.prop(self.pid)
        if isinstance(prop, RodProperty):
            A, J = prop.A, prop.J
        elif isinstance(prop, BeamProperty):
            A, J = prop.section.A, prop.section.J
        else:
            raise ModalabValueError(f"element {self.eid} (Rod) refers to property {self.pid}, a "
                                    f"{type(prop).__name__}; expected a RodProperty")
        mat = ctx.material(prop.mid)
        d = ctx.xyz(self.n2) - ctx.xyz(self.n1)
        L = float(np.sqrt(d @ d))
        if L <= 0:
            raise ModalabValueError(f"rod {self.eid} has zero length; check its node coordinates")
        e = d / L
        P = np.outer(e, e)
        B = np.array([[1.0, -1.0], [-1.0, 1.0]])
        ka, kt = mat.E * A / L, mat.shear_modulus * J / L
        dtype = np.result_type(ka, kt, float)
        K = np.zeros((12, 12), dtype)
        tr = [0, 1, 2, 6, 7, 8]
        rt = [3, 4, 5, 9, 10, 11]
        K[np.ix_(tr, tr)] = ka * np.kron(B, P)
        K[np.ix_(rt, rt)] = kt * np.kron(B, P)
        m = mat.rho * A + prop.nsm
        M = np.zeros((12, 12), np.result_type(m, float))
        if ctx.coupled_mass:
            M[np.ix_(tr, tr)] = m * L / 6 * np.kron(np.array([[2.0, 1.0], [1.0, 2.0]]), np.eye(3))
        else:
            M[np.ix_(tr, tr)] = m * L / 2 * np.eye(6)
        ge = prop.ge if prop.ge is not None else mat.ge
        return ElementMatrices(self.dofs(), K=K, M=M, ge=ge)
