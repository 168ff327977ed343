"""Element properties: PBAR, PBARL, PBEAM, PBEAML, PROD, PSHELL, PELAS, PDAMP."""
from __future__ import annotations

from dataclasses import dataclass

from modalab.core.errors import BulkDataError

from updating.fe.bulk.cards.base import Card
from updating.fe.bulk.cards.sections import SECTION_DIMS, section_properties

__all__ = ["Pbar", "Pbarl", "Pbeam", "Pbeaml", "Prod", "Pshell", "Pelas", "Pdamp"]


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

