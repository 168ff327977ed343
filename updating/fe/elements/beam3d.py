"""3-D Euler–Bernoulli frame element (Nastran CBAR without offsets or pin flags).

Two nodes, 6 DOFs each in the basic system; axial, torsion and bending in two
planes.  Consistent mass (cubic Hermite bending, linear axial and torsional
shapes, as Nastran's coupled CBAR mass) or lumped mass when the model's
``coupled_mass`` is False (PARAM COUPMASS).  Stiffness:
Przemieniecki, *Theory of Matrix Structural Analysis* (1968), eq. 5.115.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modalab.errors import ModalabValueError

from ._frame import frame_local, local_axes, transformation
from .base import Element, ElementMatrices, six_dofs
from ..properties import BeamProperty

__all__ = ["Beam3D"]


@dataclass
class Beam3D(Element):
    """Euler–Bernoulli 3-D beam.

    eid : element id.  n1, n2 : end nodes A and B.  pid : id of a
    :class:`~updating.fe.properties.BeamProperty`.  orientation : the vector v
    (basic system) or the id of a node G0 (v = x(G0) − x(A)); local y lies in
    the plane of the beam axis and v.
    """

    eid: int
    n1: int
    n2: int
    pid: int
    orientation: object = (0.0, 0.0, 1.0)

    frame = "basic"
    _shear = False

    @property
    def nodes(self) -> tuple:
        return (self.n1, self.n2)

    def dofs(self) -> list:
        return six_dofs(self.nodes)

    def axes(self, ctx):
        x1, x2 = ctx.xyz(self.n1), ctx.xyz(self.n2)
        v = self.orientation
        if np.ndim(v) == 0:
            v = ctx.xyz(int(v)) - x1
        return local_axes(x1, x2, v, self.eid)

    def matrices(self, ctx) -> ElementMatrices:
        prop = ctx.prop(self.pid)
        if not isinstance(prop, BeamProperty):
            raise ModalabValueError(f"element {self.eid} ({type(self).__name__}) refers to property "
                                    f"{self.pid}, a {type(prop).__name__}; a beam needs a BeamProperty")
        mat = ctx.material(prop.mid)
        s = prop.section
        L, lam = self.axes(ctx)
        Kl, Ml = frame_local(L, mat.E, mat.shear_modulus, mat.rho, s.A, s.Iy, s.Iz, s.J, s.polar, prop.nsm,
                             shear_y=s.ky if self._shear else None, shear_z=s.kz if self._shear else None,
                             lumped=not ctx.coupled_mass, rotary=self._shear)
        T = transformation(lam)
        ge = prop.ge if prop.ge is not None else mat.ge
        return ElementMatrices(self.dofs(), K=T.T @ Kl @ T, M=T.T @ Ml @ T, ge=ge)
