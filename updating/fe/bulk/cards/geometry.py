"""Geometry cards: GRID and the coordinate systems CORD2R, CORD2C, CORD2S."""
from __future__ import annotations

from dataclasses import dataclass

from updating.fe.bulk.fields import RawCard
from updating.fe.bulk.cards.base import Card

__all__ = ["Grid", "Coord"]


@dataclass
class Grid(Card):
    """GRID ID CP X1 X2 X3 CD PS SEID."""

    NAME = "GRID"
    KEY = "nid"
    nid: int
    cp: int = 0
    xyz: tuple = (0.0, 0.0, 0.0)
    cd: int = 0
    ps: str = ""
    seid: int = 0

    @classmethod
    def from_raw(cls, r: RawCard):
        r.check_length(8)
        nid = r.integer(1, "ID")
        if nid <= 0:
            raise r.error(f"grid id {nid}; expected an integer > 0", 1)
        c = cls(nid, r.integer(2, "CP", 0), tuple(r.real(i, f"X{i - 2}", 0.0) for i in (3, 4, 5)),
                r.integer(6, "CD", 0), r.components(7, "PS", ""), r.integer(8, "SEID", 0))
        if c.cp < 0 or c.cd < -1:
            raise r.error(f"coordinate system ids CP={c.cp}, CD={c.cd}; expected >= 0", 2)
        return c._set_meta(r)

    def values(self):
        return [self.nid, self.cp or None, *self.xyz, self.cd or None, self.ps or None, self.seid or None]


@dataclass
class Coord(Card):
    """CORD2R / CORD2C / CORD2S CID RID A1 A2 A3 B1 B2 B3 / C1 C2 C3.

    A is the origin, B a point on the local z axis, C a point in the local x–z
    plane, all given in system RID.  ``kind`` is 'R', 'C' or 'S'.
    """

    NAME = "CORD2R"
    KEY = "cid"
    cid: int
    kind: str = "R"
    rid: int = 0
    a: tuple = (0.0, 0.0, 0.0)
    b: tuple = (0.0, 0.0, 1.0)
    c: tuple = (1.0, 0.0, 0.0)

    @property
    def name(self) -> str:
        return "CORD2" + self.kind

    def where(self) -> dict:
        return {"path": self.path, "line": self.line, "card": f"{self.name} {self.cid}"}

    @classmethod
    def from_raw(cls, r: RawCard):
        r.check_length(11)
        cid = r.integer(1, "CID")
        if cid <= 0:
            raise r.error(f"coordinate system id {cid}; expected > 0 (0 is the basic system)", 1)
        vals = [r.real(i, f"field {i + 1}", 0.0) for i in range(3, 12)]
        return cls(cid, r.name[-1], r.integer(2, "RID", 0), tuple(vals[0:3]), tuple(vals[3:6]),
                   tuple(vals[6:9]))._set_meta(r)

    def values(self):
        return [self.cid, self.rid or None, *self.a, *self.b, *self.c]

