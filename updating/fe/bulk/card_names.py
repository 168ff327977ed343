"""Names of MSC/NX Nastran bulk-data cards, to tell a misspelt card from a real card this package does not model.

:data:`NASTRAN_CARDS` is a broad (not exhaustive) list of bulk-data entry names of the MSC and NX (Simcenter)
Nastran quick reference guides.  The reader (:mod:`updating.fe.bulk.reader`) adds the cards it models and the
structural cards it knowingly does not model; a name that is in none of these lists but close to one of them
(:func:`closest_card`: ``CBAT`` for ``CBAR``) is taken for a typo.  A name far from every known one (an exotic or
newer card) is kept as an unmodelled card, as before.
"""
from __future__ import annotations

import difflib

__all__ = ["NASTRAN_CARDS", "closest_card", "TYPO_CUTOFF"]


def _numbered(stem: str, first: int, last: int) -> set:
    return {f"{stem}{i}" for i in range(first, last + 1)}


#: Bulk-data entry names of MSC/NX Nastran (geometry, elements, properties, materials, constraints, loads,
#: dynamics, aero, optimisation, contact, superelements, thermal, tables, control)
NASTRAN_CARDS = frozenset({
    # --- control of the bulk section, sets, points
    "BEGIN", "ENDDATA", "INCLUDE", "ECHOON", "ECHOOFF", "PARAM", "MDLPRM", "SPOINT", "EPOINT", "SET1", "SET2",
    "SET3", "SET4", "PSET", "PVAL", "ELIST", "GROUP", "DEFUSET", "USET", "USET1", "SEQGP", "SEQSEP",
    # --- geometry
    "GRID", "GRDSET", "GRIDB", "GRIDF", "GRIDS", "GRIDG", "GRIDU", "FEEDGE", "FEFACE", "FREEPT", "POINT", "POINTAX",
    "RINGAX", "RINGFL", "CORD1C", "CORD1R", "CORD1S", "CORD2C", "CORD2R", "CORD2S", "CORD3G", "CORD3R",
    "CORD3RX", "BAROR", "BEAMOR", "SNORM", "AXIC", "AXIF", "AXSLOT", "CYAX", "CYJOIN", "CYSUP", "CYSYM",
    "GMCORD", "GMCURV", "GMSURF", "GMNURB", "GMINTC", "GMINTS",
    # --- elements
    "CBAR", "CBARAO", "CBEAM", "CBEAM3", "CBEND", "CROD", "CONROD", "CTUBE", "CBUSH", "CBUSH1D", "CBUSH2D",
    "CGAP", "CVISC", "CSHEAR", "CQUAD", "CQUAD4", "CQUAD8", "CQUADR", "CQUADX", "CQUADX4", "CQUADX8", "CTRIA3",
    "CTRIA6", "CTRIAR", "CTRIAX", "CTRIAX6", "CTRAX3", "CTRAX6", "CHEXA", "CPENTA", "CTETRA", "CPYRAM",
    "CHEXCZ", "CPENTCZ", "CQUADCZ", "CTRIACZ", "CIFHEX", "CIFPENT", "CIFQDX", "CIFQUAD", "CCONEAX",
    "CPLSTN3", "CPLSTN4", "CPLSTN6", "CPLSTN8", "CPLSTS3", "CPLSTS4", "CPLSTS6", "CPLSTS8", "CRAC2D", "CRAC3D",
    "CWELD", "CFAST", "CSEAM", "CSPOT", "CWSEAM", "CONSPOT", "CONM1", "CONM2", "CSUPER", "CSUPEXT",
    "CAABSF", "CACINF3", "CACINF4", "CAXIF2", "CAXIF3", "CAXIF4", "CFLUID2", "CFLUID3", "CFLUID4", "CHACAB",
    "CHACBR", "CSLOT3", "CSLOT4", "CHBDYE", "CHBDYG", "CHBDYP", "CMASS1", "CMASS2", "CMASS3", "CMASS4",
    "CELAS1", "CELAS2", "CELAS3", "CELAS4", "CDAMP1", "CDAMP2", "CDAMP3", "CDAMP4", "CDAMP5", "GENEL",
    "PLOTEL", "PLOTEL3", "PLOTEL4", "PLOTEL6", "PLOTEL8", "PLOTHEX", "PLOTPEN", "PLOTPYR", "PLOTTET", "CMARKB2",
    "CMARKN1", "CMFREE", "CSPH", "CTQUAD", "CTTRIA", "CAXISYM", "CTRIAX3",
    # --- rigid elements, multipoint constraints
    "RBAR", "RBAR1", "RBE1", "RBE2", "RBE2A", "RBE2GS", "RBE3", "RBE3D", "RROD", "RSPLINE", "RTRPLT", "RTRPLT1",
    "RJOINT", "RBJOINT", "RSSCON", "MPC", "MPCADD", "MPCAX", "MPCD", "MPCY",
    # --- properties
    "PBAR", "PBARL", "PBARN1", "PBCOMP", "PBEAM", "PBEAML", "PBEAM3", "PBEMN1", "PBEND", "PBMSECT", "PBRSECT",
    "PROD", "PRODN1", "PTUBE", "PBUSH", "PBUSH1D", "PBUSH2D", "PBUSHT", "PGAP", "PVISC", "PSHEAR", "PSHEARN",
    "PSHELL", "PSHLN1", "PSHLN2", "PCOMP", "PCOMPF", "PCOMPG", "PCOMPLS", "PCOMPS", "PSOLID", "PSLDN1",
    "PLSOLID", "PLPLANE", "PPLANE", "PCOHE", "PCONEAX", "PAXISYM", "PAXSYMH", "PELAS", "PELAST", "PDAMP", "PDAMP5",
    "PDAMPT", "PMASS", "PWELD", "PFAST", "PSEAM", "PRAC2D", "PRAC3D", "PAABSF", "PACABS", "PACBAR", "PACINF",
    "PHBDY", "PCONV", "PCONVM", "PINTC", "PINTS", "PMARKER", "PSPH", "PTSHELL", "PTSOLID",
    # --- non-structural mass
    "NSM", "NSM1", "NSML", "NSML1", "NSMADD",
    # --- materials
    "MAT1", "MAT2", "MAT3", "MAT4", "MAT5", "MAT8", "MAT9", "MAT10", "MAT11", "MATT1", "MATT2", "MATT3", "MATT4",
    "MATT5", "MATT8", "MATT9", "MATT11", "MATS1", "MATS3", "MATS8", "MATEP", "MATF", "MATG", "MATHE", "MATHED",
    "MATHP", "MATM", "MATORT", "MATVE", "MATVP", "MATTEP", "MATTF", "MATTG", "MATTHE", "MATTVE", "MATTORT",
    "MATD001", "MATD020", "MATDIGI", "MATCID", "CREEP", "MFLUID",
    # --- single-point constraints, boundary sets, reduction
    "SPC", "SPC1", "SPCADD", "SPCAX", "SPCD", "SPCOFF", "SPCOFF1", "SPCR", "SUPORT", "SUPORT1", "SUPAX",
    "ASET", "ASET1", "BSET", "BSET1", "CSET", "CSET1", "QSET", "QSET1", "OMIT", "OMIT1", "OMITAX", "BNDFIX",
    "BNDFIX1", "BNDFREE", "BNDFRE1", "BNDGRID", "RELEASE",
    # --- superelements and parts
    "SEBNDRY", "SEBSET", "SEBSET1", "SEBULK", "SECONCT", "SECSET", "SECSET1", "SEELT", "SEEXCLD", "SELABEL",
    "SELOC", "SEMPLN", "SENQSET", "SEQSET", "SEQSET1", "SESET", "SESUP", "SETREE", "SEUSET", "SEUSET1", "EXTRN",
    # --- static loads
    "LOAD", "LSEQ", "FORCE", "FORCE1", "FORCE2", "FORCEAX", "MOMENT", "MOMENT1", "MOMENT2", "MOMAX", "PLOAD",
    "PLOAD1", "PLOAD2", "PLOAD4", "PLOADB3", "PLOADX1", "PRESAX", "PRESPT", "GRAV", "ACCEL", "ACCEL1", "RFORCE",
    "RFORCE1", "SLOAD", "DEFORM", "CLOAD", "BOLT", "BOLTFOR", "BOLTFRC", "BOLTLD", "BOLTSEQ", "PRELOAD", "GMLOAD",
    # --- temperatures and heat transfer
    "TEMP", "TEMPD", "TEMPAX", "TEMPB3", "TEMPBC", "TEMPF", "TEMPN1", "TEMPP1", "TEMPP3", "TEMPRB", "QBDY1",
    "QBDY2", "QBDY3", "QHBDY", "QVECT", "QVOL", "CONV", "CONVM", "RADBC", "RADBND", "RADCAV", "RADLST", "RADM",
    "RADMT", "RADMTX", "RADSET", "VIEW", "VIEW3D", "PHBDY", "TF", "IC", "INITS",
    # --- dynamics: eigenvalue methods, frequencies, dynamic loads, damping, random
    "EIGR", "EIGRL", "EIGB", "EIGC", "EIGP", "FREQ", "FREQ1", "FREQ2", "FREQ3", "FREQ4", "FREQ5", "DAREA", "DELAY",
    "DPHASE", "DLOAD", "RLOAD1", "RLOAD2", "TLOAD1", "TLOAD2", "ACSRCE", "NOLIN1", "NOLIN2", "NOLIN3", "NOLIN4",
    "TIC", "TICD", "TSTEP", "TSTEPNL", "NLPARM", "NLPCI", "NLAUTO", "NLSTRAT", "NLADAPT", "NLCNTL", "NLHEATC",
    "NLRGAP", "NLRSFD", "TABDMP1", "DAMPGBL", "RANDPS", "RANDT1", "ROTORD", "ROTORG", "ROTORB", "ROTORSE", "RSPINR",
    "RSPINT", "UNBALNC", "RGYRO", "TABRND1", "TABRNDG", "DMI", "DMIAX", "DMIG", "DMIGOUT", "DMIGROT", "DMIJ",
    "DMIJI", "DMIK", "DTI", "ACMODL", "FRFCOMP", "FRFCONN", "FRFFLEX", "FRFRELS", "FRFSPC1", "FRFXIT", "FRFXIT1",
    "MODTRAK", "MONDSP1", "MONPNT1", "MONPNT2", "MONPNT3", "MONSUM", "RVDOF", "RVDOF1", "UXVEC",
    # --- tables
    "TABLED1", "TABLED2", "TABLED3", "TABLED4", "TABLED5", "TABLEDR", "TABLEM1", "TABLEM2", "TABLEM3", "TABLEM4",
    "TABLES1", "TABLEST", "TABLEH1", "TABLEHT", "TABLE3D", "TABLEFTG",
    # --- aeroelasticity
    "AERO", "AEROS", "AEFACT", "AELINK", "AELIST", "AEPARM", "AESTAT", "AESURF", "AESURFS", "AECOMP", "AECOMPL",
    "AEDW", "AEFORCE", "AEPRESS", "AESCALE", "CAERO1", "CAERO2", "CAERO3", "CAERO4", "CAERO5", "CAERO7",
    "PAERO1", "PAERO2", "PAERO3", "PAERO4", "PAERO5", "PAERO7", "SPLINE1", "SPLINE2", "SPLINE3", "SPLINE4",
    "SPLINE5", "SPLINE6", "SPLINE7", "SPLINRB", "MKAERO1", "MKAERO2", "FLUTTER", "FLFACT", "FLSYM", "GUST",
    "TRIM", "TRIM2", "DIVERG", "CSSCHD", "MONCNCM", "UXVEC",
    # --- design optimisation
    "DESVAR", "DLINK", "DDVAL", "DVPREL1", "DVPREL2", "DVMREL1", "DVMREL2", "DVCREL1", "DVCREL2", "DVGRID",
    "DVSHAP", "DVBSHAP", "DVLREL1", "DRESP1", "DRESP2", "DRESP3", "DCONSTR", "DCONADD", "DOPTPRM", "DEQATN",
    "DTABLE", "DTABLE2", "DSCREEN", "DMNCON", "TOPVAR", "TOMVAR", "BEADVAR", "MODTRAK",
    # --- contact, gluing, bolts (MSC SOL 400/600, NX SOL 101/601)
    "BCTABLE", "BCTABL1", "BCBODY", "BCBODY1", "BCBOX", "BCHANGE", "BCMATL", "BCMOVE", "BCNURB2", "BCNURBS",
    "BCPARA", "BCPATCH", "BCPFLG", "BCPROP", "BCRIGID", "BCSCAP", "BCSEG", "BCGRID", "BCAUTOP", "BCBDPRP",
    "BCONECT", "BCONP", "BCTADD", "BCTPARA", "BCTPARM", "BCTSET", "BCRPARA", "BCHANGE", "BGADD", "BGPARM",
    "BGSET", "BGTABLE", "BLSEG", "BOUTPUT", "BSURF", "BSURFS", "BWIDTH", "BFRIC", "BDYLIST", "BDYOR", "BEDGE",
    "BSCONP", "BCRGSRF", "GMBC", "GMBNDC", "GMCONV", "GMQVOL", "GMSPC",
    # --- acoustics, fluids, other
    "ACPEMCP", "ACTRAD", "ACTRIM", "PANEL", "FLSFSEL", "FLSPOUT", "FLSTCON", "FSICTRL", "FBODYLD", "FBODYSB",
    "ITER", "ADAPT", "CWELD", "SWLDPRM", "VCCT", "OUTRCV", "MARCIN", "MARCOUT", "RCROSS", "LOADCYH", "LOADCYN",
    "LOADCYT", "CONTRLT", "CYLINDR", "DYPARAM",
} | _numbered("ADUM", 1, 9) | _numbered("CDUM", 1, 9) | _numbered("PDUM", 1, 9))

#: get_close_matches cutoff: one letter changed, added, dropped or two swapped in a name of four or more letters
#: is a typo (CBAT, CBRA -> CBAR score 0.75; CBA -> CBAR 0.86); two changes in a short name are not (CXAT: 0.5)
TYPO_CUTOFF = 0.75


def _edits(a: str, b: str) -> int:
    """Optimal-string-alignment distance: insertions, deletions, substitutions and swaps of neighbours."""
    d = [[i + j if i * j == 0 else 0 for j in range(len(b) + 1)] for i in range(len(a) + 1)]
    for i in range(1, len(a) + 1):
        for j in range(1, len(b) + 1):
            d[i][j] = min(d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] != b[j - 1]))
            if i > 1 and j > 1 and a[i - 1] == b[j - 2] and a[i - 2] == b[j - 1]:
                d[i][j] = min(d[i][j], d[i - 2][j - 2] + 1)
    return d[-1][-1]


def closest_card(name: str, known, prefer=()) -> str | None:
    """The known card name closest to ``name`` when ``name`` is not a known card and looks like a typo of one
    (difflib score >= :data:`TYPO_CUTOFF`); None for a known name or one far from every known name.

    Among the close names the fewest edits win (CBRA -> CBAR, not CBARAO), then a name in ``prefer`` (the cards
    the reader models: MAT6 -> MAT1), then the higher difflib score; the winner must be at most one edit away
    from a name of up to five letters, two from a longer one."""
    name = name.upper()
    if name in known:
        return None
    close = difflib.get_close_matches(name, sorted(known), n=12, cutoff=TYPO_CUTOFF)
    if not close:
        return None
    ratio = {c: difflib.SequenceMatcher(None, name, c).ratio() for c in close}
    best = min(close, key=lambda c: (_edits(name, c), c not in prefer, -ratio[c], c))
    # at most one edit in a name of up to five letters (DOF is no typo of RVDOF), two in a longer one
    return best if _edits(name, best) <= (1 if len(name) <= 5 else 2) else None
