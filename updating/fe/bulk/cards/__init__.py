"""Typed Nastran bulk-data cards.

Every card is a dataclass built from a :class:`~updating.fe.bulk.fields.RawCard`
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

One module per card family: :mod:`.base`, :mod:`.geometry`, :mod:`.elements`, :mod:`.scalar`,
:mod:`.materials`, :mod:`.sections`, :mod:`.properties`, :mod:`.constraints`, :mod:`.control`.
"""
from __future__ import annotations

from updating.fe.bulk.fields import RawCard
from updating.fe.bulk.cards.base import Card
from updating.fe.bulk.cards.geometry import Grid, Coord
from updating.fe.bulk.cards.elements import Cbar, Cbeam, Crod, Conrod, Cquad4, Ctria3
from updating.fe.bulk.cards.scalar import Celas1, Cdamp1, Celas2, Cdamp2, Conm2
from updating.fe.bulk.cards.materials import Mat1
from updating.fe.bulk.cards.sections import SECTION_DIMS, SUPPORTED_SECTIONS, section_properties
from updating.fe.bulk.cards.properties import Pbar, Pbarl, Pbeam, Pbeaml, Prod, Pshell, Pelas, Pdamp
from updating.fe.bulk.cards.constraints import Spc, Spc1, Spcadd, Rbe2
from updating.fe.bulk.cards.control import Param, Tabdmp1, Eigrl

__all__ = [
    "Card", "Grid", "Coord", "Cbar", "Cbeam", "Crod", "Conrod", "Cquad4", "Ctria3", "Pshell", "Pbar", "Pbarl",
    "Pbeam", "Pbeaml", "Prod",
    "Mat1", "Conm2", "Celas1", "Celas2", "Pelas", "Cdamp1", "Cdamp2", "Pdamp", "Spc", "Spc1", "Spcadd",
    "Rbe2", "Param", "Tabdmp1", "Eigrl", "CARD_TYPES", "SECTION_DIMS", "section_properties", "parse_card",
]


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

