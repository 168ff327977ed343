"""Scalar spring (Nastran CELAS1/CELAS2): between two node components or to ground.

Acts on components 1..6 of each node *in the node's displacement system*
(CD), like CELAS: ``K = k [[1, −1], [−1, 1]]`` on (u_a, u_b), or ``k`` on
u_a when grounded.  Rotational components (4..6) give torsional springs in
N·m/rad.  ``ge`` is the spring's structural damping (hysteretic ``ge·K``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modalab.core.errors import ModalabValueError

from updating.fe.elements.base import Element, ElementMatrices

__all__ = ["Spring", "scalar_dofs"]


def scalar_dofs(eid, a, b) -> list:
    out = []
    for end in (a, b):
        if end is None:
            continue
        try:
            n, c = int(end[0]), int(end[1])
        except (TypeError, ValueError, IndexError):
            raise ModalabValueError(f"element {eid}: end {end!r}; expected (node, component 1..6) or None "
                                    "for ground") from None
        if not 1 <= c <= 6:
            raise ModalabValueError(f"element {eid}: component {c}; expected 1..6 (X, Y, Z, RX, RY, RZ)")
        out.append((n, c))
    if not out:
        raise ModalabValueError(f"element {eid} has no connected end; give at least one (node, component)")
    if len(out) == 2 and out[0] == out[1]:
        raise ModalabValueError(f"element {eid} connects {out[0]} to itself; use b=None for a grounded element")
    return out


def _pattern(dofs, value):
    if len(dofs) == 1:
        return np.array([[value]]) * 1.0
    return value * np.array([[1.0, -1.0], [-1.0, 1.0]])


@dataclass
class Spring(Element):
    """Spring of stiffness ``k`` (N/m or N·m/rad) from ``a = (node, comp)`` to ``b`` (None = ground)."""

    eid: int
    a: tuple
    b: tuple | None
    k: float
    ge: float = 0.0
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
        return ElementMatrices(self.dofs(), K=_pattern(self._dofs, self.k), ge=self.ge)
