"""Scalar viscous damper (Nastran CDAMP1/CDAMP2): between two node components or to ground.

``C = c [[1, −1], [−1, 1]]`` on (u_a, u_b) in the nodes' displacement systems,
``c`` (Nastran PDAMP B) in N·s/m (N·m·s/rad on rotations).
"""
from __future__ import annotations

from dataclasses import dataclass

from updating.fe.elements.base import Element, ElementMatrices
from updating.fe.elements.spring import _pattern, scalar_dofs

__all__ = ["Damper"]


@dataclass
class Damper(Element):
    """Viscous damper of coefficient ``c`` (N·s/m) from ``a = (node, comp)`` to ``b`` (None = ground)."""

    eid: int
    a: tuple
    b: tuple | None
    c: float
    group: str = ""

    frame = "node"

    def __post_init__(self):
        self._dofs = scalar_dofs(self.eid, self.a, self.b)

    @property
    def nodes(self) -> tuple:
        return tuple(d[0] for d in self._dofs)

    def dofs(self) -> list:
        return list(self._dofs)

    def matrices(self, ctx) -> ElementMatrices:
        return ElementMatrices(self.dofs(), C=_pattern(self._dofs, self.c))
