"""Case-independent control cards: PARAM, TABDMP1, EIGRL."""
from __future__ import annotations

from dataclasses import dataclass

from updating.fe.bulk.cards.base import Card

__all__ = ["Param", "Tabdmp1", "Eigrl"]


@dataclass
class Param(Card):
    """PARAM NAME V1 V2 ...  (values int, real or name)."""

    NAME = "PARAM"
    KEY = "pname"
    pname: str
    vals: tuple = ()

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

    @classmethod
    def from_raw(cls, r):
        r.check_length(8 + 8)  # option continuations (ALPH, NUMS ...) are kept out of the typed fields
        return cls(r.integer(1, "SID"), r.real(2, "V1", None), r.real(3, "V2", None), r.integer(4, "ND", None),
                   r.integer(5, "MSGLVL", 0), r.integer(6, "MAXSET", None), r.real(7, "SHFSCL", None),
                   r.string(8, "NORM", "MASS", choices=("MASS", "MAX")))._set_meta(r)

    def values(self):
        return [self.sid, self.v1, self.v2, self.nd, self.msglvl or None, self.maxset, self.shfscl,
                None if self.norm == "MASS" else self.norm]

