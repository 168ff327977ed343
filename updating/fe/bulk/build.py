"""Building an :class:`updating.fe.FEModel` from :class:`~updating.fe.bulk.reader.BulkData`.

Card → model mapping (SI units are assumed in the deck):

==================  =================================================================
GRID                node at its basic position (through CP); CD → the node's
                    displacement axes (CORD2R/C/S, ``axes_at`` the grid); PS → SPC
MAT1                :class:`~updating.fe.Material` (blank E/G/NU completed as Nastran
                    does; G blank with E and NU given stays tied to E); GE → element ge
PBAR / PBEAM        :class:`~updating.fe.GeneralSection` (A, Iy = I2, Iz = I1, J, ky = K1, kz = K2);
                    PBAR K blank → shear-rigid, PBEAM K default 1.0, K = 0.0 → shear-rigid
PBARL / PBEAML      BAR → :class:`~updating.fe.RectangularSection` (b = DIM2 along y,
                    h = DIM1 along z, so thickness parameters act as I ∝ t³), ROD/TUBE →
                    :class:`~updating.fe.TubeSection`, BOX/I → GeneralSection
                    (:func:`updating.fe.bulk.cards.section_properties`)
CBAR                :class:`~updating.fe.Beam3D` (:class:`~updating.fe.Timoshenko3D` when the
                    PBAR gives K1/K2, i.e. shear flexibility); X in the CD system of GA (OFFT
                    'G..') or basic ('B..'), or G0; rigid offsets WA/WB in the CD system of
                    their grid ('.G.') or basic ('.B.')
CBEAM               :class:`~updating.fe.Timoshenko3D`
CROD / CONROD       :class:`~updating.fe.Rod` (PROD; CONROD gets a private property ``-EID``)
PSHELL              :class:`~updating.fe.ShellProperty` (t, NSM per area, 12I/T³, TS/T); MID2 and
                    MID3 must equal MID1 (MID3 blank: the MID1 shear modulus is used, the thin-
                    plate limit of Nastran's blank MID3 is matched by the locking-free elements)
CQUAD4 / CTRIA3     :class:`~updating.fe.Quad4` (MITC4) / :class:`~updating.fe.Tria3` (DKT); THETA/MCID
                    must be 0 or blank, ZOFFS 0, corner thicknesses T1.. blank
CELAS1/2, PELAS     :class:`~updating.fe.Spring` with GE (group ``"PELAS <pid>"`` for CELAS1)
CDAMP1/2, PDAMP     :class:`~updating.fe.Damper` (group ``"PDAMP <pid>"`` for CDAMP1)
CONM2               :class:`~updating.fe.LumpedMass` (offset, inertia tensor with Nastran's
                    negated I21/I31/I32, CID −1/0/system)
RBE2                rigid link by transformation
SPC/SPC1/SPCADD     the set chosen by ``spc_id``, else by case control ``SPC =``, else the
                    only set of the deck
PARAM COUPMASS      > 0 coupled (consistent) mass, else Nastran's lumped mass (the default)
PARAM G             global structural damping D += G·K;  PARAM ALPHA1/ALPHA2 → C = α₁M + α₂K
PARAM WTMASS        multiplies every mass term (density, NSM, CONM2 mass and inertia)
TABDMP1             :class:`~updating.fe.ModalDampingTable` (chosen by ``SDAMPING =`` or the
                    only table)
==================  =================================================================

Not supported (a :class:`~modalab.core.errors.BulkDataError` names the card): pin
flags, shell offsets (ZOFFS), material orientation (THETA/MCID ≠ 0), corner thicknesses,
membrane-only / plane-strain / coupled PSHELL (MID2 blank or −1, MID4), offsets in the element
system (OFFT 'O'), I12 ≠ 0, tapered PBEAM/PBEAML, PBEAM NSI/CW/M/N terms,
scalar points, superelements.  Property and material names come from a
preceding comment ``$ name: wing`` (also Femap's ``$ Femap Property 2 : wing``
and Patran's ``$ ... region : wing``), so that parameters can select groups by name.
"""
from __future__ import annotations

import logging
import re

import numpy as np

from modalab.core.errors import BulkDataError, ModalabError
from updating.fe import (Beam3D, BeamProperty, Damper, FEModel, GeneralSection, LumpedMass, Material,
                         ModalDampingTable, Quad4, RectangularSection, Rod, RodProperty, ShellProperty, Spring,
                         Timoshenko3D, Tria3, TubeSection)

from updating.fe.bulk import cards as C
from updating.fe.bulk.geometry import resolve_coord
from updating.fe.bulk.reader import STRUCTURAL_CARDS

log = logging.getLogger(__name__)

__all__ = ["build_model", "section_of", "shell_property", "card_name"]

_NAME_RE = [re.compile(r"^\$\s*name\s*[:=]\s*(.+?)\s*$", re.IGNORECASE),
            re.compile(r"^\$\s*Femap\s+(?:with NX Nastran\s+)?(?:Property|Material)\s+\d+\s*:\s*(.+?)\s*$",
                       re.IGNORECASE),
            re.compile(r"^\$.*\bregion\s*:\s*(.+?)\s*$", re.IGNORECASE)]


def card_name(card) -> str:
    """Name given to a card by a preceding comment ('' when none)."""
    for line in reversed(card.comment or []):
        for rx in _NAME_RE:
            m = rx.match(line.strip())
            if m:
                return m.group(1).strip()
    return ""


def _num(v, card, what):
    if isinstance(v, (int, float)):
        return float(v)
    raise card.error(f"PARAM {what} = {v!r}; expected a number")


def section_of(card):
    """The updating.fe section object of a PBAR/PBARL/PBEAM/PBEAML card."""
    if isinstance(card, C.Pbar):
        if card.i12:
            raise card.error(f"I12 = {card.i12}: unsymmetric sections are not supported by build_model; give "
                             "principal axes (rotate the orientation vector) and I12 = 0")
        return GeneralSection(A=card.A, Iy=card.i2, Iz=card.i1, J=card.J, ky=card.k1 or None, kz=card.k2 or None)
    if isinstance(card, C.Pbeam):
        if not card.prismatic():
            raise card.error("tapered PBEAM (stations with different properties) is not supported by "
                             "build_model; split the beam into prismatic elements")
        a = card.stations[0]
        if a[5]:
            raise card.error(f"I12 = {a[5]}: unsymmetric sections are not supported by build_model")
        s1, s2, nsia, nsib, cwa, cwb, *mn = card.tail
        if nsia or nsib or any(mn):
            raise card.error("PBEAM non-structural inertia (NSI) and mass/neutral-axis offsets (M, N) are not "
                             "supported by build_model; remove them or model the offset mass with CONM2")
        if cwa or cwb:
            log.info("PBEAM %d: warping coefficient CW ignored (Saint-Venant torsion)", card.pid)
        return GeneralSection(A=a[2], Iy=a[4], Iz=a[3], J=a[6], ky=card.k1 or None, kz=card.k2 or None)
    if isinstance(card, (C.Pbarl, C.Pbeaml)):
        if isinstance(card, C.Pbeaml) and not card.prismatic():
            raise card.error("tapered PBEAML (stations with different dimensions) is not supported by "
                             "build_model; split the beam into prismatic elements")
        d = card.dims
        if card.type == "BAR":
            return RectangularSection(b=d[1], h=d[0])
        if card.type == "ROD":
            return TubeSection(do=2 * d[0], di=0.0)
        if card.type == "TUBE":
            if not d[1] < d[0]:
                raise card.error(f"TUBE inner radius DIM2 = {d[1]} must be smaller than the outer DIM1 = {d[0]}")
            return TubeSection(do=2 * d[0], di=2 * d[1])
        p = card.section()
        return GeneralSection(A=p["A"], Iy=p["I2"], Iz=p["I1"], J=p["J"], ky=p["k1"], kz=p["k2"])
    raise BulkDataError(f"internal: {type(card).__name__} has no section")


def shell_property(card, wtmass: float = 1.0) -> ShellProperty:
    """The :class:`~updating.fe.ShellProperty` of a PSHELL card (NSM scaled by WTMASS)."""
    if card.mid1 is None or card.mid1 <= 0:
        raise card.error(f"MID1 = {card.mid1}: a PSHELL without membrane material is not supported by "
                         "build_model; give MID1 = MID2 = MID3")
    if card.t is None or not card.t > 0:
        raise card.error(f"T = {card.t}: build_model needs the thickness on the PSHELL (> 0 m); corner "
                         "thicknesses on the elements are not supported")
    if card.mid2 is None or card.mid2 == -1:
        kind = "blank (membrane only)" if card.mid2 is None else "-1 (plane strain)"
        raise card.error(f"MID2 {kind} is not supported by build_model; give MID2 = MID1 = {card.mid1} for a "
                         "plate with bending stiffness")
    for what, m in (("MID2", card.mid2), ("MID3", card.mid3)):
        if m is not None and m != card.mid1:
            raise card.error(f"{what} = {m} differs from MID1 = {card.mid1}: build_model supports homogeneous "
                             f"isotropic shells only; give {what} = {card.mid1} (or a blank MID3)")
    if card.mid4 is not None and card.mid4 != 0:
        raise card.error(f"MID4 = {card.mid4} (membrane-bending coupling) is not supported by build_model; "
                         "leave MID4 blank")
    if card.mid3 is None:
        log.info("PSHELL %d: MID3 blank (thin-plate theory in Nastran); the MITC4/DKT elements use the MID1 "
                 "shear modulus with TS/T = %g, which has the same thin-plate limit", card.pid, card.shear)
    return ShellProperty(card.pid, card.mid1, t=card.t, nsm=card.nsm * wtmass, name=card_name(card),
                         bending=card.bending, shear=card.shear)


def _pick_set(what, chosen, available, card_kind):
    if chosen is not None:
        if chosen not in available:
            raise BulkDataError(f"{what} set {chosen} is selected but no {card_kind} card has that id; "
                                f"available: {sorted(available) or 'none'}")
        return chosen
    if len(available) == 1:
        sid = next(iter(available))
        log.info("using %s set %d, the only one in the deck (no case-control selection)", what, sid)
        return sid
    if len(available) > 1:
        raise BulkDataError(f"the deck has {len(available)} {what} sets {sorted(available)} and none is selected; "
                            f"pass {what.lower()}_id=... or put '{what} = n' in the case control")
    return None


def build_model(bulk, *, spc_id: int | None = None, sdamping: int | None = None, name: str | None = None,
                ignore_unsupported: bool = False) -> FEModel:
    """FE model of a deck read by :func:`~updating.fe.bulk.read_bdf` (see the module docstring).

    spc_id : SPC/SPCADD set to apply (default: case control, else the only set).
    sdamping : TABDMP1 id for modal damping (default: case control SDAMPING, else the only table).
    ignore_unsupported : build without the structural cards (:data:`STRUCTURAL_CARDS`) this package does not
        model; by default such a card is an error naming the file, its line and the card, since the model built
        without it is a different structure.
    """
    skipped = [r for r in bulk.unsupported if r.name.upper() in STRUCTURAL_CARDS]
    if skipped and not ignore_unsupported:
        r = skipped[0]
        more = sorted({x.name for x in skipped})
        raise BulkDataError(f"{r.name} is a structural card build_model does not model ({len(skipped)} such "
                            f"card(s): {', '.join(more)}): without it the model is a different structure; "
                            "replace it by supported elements (e.g. CTRIA6 -> CTRIA3, CQUAD8 -> CQUAD4), or pass "
                            "--ignore-unsupported to build the model without it", path=bulk.path, line=r.line,
                            card=r.name)
    if skipped:
        log.warning("%s: building the model without %d structural card(s) it does not model (%s), as asked",
                    bulk.path or "deck", len(skipped), ", ".join(sorted({x.name for x in skipped})))
    try:
        return _build(bulk, spc_id, sdamping, name)
    except BulkDataError:
        raise
    except ModalabError as e:
        raise BulkDataError(f"the model cannot be built: {e}", path=bulk.path) from None


def _build(bulk, spc_id, sdamping, name) -> FEModel:
    """The model, one card family at a time (in the order in which their errors take precedence)."""
    bulk.check()
    coupled, wt, g, a1, a2 = _mass_params(bulk.params)
    cc = bulk.case_control
    tid, md = _modal_damping(bulk, sdamping)
    m = FEModel(name or (bulk.path or "bulk data"), coupled_mass=coupled, global_ge=g,
                rayleigh=(a1, a2) if (a1 or a2) else None, modal_damping=md)
    m.metadata.update({"source": bulk.path, "wtmass": wt, "sol": cc.sol})
    ignored = sorted(set(bulk.params) - {"COUPMASS", "WTMASS", "G", "ALPHA1", "ALPHA2"})
    if ignored:
        log.info("PARAMs without effect on the model matrices here: %s", ", ".join(ignored))
    cd_axes = _add_grids(m, bulk)
    _add_materials(m, bulk, wt)
    _add_properties(m, bulk, wt)
    _add_elements(m, bulk, wt, cd_axes)
    _add_rigid(m, bulk)
    sid = _add_spcs(m, bulk, spc_id)
    if sid is not None:
        m.metadata["spc_id"] = sid
    if tid is not None:
        m.metadata["sdamping"] = tid
    log.info("built %r from %s", m, bulk.path or "text")
    return m


def _mass_params(P) -> tuple:
    """PARAM COUPMASS, WTMASS, G, ALPHA1, ALPHA2: (coupled mass?, wtmass, G, alpha1, alpha2)."""
    coup = P.get("COUPMASS")
    coupled = False
    if coup is not None:
        v = coup.value
        coupled = (v.upper() in ("YES", "ON")) if isinstance(v, str) else v > 0
    wt = _num(P["WTMASS"].value, P["WTMASS"], "WTMASS") if "WTMASS" in P else 1.0
    if not wt > 0:
        raise P["WTMASS"].error(f"WTMASS = {wt}; expected > 0")
    g = _num(P["G"].value, P["G"], "G") if "G" in P else 0.0
    a1 = _num(P["ALPHA1"].value, P["ALPHA1"], "ALPHA1") if "ALPHA1" in P else 0.0
    a2 = _num(P["ALPHA2"].value, P["ALPHA2"], "ALPHA2") if "ALPHA2" in P else 0.0
    return coupled, wt, g, a1, a2


def _modal_damping(bulk, sdamping) -> tuple:
    """TABDMP1 chosen by ``sdamping``, case control SDAMPING or as the only table: (id, ModalDampingTable)."""
    tid = _pick_set("SDAMPING", sdamping if sdamping is not None else bulk.case_control.selection("SDAMPING"),
                    bulk.tables, "TABDMP1")
    md = None
    if tid is not None:
        t = bulk.tables[tid]
        md = ModalDampingTable(tuple(t.freq_hz), tuple(t.damping), kind=t.type)
    return tid, md


def _add_grids(m: FEModel, bulk) -> dict:
    """GRID: nodes at their basic positions, CD axes and PS constraints.  Node id -> CD axes (3 × 3)."""
    cd_axes = {}
    for nid in sorted(bulk.grids):
        gr = bulk.grids[nid]
        if gr.seid:
            raise gr.error(f"SEID = {gr.seid}: superelements are not supported; give SEID 0")
        if gr.cd < 0:
            raise gr.error(f"CD = {gr.cd}: fluid grids are not supported")
        x = resolve_coord(bulk, gr.cp).to_basic(gr.xyz)
        R = resolve_coord(bulk, gr.cd).axes_at(x) if gr.cd else None
        cd_axes[nid] = np.eye(3) if R is None else R
        m.add_node(nid, x, cd=R)
        if gr.ps:
            m.add_spc(nid, gr.ps)
    return cd_axes


def _add_materials(m: FEModel, bulk, wt: float) -> None:
    """MAT1, completed as Nastran does (G blank with E and NU given stays tied to E)."""
    for mid in sorted(bulk.materials):
        mc = bulk.materials[mid]
        E, G, nu = mc.resolved()
        if not E > 0:
            raise mc.error(f"E = {E}: build_model needs a positive Young's modulus")
        if mc.G is None and mc.nu is not None:
            mat = Material(mid, E=E, nu=nu, rho=mc.rho * wt, G=None, ge=mc.ge, name=card_name(mc))
        else:
            if G == 0.0:
                log.warning("MAT1 %d gives E only: Nastran sets G = 0, so torsion and shear carry no stiffness",
                            mid)
            mat = Material(mid, E=E, nu=nu, rho=mc.rho * wt, G=G, ge=mc.ge, name=card_name(mc))
        m.add_material(mat)


def _add_properties(m: FEModel, bulk, wt: float) -> None:
    """PROD, PSHELL, PBAR/PBEAM(L) (PELAS/PDAMP are read by their elements)."""
    for pid in sorted(bulk.properties):
        pc = bulk.properties[pid]
        if isinstance(pc, (C.Pelas, C.Pdamp)):
            continue
        if isinstance(pc, C.Prod):
            m.add_property(RodProperty(pid, pc.mid, A=pc.A, J=pc.J, nsm=pc.nsm * wt, name=card_name(pc)))
            continue
        if isinstance(pc, C.Pshell):
            m.add_property(shell_property(pc, wt))
            continue
        nsm = pc.nsm if not isinstance(pc, C.Pbeam) else pc.stations[0][7]
        m.add_property(BeamProperty(pid, pc.mid, section_of(pc), nsm=nsm * wt, name=card_name(pc)))


def _bar_element(bulk, eid: int, e, cd_axes: dict):
    """CBAR / CBEAM: orientation (G0 or X in the GA CD system or basic) and rigid end offsets."""
    if e.pa or e.pb:
        raise e.error(f"pin flags PA = {e.pa!r}, PB = {e.pb!r} are not supported by build_model; release "
                      "the DOFs with a second grid and an RBE2/CELAS instead")
    offt = e.offt
    if len(offt) != 3 or offt[0] not in "GB" or offt[1] not in "GBO" or offt[2] not in "GBO":
        raise e.error(f"OFFT = {offt!r}; expected three letters: G or B for the orientation vector, "
                      "then G, B or O for each end offset")
    if ("O" in offt[1:]) and (any(e.wa) or any(e.wb)):
        raise e.error(f"OFFT = {offt!r}: offsets in the element system (O) are not supported by "
                      "build_model; give them in the displacement (G) or basic (B) system")
    if e.g0 is not None:
        orient = int(e.g0)
    else:
        x = np.asarray(e.x, float)
        orient = tuple(cd_axes[e.ga] @ x if offt[0] == "G" else x)
    wa = wb = None
    if any(e.wa):
        wa = cd_axes[e.ga] @ np.asarray(e.wa) if offt[1] == "G" else np.asarray(e.wa, float)
    if any(e.wb):
        wb = cd_axes[e.gb] @ np.asarray(e.wb) if offt[2] == "G" else np.asarray(e.wb, float)
    prop = bulk.properties[e.pid]
    if isinstance(e, C.Cbeam):
        cls = Timoshenko3D
    else:
        shear = isinstance(prop, C.Pbar) and (prop.k1 or prop.k2)
        cls = Timoshenko3D if shear else Beam3D
    return cls(eid, e.ga, e.gb, e.pid, orientation=orient,
               offset_a=None if wa is None else tuple(wa), offset_b=None if wb is None else tuple(wb),
               lumped_torsion=isinstance(e, C.Cbeam))           # lumped CBEAM mass has torsional inertia


def _scalar_or_mass_element(m: FEModel, bulk, eid: int, e, wt: float):
    """CELAS1/2 springs, CDAMP1/2 dampers, CONM2 lumped masses; None for any other card."""
    if isinstance(e, C.Cdamp1):
        pd = bulk.properties[e.pid]
        a, b = (e.a, e.b) if e.a is not None else (e.b, None)
        return Damper(eid, a, b, pd.b, group=card_name(pd) or f"PDAMP {e.pid}")
    if isinstance(e, C.Celas1):
        pe = bulk.properties[e.pid]
        a, b = (e.a, e.b) if e.a is not None else (e.b, None)
        return Spring(eid, a, b, pe.k, ge=pe.ge, group=card_name(pe) or f"PELAS {e.pid}")
    if isinstance(e, C.Celas2):
        a, b = (e.a, e.b) if e.a is not None else (e.b, None)
        return Spring(eid, a, b, e.k, ge=e.ge, group=card_name(e))
    if isinstance(e, C.Cdamp2):
        a, b = (e.a, e.b) if e.a is not None else (e.b, None)
        return Damper(eid, a, b, e.b_value, group=card_name(e))
    if isinstance(e, C.Conm2):
        x_g = m.node_xyz(e.g)
        axes = None
        if e.cid == -1:
            offset = np.asarray(e.x, float) - x_g
        else:
            offset = np.asarray(e.x, float)
            if e.cid > 0:
                axes = resolve_coord(bulk, e.cid).axes_at(x_g)
        return LumpedMass(eid, e.g, e.m * wt, inertia=e.tensor() * wt, offset=offset, axes=axes, group=card_name(e))
    return None


def _add_elements(m: FEModel, bulk, wt: float, cd_axes: dict) -> None:
    """Every element card in id order (CONROD adds its private property ``-EID`` first)."""
    for eid in sorted(bulk.elements):
        e = bulk.elements[eid]
        if isinstance(e, C.Cbar):             # and CBEAM
            m.add_element(_bar_element(bulk, eid, e, cd_axes))
        elif isinstance(e, C.Cquad4):       # and CTRIA3
            bad = e.unsupported_fields()
            if bad:
                raise e.error("not supported by build_model: " + "; ".join(bad))
            cls = Tria3 if isinstance(e, C.Ctria3) else Quad4
            m.add_element(cls(eid, *e.g, e.pid))
        elif isinstance(e, C.Crod):
            m.add_element(Rod(eid, e.ga, e.gb, e.pid))
        elif isinstance(e, C.Conrod):
            m.add_property(RodProperty(-eid, e.mid, A=e.A, J=e.J, nsm=e.nsm * wt, name=f"CONROD {eid}"))
            m.add_element(Rod(eid, e.ga, e.gb, -eid))
        else:
            el = _scalar_or_mass_element(m, bulk, eid, e, wt)
            if el is None:  # pragma: no cover - the reader only stores the types above
                raise e.error("internal: element type not handled by build_model")
            m.add_element(el)


def _add_rigid(m: FEModel, bulk) -> None:
    """RBE2 rigid links."""
    for eid in sorted(bulk.rigid):
        r = bulk.rigid[eid]
        if r.alpha:
            log.info("RBE2 %d: thermal expansion ALPHA ignored", eid)
        m.add_rbe2(eid, r.gn, list(r.gm), r.cm)


def _add_spcs(m: FEModel, bulk, spc_id) -> int | None:
    """SPC/SPC1 of the set chosen by ``spc_id``, case control SPC or as the only set (SPCADD expanded).
    The set id, or None."""
    avail = set(bulk.spcs) | set(bulk.spcadds)
    sid = _pick_set("SPC", spc_id if spc_id is not None else bulk.case_control.selection("SPC"), avail,
                    "SPC/SPC1/SPCADD")
    if sid is not None:
        sets = list(bulk.spcadds[sid].sets) if sid in bulk.spcadds else [sid]
        for s in sets:
            for card in bulk.spcs.get(s, []):
                if isinstance(card, C.Spc1):
                    for nid in card.grid_ids:
                        m.add_spc(nid, card.c)
                else:
                    for nid, comps, d in card.items:
                        if d:
                            log.warning("SPC %d on grid %d: enforced displacement %g ignored (modal model)",
                                        s, nid, d)
                        if comps:
                            m.add_spc(nid, comps)
    return sid
