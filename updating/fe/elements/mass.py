"""Lumped mass with rotary inertia and offset (Nastran CONM2).

The 6×6 mass matrix at the node, in the basic system, is

    M = Aᵀ [[m I₃, 0], [0, J]] A,   A = [[I₃, −[r]×], [0, I₃]],

where r is the offset from the node to the centre of gravity and J the
inertia tensor about the centre of gravity (kg·m²).  ``axes`` (a 3×3
rotation, columns = the axes of the system in which offset and inertia are
given, expressed in basic) rotates both into the basic system:
r = R r', J = R J' Rᵀ.

Note on Nastran: CONM2 lists I11, I21, I22, I31, I32, I33 and builds the
matrix with *negated* off-diagonal entries ([[I11, −I21, −I31], ...]); pass
the tensor, i.e. ``J[1, 0] = −I21``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modalab.core.errors import ModalabValueError

from updating.fe.elements.base import Element, ElementMatrices

__all__ = ["LumpedMass"]


def _skew(r):
    x, y, z = r
    return np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])


@dataclass
class LumpedMass(Element):
    """Point mass ``mass`` (kg) at ``node`` with inertia tensor (3×3 or 3 principal values) and offset (m)."""

    eid: int
    node: int
    mass: float
    inertia: object = None
    offset: object = (0.0, 0.0, 0.0)
    axes: object = None
    group: str = ""

    frame = "basic"

    def __post_init__(self):
        if np.real(self.mass) < 0:
            raise ModalabValueError(f"mass element {self.eid}: mass {self.mass!r}; expected >= 0 kg")
        J = np.zeros((3, 3)) if self.inertia is None else np.asarray(self.inertia)
        if J.shape == (3,):
            J = np.diag(J)
        if J.shape != (3, 3):
            raise ModalabValueError(f"mass element {self.eid}: inertia of shape {J.shape}; expected a 3x3 "
                                    "tensor or 3 principal values in kg m^2")
        self.inertia = J
        r = np.asarray(self.offset, dtype=float)
        if r.shape != (3,):
            raise ModalabValueError(f"mass element {self.eid}: offset {self.offset!r}; expected 3 values in m")
        self.offset = r

    @property
    def nodes(self) -> tuple:
        return (self.node,)

    def dofs(self) -> list:
        return [(self.node, a) for a in range(1, 7)]

    def matrices(self, ctx) -> ElementMatrices:
        r, J = self.offset, self.inertia
        if self.axes is not None:
            R = np.asarray(self.axes, float)
            r, J = R @ r, R @ J @ R.T
        A = np.eye(6)
        A[:3, 3:] = -_skew(r)
        dtype = np.result_type(self.mass, J, float)
        D = np.zeros((6, 6), dtype)
        D[:3, :3] = self.mass * np.eye(3)
        D[3:, 3:] = J
        return ElementMatrices(self.dofs(), M=A.T @ D @ A)
