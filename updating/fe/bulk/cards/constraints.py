"""Constraints: SPC, SPC1, SPCADD and rigid elements RBE2."""
from __future__ import annotations

from dataclasses import dataclass

from updating.fe.bulk.cards.base import Card

__all__ = ["Spc", "Spc1", "Spcadd", "Rbe2"]


@dataclass
class Spc(Card):
    """SPC SID G1 C1 D1 G2 C2 D2; ``items`` = ((grid, comps, d), ...)."""

    NAME = "SPC"
    KEY = "sid"
    sid: int
    items: tuple = ()

    @classmethod
    def from_raw(cls, r):
        r.check_length(7)
        items = []
        for i in (2, 5):
            if i == 5 and all(r.blank(j) for j in (5, 6, 7)):
                continue
            items.append((r.integer(i, "G"), r.components(i + 1, "C", allow_zero=True), r.real(i + 2, "D", 0.0)))
        return cls(r.integer(1, "SID"), tuple(items))._set_meta(r)

    def grids(self):
        return [g for g, _, _ in self.items]

    def values(self):
        out = [self.sid]
        for g, c, d in self.items:
            out += [g, c or "0", d or None]
        return [int(v) if isinstance(v, str) and v.isdigit() else v for v in out]


def _grid_list(r, i0, what):
    """Grid ids from field i0 on, with 'G1 THRU G2' ranges."""
    out = []
    end = r.n_used()
    i = i0
    while i < end:
        if r.blank(i):
            i += 1
            continue
        v = r.value(i, what)
        if v == "THRU":
            if not out or i + 1 >= end:
                raise r.error("THRU needs a grid id before and after it", i)
            hi = r.integer(i + 1, what)
            lo = out[-1]
            if hi < lo:
                raise r.error(f"THRU range {lo} THRU {hi} runs backwards", i + 1)
            if hi - lo > 10_000_000:
                raise r.error(f"THRU range {lo} THRU {hi} is implausibly long", i + 1)
            out.extend(range(lo + 1, hi + 1))
            i += 2
            continue
        out.append(r.integer(i, what))
        i += 1
    return out


@dataclass
class Spc1(Card):
    """SPC1 SID C G1 G2 ... (with THRU ranges)."""

    NAME = "SPC1"
    KEY = "sid"
    sid: int
    c: str = "123456"
    grid_ids: tuple = ()

    @classmethod
    def from_raw(cls, r):
        grids = _grid_list(r, 3, "G")
        if not grids:
            raise r.error("SPC1 lists no grid", 3)
        return cls(r.integer(1, "SID"), r.components(2, "C"), tuple(grids))._set_meta(r)

    def grids(self):
        return list(self.grid_ids)

    def values(self):
        return [self.sid, int(self.c), *self.grid_ids]


@dataclass
class Spcadd(Card):
    """SPCADD SID S1 S2 ...: union of SPC sets."""

    NAME = "SPCADD"
    KEY = "sid"
    sid: int
    sets: tuple = ()

    @classmethod
    def from_raw(cls, r):
        sets = _grid_list(r, 2, "S")
        if not sets:
            raise r.error("SPCADD lists no set", 2)
        return cls(r.integer(1, "SID"), tuple(sets))._set_meta(r)

    def values(self):
        return [self.sid, *self.sets]


@dataclass
class Rbe2(Card):
    """RBE2 EID GN CM GM1 GM2 ... [ALPHA [TREF]]."""

    NAME = "RBE2"
    KEY = "eid"
    eid: int
    gn: int
    cm: str
    gm: tuple = ()
    alpha: float = 0.0

    @classmethod
    def from_raw(cls, r):
        eid, gn, cm = r.integer(1, "EID"), r.integer(2, "GN"), r.components(3, "CM")
        gm = []
        alpha = 0.0
        end = r.n_used()
        i = 4
        while i < end:
            if r.blank(i):
                i += 1
                continue
            v = r.value(i, "GM")
            if isinstance(v, float):
                alpha = v
                if any(not r.blank(j) for j in range(i + 2, end)):
                    raise r.error("fields after ALPHA (and TREF) must be blank", i + 2)
                break
            if not isinstance(v, int) or v <= 0:
                raise r.error(f"dependent grid {v!r}; expected a grid id > 0", i)
            gm.append(v)
            i += 1
        if not gm:
            raise r.error("RBE2 lists no dependent grid GMi", 4)
        if gn in gm:
            raise r.error(f"grid {gn} is both the independent GN and a dependent GM", 2)
        return cls(eid, gn, cm, tuple(gm), alpha)._set_meta(r)

    @property
    def nodes(self):
        return (self.gn, *self.gm)

    def values(self):
        return [self.eid, self.gn, int(self.cm), *self.gm, self.alpha or None]

