"""Typed Nastran bulk-data cards.

Every card is a dataclass built from a :class:`~updating.bulk.fields.RawCard`
by ``from_raw`` (checking types, defaults and card length) and written back by
``values()`` (the data fields, field 2 first, ``None`` for blank).  Source
location (``line``, ``path``) and preceding ``$`` comments travel with each
card but do not take part in equality, so read → write → read compares values.

Supported: GRID, CORD2R, CORD2C, CORD2S, CBAR, CBEAM, CROD, CONROD, CQUAD4,
CTRIA3, PBAR, PBARL, PBEAM, PBEAML, PROD, PSHELL, MAT1, CONM2, CELAS1, CELAS2,
PELAS, CDAMP1, CDAMP2, PDAMP, SPC, SPC1, SPCADD, RBE2, PARAM, TABDMP1, EIGRL.
Shell cards are read and written with all their fields; what build_model does
not model (THETA/MCID, ZOFFS, corner thicknesses, MID4, MID2 ≠ MID1 ...) is
rejected there, naming the card.

Cross-section formulas for PBARL/PBEAML (:func:`section_properties`) follow
the MSC/NX section library conventions: element y along DIM2 of BAR (so
I1 = DIM1·DIM2³/12), ROD and TUBE dimensions are radii.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from modalab.errors import BulkDataError

from .fields import REQUIRED, RawCard

__all__ = [
    "Card", "Grid", "Coord", "Cbar", "Cbeam", "Crod", "Conrod", "Cquad4", "Ctria3", "Pshell", "Pbar", "Pbarl",
    "Pbeam", "Pbeaml", "Prod",
    "Mat1", "Conm2", "Celas1", "Celas2", "Pelas", "Cdamp1", "Cdamp2", "Pdamp", "Spc", "Spc1", "Spcadd",
    "Rbe2", "Param", "Tabdmp1", "Eigrl", "CARD_TYPES", "SECTION_DIMS", "section_properties", "parse_card",
]


def _meta():
    return field(default=None, compare=False, repr=False)


@dataclass
class Card:
    """Base: source location and comment (not compared)."""

    @property
    def name(self) -> str:
        return self.NAME

    def where(self) -> dict:
        return {"path": self.path, "line": self.line, "card": f"{self.NAME} {self.key()}"}

    def error(self, msg: str) -> BulkDataError:
        return BulkDataError(msg, **self.where())

    def key(self):
        return getattr(self, self.KEY)

    def _set_meta(self, raw: RawCard):
        self.line, self.path, self.comment = raw.line, raw.path, list(raw.comment)
        return self


# ----------------------------------------------------------------- geometry
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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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


# ------------------------------------------------------------------ elements
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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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


# ---------------------------------------------------------------- properties
@dataclass
class Mat1(Card):
    """MAT1 MID E G NU RHO A TREF GE / ST SC SS MCSID (blank E/G/NU completed as Nastran does)."""

    NAME = "MAT1"
    KEY = "mid"
    mid: int
    E: float | None
    G: float | None
    nu: float | None
    rho: float = 0.0
    a: float = 0.0
    tref: float = 0.0
    ge: float = 0.0
    st: float = 0.0
    sc: float = 0.0
    ss: float = 0.0
    mcsid: int = 0
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw(cls, r):
        r.check_length(12)
        c = cls(r.integer(1, "MID"), r.real(2, "E", None), r.real(3, "G", None), r.real(4, "NU", None),
                r.real(5, "RHO", 0.0), r.real(6, "A", 0.0), r.real(7, "TREF", 0.0), r.real(8, "GE", 0.0),
                r.real(9, "ST", 0.0), r.real(10, "SC", 0.0), r.real(11, "SS", 0.0), r.integer(12, "MCSID", 0))
        if c.E is None and c.G is None:
            raise r.error("E and G are both blank; give at least one of them", 2)
        if c.nu is not None and not -1.0 < c.nu <= 0.5:
            raise r.error(f"NU = {c.nu}; expected -1 < NU <= 0.5", 4)
        return c._set_meta(r)

    def resolved(self) -> tuple:
        """(E, G, nu) completed by Nastran's MAT1 rules (two given → third; one given → others 0)."""
        E, G, nu = self.E, self.G, self.nu
        if E is not None and G is not None and nu is None:
            nu = E / (2.0 * G) - 1.0 if G else 0.0
        elif E is not None and nu is not None and G is None:
            G = E / (2.0 * (1.0 + nu))
        elif G is not None and nu is not None and E is None:
            E = 2.0 * (1.0 + nu) * G
        elif E is not None and G is None and nu is None:
            G, nu = 0.0, 0.0
        elif G is not None and E is None and nu is None:
            E, nu = 0.0, 0.0
        return E, G, nu

    def values(self):
        z = lambda v: None if not v else v  # noqa: E731
        return [self.mid, self.E, self.G, self.nu, z(self.rho), z(self.a), z(self.tref), z(self.ge),
                z(self.st), z(self.sc), z(self.ss), z(self.mcsid)]


@dataclass
class Pbar(Card):
    """PBAR PID MID A I1 I2 J NSM / C1 C2 D1 D2 E1 E2 F1 F2 / K1 K2 I12."""

    NAME = "PBAR"
    KEY = "pid"
    pid: int
    mid: int
    A: float = 0.0
    i1: float = 0.0
    i2: float = 0.0
    J: float = 0.0
    nsm: float = 0.0
    stress: tuple = (0.0,) * 8
    k1: float | None = None
    k2: float | None = None
    i12: float = 0.0
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw(cls, r):
        r.check_length(19)
        if not r.blank(8):
            raise r.error("field 9 of PBAR must be blank", 8)
        c = cls(r.integer(1, "PID"), r.integer(2, "MID"), r.real(3, "A", 0.0), r.real(4, "I1", 0.0),
                r.real(5, "I2", 0.0), r.real(6, "J", 0.0), r.real(7, "NSM", 0.0),
                tuple(r.real(i, "stress point", 0.0) for i in range(9, 17)),
                r.real(17, "K1", None), r.real(18, "K2", None), r.real(19, "I12", 0.0))
        if c.i1 < 0 or c.i2 < 0 or c.i1 * c.i2 < c.i12 ** 2:
            raise r.error(f"I1 = {c.i1}, I2 = {c.i2}, I12 = {c.i12}; expected I1, I2 >= 0 and I1·I2 >= I12²", 4)
        return c._set_meta(r)

    def values(self):
        z = lambda v: None if not v else v  # noqa: E731
        return [self.pid, self.mid, self.A, self.i1, self.i2, z(self.J), z(self.nsm), None,
                *[z(v) for v in self.stress], self.k1, self.k2, z(self.i12)]


#: number of DIMi of each PBARL/PBEAML section type (MSC section library)
SECTION_DIMS = {"ROD": 1, "TUBE": 2, "TUBE2": 2, "I": 6, "CHAN": 4, "T": 4, "BOX": 4, "BAR": 2, "CROSS": 4,
                "H": 4, "T1": 4, "I1": 4, "CHAN1": 4, "Z": 4, "CHAN2": 4, "T2": 4, "BOX1": 6, "HEXA": 3,
                "HAT": 4, "HAT1": 5, "DBOX": 10, "L": 4}
#: section types whose properties :func:`section_properties` computes
SUPPORTED_SECTIONS = ("ROD", "TUBE", "BAR", "BOX", "I")


def _rect_J(a: float, b: float) -> float:
    """Saint-Venant torsion constant of a solid a×b rectangle (Roark), as updating.fe's RectangularSection."""
    a, c = (a, b) if a >= b else (b, a)
    r = c / a
    return a * c ** 3 * (1.0 / 3.0 - 0.21 * r * (1.0 - r ** 4 / 12.0))


def section_properties(kind: str, dims) -> dict:
    """A, I1, I2, J (and shear factors k1, k2) of a PBARL/PBEAML section.

    I1 bends in plane 1 (about element z; element y along DIM2 of BAR and BOX,
    along the web DIM1 of I), I2 in plane 2.  Formulas:

    * BAR  (DIM1 = b along z, DIM2 = h along y): A = bh, I1 = b h³/12, I2 = h b³/12,
      J (Roark) = a c³ [1/3 − 0.21 (c/a)(1 − (c/a)⁴/12)], a ≥ c the sides; k = 5/6.
    * ROD  (DIM1 = r): A = πr², I1 = I2 = πr⁴/4, J = πr⁴/2.
    * TUBE (DIM1 = r_o, DIM2 = r_i): A = π(r_o²−r_i²), I = π(r_o⁴−r_i⁴)/4, J = 2I.
    * BOX  (DIM1 = b, DIM2 = h, DIM3 = t of the walls across h, DIM4 = t of the walls across b):
      A = bh − b_i h_i, I1 = (b h³ − b_i h_i³)/12, I2 = (h b³ − h_i b_i³)/12 with
      b_i = b − 2·DIM4, h_i = h − 2·DIM3; Bredt's J = 2 t₃ t₄ (b−t₄)² (h−t₃)² / (b t₄ + h t₃ − t₄² − t₃²);
      shear areas: the walls parallel to each shear direction.
    * I    (DIM1 = depth h along y, DIM2/DIM3 = bottom/top flange widths, DIM4 = web
      thickness, DIM5/DIM6 = bottom/top flange thicknesses): parallel-axis theorem about
      the centroid; open-section J = (DIM2·DIM5³ + DIM3·DIM6³ + (h−DIM5−DIM6)·DIM4³)/3;
      k1 = web area / A (shear along the web), k2 = (5/6)·flange area / A.
    """
    k = kind.upper()
    d = [float(v) for v in dims]
    need = SECTION_DIMS.get(k)
    if need is None:
        raise BulkDataError(f"unknown section type {kind!r}; known types: {', '.join(SECTION_DIMS)}")
    if len(d) != need:
        raise BulkDataError(f"section {k} needs {need} dimensions; got {len(d)}")
    if any(not v > 0 for v in d):
        raise BulkDataError(f"section {k} dimensions {d}; every DIMi must be > 0")
    if k == "BAR":
        b, h = d
        return {"A": b * h, "I1": b * h ** 3 / 12, "I2": h * b ** 3 / 12, "J": _rect_J(b, h),
                "k1": 5 / 6, "k2": 5 / 6}
    if k == "ROD":
        r = d[0]
        I = math.pi * r ** 4 / 4
        return {"A": math.pi * r * r, "I1": I, "I2": I, "J": 2 * I, "k1": 0.9, "k2": 0.9}
    if k == "TUBE":
        ro, ri = d
        if not ri < ro:
            raise BulkDataError(f"TUBE inner radius DIM2 = {ri} must be smaller than the outer DIM1 = {ro}")
        I = math.pi * (ro ** 4 - ri ** 4) / 4
        return {"A": math.pi * (ro ** 2 - ri ** 2), "I1": I, "I2": I, "J": 2 * I, "k1": 0.5, "k2": 0.5}
    if k == "BOX":
        b, h, t3, t4 = d
        bi, hi = b - 2 * t4, h - 2 * t3
        if not (bi > 0 and hi > 0):
            raise BulkDataError(f"BOX walls too thick: DIM1 = {b} must exceed 2·DIM4 = {2 * t4} and DIM2 = {h} "
                                f"2·DIM3 = {2 * t3}")
        A = b * h - bi * hi
        J = 2 * t3 * t4 * (b - t4) ** 2 * (h - t3) ** 2 / (b * t4 + h * t3 - t4 ** 2 - t3 ** 2)
        return {"A": A, "I1": (b * h ** 3 - bi * hi ** 3) / 12, "I2": (h * b ** 3 - hi * bi ** 3) / 12, "J": J,
                "k1": 2 * h * t4 / A, "k2": 2 * b * t3 / A}
    if k == "I":
        h, wb, wt, tw, tb, tt = d
        hw = h - tb - tt
        if not hw > 0:
            raise BulkDataError(f"I section: flange thicknesses DIM5 + DIM6 = {tb + tt} must be below the depth "
                                f"DIM1 = {h}")
        parts = [(wb * tb, tb / 2, wb * tb ** 3 / 12), (hw * tw, tb + hw / 2, tw * hw ** 3 / 12),
                 (wt * tt, h - tt / 2, wt * tt ** 3 / 12)]
        A = sum(p[0] for p in parts)
        yc = sum(p[0] * p[1] for p in parts) / A
        I1 = sum(p[2] + p[0] * (p[1] - yc) ** 2 for p in parts)
        I2 = (tb * wb ** 3 + hw * tw ** 3 + tt * wt ** 3) / 12
        J = (wb * tb ** 3 + wt * tt ** 3 + hw * tw ** 3) / 3
        return {"A": A, "I1": I1, "I2": I2, "J": J, "k1": hw * tw / A, "k2": 5 / 6 * (wb * tb + wt * tt) / A}
    raise BulkDataError(f"section type {k} is read but its properties are not implemented; supported: "
                        f"{', '.join(SUPPORTED_SECTIONS)}. Convert it to PBAR/PBEAM")


@dataclass
class Pbarl(Card):
    """PBARL PID MID GROUP TYPE / DIM1 ... DIMn NSM."""

    NAME = "PBARL"
    KEY = "pid"
    pid: int
    mid: int
    group: str = "MSCBML0"
    type: str = "BAR"
    dims: tuple = ()
    nsm: float = 0.0
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw(cls, r):
        pid, mid = r.integer(1, "PID"), r.integer(2, "MID")
        group = r.string(3, "GROUP", "MSCBML0")
        typ = r.string(4, "TYPE", choices=tuple(SECTION_DIMS))
        n = SECTION_DIMS[typ]
        r.check_length(8 + n + 1, f" for section {typ} ({n} dimensions and NSM)")
        dims = tuple(r.real(9 + i, f"DIM{i + 1}") for i in range(n))
        for i, v in enumerate(dims):
            if not v > 0:
                raise r.error(f"DIM{i + 1} = {v}; section dimensions must be > 0", 9 + i)
        return cls(pid, mid, group, typ, dims, r.real(9 + n, "NSM", 0.0))._set_meta(r)

    def section(self) -> dict:
        try:
            return section_properties(self.type, self.dims)
        except BulkDataError as e:
            raise self.error(str(e)) from None

    def values(self):
        return [self.pid, self.mid, None if self.group == "MSCBML0" else self.group, self.type, None, None,
                None, None, *self.dims, self.nsm or None]


@dataclass
class Pbeam(Card):
    """PBEAM (stations: end A, optional intermediate, end B) with K1 K2 S1 S2 NSI CW / M N.

    ``stations`` is a tuple of (so, x/xb, A, I1, I2, I12, J, NSM, stress(8)) with
    end A first (so = 'YES', x = 0).  A card with only end A is prismatic.
    """

    NAME = "PBEAM"
    KEY = "pid"
    pid: int
    mid: int
    stations: tuple = ()
    k1: float = 1.0
    k2: float = 1.0
    tail: tuple = (0.0,) * 14     # S1 S2 NSI(A) NSI(B) CW(A) CW(B) M1(A) M2(A) M1(B) M2(B) N1(A) N2(A) N1(B) N2(B)
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw(cls, r):
        """Line layout: line 0 end A; then, when the card has SO lines, line 1 is end A's stress
        line (unless it is an SO line); each ``SO = YES`` station line is followed by its stress
        line; the last (at most two) lines are K1 K2 S1 S2 NSI CW and M N.  Without SO lines a
        card of 2, 3 or 4 lines is (K), (K, M) or (stress, K, M).  End B defaults to end A."""
        pid, mid = r.integer(1, "PID"), r.integer(2, "MID")
        nlines = (r.n_used() - 1 + 7) // 8

        def start(k):
            return 1 + 8 * k

        def is_so(k):
            return k < nlines and isinstance(r.value(start(k), "SO"), str)

        def props(i0, what, default):
            return tuple(r.real(i0 + j, f"{nm}{what}", default[j]) for j, nm in
                         enumerate(("A", "I1", "I2", "I12", "J", "NSM")))

        def stress(i0):
            return tuple(r.real(i0 + j, "stress point", 0.0) for j in range(8))

        a_props = props(3, "(A)", (0.0,) * 6)
        has_so = any(is_so(k) for k in range(1, nlines))
        k = 1
        a_stress = (0.0,) * 8
        if k < nlines and not is_so(k) and (has_so or nlines == 4):
            a_stress = stress(start(k))
            k += 1
        stations = [("YES", 0.0, *a_props, a_stress)]
        while is_so(k):
            i0 = start(k)
            so = r.string(i0, "SO", choices=("YES", "YESA", "NO"))
            x = r.real(i0 + 1, "X/XB")
            if not 0.0 < x <= 1.0:
                raise r.error(f"station X/XB = {x}; expected 0 < X/XB <= 1", i0 + 1)
            if x <= stations[-1][1]:
                raise r.error(f"station X/XB = {x} does not increase along the beam", i0 + 1)
            p = props(i0 + 2, f"(station {len(stations)})", a_props)
            k += 1
            st = (0.0,) * 8
            if so == "YES" and k < nlines and not is_so(k):
                st = stress(start(k))
                k += 1
            stations.append((so, x, *p, st))
        if stations[-1][1] != 1.0:
            if len(stations) > 1:
                raise r.error(f"the last PBEAM station is at X/XB = {stations[-1][1]}; end B must be X/XB = 1.0")
            stations.append(("YES", 1.0, *a_props, a_stress))
        if nlines - k > 2:
            raise r.error(f"PBEAM has {nlines - k} lines after its stations; expected at most two "
                          "(K1 K2 S1 S2 NSI CW, and M N). Check the SO fields (YES/YESA/NO)", start(k))
        k1, k2, tail = 1.0, 1.0, [0.0] * 14
        if k < nlines:
            i0 = start(k)
            k1, k2 = r.real(i0, "K1", 1.0), r.real(i0 + 1, "K2", 1.0)
            for j in range(6):
                tail[j] = r.real(i0 + 2 + j, "S/NSI/CW", 0.0)
            k += 1
        if k < nlines:
            i0 = start(k)
            for j in range(8):
                tail[6 + j] = r.real(i0 + j, "M/N", 0.0)
        return cls(pid, mid, tuple(stations), k1, k2, tuple(tail))._set_meta(r)

    def prismatic(self) -> bool:
        a = self.stations[0][2:8]
        return all(tuple(s[2:8]) == tuple(a) for s in self.stations[1:])

    def values(self):
        z = lambda v: None if not v else v  # noqa: E731
        a = self.stations[0]
        out = [self.pid, self.mid, a[2], a[3], a[4], z(a[5]), z(a[6]), z(a[7]), *[z(v) for v in a[8]]]
        for s in self.stations[1:]:
            out += [s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7]]
            if s[0] == "YES":
                out += [z(v) for v in s[8]]
        tail = [None if self.k1 == 1.0 else self.k1, None if self.k2 == 1.0 else self.k2,
                *[z(v) for v in self.tail]]
        if any(v is not None for v in tail):
            out += tail
        return out


@dataclass
class Pbeaml(Card):
    """PBEAML PID MID GROUP TYPE / DIM1(A)..DIMn(A) NSM(A) [SO X/XB DIM1..DIMn NSM]...

    ``stations``: tuple of (so, x/xb, dims, nsm), end A first.
    """

    NAME = "PBEAML"
    KEY = "pid"
    pid: int
    mid: int
    group: str = "MSCBML0"
    type: str = "BAR"
    stations: tuple = ()
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw(cls, r):
        pid, mid = r.integer(1, "PID"), r.integer(2, "MID")
        group = r.string(3, "GROUP", "MSCBML0")
        typ = r.string(4, "TYPE", choices=tuple(SECTION_DIMS))
        n = SECTION_DIMS[typ]
        i = 9
        dims = tuple(r.real(i + j, f"DIM{j + 1}(A)") for j in range(n))
        stations = [("YES", 0.0, dims, r.real(i + n, "NSM(A)", 0.0))]
        i += n + 1
        end = r.n_used()
        while i < end:
            so = r.string(i, "SO", "YES", choices=("YES", "YESA", "NO"))
            x = r.real(i + 1, "X/XB")
            if not 0.0 < x <= 1.0:
                raise r.error(f"station X/XB = {x}; expected 0 < X/XB <= 1", i + 1)
            d = tuple(r.real(i + 2 + j, f"DIM{j + 1}") for j in range(n))
            stations.append((so, x, d, r.real(i + 2 + n, "NSM", 0.0)))
            i += n + 3
        for s in stations:
            for j, v in enumerate(s[2]):
                if not v > 0:
                    raise r.error(f"DIM{j + 1} = {v} at X/XB = {s[1]}; section dimensions must be > 0")
        if stations[-1][1] != 1.0:
            if len(stations) > 1:
                raise r.error(f"the last PBEAML station is at X/XB = {stations[-1][1]}; end B must be "
                              "X/XB = 1.0")
            stations.append(("YES", 1.0, dims, stations[0][3]))
        return cls(pid, mid, group, typ, tuple(stations))._set_meta(r)

    def prismatic(self) -> bool:
        return all(s[2] == self.stations[0][2] and s[3] == self.stations[0][3] for s in self.stations[1:])

    @property
    def dims(self):
        return self.stations[0][2]

    @property
    def nsm(self):
        return self.stations[0][3]

    def section(self) -> dict:
        try:
            return section_properties(self.type, self.dims)
        except BulkDataError as e:
            raise self.error(str(e)) from None

    def values(self):
        out = [self.pid, self.mid, None if self.group == "MSCBML0" else self.group, self.type, None, None,
               None, None, *self.stations[0][2], self.stations[0][3] or None]
        for so, x, d, nsm in self.stations[1:]:
            out += [None if so == "YES" else so, x, *d, nsm or None]
        return out


@dataclass
class Prod(Card):
    """PROD PID MID A J C NSM."""

    NAME = "PROD"
    KEY = "pid"
    pid: int
    mid: int
    A: float = 0.0
    J: float = 0.0
    c: float = 0.0
    nsm: float = 0.0
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw(cls, r):
        r.check_length(6)
        return cls(r.integer(1, "PID"), r.integer(2, "MID"), r.real(3, "A"), r.real(4, "J", 0.0),
                   r.real(5, "C", 0.0), r.real(6, "NSM", 0.0))._set_meta(r)

    def values(self):
        return [self.pid, self.mid, self.A, self.J or None, self.c or None, self.nsm or None]


@dataclass
class Pshell(Card):
    """PSHELL PID MID1 T MID2 12I/T3 MID3 TS/T NSM / Z1 Z2 MID4 (blank MID2/MID3/MID4 are None)."""

    NAME = "PSHELL"
    KEY = "pid"
    pid: int
    mid1: int | None
    t: float | None = None
    mid2: int | None = None
    bending: float = 1.0
    mid3: int | None = None
    shear: float = 0.833333
    nsm: float = 0.0
    z1: float | None = None
    z2: float | None = None
    mid4: int | None = None
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw(cls, r):
        r.check_length(11)
        c = cls(r.integer(1, "PID"), r.integer(2, "MID1", None), r.real(3, "T", None), r.integer(4, "MID2", None),
                r.real(5, "12I/T**3", 1.0), r.integer(6, "MID3", None), r.real(7, "TS/T", 0.833333),
                r.real(8, "NSM", 0.0), r.real(9, "Z1", None), r.real(10, "Z2", None), r.integer(11, "MID4", None))
        if c.t is not None and c.t < 0:
            raise r.error(f"T = {c.t}; expected a thickness >= 0", 3)
        return c._set_meta(r)

    @property
    def mid(self):
        """MID1 (the material cross-referenced by :meth:`BulkData.check`)."""
        return self.mid1

    def values(self):
        return [self.pid, self.mid1, self.t, self.mid2, None if self.bending == 1.0 else self.bending, self.mid3,
                None if self.shear == 0.833333 else self.shear, self.nsm or None, self.z1, self.z2, self.mid4]


@dataclass
class Pelas(Card):
    """One PELAS property (a card may hold two): PID K GE S."""

    NAME = "PELAS"
    KEY = "pid"
    pid: int
    k: float
    ge: float = 0.0
    s: float = 0.0
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw_all(cls, r):
        r.check_length(8)
        out = [cls(r.integer(1, "PID1"), r.real(2, "K1"), r.real(3, "GE1", 0.0), r.real(4, "S1", 0.0))]
        if not all(r.blank(i) for i in range(5, 9)):
            out.append(cls(r.integer(5, "PID2"), r.real(6, "K2"), r.real(7, "GE2", 0.0), r.real(8, "S2", 0.0)))
        return [c._set_meta(r) for c in out]

    def values(self):
        return [self.pid, self.k, self.ge or None, self.s or None]


@dataclass
class Pdamp(Card):
    """One PDAMP property (a card may hold four): PID B."""

    NAME = "PDAMP"
    KEY = "pid"
    pid: int
    b: float
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw_all(cls, r):
        r.check_length(8)
        out = []
        for j in range(4):
            i = 1 + 2 * j
            if j and r.blank(i) and r.blank(i + 1):
                continue
            out.append(cls(r.integer(i, f"PID{j + 1}"), r.real(i + 1, f"B{j + 1}")))
        return [c._set_meta(r) for c in out]

    def values(self):
        return [self.pid, self.b]


# --------------------------------------------------------------- constraints
@dataclass
class Spc(Card):
    """SPC SID G1 C1 D1 G2 C2 D2; ``items`` = ((grid, comps, d), ...)."""

    NAME = "SPC"
    KEY = "sid"
    sid: int
    items: tuple = ()
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

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


# ------------------------------------------------------------- model control
@dataclass
class Param(Card):
    """PARAM NAME V1 V2 ...  (values int, real or name)."""

    NAME = "PARAM"
    KEY = "pname"
    pname: str
    vals: tuple = ()
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw(cls, r):
        name = r.string(1, "N")
        n = r.n_used()
        vals = tuple(r.value(i, "V") for i in range(2, n))
        if not vals or vals[0] is None:
            raise r.error(f"PARAM {name} has no value in field 3", 2)
        return cls(name, vals)._set_meta(r)

    @property
    def value(self):
        return self.vals[0]

    def values(self):
        return [self.pname, *self.vals]


@dataclass
class Tabdmp1(Card):
    """TABDMP1 TID TYPE / f1 g1 f2 g2 ... ENDT (TYPE = G, CRIT or Q)."""

    NAME = "TABDMP1"
    KEY = "tid"
    tid: int
    type: str = "G"
    freq_hz: tuple = ()
    damping: tuple = ()
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw(cls, r):
        tid = r.integer(1, "TID")
        typ = r.string(2, "TYPE", "G", choices=("G", "CRIT", "Q"))
        for i in range(3, 9):
            if not r.blank(i):
                raise r.error("fields 4-9 of TABDMP1 must be blank", i)
        f, g = [], []
        i, end = 9, r.n_used()
        closed = False
        while i < end:
            if r.raw(i).upper() == "ENDT":
                closed = True
                if any(not r.blank(j) for j in range(i + 1, end)):
                    raise r.error("fields after ENDT must be blank", i + 1)
                break
            if r.raw(i).upper() == "SKIP" or r.raw(i + 1).upper() == "SKIP":
                i += 2
                continue
            f.append(r.real(i, "f"))
            g.append(r.real(i + 1, "g"))
            i += 2
        if not closed:
            raise r.error("TABDMP1 table is not closed by ENDT; add ENDT after the last (f, g) pair")
        if not f:
            raise r.error("TABDMP1 table has no (f, g) pair")
        if any(b < a for a, b in zip(f, f[1:])):
            raise r.error(f"TABDMP1 frequencies {f} must ascend")
        return cls(tid, typ, tuple(f), tuple(g))._set_meta(r)

    def values(self):
        out = [self.tid, self.type, None, None, None, None, None, None]
        for a, b in zip(self.freq_hz, self.damping):
            out += [a, b]
        return out + ["ENDT"]


@dataclass
class Eigrl(Card):
    """EIGRL SID V1 V2 ND MSGLVL MAXSET SHFSCL NORM (Lanczos request; stored for information)."""

    NAME = "EIGRL"
    KEY = "sid"
    sid: int
    v1: float | None = None
    v2: float | None = None
    nd: int | None = None
    msglvl: int = 0
    maxset: int | None = None
    shfscl: float | None = None
    norm: str = "MASS"
    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @classmethod
    def from_raw(cls, r):
        r.check_length(8 + 8)  # option continuations (ALPH, NUMS ...) are kept out of the typed fields
        return cls(r.integer(1, "SID"), r.real(2, "V1", None), r.real(3, "V2", None), r.integer(4, "ND", None),
                   r.integer(5, "MSGLVL", 0), r.integer(6, "MAXSET", None), r.real(7, "SHFSCL", None),
                   r.string(8, "NORM", "MASS", choices=("MASS", "MAX")))._set_meta(r)

    def values(self):
        return [self.sid, self.v1, self.v2, self.nd, self.msglvl or None, self.maxset, self.shfscl,
                None if self.norm == "MASS" else self.norm]


# -------------------------------------------------------------------- parsing
def _single(cls):
    return lambda r: [cls.from_raw(r)]


CARD_TYPES = {
    "GRID": _single(Grid), "CORD2R": _single(Coord), "CORD2C": _single(Coord), "CORD2S": _single(Coord),
    "CBAR": _single(Cbar), "CBEAM": _single(Cbeam), "CROD": _single(Crod), "CONROD": _single(Conrod),
    "CQUAD4": _single(Cquad4), "CTRIA3": _single(Ctria3), "PSHELL": _single(Pshell),
    "PBAR": _single(Pbar), "PBARL": _single(Pbarl), "PBEAM": _single(Pbeam), "PBEAML": _single(Pbeaml),
    "PROD": _single(Prod), "MAT1": _single(Mat1), "CONM2": _single(Conm2),
    "CELAS1": _single(Celas1), "CELAS2": _single(Celas2), "PELAS": Pelas.from_raw_all,
    "CDAMP1": _single(Cdamp1), "CDAMP2": _single(Cdamp2), "PDAMP": Pdamp.from_raw_all,
    "SPC": _single(Spc), "SPC1": _single(Spc1), "SPCADD": _single(Spcadd), "RBE2": _single(Rbe2),
    "PARAM": _single(Param), "TABDMP1": _single(Tabdmp1), "EIGRL": _single(Eigrl),
}


def parse_card(raw: RawCard) -> list | None:
    """Typed cards from a raw card, or None when the card type is not supported."""
    f = CARD_TYPES.get(raw.name)
    if f is None:
        return None
    return f(raw)
