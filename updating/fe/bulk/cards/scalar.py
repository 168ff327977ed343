"""Scalar and point elements: CELAS1, CELAS2, CDAMP1, CDAMP2 and the point mass CONM2."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from updating.fe.bulk.fields import REQUIRED
from updating.fe.bulk.cards.base import Card

__all__ = ["Celas1", "Cdamp1", "Celas2", "Cdamp2", "Conm2"]


def _grid_comp(r, i, what, required):
    g = r.integer(i, f"G{what}", REQUIRED if required else 0)
    c = r.integer(i + 1, f"C{what}", 0)
    if g < 0:
        raise r.error(f"grid G{what} = {g}; expected > 0 or blank for ground", i)
    if not 0 <= c <= 6:
        raise r.error(f"component C{what} = {c}; expected 1..6 (0 or blank for a scalar point)", i + 1)
    if g and not c:
        raise r.error(f"grid G{what} = {g} needs a component 1..6 (scalar points are not supported)", i + 1)
    return (g, c) if g else None


class _Scalar(Card):
    @property
    def nodes(self):
        return tuple(e[0] for e in (self.a, self.b) if e is not None)

    def _ends(self):
        out = []
        for e in (self.a, self.b):
            out += [e[0], e[1]] if e is not None else [None, None]
        return out


def _scalar_ends(r, i0):
    a = _grid_comp(r, i0, "1", False)
    b = _grid_comp(r, i0 + 2, "2", False)
    if a is None and b is None:
        raise r.error("both ends are grounded; give at least G1/C1", i0)
    if a is not None and a == b:
        raise r.error(f"both ends are grid {a[0]} component {a[1]}; the two connection points must differ", i0 + 2)
    return a, b


@dataclass
class Celas1(_Scalar):
    """CELAS1 EID PID G1 C1 G2 C2 (spring with a PELAS)."""

    NAME = "CELAS1"
    KEY = "eid"
    eid: int
    pid: int
    a: tuple | None
    b: tuple | None = None

    @classmethod
    def from_raw(cls, r):
        r.check_length(6)
        eid = r.integer(1, "EID")
        a, b = _scalar_ends(r, 3)
        return cls(eid, r.integer(2, "PID", eid), a, b)._set_meta(r)

    def values(self):
        return [self.eid, self.pid, *self._ends()]


@dataclass
class Cdamp1(Celas1):
    """CDAMP1 EID PID G1 C1 G2 C2 (viscous damper with a PDAMP)."""

    NAME = "CDAMP1"


@dataclass
class Celas2(_Scalar):
    """CELAS2 EID K G1 C1 G2 C2 GE S."""

    NAME = "CELAS2"
    KEY = "eid"
    eid: int
    k: float
    a: tuple | None
    b: tuple | None = None
    ge: float = 0.0
    s: float = 0.0

    @classmethod
    def from_raw(cls, r):
        r.check_length(8)
        a, b = _scalar_ends(r, 3)
        return cls(r.integer(1, "EID"), r.real(2, "K"), a, b, r.real(7, "GE", 0.0),
                   r.real(8, "S", 0.0))._set_meta(r)

    def values(self):
        return [self.eid, self.k, *self._ends(), self.ge or None, self.s or None]


@dataclass
class Cdamp2(_Scalar):
    """CDAMP2 EID B G1 C1 G2 C2."""

    NAME = "CDAMP2"
    KEY = "eid"
    eid: int
    b_value: float
    a: tuple | None
    b: tuple | None = None

    @classmethod
    def from_raw(cls, r):
        r.check_length(6)
        a, b = _scalar_ends(r, 3)
        return cls(r.integer(1, "EID"), r.real(2, "B"), a, b)._set_meta(r)

    def values(self):
        return [self.eid, self.b_value, *self._ends()]


@dataclass
class Conm2(Card):
    """CONM2 EID G CID M X1 X2 X3 / I11 I21 I22 I31 I32 I33.

    CID = -1: X is the centre of gravity in basic coordinates; otherwise the
    offset from G (and the inertias) in system CID.
    """

    NAME = "CONM2"
    KEY = "eid"
    eid: int
    g: int
    cid: int = 0
    m: float = 0.0
    x: tuple = (0.0, 0.0, 0.0)
    inertia: tuple = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)   # I11 I21 I22 I31 I32 I33

    @classmethod
    def from_raw(cls, r):
        r.check_length(14)
        c = cls(r.integer(1, "EID"), r.integer(2, "G"), r.integer(3, "CID", 0), r.real(4, "M", 0.0),
                tuple(r.real(i, "X", 0.0) for i in (5, 6, 7)),
                tuple(r.real(i, "I", 0.0) for i in range(9, 15)))
        if c.cid < -1:
            raise r.error(f"CID = {c.cid}; expected -1, 0 or a coordinate system id", 3)
        if c.m < 0:
            raise r.error(f"mass M = {c.m}; expected >= 0", 4)
        i11, i21, i22, i31, i32, i33 = c.inertia
        if i11 < 0 or i22 < 0 or i33 < 0:
            raise r.error(f"inertias I11, I22, I33 = {i11}, {i22}, {i33}; expected >= 0", 9)
        return c._set_meta(r)

    @property
    def nodes(self):
        return (self.g,)

    def values(self):
        z = [None if v == 0.0 else v for v in self.x]
        ii = [None if v == 0.0 else v for v in self.inertia]
        return [self.eid, self.g, self.cid or None, self.m, *z, None, *ii]

    def tensor(self) -> np.ndarray:
        """The inertia tensor [[I11, −I21, −I31], [−I21, I22, −I32], [−I31, −I32, I33]] (Nastran's sign)."""
        i11, i21, i22, i31, i32, i33 = self.inertia
        return np.array([[i11, -i21, -i31], [-i21, i22, -i32], [-i31, -i32, i33]])

