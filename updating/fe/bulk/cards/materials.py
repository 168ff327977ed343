"""Materials: MAT1."""
from __future__ import annotations

from dataclasses import dataclass

from updating.fe.bulk.cards.base import Card

__all__ = ["Mat1"]


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

