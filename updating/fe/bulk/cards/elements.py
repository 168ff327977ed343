"""Line and shell element connectivity: CBAR, CBEAM, CROD, CONROD, CQUAD4, CTRIA3."""
from __future__ import annotations

from dataclasses import dataclass

from updating.fe.bulk.fields import RawCard
from updating.fe.bulk.cards.base import Card

__all__ = ["Cbar", "Cbeam", "Crod", "Conrod", "Cquad4", "Ctria3"]


def _orientation(r: RawCard, i: int):
    """CBAR/CBEAM field 6: G0 (integer, fields 7-8 blank) or X1 X2 X3 (reals)."""
    v = r.int_or_real(i, "X1/G0", None)
    if isinstance(v, int):
        if not (r.blank(i + 1) and r.blank(i + 2)):
            raise r.error("G0 is given (an integer) so X2 and X3 must be blank", i + 1)
        if v <= 0:
            raise r.error(f"G0 = {v}; expected a grid id > 0", i)
        return None, v
    x = (0.0 if v is None else v, r.real(i + 1, "X2", 0.0), r.real(i + 2, "X3", 0.0))
    if v is None and r.blank(i + 1) and r.blank(i + 2):
        raise r.error("orientation missing: give G0 or the vector X1 X2 X3 (Nastran has no default "
                      "orientation for CBAR/CBEAM)", i)
    return x, None


@dataclass
class Cbar(Card):
    """CBAR EID PID GA GB X1/G0 X2 X3 OFFT / PA PB W1A W2A W3A W1B W2B W3B."""

    NAME = "CBAR"
    KEY = "eid"
    eid: int
    pid: int
    ga: int
    gb: int
    x: tuple | None = None
    g0: int | None = None
    offt: str = "GGG"
    pa: str = ""
    pb: str = ""
    wa: tuple = (0.0, 0.0, 0.0)
    wb: tuple = (0.0, 0.0, 0.0)

    N_MAX = 16

    @classmethod
    def from_raw(cls, r: RawCard):
        r.check_length(cls.N_MAX)
        eid = r.integer(1, "EID")
        x, g0 = _orientation(r, 5)
        offt = r.string(8, "OFFT", "GGG")
        c = cls(eid, r.integer(2, "PID", eid), r.integer(3, "GA"), r.integer(4, "GB"), x, g0, offt,
                r.components(9, "PA", ""), r.components(10, "PB", ""),
                tuple(r.real(i, "offset", 0.0) for i in (11, 12, 13)),
                tuple(r.real(i, "offset", 0.0) for i in (14, 15, 16)))
        if c.ga == c.gb:
            raise r.error(f"GA = GB = {c.ga}; a bar needs two different grids", 4)
        return c._set_meta(r)

    @property
    def nodes(self):
        return (self.ga, self.gb)

    def values(self):
        o = [self.g0, None, None] if self.g0 is not None else list(self.x)
        w = [None if v == 0.0 else v for v in (*self.wa, *self.wb)]
        return [self.eid, self.pid, self.ga, self.gb, *o, None if self.offt == "GGG" else self.offt,
                self.pa or None, self.pb or None, *w]


@dataclass
class Cbeam(Cbar):
    """CBEAM EID PID GA GB X1/G0 X2 X3 OFFT / PA PB W1A .. W3B / SA SB."""

    NAME = "CBEAM"
    sa: int = 0
    sb: int = 0

    N_MAX = 18

    @classmethod
    def from_raw(cls, r: RawCard):
        base = Cbar.from_raw.__func__(cls, r)
        base.sa, base.sb = r.integer(17, "SA", 0), r.integer(18, "SB", 0)
        return base

    def values(self):
        v = super().values()
        v += [None] * (16 - len(v))
        return v + [self.sa or None, self.sb or None]


@dataclass
class Crod(Card):
    """CROD EID PID G1 G2."""

    NAME = "CROD"
    KEY = "eid"
    eid: int
    pid: int
    ga: int
    gb: int

    @classmethod
    def from_raw(cls, r):
        r.check_length(4)
        eid = r.integer(1, "EID")
        c = cls(eid, r.integer(2, "PID", eid), r.integer(3, "G1"), r.integer(4, "G2"))
        if c.ga == c.gb:
            raise r.error(f"G1 = G2 = {c.ga}; a rod needs two different grids", 4)
        return c._set_meta(r)

    @property
    def nodes(self):
        return (self.ga, self.gb)

    def values(self):
        return [self.eid, self.pid, self.ga, self.gb]


@dataclass
class Conrod(Card):
    """CONROD EID G1 G2 MID A J C NSM."""

    NAME = "CONROD"
    KEY = "eid"
    eid: int
    ga: int
    gb: int
    mid: int
    A: float
    J: float = 0.0
    c: float = 0.0
    nsm: float = 0.0

    @classmethod
    def from_raw(cls, r):
        r.check_length(8)
        c = cls(r.integer(1, "EID"), r.integer(2, "G1"), r.integer(3, "G2"), r.integer(4, "MID"),
                r.real(5, "A", 0.0), r.real(6, "J", 0.0), r.real(7, "C", 0.0), r.real(8, "NSM", 0.0))
        if c.ga == c.gb:
            raise r.error(f"G1 = G2 = {c.ga}; a rod needs two different grids", 3)
        return c._set_meta(r)

    @property
    def nodes(self):
        return (self.ga, self.gb)

    def values(self):
        return [self.eid, self.ga, self.gb, self.mid, self.A, self.J or None, self.c or None, self.nsm or None]


def _shell_grids(r, n, cls_name):
    g = tuple(r.integer(3 + k, f"G{k + 1}") for k in range(n))
    for k, gk in enumerate(g):
        if gk <= 0:
            raise r.error(f"G{k + 1} = {gk}; expected a grid id > 0", 3 + k)
    if len(set(g)) != n:
        raise r.error(f"grids {g} repeat a grid; a {cls_name} needs {n} different grids", 3)
    return g


@dataclass
class Cquad4(Card):
    """CQUAD4 EID PID G1 G2 G3 G4 THETA/MCID ZOFFS / blank TFLAG T1 T2 T3 T4.

    ``theta`` is THETA (real, degrees) or MCID (integer); ``t`` the corner
    thicknesses (None when blank).
    """

    NAME = "CQUAD4"
    KEY = "eid"
    eid: int
    pid: int
    g: tuple
    theta: float | int = 0.0
    zoffs: float = 0.0
    tflag: int = 0
    t: tuple = (None, None, None, None)

    N_GRID = 4

    @classmethod
    def from_raw(cls, r):
        n = cls.N_GRID
        i_th = 3 + n                       # THETA/MCID, then ZOFFS
        i_tf = 10                          # TFLAG on the continuation (after one blank / two for CTRIA3)
        r.check_length(i_tf + n)
        eid = r.integer(1, "EID")
        if eid <= 0:
            raise r.error(f"element id {eid}; expected an integer > 0", 1)
        g = _shell_grids(r, n, cls.NAME)
        theta = r.int_or_real(i_th, "THETA/MCID", 0.0)
        zoffs = r.real(i_th + 1, "ZOFFS", 0.0)
        for i in range(i_th + 2, i_tf):
            if not r.blank(i):
                raise r.error(f"field must be blank in {cls.NAME}", i)
        c = cls(eid, r.integer(2, "PID", eid), g, theta, zoffs, r.integer(i_tf, "TFLAG", 0),
                tuple(r.real(i_tf + 1 + k, f"T{k + 1}", None) for k in range(n)))
        return c._set_meta(r)

    @property
    def nodes(self):
        return tuple(self.g)

    def values(self):
        th = None if (isinstance(self.theta, float) and self.theta == 0.0) else self.theta
        head = [self.eid, self.pid, *self.g, th, self.zoffs or None]
        tail = [self.tflag or None, *self.t]
        if all(v is None for v in tail):
            return head
        return head + [None] * (9 - len(head)) + tail     # blanks up to TFLAG (field index 10)

    def unsupported_fields(self) -> list:
        """Descriptions of the fields build_model cannot model ([] when none)."""
        out = []
        if self.theta != 0:
            kind = "MCID" if isinstance(self.theta, int) else "THETA"
            out.append(f"{kind} = {self.theta} (material orientation; leave the field blank — the material is "
                       "isotropic MAT1 so it has no effect on the matrices)")
        if self.zoffs:
            out.append(f"ZOFFS = {self.zoffs} (offset of the reference plane; model the offset with a separate "
                       "grid plane and RBE2 links, or move the grids to the mid-surface)")
        if any(v is not None for v in self.t) or self.tflag:
            out.append(f"TFLAG/T1.. = {self.tflag}, {self.t} (corner thicknesses; give the thickness on the "
                       "PSHELL and leave T1.. blank)")
        return out


@dataclass
class Ctria3(Cquad4):
    """CTRIA3 EID PID G1 G2 G3 THETA/MCID ZOFFS blank / blank TFLAG T1 T2 T3."""

    NAME = "CTRIA3"
    g: tuple = (0, 0, 0)
    t: tuple = (None, None, None)

    N_GRID = 3

