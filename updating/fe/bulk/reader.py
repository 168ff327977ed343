"""Reading whole Nastran decks into :class:`BulkData`.

``read_bdf(source)`` accepts a path or the text of a deck:

* a SOL 103 input file — executive control (``SOL 103`` … ``CEND``) and case
  control (``SUBCASE``, ``SPC = 1``, ``METHOD = 10``, ``SDAMPING = 5`` …) are
  recognised and skipped up to ``BEGIN BULK``; the SOL statement and the
  case-control selections are kept in :attr:`BulkData.case_control`;
* a bulk-data-only file (no ``CEND``/``BEGIN BULK``).

``INCLUDE 'file'`` is honoured in every section (paths relative to the
including file, then to the main file); reading stops at ``ENDDATA``.
Cards this package does not model are kept in :attr:`BulkData.unsupported`
(and written back by the writer) and listed, with counts and line numbers, in
ONE logged warning (logger ``updating.fe.bulk.reader``); nothing is dropped silently.  A card name that is no
Nastran card but close to one (:data:`KNOWN_CARDS`: ``CBAT`` or ``CBRA`` for ``CBAR``) is a typo: a
:class:`~modalab.core.errors.BulkDataError` naming the file, the line and the closest card, unless
``ignore_unsupported``; a name far from every known card (an exotic card) is kept with the warning.

A deck file that is empty, not text, or looks cut short (its last line has no
line break and there is no ``ENDDATA``; grids but no elements without
``ENDDATA``) raises :class:`modalab.core.errors.BulkDataError` naming the file and
line and saying that it looks truncated.

Cross-reference checks (``xref=True``): duplicate grid, element, property,
material and coordinate-system ids; elements referring to unknown grids,
properties or materials; grids referring to unknown coordinate systems; SPC,
RBE2 and CONM2 referring to unknown grids.  Each raises
:class:`modalab.core.errors.BulkDataError` naming the card, line and file.
"""
from __future__ import annotations

import logging
import os
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from modalab.core.errors import BulkDataError

from updating.fe.bulk import cards as C
from updating.fe.bulk.card_names import NASTRAN_CARDS, closest_card
from updating.fe.bulk.fields import Line, group_cards
from updating.fe.bulk.geometry import resolve_coord
from modalab.core.errors import _where

log = logging.getLogger(__name__)

__all__ = ["BulkData", "read_bdf", "UnsupportedCardWarning", "CaseControl"]


class UnsupportedCardWarning(UserWarning):
    """Kept for backward compatibility; unsupported cards are now reported by one logged warning."""


@dataclass
class CaseControl:
    """What the reader keeps from executive and case control.

    ``sol``: the SOL statement value ('103', 'SEMODES' ...) or None.
    ``commands``: {subcase id (0 = above the first SUBCASE): {'SPC': '1', 'METHOD': '10', ...}}.
    ``executive``, ``case``: the raw lines (without comments), for writing the deck back.
    """

    sol: str | None = None
    commands: dict = field(default_factory=dict)
    executive: list = field(default_factory=list)
    case: list = field(default_factory=list)

    def selection(self, key: str):
        """Integer set id chosen by ``key`` (SPC, METHOD, SDAMPING ...) in the first subcase or globally; None when
        none is chosen, an error when the value is not an integer (a typo must not fall back to 'no selection')."""
        key = key.upper()
        for sc in sorted(self.commands, key=lambda s: (s == 0, s)):
            v = self.commands[sc].get(key)
            if v is not None:
                try:
                    return int(v)
                except ValueError:
                    raise BulkDataError(f"case control '{key} = {v}'" + (f" (subcase {sc})" if sc else "")
                                        + f": expected an integer set id, e.g. '{key} = 1'") from None
        return None

    @property
    def present(self) -> bool:
        return bool(self.executive or self.case)


@dataclass
class BulkData:
    """Typed cards of a deck, keyed by id.

    grids {nid: Grid}; coords {cid: Coord}; elements {eid: CBAR/CBEAM/CROD/CONROD/CQUAD4/CTRIA3/CELASi/CDAMPi/
    CONM2}; rigid {eid: RBE2}; properties {pid: PBAR/PBARL/PBEAM/PBEAML/PROD/PSHELL/PELAS/PDAMP};
    materials {mid: MAT1}; spcs {sid: [SPC/SPC1 ...]}; spcadds {sid: SPCADD};
    params {name: PARAM}; tables {tid: TABDMP1}; eigrls {sid: EIGRL};
    unsupported [RawCard]; case_control :class:`CaseControl`; path.
    """

    grids: dict = field(default_factory=dict)
    coords: dict = field(default_factory=dict)
    elements: dict = field(default_factory=dict)
    rigid: dict = field(default_factory=dict)
    properties: dict = field(default_factory=dict)
    materials: dict = field(default_factory=dict)
    spcs: dict = field(default_factory=dict)
    spcadds: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)
    tables: dict = field(default_factory=dict)
    eigrls: dict = field(default_factory=dict)
    unsupported: list = field(default_factory=list)
    case_control: CaseControl = field(default_factory=CaseControl)
    path: str | None = None

    # ------------------------------------------------------------- adding
    def add(self, card) -> None:
        """Add a typed card; duplicate ids raise :class:`BulkDataError` naming both lines."""
        if isinstance(card, C.Grid):
            self._put(self.grids, card.nid, card, "grid id")
        elif isinstance(card, C.Coord):
            self._put(self.coords, card.cid, card, "coordinate system id")
        elif isinstance(card, C.Rbe2):
            self._unique_eid(card)
            self.rigid[card.eid] = card
        elif isinstance(card, (C.Cbar, C.Crod, C.Conrod, C.Cquad4, C.Celas1, C.Celas2, C.Cdamp2, C.Conm2)):
            self._unique_eid(card)
            self.elements[card.eid] = card
        elif isinstance(card, (C.Pbar, C.Pbarl, C.Pbeam, C.Pbeaml, C.Prod, C.Pshell, C.Pelas, C.Pdamp)):
            self._put(self.properties, card.pid, card, "property id")
        elif isinstance(card, C.Mat1):
            self._put(self.materials, card.mid, card, "material id")
        elif isinstance(card, (C.Spc, C.Spc1)):
            self.spcs.setdefault(card.sid, []).append(card)
        elif isinstance(card, C.Spcadd):
            self._put(self.spcadds, card.sid, card, "SPCADD set id")
        elif isinstance(card, C.Param):
            if card.pname in self.params and self.params[card.pname] != card:
                old = self.params[card.pname]
                raise card.error(f"PARAM {card.pname} is given twice with different values ({old.vals} at line "
                                 f"{old.line}, {card.vals} here); keep one")
            self.params[card.pname] = card
        elif isinstance(card, C.Tabdmp1):
            self._put(self.tables, card.tid, card, "TABDMP1 id")
        elif isinstance(card, C.Eigrl):
            self._put(self.eigrls, card.sid, card, "EIGRL set id")
        else:  # pragma: no cover - every parsed type is handled above
            raise BulkDataError(f"internal: no slot for card {type(card).__name__}")

    def _put(self, table, key, card, what):
        old = table.get(key)
        if old is not None:
            loc = f"line {old.line}" + (f" of {old.path!r}" if old.path and old.path != card.path else "")
            raise card.error(f"duplicate {what} {key}: already defined by {old.name} at {loc}; every "
                             f"{what} must be unique — renumber one of them")
        table[key] = card

    def _unique_eid(self, card):
        for table in (self.elements, self.rigid):
            if card.eid in table:
                self._put(table, card.eid, card, "element id")

    # ------------------------------------------------------------ queries
    def param(self, name: str, default=None):
        p = self.params.get(name.upper())
        return default if p is None else p.value

    def count(self) -> Counter:
        """Number of cards of each type (unsupported included)."""
        c = Counter()
        for table in (self.grids, self.coords, self.elements, self.rigid, self.properties, self.materials,
                      self.spcadds, self.params, self.tables, self.eigrls):
            c.update(card.name for card in table.values())
        for lst in self.spcs.values():
            c.update(card.name for card in lst)
        c.update(r.name for r in self.unsupported)
        return c

    def cards(self) -> list:
        """Every typed card, in a stable writing order."""
        out = [*self.params.values(), *self.eigrls.values(), *self.tables.values()]
        out += [self.coords[k] for k in sorted(self.coords)]
        out += [self.grids[k] for k in sorted(self.grids)]
        out += [self.materials[k] for k in sorted(self.materials)]
        out += [self.properties[k] for k in sorted(self.properties)]
        out += [self.elements[k] for k in sorted(self.elements)]
        out += [self.rigid[k] for k in sorted(self.rigid)]
        for sid in sorted(self.spcs):
            out += self.spcs[sid]
        out += [self.spcadds[k] for k in sorted(self.spcadds)]
        return out

    def __eq__(self, other) -> bool:
        if not isinstance(other, BulkData):
            return NotImplemented
        keys = ("grids", "coords", "elements", "rigid", "properties", "materials", "spcs", "spcadds", "params",
                "tables", "eigrls")
        if any(getattr(self, k) != getattr(other, k) for k in keys):
            return False
        ua = [(r.name, [f.strip() for f in r.fields[:r.n_used()]]) for r in self.unsupported]
        ub = [(r.name, [f.strip() for f in r.fields[:r.n_used()]]) for r in other.unsupported]
        return ua == ub

    def __repr__(self) -> str:
        c = self.count()
        top = ", ".join(f"{k} {v}" for k, v in sorted(c.items()))
        return f"BulkData({self.path or 'text'}: {top or 'empty'})"

    # --------------------------------------------------------- geometry
    def coord_system(self, cid: int):
        """The resolved :class:`CoordSystem` of ``cid`` (0 = basic)."""
        return resolve_coord(self, cid)

    def grid_xyz(self, nid: int) -> np.ndarray:
        """Basic coordinates of grid ``nid`` (through its CP system)."""
        g = self.grids[nid]
        return self.coord_system(g.cp).to_basic(g.xyz)

    # ------------------------------------------------------ cross-reference
    def check(self) -> None:
        """Cross-reference checks (see the module docstring)."""

        def need_grid(card, nid, what="grid"):
            if nid not in self.grids:
                raise card.error(f"{what} {nid} is not defined by any GRID card; add the GRID or fix the id")

        for cid in self.coords:
            resolve_coord(self, cid)
        for g in self.grids.values():
            for what, cid in (("CP", g.cp), ("CD", g.cd)):
                if cid > 0 and cid not in self.coords:
                    raise g.error(f"{what} = {cid} refers to an undefined coordinate system; add a CORD2R/C/S "
                                  f"card with CID {cid}")
        for p in self.properties.values():
            mid = getattr(p, "mid", None)
            if mid is not None and mid not in self.materials:
                raise p.error(f"material {mid} is not defined; add a MAT1 card with MID {mid}")
            if isinstance(p, C.Pshell):
                for what, m in (("MID2", p.mid2), ("MID3", p.mid3), ("MID4", p.mid4)):
                    if m is not None and m > 0 and m not in self.materials:
                        raise p.error(f"{what} = {m} is not defined; add a MAT1 card with MID {m}")
        beam_props = (C.Pbar, C.Pbarl)
        for e in self.elements.values():
            for n in e.nodes:
                need_grid(e, n)
            if isinstance(e, C.Cbar):
                g0 = e.g0
                if g0 is not None:
                    need_grid(e, g0, "orientation grid G0")
                ok = (C.Pbeam, C.Pbeaml) if isinstance(e, C.Cbeam) else beam_props
                self._need_prop(e, e.pid, ok)
            elif isinstance(e, C.Crod):
                self._need_prop(e, e.pid, (C.Prod,))
            elif isinstance(e, C.Cquad4):           # and CTRIA3
                self._need_prop(e, e.pid, (C.Pshell,))
            elif isinstance(e, C.Conrod):
                if e.mid not in self.materials:
                    raise e.error(f"material {e.mid} is not defined; add a MAT1 card with MID {e.mid}")
            elif isinstance(e, C.Cdamp1):
                self._need_prop(e, e.pid, (C.Pdamp,))
            elif isinstance(e, C.Celas1):
                self._need_prop(e, e.pid, (C.Pelas,))
            elif isinstance(e, C.Conm2):
                if e.cid > 0 and e.cid not in self.coords:
                    raise e.error(f"CID = {e.cid} refers to an undefined coordinate system")
        for r in self.rigid.values():
            for n in r.nodes:
                need_grid(r, n)
        for lst in self.spcs.values():
            for s in lst:
                for n in s.grids():
                    need_grid(s, n)
        for a in self.spcadds.values():
            for sid in a.sets:
                if sid not in self.spcs:
                    raise a.error(f"SPC set {sid} is not defined by any SPC/SPC1 card")

    def _need_prop(self, e, pid, kinds):
        p = self.properties.get(pid)
        names = "/".join(k.NAME for k in kinds)
        if p is None:
            raise e.error(f"property {pid} is not defined; add a {names} card with PID {pid}")
        if not isinstance(p, kinds):
            raise e.error(f"property {pid} is a {p.name} (line {p.line}); a {e.name} needs a {names}")


# ---------------------------------------------------------------- deck reading
_BEGIN_BULK = re.compile(r"^\s*BEGIN\s*,?\s*(BULK)?\s*(\$.*)?$", re.IGNORECASE)
_CEND = re.compile(r"^\s*CEND\s*(\$.*)?$", re.IGNORECASE)
_ENDDATA = re.compile(r"^\s*ENDDATA", re.IGNORECASE)
_INCLUDE = re.compile(r"^\s*INCLUDE\b\s*(.*)$", re.IGNORECASE)
_SUBCASE = re.compile(r"^\s*SUBCASE\s+(\d+)", re.IGNORECASE)
_ASSIGN = re.compile(r"^\s*([A-Z][A-Z0-9]*)\s*(?:\([^)]*\))?\s*=\s*(.+?)\s*$", re.IGNORECASE)
_SOL = re.compile(r"^\s*SOL\s+([A-Z0-9]+)", re.IGNORECASE)


class _Lines(list):
    """The lines of a file, with whether the file ends with a line break (a cut file usually does not)."""

    ends_with_newline = True


def _file_lines(path: Path) -> list:
    try:
        raw = path.read_bytes()
    except IsADirectoryError:
        raise BulkDataError("the path is a folder; expected a Nastran bulk-data file (.bdf)", path=str(path)) from None
    except OSError as e:
        raise BulkDataError(f"cannot read the file: {e.strerror or e}; check the path", path=str(path)) from None
    nul = raw.find(b"\x00")
    if nul >= 0:
        raise BulkDataError(f"the file is not text (a NUL byte at offset {nul}); expected Nastran bulk data",
                            path=str(path), line=raw.count(b"\n", 0, nul) + 1)
    text = raw.decode("utf-8", errors="replace")
    bad = text.count("\ufffd")
    if bad > max(8, len(text) // 50):
        first = text.index("\ufffd")
        raise BulkDataError(f"the file is not text ({bad} bytes are neither UTF-8 nor ASCII); expected Nastran bulk "
                            "data", path=str(path), line=text.count("\n", 0, first) + 1)
    out = _Lines(Line(t, i + 1, str(path)) for i, t in enumerate(text.splitlines()))
    out.ends_with_newline = not raw or raw.endswith((b"\n", b"\r"))
    return out


def _expand_includes(lines, base_dirs, stack, depth=0) -> list:
    """Inline INCLUDE files (quoted names may continue over lines until the closing quote)."""
    out = []
    i = 0
    while i < len(lines):
        ln = lines[i]
        m = _INCLUDE.match(ln.text)
        if not m or ln.text.lstrip().startswith("$"):
            out.append(ln)
            i += 1
            continue
        arg = m.group(1).strip()
        if arg.startswith(("'", '"')):
            q = arg[0]
            name = arg[1:]
            while q not in name:
                i += 1
                if i >= len(lines):
                    raise BulkDataError("INCLUDE file name has no closing quote", path=ln.path, line=ln.lineno,
                                        card="INCLUDE")
                name += lines[i].text.strip()
            name = name[:name.index(q)]
        else:
            name = arg.split("$")[0].strip()
        if not name:
            raise BulkDataError("INCLUDE without a file name", path=ln.path, line=ln.lineno, card="INCLUDE")
        here = Path(ln.path).parent if ln.path else None
        cands = [Path(name)] if os.path.isabs(name) else [d / name for d in ([here] if here else []) + base_dirs]
        target = next((c for c in cands if c.is_file()), None)
        if target is None:
            raise BulkDataError(f"INCLUDE file {name!r} not found (looked in "
                                f"{', '.join(str(c.parent) for c in cands) or 'nowhere'}); fix the path",
                                path=ln.path, line=ln.lineno, card="INCLUDE")
        key = str(target.resolve())
        if key in stack or depth > 20:
            raise BulkDataError(f"INCLUDE of {name!r} is recursive; a file cannot include itself",
                                path=ln.path, line=ln.lineno, card="INCLUDE")
        out.extend(_expand_includes(_file_lines(target), base_dirs, stack | {key}, depth + 1))
        i += 1
    return out


def _split_sections(lines, cc: CaseControl) -> list:
    """Return the bulk lines; fill ``cc`` from executive and case control."""
    has_begin = any(_BEGIN_BULK.match(ln.text) and "BULK" in ln.text.upper() for ln in lines)
    has_cend = any(_CEND.match(ln.text) for ln in lines)
    if not has_begin:
        if has_cend:
            ln = next(ln for ln in lines if _CEND.match(ln.text))
            raise BulkDataError("the deck has CEND but no BEGIN BULK; add 'BEGIN BULK' before the bulk data",
                                path=ln.path, line=ln.lineno)
        state = "bulk"
    else:
        state = "exec" if has_cend else "case"
    bulk = []
    subcase = 0
    for ln in lines:
        t = ln.text
        s = t.split("$")[0].strip()
        if state == "bulk":
            if _ENDDATA.match(t):
                break
            if _BEGIN_BULK.match(t) and "BULK" in t.upper():
                continue
            bulk.append(ln)
            continue
        if not s:
            continue
        if state == "exec":
            cc.executive.append(s)
            m = _SOL.match(s)
            if m:
                cc.sol = m.group(1).upper()
            if _CEND.match(s):
                state = "case"
            continue
        # case control
        if _BEGIN_BULK.match(s) and "BULK" in s.upper():
            state = "bulk"
            continue
        cc.case.append(s)
        m = _SUBCASE.match(s)
        if m:
            subcase = int(m.group(1))
            cc.commands.setdefault(subcase, {})
            continue
        m = _ASSIGN.match(s)
        if m:
            key = m.group(1).upper()
            if len(key) > 4 and key[:4] in ("METH", "SDAM"):
                key = {"METH": "METHOD", "SDAM": "SDAMPING"}[key[:4]]
            cc.commands.setdefault(subcase, {})[key] = m.group(2).strip().upper()
    return bulk


def read_bdf(source, *, xref: bool = True, base_dir=None, whole_model: bool = False,
             ignore_unsupported: bool = False) -> BulkData:
    """Read a Nastran deck (path, or text containing a newline) into :class:`BulkData`.

    xref : run the cross-reference checks (:meth:`BulkData.check`).
    ignore_unsupported : a card name that is no known Nastran card but close to one (a typo: ``CBAT`` for
        ``CBAR``) is an error naming the file, the line and the closest card; with ``ignore_unsupported`` (the CLI's
        ``--ignore-unsupported``) it is kept in :attr:`BulkData.unsupported` like any unmodelled card, and named as
        a likely typo in the warning.  A name far from every known card is always kept, with the warning.
    whole_model : the deck must be a whole model: a deck with grids but no elements or masses is an error
    (it looks truncated when it has no ENDDATA), not a model with a zero mass matrix.
    base_dir : extra directory for INCLUDE files (default: the main file's directory
    or, for text, the current directory).
    """
    if isinstance(source, (str, os.PathLike)) and not (isinstance(source, str) and "\n" in source):
        path = Path(source)
        lines = _file_lines(path)
        base = [Path(base_dir)] if base_dir else [path.parent]
        stack = {str(path.resolve())}
        src_path = str(path)
    elif isinstance(source, str):
        lines = [Line(t, i + 1, None) for i, t in enumerate(source.splitlines())]
        base = [Path(base_dir) if base_dir else Path.cwd()]
        stack = set()
        src_path = None
    else:
        raise BulkDataError(f"read_bdf needs a path or the text of a deck; got {type(source).__name__}")
    ends_with_newline = getattr(lines, "ends_with_newline", True)
    last_line = lines[-1].lineno if lines else 1
    lines = _expand_includes(lines, base, stack)
    has_enddata = any(_ENDDATA.match(ln.text) for ln in lines)
    bulk = BulkData(path=src_path)
    bulk_lines = _split_sections(lines, bulk.case_control)
    cut = (src_path is not None and not has_enddata and not ends_with_newline)
    try:
        raw_cards = group_cards(bulk_lines)
        for raw in raw_cards:
            typed = C.parse_card(raw)
            if typed is None:
                if not ignore_unsupported:
                    _refuse_typo(raw)
                bulk.unsupported.append(raw)
                continue
            for card in typed:
                bulk.add(card)
    except BulkDataError as e:
        if cut:
            raise BulkDataError(f"{_msg(e)}. The last line ({last_line}) has no line break and the deck no ENDDATA: "
                                "the file looks truncated", path=e.path, line=e.line, card=e.card) from None
        raise
    if src_path is not None:
        _check_complete(bulk, src_path, has_enddata, ends_with_newline, last_line, whole_model)
    if bulk.unsupported:
        _report_unsupported(bulk)
    if xref:
        try:
            bulk.check()
        except BulkDataError as e:
            if src_path is None or has_enddata:
                raise
            raise BulkDataError(f"{_msg(e)} (the deck has no ENDDATA: if the file was cut short, the definition "
                                "may have been lost; otherwise add the missing card)", path=e.path, line=e.line,
                                card=e.card) from None
    log.info("read %s", bulk)
    return bulk


def _msg(e: BulkDataError) -> str:
    """The message of ``e`` without its 'file ..., line ...: ' prefix (to rebuild it with more text)."""

    prefix = _where(("file", e.path), ("line", e.line), ("card", e.card))
    text = str(e)
    return text[len(prefix):] if prefix and text.startswith(prefix) else text


def _check_complete(bulk: BulkData, path: str, has_enddata: bool, ends_with_newline: bool, last_line: int,
                    whole_model: bool = False) -> None:
    """A deck file must hold bulk data, and not look cut short."""
    n_typed = sum(len(t) for t in (bulk.grids, bulk.coords, bulk.elements, bulk.rigid, bulk.properties,
                                   bulk.materials, bulk.params, bulk.tables, bulk.eigrls)) + len(bulk.spcs)
    if n_typed == 0:
        if not bulk.unsupported:
            raise BulkDataError("the file holds no bulk-data cards (it is empty or holds only comments / case control"
                                f"{'; it looks truncated' if not has_enddata else ''}); expected GRID, element, "
                                "property and material cards", path=path, line=last_line)
        names = sorted({r.name for r in bulk.unsupported})
        raise BulkDataError(f"the file holds no bulk-data card modalab reads (found {', '.join(names[:6])}"
                            f"{' ...' if len(names) > 6 else ''}); is it a Nastran bulk-data file?", path=path,
                            line=bulk.unsupported[0].line)
    if not has_enddata and not ends_with_newline:
        raise BulkDataError(f"the last line ({last_line}) ends without a line break and the deck has no ENDDATA: "
                            "the file looks truncated (cut inside that line). If the deck is complete, end it with "
                            "ENDDATA", path=path, line=last_line)
    if whole_model and not bulk.elements:
        raise BulkDataError(f"the deck defines {len(bulk.grids)} GRID(s) but no elements or masses"
                            + (", and has no ENDDATA: the file looks truncated" if not has_enddata else
                               "; a model needs elements (CBAR, CQUAD4 ...) or CONM2 masses"),
                            path=path, line=last_line)
    if not has_enddata and bulk.elements:
        used = {n for e in bulk.elements.values() for n in e.nodes} | {n for r in bulk.rigid.values() for n in r.nodes}
        loose = sorted(set(bulk.grids) - used)
        if loose:       # a deck cut at a line break after its grids: what follows fails far from the cause
            log.warning("%s: no ENDDATA, and %d GRID(s) are connected to no element or rigid link (%s): if the file "
                        "was cut short, the cards after line %d are missing; a complete deck ends with ENDDATA",
                        path, len(loose), ", ".join(map(str, loose[:8])) + (" ..." if len(loose) > 8 else ""),
                        last_line)


#: Nastran cards that add stiffness, mass, damping or constraints to the structure: when build_model does not model
#: one, the model it builds is a different structure (an error unless the caller opts in to ignore them)
STRUCTURAL_CARDS = frozenset({
    "CBEAM", "CBEAM3", "CBEND", "CBUSH", "CBUSH1D", "CBUSH2D", "CGAP", "CHEXA", "CPENTA", "CPYRAM", "CTETRA",
    "CQUAD", "CQUAD8", "CQUADR", "CQUADX", "CTRIA6", "CTRIAR", "CTRIAX", "CTRIAX6", "CSHEAR", "CTUBE", "CCONEAX",
    "CWELD", "CFAST", "CSEAM", "CMASS1", "CMASS2", "CMASS3", "CMASS4", "CONM1", "CELAS3", "CELAS4", "CDAMP3",
    "CDAMP4", "CDAMP5", "CVISC", "GENEL", "DMIG", "RBE1", "RROD", "RSPLINE", "RTRPLT", "MPC", "MPCADD"})


#: Every card name the reader knows: the cards it models, the structural cards it knowingly does not model and the
#: other MSC/NX Nastran bulk-data cards (:data:`~updating.fe.bulk.card_names.NASTRAN_CARDS`)
KNOWN_CARDS = frozenset(C.CARD_TYPES) | STRUCTURAL_CARDS | NASTRAN_CARDS


def _refuse_typo(raw) -> None:
    """A card whose name is no known Nastran card but close to one is a typo: an error naming the closest."""
    near = closest_card(raw.name, KNOWN_CARDS, C.CARD_TYPES)
    if near is not None:
        raise raw.error(f"unknown bulk-data card {raw.name!r}; did you mean {near!r}? Correct the card name (or "
                        f"remove the card); if {raw.name} is a Nastran card modalab does not know, pass "
                        "--ignore-unsupported to keep it unmodelled")


def _report_unsupported(bulk: BulkData) -> None:
    """One logged warning listing the cards that are kept but not modelled, with their line numbers."""
    by_name: dict = {}
    for r in bulk.unsupported:
        if r.name.upper() in STRUCTURAL_CARDS:          # build_model refuses them, or warns when told to ignore them
            continue
        by_name.setdefault(r.name, []).append(r.line)
    parts = []
    for name in sorted(by_name):
        ls = [str(v) for v in by_name[name] if v is not None]
        shown = ", ".join(ls[:8]) + (f" ... ({len(ls)} in all)" if len(ls) > 8 else "")
        near = closest_card(name, KNOWN_CARDS, C.CARD_TYPES)
        typo = f"; not a Nastran card: did you mean {near}?" if near else ""
        parts.append(f"{name} ({len(by_name[name])}: line{'s' if len(ls) > 1 else ''} {shown}{typo})")
    if not by_name:
        return
    msg = (f"{bulk.path or 'deck'}: {sum(len(v) for v in by_name.values())} bulk-data card(s) of {len(by_name)} type(s) are not "
           f"modelled by updating.fe.bulk and are ignored by build_model (kept in BulkData.unsupported and written "
           f"back): {'; '.join(parts)}")
    log.warning(msg)
