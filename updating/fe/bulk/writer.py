"""Writing bulk data, and exporting an (updated) FE model as bulk data.

``write_bdf(bulk, path=None, *, format='small', exact=True)`` writes a
:class:`~updating.fe.bulk.reader.BulkData` (or an :class:`updating.fe.FEModel`,
converted by :func:`to_bulk`) and returns the text.  Executive and case control
read with the deck are written back before ``BEGIN BULK``; unsupported cards
are written back unchanged; ``$`` comments before a card are kept.

Formats: 'small' (8-column fields), 'large' (16-column, ``GRID*``) and 'free'
(commas, fields of up to 16 characters).  Reals are written in the shortest
form that reproduces the double exactly when it fits the field; with
``exact=True`` (default) a card whose values do not fit a small field exactly
is written in large field instead (Nastran allows mixing formats card by
card), so nothing is rounded to 8 characters silently.  Large and free fields
hold about 11 significant digits.

``to_bulk(model, template=None)`` turns an FE model — typically
``ParametricFEModel(...).model_at(p)`` after updating — into bulk data.  With
the deck the model was built from as ``template``, every card whose model
object is unchanged is kept as it was (ids, coordinate systems, PBARL
dimensions, comments, unsupported cards, case control) and only what changed
is rewritten: MAT1 values, section properties (PBARL/PBEAML dimensions for
rectangles and tubes, PBAR/PBEAM otherwise), PSHELL thickness and NSM (with
MID1 = MID2 = MID3, a blank MID3 of the template kept), CQUAD4/CTRIA3 (THETA,
ZOFFS ... of the template kept), spring/damper/mass values (as
CELAS2/CDAMP2/CONM2), new grids (split nodes), new elements, links and SPCs.
"""
from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np

from modalab.core.errors import BulkDataError
from updating.fe import (Beam3D, BeamProperty, Damper, FEModel, LumpedMass, Material, Quad4,
                         RectangularSection, Rod, RodProperty, ShellProperty, Spring, Timoshenko3D, Tria3,
                         TubeSection)

from updating.fe.bulk import cards as C
from updating.fe.bulk.build import section_of
from updating.fe.bulk.fields import Verbatim, card_lines, fits_exactly
from updating.fe.bulk.geometry import resolve_coord
from updating.fe.bulk.reader import BulkData, CaseControl

log = logging.getLogger(__name__)

__all__ = ["write_bdf", "to_bulk", "card_text"]

_FORMATS = ("small", "large", "free")
_OFFT_OK = {a + b + c for a in "GB" for b in "GB" for c in "GB"}


def _fits(values, width) -> bool:
    for v in values:
        if v is None:
            continue
        if isinstance(v, float):
            if not fits_exactly(v, width):
                return False
        elif len(str(v)) > width:
            return False
    return True


def card_text(name: str, values, format: str = "small", exact: bool = True) -> list:
    """Lines of one card; ``exact`` promotes small to large field when a value would be rounded."""
    fmt = format
    if fmt == "small" and exact and not _fits(values, 8):
        fmt = "large"
    return card_lines(name, values, fmt)


def _raw_values(raw):
    """Fields of an unsupported card, written back verbatim."""
    return [Verbatim(f.strip()) if f.strip() else None for f in raw.fields[1:raw.n_used()]]


def write_bdf(bulk, path=None, *, format: str = "small", exact: bool = True, enddata: bool = True) -> str:
    """Write ``bulk`` (BulkData or FEModel) in ``format`` ('small', 'large', 'free'); return the text.

    path : file to write (None: only return the text).
    exact : write a card in large field when small fields would round one of its reals.
    """
    if format not in _FORMATS:
        raise BulkDataError(f"format {format!r}; expected one of {', '.join(_FORMATS)}")
    if isinstance(bulk, FEModel):
        bulk = to_bulk(bulk)
    if not isinstance(bulk, BulkData):
        raise BulkDataError(f"write_bdf needs BulkData or an FEModel; got {type(bulk).__name__}")
    out = []
    cc = bulk.case_control
    if cc.present:
        out += cc.executive
        if cc.executive and not any(s.upper().startswith("CEND") for s in cc.executive):
            out.append("CEND")
        out += cc.case
        out.append("BEGIN BULK")
    for card in bulk.cards():
        out += [c.rstrip() for c in (card.comment or [])]
        out += card_text(card.name, card.values(), format, exact)
    for raw in bulk.unsupported:
        out += [c.rstrip() for c in raw.comment]
        out += card_text(raw.name, _raw_values(raw), format, exact)
    if enddata:
        out.append("ENDDATA")
    text = "\n".join(out) + "\n"
    if path is not None:
        Path(path).write_text(text)
        log.info("wrote %s (%d lines, %s field)", path, len(out), format)
    return text


# ------------------------------------------------------------------ export
def _same(a, b, rtol=1e-12) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and np.allclose(a, b, rtol=rtol, atol=rtol * max(np.abs(a).max(initial=0),
                                                                            np.abs(b).max(initial=0), 1e-300))


def _meta_from(card, template_card, group: str = ""):
    if template_card is not None:
        card.comment = list(template_card.comment or [])
    elif group:
        card.comment = _name_comment(group)
    return card


def _name_comment(name):
    return [f"$ name: {name}"] if name else []


class _Exporter:
    def __init__(self, model: FEModel, template: BulkData | None):
        self.m = model
        self.t = template if template is not None else BulkData()
        self.wt = float(self.t.param("WTMASS", 1.0)) if template is not None else 1.0
        self.b = BulkData(path=None, case_control=dataclasses.replace(self.t.case_control)
                          if template is not None else CaseControl())
        self.next_cid = max([0, *self.t.coords]) + 1
        self.next_mid = max([0, *self.t.materials, *model.materials]) + 1

    # ---------------------------------------------------------- helpers
    def coord_for(self, R) -> int:
        """Id of a rectangular system with axes R (existing in template/output, or a new CORD2R)."""
        if R is None or _same(R, np.eye(3)):
            return 0
        for table in (self.b.coords, self.t.coords):
            for cid, card in table.items():
                if card.kind == "R":
                    cs = resolve_coord(self.b if table is self.b else self.t, cid)
                    if _same(cs.R, R):
                        if cid not in self.b.coords:
                            self.add_coord_chain(cid)
                        return cid
        cid = self.next_cid
        self.next_cid += 1
        R = np.asarray(R, float)
        self.b.add(C.Coord(cid, "R", 0, (0.0, 0.0, 0.0), tuple(R[:, 2]), tuple(R[:, 0])))
        return cid

    def cd_of(self, nid) -> np.ndarray:
        node = self.m.nodes[nid]
        return np.eye(3) if node.cd is None else node.cd

    def add_coord_chain(self, cid):
        while cid and cid not in self.b.coords:
            card = self.t.coords[cid]
            self.b.add(card)
            cid = card.rid

    # ---------------------------------------------------------- parts
    def params(self):
        for p in self.t.params.values():
            if p.pname not in ("COUPMASS", "G", "ALPHA1", "ALPHA2"):
                self.b.add(p)
        m = self.m
        old = self.t.params.get("COUPMASS")
        if m.coupled_mass:
            self.b.add(old if old is not None and not isinstance(old.value, str) and old.value > 0
                       else C.Param("COUPMASS", (1,)))
        elif old is not None:
            self.b.add(C.Param("COUPMASS", (-1,)))
        if m.global_ge:
            self.b.add(C.Param("G", (float(m.global_ge),)))
        if m.rayleigh is not None:
            a, b = m.rayleigh
            if a:
                self.b.add(C.Param("ALPHA1", (float(a),)))
            if b:
                self.b.add(C.Param("ALPHA2", (float(b),)))
        for e in self.t.eigrls.values():
            self.b.add(e)
        if m.modal_damping is not None:
            md = m.modal_damping
            tid = self.t.case_control.selection("SDAMPING") or m.metadata.get("sdamping") or 1
            card = C.Tabdmp1(int(tid), md.kind, tuple(float(f) for f in md.freq_hz),
                             tuple(float(v) for v in md.values))
            self.b.add(_meta_from(card, self.t.tables.get(tid)))

    def grids(self):
        for nid in sorted(self.m.nodes):
            node = self.m.nodes[nid]
            tg = self.t.grids.get(nid)
            if tg is not None:
                x0 = resolve_coord(self.t, tg.cp).to_basic(tg.xyz)
                R0 = resolve_coord(self.t, tg.cd).axes_at(x0)
                R1 = np.eye(3) if node.cd is None else node.cd
                if _same(x0, node.xyz) and _same(R0, R1):
                    self.add_coord_chain(tg.cp)
                    self.add_coord_chain(tg.cd)
                    self.b.add(tg)
                    continue
            cd = self.coord_for(node.cd)
            self.b.add(_meta_from(C.Grid(nid, 0, tuple(float(v) for v in node.xyz), cd,
                                         tg.ps if tg is not None else "", 0), tg))

    def material(self, mat: Material, mid=None) -> int:
        mid = mat.mid if mid is None else mid
        if mid in self.b.materials:
            return mid
        tm = self.t.materials.get(mat.mid)
        E = float(np.real(mat.E))
        rho = float(np.real(mat.rho)) / self.wt
        if mat.G is None:
            G, nu = None, float(mat.nu)
        else:
            G, nu = float(mat.G), (None if mat.nu is None else float(mat.nu))
        if tm is not None and tm.mid == mid:
            tE, tG, tnu = tm.resolved()
            same = (_same(tE, E) and _same(tm.rho, rho) and _same(tm.ge, mat.ge)
                    and (G is None) == (tm.G is None) and (_same(tG, G) if G is not None else _same(tnu, nu)))
            if same:
                self.b.add(tm)
                return mid
        base = tm if tm is not None else C.Mat1(mid, None, None, None)
        card = dataclasses.replace(base, mid=mid, E=E, G=G, nu=nu, rho=rho, ge=float(mat.ge))
        card.comment = list(base.comment or []) or _name_comment(mat.name)
        self.b.add(card)
        return mid

    def beam_property(self, prop: BeamProperty, beam_family: bool):
        mid = self.own_material(prop)
        tp = self.t.properties.get(prop.pid)
        nsm = float(np.real(prop.nsm)) / self.wt
        if tp is not None and getattr(tp, "mid", None) == mid:
            try:
                same = section_of(tp) == prop.section
            except BulkDataError:
                same = False
            tnsm = tp.stations[0][7] if isinstance(tp, C.Pbeam) else tp.nsm
            if same and _same(tnsm, nsm):
                self.b.add(tp)
                return
        if tp is not None:
            beam_family = isinstance(tp, (C.Pbeam, C.Pbeaml))
        s = prop.section
        if isinstance(s, RectangularSection):
            dims, typ = (float(s.h), float(s.b)), "BAR"
        elif isinstance(s, TubeSection):
            dims, typ = ((float(s.do) / 2,), "ROD") if s.di == 0 else ((float(s.do) / 2, float(s.di) / 2), "TUBE")
        else:
            dims, typ = None, None
        if dims is not None:
            if beam_family:
                card = C.Pbeaml(prop.pid, mid, "MSCBML0", typ, (("YES", 0.0, dims, nsm), ("YES", 1.0, dims, nsm)))
            else:
                card = C.Pbarl(prop.pid, mid, "MSCBML0", typ, dims, nsm)
        else:
            A, Iy, Iz, J = (float(np.real(getattr(s, k))) for k in ("A", "Iy", "Iz", "J"))
            ky, kz = getattr(s, "ky", None), getattr(s, "kz", None)
            if beam_family:
                st = (0.0,) * 8
                sta = ("YES", 0.0, A, Iz, Iy, 0.0, J, nsm, st)
                card = C.Pbeam(prop.pid, mid, (sta, ("YES", 1.0, *sta[2:])),
                               float(ky) if ky else 0.0, float(kz) if kz else 0.0)
            else:
                card = C.Pbar(prop.pid, mid, A, Iz, Iy, J, nsm, (0.0,) * 8,
                              float(ky) if ky else None, float(kz) if kz else None)
        card.comment = list(tp.comment or []) if tp is not None else _name_comment(prop.name)
        self.b.add(card)

    def own_material(self, prop) -> int:
        """MID written for a property: a copy of its material when the property has its own GE."""
        mat = self.m.material(prop.mid)
        mid = prop.mid
        if prop.ge is not None and prop.ge != mat.ge:
            mid = self.next_mid
            self.next_mid += 1
            mat = dataclasses.replace(mat, ge=prop.ge)
            log.info("property %d has its own GE: written with a copy of material %d as MID %d",
                     prop.pid, prop.mid, mid)
        return self.material(mat, mid)

    def shell_property(self, prop: ShellProperty):
        mid = self.own_material(prop)
        tp = self.t.properties.get(prop.pid)
        t, nsm = float(np.real(prop.t)), float(np.real(prop.nsm)) / self.wt
        bending, shear = float(np.real(prop.bending)), float(np.real(prop.shear))
        if isinstance(tp, C.Pshell):
            card = dataclasses.replace(tp, mid1=mid, mid2=mid, mid3=None if tp.mid3 is None else mid,
                                       t=tp.t if _same(tp.t, t) else t, nsm=tp.nsm if _same(tp.nsm, nsm) else nsm,
                                       bending=tp.bending if _same(tp.bending, bending) else bending,
                                       shear=tp.shear if _same(tp.shear, shear) else shear)
            if card == tp:
                card = tp
            else:
                card.comment = list(tp.comment or [])
        else:
            card = C.Pshell(prop.pid, mid, t, mid, bending, mid, shear, nsm)
            card.comment = _name_comment(prop.name)
        self.b.add(card)

    def properties(self):
        timo = {e.pid for e in self.m.elements.values() if isinstance(e, Timoshenko3D)}
        for pid in sorted(self.m.properties):
            prop = self.m.properties[pid]
            if isinstance(prop, BeamProperty):
                self.beam_property(prop, pid in timo)
            elif isinstance(prop, ShellProperty):
                self.shell_property(prop)
            elif isinstance(prop, RodProperty):
                if pid < 0:
                    continue  # CONROD
                mid = self.material(self.m.material(prop.mid))
                tp = self.t.properties.get(pid)
                card = C.Prod(pid, mid, float(prop.A), float(prop.J), tp.c if isinstance(tp, C.Prod) else 0.0,
                              float(prop.nsm) / self.wt)
                if tp is not None and tp == card:
                    card = tp
                else:
                    card.comment = list(tp.comment or []) if tp is not None else _name_comment(prop.name)
                self.b.add(card)
            else:
                raise BulkDataError(f"property {pid} ({type(prop).__name__}) has no bulk-data equivalent")

    def elements(self):
        for eid in sorted(self.m.elements):
            el = self.m.elements[eid]
            te = self.t.elements.get(eid)
            if isinstance(el, (Beam3D, Timoshenko3D)):
                cls = C.Cbeam if isinstance(el, Timoshenko3D) else C.Cbar
                if isinstance(te, C.Cbar) and isinstance(el, Timoshenko3D) and not isinstance(te, C.Cbeam):
                    cls = C.Cbar  # CBAR with PBAR shear factors was built as Timoshenko3D
                offt = te.offt if isinstance(te, C.Cbar) and te.offt in _OFFT_OK else "GGG"
                Ra, Rb = (self.cd_of(n) for n in (el.n1, el.n2))
                if np.ndim(el.orientation) == 0:
                    x, g0 = None, int(el.orientation)
                else:
                    v = np.asarray(el.orientation, float)
                    x, g0 = tuple(float(c) for c in (Ra.T @ v if offt[0] == "G" else v)), None
                wa, wb = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
                if el.offset_a is not None:
                    w = np.asarray(el.offset_a, float)
                    wa = tuple(float(c) for c in (Ra.T @ w if offt[1] == "G" else w))
                if el.offset_b is not None:
                    w = np.asarray(el.offset_b, float)
                    wb = tuple(float(c) for c in (Rb.T @ w if offt[2] == "G" else w))
                card = cls(eid, el.pid, el.n1, el.n2, x, g0, offt, wa=wa, wb=wb)
                if te is not None and type(te) is cls:
                    same_orient = (te.g0 == g0) if g0 is not None else (te.x is not None and _same(te.x, x))
                    card = dataclasses.replace(te, pid=el.pid, ga=el.n1, gb=el.n2,
                                               x=te.x if same_orient else x, g0=te.g0 if same_orient else g0,
                                               wa=te.wa if _same(te.wa, wa) else wa,
                                               wb=te.wb if _same(te.wb, wb) else wb)
                self.b.add(_meta_from(card, te))
            elif isinstance(el, (Quad4, Tria3)):
                cls = C.Ctria3 if isinstance(el, Tria3) else C.Cquad4
                if type(te) is cls:
                    card = dataclasses.replace(te, pid=el.pid, g=tuple(el.nodes))
                else:
                    card = cls(eid, el.pid, tuple(el.nodes))
                self.b.add(_meta_from(card, te, el.group))
            elif isinstance(el, Rod):
                prop = self.m.prop(el.pid)
                if el.pid < 0:
                    mid = self.material(self.m.material(prop.mid))
                    c = te.c if isinstance(te, C.Conrod) else 0.0
                    card = C.Conrod(eid, el.n1, el.n2, mid, float(prop.A), float(prop.J), c,
                                    float(prop.nsm) / self.wt)
                else:
                    card = C.Crod(eid, el.pid, el.n1, el.n2)
                self.b.add(_meta_from(card, te))
            elif isinstance(el, Spring):
                a, b = tuple(el.a), (None if el.b is None else tuple(el.b))
                # Nastran adds PARAM G to every GE: a spring that G does not damp is written with GE - G
                ge = float(el.ge) - (float(self.m.global_ge or 0.0) if eid in self.m.global_ge_exempt else 0.0)
                if isinstance(te, C.Celas1) and not isinstance(te, C.Cdamp1):
                    pe = self.t.properties.get(te.pid)
                    if pe is not None and _same(pe.k, el.k) and _same(pe.ge, ge) and \
                            {te.a, te.b} == {a, b}:
                        self.b.add(te)
                        if te.pid not in self.b.properties:
                            self.b.add(pe)
                        continue
                s = te.s if isinstance(te, C.Celas2) else 0.0
                self.b.add(_meta_from(C.Celas2(eid, float(el.k), a, b, ge, s), te, el.group))
            elif isinstance(el, Damper):
                a, b = tuple(el.a), (None if el.b is None else tuple(el.b))
                if isinstance(te, C.Cdamp1):
                    pd = self.t.properties.get(te.pid)
                    if pd is not None and _same(pd.b, el.c) and {te.a, te.b} == {a, b}:
                        self.b.add(te)
                        if te.pid not in self.b.properties:
                            self.b.add(pd)
                        continue
                self.b.add(_meta_from(C.Cdamp2(eid, float(el.c), a, b), te, el.group))
            elif isinstance(el, LumpedMass):
                self.b.add(self.conm2(el, te))
            else:
                raise BulkDataError(f"element {eid} is a {type(el).__name__}, which has no Nastran bulk-data "
                                    "equivalent; export models built from 3-D elements")

    def conm2(self, el: LumpedMass, te):
        w = self.wt
        J = np.real(np.asarray(el.inertia, complex)) / w
        mass = float(np.real(el.mass)) / w
        r = np.asarray(el.offset, float)
        if el.axes is not None:
            cid = self.coord_for(np.asarray(el.axes, float))
            if cid and self.b.coords[cid].kind != "R":
                cid = 0
            if cid == 0:
                A = np.asarray(el.axes, float)
                r, J = A @ r, A @ J @ A.T
        else:
            cid = 0
        inertia = (J[0, 0], -J[1, 0], J[1, 1], -J[2, 0], -J[2, 1], J[2, 2])
        inertia = tuple(float(v) + 0.0 for v in inertia)
        card = C.Conm2(el.eid, el.node, cid, mass, tuple(float(v) for v in r), inertia)
        if isinstance(te, C.Conm2):
            if te.cid == -1 and cid == 0:
                x = self.m.node_xyz(el.node) + r
                alt = dataclasses.replace(card, cid=-1, x=tuple(float(v) for v in x))
                if alt.m == te.m and _same(alt.x, te.x) and _same(alt.inertia, te.inertia):
                    return te
                card = alt
            elif te.cid == cid and _same(te.x, card.x) and _same(te.inertia, card.inertia) and _same(te.m, mass):
                return te
        if card.comment is None and el.group:
            card.comment = _name_comment(el.group)
        return _meta_from(card, te) if te is not None else card

    def constraints(self):
        for eid in sorted(self.m.rbe2s):
            link = self.m.rbe2s[eid]
            tr = self.t.rigid.get(eid)
            card = C.Rbe2(eid, link.independent, "".join(str(c) for c in link.components), tuple(link.dependents),
                          tr.alpha if tr is not None else 0.0)
            self.b.add(_meta_from(card, tr))
        sid = self.m.metadata.get("spc_id") or self.t.case_control.selection("SPC") or 1
        groups = {}
        ps = {nid: set(g.ps) for nid, g in self.b.grids.items() if g.ps}
        for s in self.m.spcs:
            comps = "".join(str(c) for c in s.components if str(c) not in ps.get(s.node, set()))
            if comps:
                groups.setdefault(comps, []).append(s.node)
        for comps in sorted(groups):
            nodes = sorted(set(groups[comps]))
            self.b.add(C.Spc1(int(sid), comps, tuple(nodes)))
        if groups and self.t.case_control.present and self.t.case_control.selection("SPC") is None:
            log.warning("exported SPC set %d is not selected in the case control; add 'SPC = %d'", sid, sid)

    def run(self) -> BulkData:
        self.params()
        self.grids()
        self.properties()
        self.elements()
        self.constraints()
        self.b.unsupported = list(self.t.unsupported)
        self.b.check()
        return self.b


def to_bulk(model: FEModel, template: BulkData | None = None) -> BulkData:
    """Bulk data of an FE model; with ``template`` (the deck it came from) unchanged cards are kept.

    Raises :class:`BulkDataError` for model objects without a Nastran card (Beam2D ...).
    """
    if not isinstance(model, FEModel):
        raise BulkDataError(f"to_bulk needs an updating.fe.FEModel; got {type(model).__name__}")
    return _Exporter(model, template).run()
