"""The library of model augmentations that ``modalab diagnose`` tests.

Each :class:`Candidate` is one physical effect the nominal model may have
left out, at one place, with one non-negative value:

=====================  ==============================================  ==========  =========
physics                what is added (bulk data)                       value       matrix
=====================  ==============================================  ==========  =========
ground_spring          spring to ground on one DOF (CELAS1/2)          k           K
added_mass             point mass at a node (CONM2), or rotary         m, J        M
                       inertia about one axis
local_damping          hysteretic damping on an element group          ge (η)      D
                       (property clone with GE), or a dashpot to
                       ground on one DOF (CDAMP)                       c           C
joint_flexibility      a member end at a joint node (every node where  k           K
                       two or more members meet) on a node of its own
                       (new GRID), joined rigidly except one rotation,
                       which gets a spring (RBE2 + CELAS)
boundary_flexibility   constrained components released (SPC edited)    k           K
                       into springs to ground: one, or a clamp's
                       translations or rotations together
=====================  ==============================================  ==========  =========

The frequency signature of each follows from the dynamic stiffness it adds:
real and constant (stiffness), real ∝ −ω² (mass), imaginary ∝ ω (viscous),
imaginary and constant (hysteretic).  Candidates of the first three kinds act
on the existing DOFs (``shared=True``): their unit matrix ``G`` on the model's
constrained DOFs enters the linear screening.  ``G`` is a :class:`LocalMatrix` (the few DOF indices it
touches and a small dense block), never an n × n matrix: a 100k-DOF model has ~10⁵ candidates.  Joint and boundary candidates
change the DOF set; they carry their ``release`` and are screened exactly, at
every place, as rank-1..3 updates of the nominal receptance
(:mod:`~updating.diagnosis.release`).

Every candidate knows how to add itself to an :class:`~updating.fe.FEModel`
together with an updating :class:`~updating.fe.Parameter` for its value, so
the augmented model is differentiated exactly like any other.
"""
from __future__ import annotations

import dataclasses
import difflib
import logging
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp

from modalab.core.dof import DIRECTION_NAMES
from modalab.core.errors import ModalabValueError

from updating.fe import Damper, FEModel, LumpedMass, Parameter, Spring
from updating.fe.assembly import assemble, element_stiffness
from updating.diagnosis.local_matrix import LocalMatrix, _group_G

log = logging.getLogger(__name__)
__all__ = ["Candidate", "LocalMatrix", "build_library", "spring_loss_candidates", "loss_of", "UNITS"]

#: the group label prefix of the springs to ground the diagnosis adds (its terms, :func:`_dof_candidates`)
SPRING_GROUP = "diag_k_"
#: the group label prefix of the springs that hold a support's released components (:func:`_release_spc`)
SUPPORT_GROUP = "diag_bc_"
#: the label of a found spring's own loss (:func:`spring_loss_candidates`)
SPRING_LOSS = "loss factor of the spring to ground at"

UNITS = {("ground_spring", 1): "N/m", ("ground_spring", 4): "N·m/rad", ("added_mass", 1): "kg",
         ("added_mass", 4): "kg·m²", ("local_damping", "D"): "-", ("local_damping", "C"): "N·s/m",
         ("joint_flexibility", 1): "N/m", ("joint_flexibility", 4): "N·m/rad",
         ("boundary_flexibility", 1): "N/m", ("boundary_flexibility", 4): "N·m/rad"}


def _unit(physics, comp=None, matrix=None):
    if physics == "local_damping":
        return UNITS[(physics, matrix)]
    return UNITS[(physics, 1 if comp <= 3 else 4)]


@dataclass
class Candidate:
    """One augmentation: category, place, value name and unit, and how to build it."""

    physics: str
    label: str
    nodes: tuple
    dofs: tuple                      # DOF labels, e.g. ('14+Z',)
    elements: tuple                  # element ids concerned (damping group, joint side)
    value_name: str                  # 'k', 'm', 'J', 'eta', 'c'
    unit: str
    matrix: str                      # 'K', 'M', 'C', 'D'
    shared: bool
    apply: Callable = field(repr=False, default=None)   # (FEModel, eid) -> (FEModel, Parameter, scale)
    G: "LocalMatrix | sp.spmatrix | None" = field(repr=False, default=None)   # the unit matrix on the a-set
    initial: float = 0.0
    key: str = ""
    upper: float = np.inf            # largest plausible value (in ``unit``); the fits are bounded by it
    #: a release (joint or support flexibility) in the exact low-rank form of :mod:`~updating.diagnosis.release`:
    #: ``(kind, node, components, elements)``: 'joint' (the ``elements`` at ``node`` get the released
    #: ``components`` of their own) or 'support' (the constrained ``components`` of ``node`` freed)
    release: tuple | None = None

    def __post_init__(self):
        if not self.key:
            self.key = f"{self.physics}:{self.label}"


def _nodes_of(el) -> tuple:
    """The element's grid ids (``nodes`` of the element API; empty for scalar elements to ground)."""
    try:
        return tuple(n for n in el.nodes if n is not None)
    except (NotImplementedError, AttributeError, TypeError):
        return ()


def _next_id(model: FEModel) -> int:
    ids = list(model.elements) + list(model.rbe2s)
    return (max(ids) if ids else 0) + 1


def _next_node(model: FEModel) -> int:
    return max(model.nodes) + 1 if model.nodes else 1


def _fix_foreign(m: FEModel, node: int, comps) -> None:
    """A lumped mass touches all six components; constrain those the model did not have (planar models)."""
    foreign = [c for c in range(1, 7) if c not in comps]
    if foreign:
        m.add_spc(node, "".join(map(str, foreign)))


def _member_ends(model: FEModel) -> list[tuple[int, tuple]]:
    """``[(node, side)]``: the member ends of the model's two-node beams at every node where two or more
    members meet.  The elements at a node are grouped into members: two elements of the same property whose
    directions from the node are opposite (collinear) continue one member through it; every other element
    ends a member there.  A node with a single member (an interior node of a straight run) is no joint.
    With two members one side is listed (releasing either is the same split); with more, each member's."""
    by_node: dict[int, list] = {}
    for e in model.elements.values():
        if hasattr(e, "n1") and hasattr(e, "n2") and getattr(e, "pid", None) is not None and e.n1 != e.n2:
            by_node.setdefault(e.n1, []).append(e)
            by_node.setdefault(e.n2, []).append(e)
    out = []
    for n, els in sorted(by_node.items()):
        if len(els) < 2:
            continue
        x0 = np.asarray(model.nodes[n].xyz, float)
        dirs = []
        for e in els:
            d = np.asarray(model.nodes[e.n2 if e.n1 == n else e.n1].xyz, float) - x0
            dirs.append(d / max(np.linalg.norm(d), 1e-300))
        groups, used = [], set()
        for a in range(len(els)):
            if a in used:
                continue
            used.add(a)
            g = [a]
            for b in range(a + 1, len(els)):
                if b not in used and els[b].pid == els[a].pid and float(dirs[a] @ dirs[b]) < -1 + 1e-6:
                    g.append(b)
                    used.add(b)
                    break
            groups.append(tuple(sorted(els[i].eid for i in g)))
        if len(groups) < 2:
            continue
        groups.sort(key=lambda g: (len(g), g))
        for g in (groups[:1] if len(groups) == 2 else groups):
            out.append((n, g))
    return out


#: an omitted mass (sensors, cables, fixtures) is at most this fraction of the structure's own mass
PLAUSIBLE_MASS_FRACTION = 0.5


def _plausible_inertia(model: FEModel) -> tuple[float, float]:
    """Upper bounds of an omitted point mass and rotary inertia: ``PLAUSIBLE_MASS_FRACTION`` of the model's
    mass (its largest rigid translational mass over x, y, z, on the free DOFs) and of that mass times the
    square of the model's largest dimension.  A very heavy mass pins its node like a support would, so
    without the bound it competes with springs to ground on physically absurd terms."""
    st = model.structure()
    M = st.M
    masses = [float(u @ (M @ u)) for u in (np.array([1.0 if d.axis == ax else 0.0 for d in st.dofs])
                                           for ax in (1, 2, 3))]
    mass = max(masses) if all(np.isfinite(masses)) else np.nan
    xyz = np.array([nd.xyz for nd in model.nodes.values()], float)
    size = float(np.max(np.ptp(xyz, axis=0))) if len(xyz) > 1 else 1.0
    if not np.isfinite(mass):
        raise ModalabValueError(f"model {model.name!r}: its translational mass is {mass!r}; check the densities, "
                                "CONM2 masses and non-structural masses of the deck")
    if not mass > 0:
        # no translational mass on the free DOFs (e.g. only rotations free): nothing to scale a bound by
        log.info("model %r has no translational mass on its free DOFs: added masses are not bounded", model.name)
        return np.inf, np.inf
    return PLAUSIBLE_MASS_FRACTION * mass, PLAUSIBLE_MASS_FRACTION * mass * max(size, 1e-3) ** 2


#: the kinds of missing physics the library builds (``modalab diagnose --kinds``)
KINDS = ("ground_spring", "added_mass", "local_damping", "joint_flexibility", "boundary_flexibility")


def validate_kinds(kinds) -> frozenset:
    """``kinds`` as a set of :data:`KINDS` (None or empty: all of them).  A name that is not a kind is an
    error naming it and suggesting the closest kind; a misspelt kind never silently yields zero candidates."""
    if kinds is None:
        return frozenset(KINDS)
    if isinstance(kinds, str):
        kinds = [k for k in kinds.replace(",", " ").split() if k]
    out = set()
    for k in kinds:
        k = str(k).strip()
        if k not in KINDS:
            close = difflib.get_close_matches(k, KINDS, n=1, cutoff=0.5)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise ModalabValueError(f"unknown kind of missing physics {k!r}; {hint}expected some of {', '.join(KINDS)}")
        out.add(k)
    if not out:
        raise ModalabValueError(f"no kind of missing physics selected; expected some of {', '.join(KINDS)}")
    return frozenset(out)


def build_library(model: FEModel, *, kinds=None, nodes=None, joint_nodes=None, group_size: int = 2,
                  stiffness_scale: float | None = None, log_level: int = logging.INFO) -> list[Candidate]:
    """All candidates of the requested ``kinds`` for ``model``.

    nodes : restrict DOF-wise candidates to these nodes (default: every node).
    joint_nodes : nodes where joint-flexibility candidates are built (default: nodes joined by rigid
        links, and nodes where elements of different properties meet).
    group_size : element groups for local damping are single elements and runs of this many
        neighbouring elements sharing a node.
    log_level : of the one-line summary (a caller that only looks at part of the library lowers it).

    The unit matrices ``G`` of shared candidates are :class:`LocalMatrix` (indices and a small block).
    """
    kinds = validate_kinds(kinds)
    ctx = _LibraryContext(model, nodes)
    cands: list[Candidate] = []
    if kinds & {"ground_spring", "local_damping", "added_mass"}:
        cands += _dof_candidates(ctx, kinds)
    if "local_damping" in kinds:
        cands += _group_damping_candidates(ctx, group_size)
    if "boundary_flexibility" in kinds:
        cands += _boundary_candidates(ctx)
    if "joint_flexibility" in kinds:
        jnodes = set(joint_nodes) if joint_nodes is not None else None
        cands += _link_candidates(ctx, jnodes) + _member_end_candidates(ctx, jnodes)
    log.log(log_level, "candidate library: %d candidates (%s)", len(cands),
             ", ".join(f"{k}={sum(c.physics == k for c in cands)}" for k in sorted(kinds)))
    return cands


class _LibraryContext:
    """What every part of the library needs to know about the model: its reduction (``u = T u_a``), the
    full DOF index, the components present and constrained at each node, the selected nodes."""

    def __init__(self, model: FEModel, nodes):
        self.model = model
        self.red = red = model.reduction()
        self.full = red.full_dofs
        self.fidx = {(d.node, d.axis): i for i, d in enumerate(self.full)}
        self.present: dict = {}
        for d in self.full:
            self.present.setdefault(d.node, []).append(d.axis)
        self.fixed = {(d.node, d.axis) for d in red.fixed}
        self.nodes = nodes
        self.sel_nodes = sorted(self.present) if nodes is None else [n for n in nodes if n in self.present]

    def dof_G(self, keys):
        """``Rᵀ R``, ``R`` the rows of T for the (node, comp) ``keys`` (None when none moves)."""
        rows = [self.fidx[k] for k in keys if k in self.fidx]
        if not rows:
            return None
        return LocalMatrix.from_csr_rows(self.red.T, rows, self.red.n_dof)


def _dof_candidates(ctx: _LibraryContext, kinds) -> list[Candidate]:
    """Springs and dashpots to ground, rotary inertias on each free DOF, point masses at each node."""
    out = []
    m_max, j_max = _plausible_inertia(ctx.model)
    present = ctx.present
    for n in ctx.sel_nodes:
        comps = [c for c in present[n] if (n, c) not in ctx.fixed]
        for c in comps:
            lbl = f"{n}+{DIRECTION_NAMES[c]}"
            G = ctx.dof_G([(n, c)])
            if G is None:
                continue
            if "ground_spring" in kinds:
                def add_spring(m, eid, n=n, c=c):
                    m = m.copy()
                    m.add_element(Spring(eid, a=(n, c), b=None, k=0.0, group=f"{SPRING_GROUP}{eid}"))
                    return m, Parameter(f"k_{n}_{c}", "k", elements=(eid,), mode="value"), 1.0
                out.append(Candidate("ground_spring", f"spring to ground at {lbl}", (n,), (lbl,), (), "k",
                                     _unit("ground_spring", c), "K", True, add_spring, G))
            if "local_damping" in kinds:
                def add_damper(m, eid, n=n, c=c):
                    m = m.copy()
                    m.add_element(Damper(eid, a=(n, c), b=None, c=0.0, group=f"diag_c_{eid}"))
                    return m, Parameter(f"c_{n}_{c}", "c", elements=(eid,), mode="value"), 1.0
                out.append(Candidate("local_damping", f"dashpot to ground at {lbl}", (n,), (lbl,), (), "c",
                                     _unit("local_damping", matrix="C"), "C", True, add_damper, G))
            if "added_mass" in kinds and c >= 4:
                def add_inertia(m, eid, n=n, c=c, guess=1e-3):
                    m = m.copy()
                    inertia = [0.0, 0.0, 0.0]
                    inertia[c - 4] = guess
                    m.add_element(LumpedMass(eid, n, mass=0.0, inertia=inertia, group=f"diag_J_{eid}"))
                    _fix_foreign(m, n, present[n])
                    return m, Parameter(f"J_{n}_{c}", "inertia", elements=(eid,), mode="factor"), guess
                out.append(Candidate("added_mass", f"rotary inertia at {lbl}", (n,), (lbl,), (), "J",
                                     _unit("added_mass", c), "M", True, add_inertia, G, upper=j_max))
        trans = [c for c in comps if c <= 3]
        if "added_mass" in kinds and trans:
            G = ctx.dof_G([(n, c) for c in trans])
            if G is not None:
                def add_mass(m, eid, n=n):
                    m = m.copy()
                    m.add_element(LumpedMass(eid, n, mass=0.0, group=f"diag_m_{eid}"))
                    _fix_foreign(m, n, present[n])
                    return m, Parameter(f"m_{n}", "mass", elements=(eid,), mode="value"), 1.0
                out.append(Candidate("added_mass", f"point mass at node {n}", (n,),
                                     tuple(f"{n}+{DIRECTION_NAMES[c]}" for c in trans), (), "m",
                                     _unit("added_mass", 1), "M", True, add_mass, G, upper=m_max))
    return out


def spring_loss_candidates(model: FEModel) -> list[Candidate]:
    """The loss of each spring to ground that the diagnosis has added to ``model`` (a current term), and of
    each support it has released (:func:`_release_spc`: the springs that hold a clamp's released components).

    A rubber mount, a cord or an elastic support dissipates in proportion to its own deflection: a
    hysteretic ``i η k`` at its DOF, the spring's own structural damping (CELAS ``GE``, on top of PARAM G,
    which acts on every stiffness).  One value each, η of that spring (bounded to [0, 1]; one η for the
    springs of a support released with one stiffness); ``G`` is the spring's stiffness at ``model``, so that
    the screening's value is η itself.  Without this form the loss of a found spring shows up as a dashpot
    to ground wherever the spring's own mode moves (on a free frame, anywhere along the spring's direction),
    and an elastic clamp's loss as a dashpot up the member it holds (held-out AW 3639, a portal's foot): a
    second finding the data do not need."""
    springs = [e for e in model.elements.values() if isinstance(e, Spring) and e.b is None and e.k > 0 and
               e.group.startswith((SPRING_GROUP, SUPPORT_GROUP))]
    if not springs:
        return []
    ctx, out, groups = _LibraryContext(model, None), [], {}
    for e in springs:
        groups.setdefault(e.group if e.group.startswith(SUPPORT_GROUP) else e.eid, []).append(e)
    for group, els in groups.items():
        keys = [(int(e.a[0]), int(e.a[1])) for e in els]
        G = ctx.dof_G(keys)
        if G is None or len({e.k for e in els}) != 1:
            continue
        dofs = tuple(f"{n}+{DIRECTION_NAMES[c]}" for n, c in keys)
        lbl = ", ".join(dofs)

        def add_loss(m, eid, keys=tuple(keys), lbl=lbl):
            hit = [x for x in m.elements.values() if isinstance(x, Spring) and x.b is None and
                   (int(x.a[0]), int(x.a[1])) in keys and x.group.startswith((SPRING_GROUP, SUPPORT_GROUP))]
            if len(hit) != len(keys):
                raise ModalabValueError(f"{SPRING_LOSS} {lbl}: the model has no spring to ground there (its "
                                        "spring must be a term before its loss)")
            name = "_".join(f"{n}_{c}" for n, c in keys)
            return m, Parameter(f"ge_{name}", "ge", elements=tuple(x.eid for x in hit), mode="value"), 1.0
        out.append(Candidate("local_damping", f"{SPRING_LOSS} {lbl}", (keys[0][0],), dofs, (),
                             "eta", _unit("local_damping", matrix="D"), "D", True, add_loss,
                             LocalMatrix(G.rows, G.block * float(els[0].k), G.n), upper=1.0))
    return out


def loss_of(c: Candidate, spring: Candidate) -> bool:
    """Whether ``c`` is the own loss (:func:`spring_loss_candidates`) of the spring to ground or the released
    support ``spring``."""
    return (spring.physics in ("ground_spring", "boundary_flexibility") and c.label.startswith(SPRING_LOSS)
            and tuple(c.dofs) == tuple(spring.dofs))


def _damping_groups(model: FEModel, group_size: int) -> list[tuple]:
    """Element groups for local damping: every structural element with a property (beams, rods, shells)
    alone, and the runs of up to ``group_size + 1`` elements sharing a node; each group once."""
    beams = [e for e in model.elements.values() if getattr(e, "pid", None) is not None
             and len(_nodes_of(e)) >= 2 and hasattr(model.properties.get(e.pid), "mid")]
    groups = [(e.eid,) for e in beams]
    if group_size > 1:
        by_node: dict[int, list] = {}
        for e in beams:
            for n in _nodes_of(e):
                by_node.setdefault(n, []).append(e.eid)
        for n, eids in sorted(by_node.items()):
            if len(eids) >= 2:
                groups.append(tuple(sorted(eids))[:group_size + 1])
    return list(dict.fromkeys(groups))


def _add_group_damping(m, eid, g):
    """The elements ``g`` moved to clones of their properties with a loss factor (GE) of their own."""
    m = m.copy()
    new_pid = max(m.properties) + 1
    groupname = f"diag_damped_{eid}"
    pids = {m.elements[i].pid for i in g}
    mapping = {}
    for k, pid in enumerate(sorted(pids)):
        prop = m.properties[pid]
        clone = dataclasses.replace(prop, pid=new_pid + k, ge=0.0)
        if hasattr(clone, "name"):
            clone = dataclasses.replace(clone, name=getattr(prop, "name", ""))
        m.add_property(clone)
        mapping[pid] = new_pid + k
    for i in g:
        m.elements[i] = dataclasses.replace(m.elements[i], pid=mapping[m.elements[i].pid])
    m._changed()
    m.metadata.setdefault("diagnosis_groups", {})[groupname] = list(mapping.values())
    return m, Parameter(f"eta_{'_'.join(map(str, g))}", "ge", properties=tuple(mapping.values()), mode="value"), 1.0


def _group_damping_candidates(ctx: _LibraryContext, group_size: int) -> list[Candidate]:
    """Structural damping on element groups; ``G`` the group's stiffness on the a-set."""
    model, nodes = ctx.model, ctx.nodes
    groups = [g for g in _damping_groups(model, group_size)
              if nodes is None or any(n in nodes for i in g for n in _nodes_of(model.elements[i]))]
    used = sorted({i for g in groups for i in g})
    blocks = dict(zip(used, element_stiffness(model, [model.elements[i] for i in used])))
    out = []
    for g in groups:
        G = _group_G(ctx.red, [blocks[i] for i in g if i in blocks], ctx.red.n_dof) \
            if any(i in blocks for i in g) else None
        enodes = tuple(sorted({n for i in g for n in _nodes_of(model.elements[i])}))
        out.append(Candidate("local_damping", f"structural damping on element(s) {', '.join(map(str, g))}",
                             enodes, (), g, "eta", "-", "D", True,
                             lambda m, eid, g=g: _add_group_damping(m, eid, g), G))
    return out


def _active_components(ctx: _LibraryContext, spc, Kfull, moving) -> list[int]:
    """The components of ``spc`` that hold something: released, they couple through the element stiffness
    to a DOF that moves (not the components a planar model constrains everywhere)."""
    active = []
    for c in spc.components:
        i = ctx.fidx.get((spc.node, c))
        if i is None:
            continue
        row = Kfull.getrow(i)
        if np.any(moving[row.indices[np.abs(row.data) > 1e-12 * max(abs(Kfull[i, i]), 1e-300)]]):
            active.append(c)
    return active


def _release_spc(m, eid, spc, group):
    """The components ``group`` of ``spc`` released into springs to ground (one parameter).  The constraints
    of ``spc.node`` are matched by node and components, not by identity, so that a second release at the same
    node (a clamp's translations after its rotations) applies to a model where the first has replaced the
    constraint by the components it left."""
    m = m.copy()
    hit = [s for s in m.spcs if s.node == spc.node and set(s.components) & set(group)]
    m.spcs = [s for s in m.spcs if s not in hit]
    for s in hit:
        rest = tuple(x for x in s.components if x not in group)
        if rest:
            m.add_spc(s.node, "".join(map(str, rest)))
    for k, c in enumerate(group):
        m.add_element(Spring(eid + k, a=(spc.node, c), b=None, k=0.0, group=f"{SUPPORT_GROUP}{eid}"))
    m._changed()
    return m, Parameter(f"kbc_{spc.node}_{''.join(map(str, group))}", "k",
                        elements=tuple(eid + k for k in range(len(group))), mode="value"), 1.0


def _boundary_candidates(ctx: _LibraryContext) -> list[Candidate]:
    """Constrained components released into springs to ground: each alone, and a clamp's translations (one
    stiffness) and rotations (one rotational stiffness) together, a rank-2..3 change each."""
    model, red = ctx.model, ctx.red
    out, Kfull, moving = [], None, None
    free_keys = {(d.node, d.axis) for d in red.dofs} if hasattr(red, "dofs") else set()
    for spc in model.spcs:
        if ctx.nodes is not None and spc.node not in ctx.nodes:
            continue
        if Kfull is None:
            Kfull = sp.csr_matrix(assemble(model).K)
            moving = np.zeros(len(ctx.full), bool)
            moving[[ctx.fidx[k] for k in free_keys if k in ctx.fidx]] = True
        active = _active_components(ctx, spc, Kfull, moving)
        for c in active:
            lbl = f"{spc.node}+{DIRECTION_NAMES[c]}"
            out.append(Candidate("boundary_flexibility", f"support flexibility at {lbl}", (spc.node,), (lbl,),
                                 (), "k", _unit("boundary_flexibility", c), "K", False,
                                 lambda m, eid, spc=spc, c=c: _release_spc(m, eid, spc, (c,)), None,
                                 release=("support", spc.node, (c,), ())))
        for group in ([c for c in active if c <= 3], [c for c in active if c >= 4]):
            if len(group) < 2:
                continue
            lbls = tuple(f"{spc.node}+{DIRECTION_NAMES[c]}" for c in group)
            what = "translations" if group[0] <= 3 else "rotations"
            out.append(Candidate("boundary_flexibility", f"support flexibility at node {spc.node} ({what} "
                                 f"{', '.join(DIRECTION_NAMES[c] for c in group)})", (spc.node,), lbls, (),
                                 "k", _unit("boundary_flexibility", group[0]), "K", False,
                                 lambda m, eid, spc=spc, group=tuple(group): _release_spc(m, eid, spc, group),
                                 None, release=("support", spc.node, tuple(group), ())))
    return out


def _soften_link(m, eid, link, dep, c):
    """Component ``c`` of the rigid link's dependent node ``dep`` replaced by a spring."""
    m = m.copy()
    del m.rbe2s[link.eid]
    others = tuple(d for d in link.dependents if d != dep)
    if others:
        m.add_rbe2(link.eid, link.independent, others, "".join(map(str, link.components)))
    rest = tuple(x for x in link.components if x != c)
    new = _next_id(m)
    if rest:
        m.add_rbe2(max(new, eid + 1), link.independent, (dep,), "".join(map(str, rest)))
    m.add_element(Spring(eid, a=(link.independent, c), b=(dep, c), k=0.0, group=f"diag_j_{eid}"))
    m._changed()
    return m, Parameter(f"kj_{dep}_{c}", "k", elements=(eid,), mode="value"), 1.0


def _link_candidates(ctx: _LibraryContext, jnodes) -> list[Candidate]:
    """Rigid links: one component of a dependent node released into a spring."""
    out = []
    for link in ctx.model.rbe2s.values():
        for dep in link.dependents:
            if jnodes is not None and dep not in jnodes and link.independent not in jnodes:
                continue
            for c in link.components:
                lbl = f"{dep}+{DIRECTION_NAMES[c]}"
                out.append(Candidate("joint_flexibility", f"flexible joint ({DIRECTION_NAMES[c]}) at the link "
                                     f"{link.independent}-{dep}", (link.independent, dep), (lbl,), (link.eid,),
                                     "k", _unit("joint_flexibility", c), "K", False,
                                     lambda m, eid, link=link, dep=dep, c=c: _soften_link(m, eid, link, dep, c),
                                     None))
    return out


def _split_node(m, eid, n, side, c, comps_present):
    """The member end ``side`` at node ``n`` on a new GRID, joined rigidly except rotation ``c`` (a spring)."""
    m = m.copy()
    nn = _next_node(m)
    m.add_node(nn, m.nodes[n].xyz, m.nodes[n].cd)
    for i in side:
        e = m.elements[i]
        kw = {}
        if e.n1 == n:
            kw["n1"] = nn
        if e.n2 == n:
            kw["n2"] = nn
        m.elements[i] = dataclasses.replace(e, **kw)
    comps = [x for x in comps_present if x != c]
    rid = eid + 1
    while rid in m.elements or rid in m.rbe2s:
        rid += 1
    if comps:
        m.add_rbe2(rid, n, (nn,), "".join(map(str, comps)))
    _fix_foreign(m, n, comps_present)
    _fix_foreign(m, nn, comps_present)
    m.add_element(Spring(eid, a=(n, c), b=(nn, c), k=0.0, group=f"diag_j_{eid}"))
    m._changed()
    # named by the member end too: two ends at one junction released about the same axis are two terms
    return m, Parameter(f"kj_{n}_{c}_e{min(side)}", "k", elements=(eid,), mode="value"), 1.0


def _member_end_candidates(ctx: _LibraryContext, jnodes) -> list[Candidate]:
    """Member ends at beam junctions (every node where two or more members meet): one member end gets the
    released rotation of its own (a node split); screened exactly by :mod:`~updating.diagnosis.release`."""
    out = []
    for n, side in _member_ends(ctx.model):
        if jnodes is not None and n not in jnodes:
            continue
        for c in ctx.present.get(n, []):
            if c < 4 or (n, c) in ctx.fixed:
                continue
            lbl = f"{n}+{DIRECTION_NAMES[c]}"
            out.append(Candidate("joint_flexibility", f"flexible joint ({DIRECTION_NAMES[c]}) at node {n} "
                                 f"between element(s) {', '.join(map(str, side))} and the rest", (n,), (lbl,),
                                 side, "k", _unit("joint_flexibility", c), "K", False,
                                 lambda m, eid, n=n, side=side, c=c: _split_node(m, eid, n, side, c,
                                                                                 ctx.present[n]),
                                 None, release=("joint", n, (c,), side)))
    return out
