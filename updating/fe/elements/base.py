"""Element protocol shared by all element types.

An element names the DOFs it couples, as ``(node, axis)`` pairs with axis
1..6 (X, Y, Z, RX, RY, RZ), and returns its matrices on those DOFs.  Frame
elements work in the *basic* coordinate system (``frame = "basic"``); the
assembly rotates them into each node's displacement system (Nastran CD).
Scalar elements (springs, dampers) act directly on a node's displacement
components (``frame = "node"``), like Nastran CELAS/CDAMP.

An element class may also provide a classmethod
``batch_matrices(elements, ctx) -> (K, M, ge)`` returning stacked (n, d, d)
matrices in basic axes and (n,) damping coefficients; the assembly then
builds all elements of that class in one vectorised call (the frame elements
do: a 100k-DOF frame assembles in seconds).

Element code is written with plain arithmetic so that a property can be a
complex number: :mod:`updating.fe.parameters` differentiates by the complex
step (exact to rounding, no truncation error).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Element", "ElementMatrices", "AssemblyContext"]


@dataclass
class ElementMatrices:
    """Matrices of one element on its DOFs (``None`` when absent).

    ``ge`` is the element's structural damping coefficient: its hysteretic
    matrix is ``ge · K``.
    """

    dofs: list
    K: np.ndarray | None = None
    M: np.ndarray | None = None
    C: np.ndarray | None = None
    ge: complex | float = 0.0


class AssemblyContext:
    """What an element may read from the model while building its matrices."""

    def __init__(self, model):
        self._model = model

    def xyz(self, nid) -> np.ndarray:
        return self._model.node_xyz(nid)

    def material(self, mid):
        return self._model.material(mid)

    def prop(self, pid):
        return self._model.prop(pid)

    @property
    def coupled_mass(self) -> bool:
        return self._model.coupled_mass


class Element:
    """Base class: ``eid``, ``nodes``; subclasses set ``frame`` and implement :meth:`dofs`, :meth:`matrices`."""

    frame = "basic"
    eid: int
    pid: int | None = None
    group: str = ""

    @property
    def nodes(self) -> tuple:
        raise NotImplementedError

    def dofs(self) -> list:
        """``(node, axis)`` pairs in matrix order."""
        raise NotImplementedError

    def matrices(self, ctx: AssemblyContext) -> ElementMatrices:
        raise NotImplementedError


def six_dofs(nodes) -> list:
    return [(n, a) for n in nodes for a in range(1, 7)]
