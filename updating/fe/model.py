"""The :class:`FEModel` container: nodes, materials, properties, elements, constraints.

A model is built incrementally (``add_node``, ``add_material``, ...) by
Python code or by the Nastran bulk-data reader, then assembled into sparse
matrices.  Ids are unique per kind (node, material, property, element/link),
as in Nastran; a duplicate raises an error naming both.

Mass formulation: ``coupled_mass=True`` uses consistent element mass,
False uses Nastran's lumped mass (PARAM COUPMASS ≤ 0, Nastran's default).
``global_ge`` is PARAM G (D += G·K).  ``rayleigh = (α, β)`` adds C = αM + βK.
``modal_damping`` (a :class:`~updating.fe.damping.ModalDampingTable`) is used by
modal FRF synthesis, like TABDMP1 with SDAMPING.
"""
from __future__ import annotations

import copy
import difflib
import logging
from dataclasses import dataclass

import numpy as np

from modalab.core.dof import Dof
from modalab.core.errors import ModalabValueError
from modalab.core.structure import Structure

from updating.fe.assembly import Matrices, assemble
from updating.fe.constraints import RBE2, SPC, Reduction, build_reduction, parse_components
from updating.fe.elements.base import Element
from updating.fe.properties import Material
from updating.fe.solvers import modes_of
from updating.fe.solvers import frf_direct, frf_modal

log = logging.getLogger(__name__)

__all__ = ["Node", "FEModel", "FESystem"]


@dataclass(frozen=True)
class Node:
    """A grid point: id, basic coordinates (m), optional displacement system ``cd``.

    ``cd`` is a 3×3 rotation matrix whose columns are the CD axes expressed in
    the basic system (u_basic = cd @ u_cd); None means basic.
    """

    nid: int
    xyz: np.ndarray
    cd: np.ndarray | None = None


@dataclass
class FESystem:
    """Constrained matrices of a model on its independent DOFs, with the map back to all DOFs."""

    K: object
    M: object
    C: object
    D: object
    dofs: list
    reduction: Reduction

    @property
    def n_dof(self) -> int:
        return len(self.dofs)

    def structure(self, coords=None, name: str = "") -> Structure:
        return Structure(M=self.M, K=self.K, C=self.C, D=self.D, dofs=self.dofs, coords=coords, name=name)


class FEModel:
    """A finite-element model (see the module docstring)."""

    def __init__(self, name: str = "", *, coupled_mass: bool = True, global_ge: float = 0.0,
                 rayleigh: tuple | None = None, modal_damping=None):
        self.name = name
        self.nodes: dict[int, Node] = {}
        self.materials: dict[int, Material] = {}
        self.properties: dict[int, object] = {}
        self.elements: dict[int, Element] = {}
        self.rbe2s: dict[int, RBE2] = {}
        self.spcs: list[SPC] = []
        self.coupled_mass = bool(coupled_mass)
        self.global_ge = global_ge
        #: ids of the elements whose stiffness PARAM G does not damp (their own ``ge`` is their whole loss
        #: factor): empty for a deck as Nastran reads it (G·K over the whole K); see :func:`own_loss_exempt`
        self.global_ge_exempt: frozenset = frozenset()
        self.rayleigh = rayleigh
        self.modal_damping = modal_damping
        #: free-form information (named nodes, source file ...), copied with the model
        self.metadata: dict = {}
        self._dofs = None

    # ------------------------------------------------------------- building
    def _changed(self):
        self._dofs = None

    def add_node(self, nid: int, xyz, cd=None) -> Node:
        """Add grid ``nid`` at ``xyz`` (m, basic); ``cd`` a 3×3 rotation (columns = CD axes) or None."""
        nid = int(nid)
        if nid in self.nodes:
            raise ModalabValueError(f"duplicate node id {nid}; every node needs its own id")
        x = np.asarray(xyz, dtype=float)
        if x.shape != (3,) or not np.all(np.isfinite(x)):
            raise ModalabValueError(f"node {nid}: coordinates {xyz!r}; expected three finite numbers in m")
        R = None
        if cd is not None:
            R = np.asarray(cd, dtype=float)
            if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-8) or np.linalg.det(R) < 0:
                raise ModalabValueError(f"node {nid}: cd must be a proper 3x3 rotation matrix (orthonormal, det +1) "
                                        "whose columns are the displacement axes in the basic system")
            if np.allclose(R, np.eye(3), atol=1e-14):
                R = None
        node = Node(nid, x, R)
        self.nodes[nid] = node
        self._changed()
        return node

    def add_material(self, material: Material) -> Material:
        if material.mid in self.materials:
            raise ModalabValueError(f"duplicate material id {material.mid}")
        self.materials[material.mid] = material
        return material

    def add_property(self, prop) -> object:
        if prop.pid in self.properties:
            raise ModalabValueError(f"duplicate property id {prop.pid}")
        self.properties[prop.pid] = prop
        return prop

    def add_element(self, element: Element) -> Element:
        if not isinstance(element, Element):
            raise ModalabValueError(f"add_element got a {type(element).__name__}; expected an element such as "
                                    "Beam3D, Spring or LumpedMass (rigid links go through add_rbe2)")
        eid = element.eid
        if eid in self.elements or eid in self.rbe2s:
            raise ModalabValueError(f"duplicate element id {eid}; element and rigid-link ids must be unique")
        self.elements[eid] = element
        self._changed()
        return element

    def add_rbe2(self, eid: int, independent: int, dependents, components="123456") -> RBE2:
        """Rigid link: ``components`` of each dependent node follow node ``independent`` rigidly."""
        if eid in self.elements or eid in self.rbe2s:
            raise ModalabValueError(f"duplicate element id {eid}; element and rigid-link ids must be unique")
        deps = (int(dependents),) if np.ndim(dependents) == 0 else tuple(int(d) for d in dependents)
        if int(independent) in deps:
            raise ModalabValueError(f"rigid link {eid}: node {independent} is both independent and dependent")
        link = RBE2(int(eid), int(independent), deps, parse_components(components, f"rigid link {eid}"))
        self.rbe2s[link.eid] = link
        self._changed()
        return link

    def add_spc(self, node: int, components="123456") -> SPC:
        """Fix ``components`` (in the node's CD system) of ``node``."""
        s = SPC(int(node), parse_components(components, f"SPC on node {node}"))
        self.spcs.append(s)
        return s

    # ------------------------------------------------------------- look-ups
    def node_xyz(self, nid) -> np.ndarray:
        try:
            return self.nodes[nid].xyz
        except KeyError:
            raise ModalabValueError(f"node {nid} is not defined; add it with add_node before using it") from None

    def material(self, mid) -> Material:
        try:
            return self.materials[mid]
        except KeyError:
            raise ModalabValueError(f"material id {mid} is not defined; known ids: {sorted(self.materials)[:20]}") from None

    def prop(self, pid):
        try:
            return self.properties[pid]
        except KeyError:
            raise ModalabValueError(f"property id {pid} is not defined; known ids: {sorted(self.properties)[:20]}") from None

    def property_ids(self, name_or_ids) -> list:
        """Property ids for a group name (``BeamProperty.name``), an id, or a list of either."""
        items = [name_or_ids] if isinstance(name_or_ids, (str, int, np.integer)) else list(name_or_ids)
        out = []
        for it in items:
            if isinstance(it, str):
                hits = [p.pid for p in self.properties.values() if getattr(p, "name", "") == it]
                if not hits:
                    names = sorted({getattr(p, 'name', '') for p in self.properties.values()} - {""})
                    close = difflib.get_close_matches(it, names, n=1)
                    raise ModalabValueError(f"no property is named {it!r}"
                                            + (f" (did you mean {close[0]!r}?)" if close else "")
                                            + f"; known names: {names}")
                out.extend(hits)
            else:
                self.prop(int(it))
                out.append(int(it))
        return sorted(set(out))

    def elements_with_property(self, pids) -> list:
        s = set(pids)
        return [e for e in self.elements.values() if getattr(e, "pid", None) in s]

    def copy(self) -> "FEModel":
        """A copy whose dictionaries can be changed without touching this model (objects shared)."""
        new = copy.copy(self)
        new.nodes = dict(self.nodes)
        new.materials = dict(self.materials)
        new.properties = dict(self.properties)
        new.elements = dict(self.elements)
        new.rbe2s = dict(self.rbe2s)
        new.spcs = list(self.spcs)
        new.metadata = dict(self.metadata)
        return new

    def __repr__(self) -> str:
        return (f"FEModel({self.name or 'unnamed'}: {len(self.nodes)} nodes, {len(self.elements)} elements, "
                f"{len(self.rbe2s)} rigid links, {len(self.spcs)} SPCs)")

    # ------------------------------------------------------------ DOFs, matrices
    @property
    def dofs(self) -> list:
        """All DOFs (before constraints), sorted by node then axis, as positive :class:`Dof`."""
        if self._dofs is None:
            keys = set()
            basic = set()
            for el in self.elements.values():
                for n, a in el.dofs():
                    if n not in self.nodes:
                        raise ModalabValueError(f"element {el.eid} uses node {n}, which is not defined; add the node")
                    keys.add((n, a))
                    if el.frame == "basic":
                        basic.add((n, a))
            for link in self.rbe2s.values():
                for n in (link.independent, *link.dependents):
                    if n not in self.nodes:
                        raise ModalabValueError(f"rigid link {link.eid} uses node {n}, which is not defined")
                keys.update((link.independent, a) for a in range(1, 7))
                keys.update((d, c) for d in link.dependents for c in link.components)
            # a rotated node needs whole triplets where basic-frame elements act on it
            for n, a in basic:
                if self.nodes[n].cd is not None:
                    base = 1 if a <= 3 else 4
                    keys.update((n, base + k) for k in range(3))
            self._dofs = [Dof(n, a) for n, a in sorted(keys)]
        return self._dofs

    @property
    def n_dof(self) -> int:
        return len(self.dofs)

    def coords(self) -> dict:
        return {nid: tuple(n.xyz) for nid, n in self.nodes.items()}

    def assemble(self) -> Matrices:
        """Unconstrained K, M, C, D on :attr:`dofs` (see :mod:`updating.fe.assembly`)."""
        return assemble(self)

    def reduction(self) -> Reduction:
        """The SPC / rigid-link transformation ``u = T u_a``."""
        return build_reduction(self)

    def system(self) -> FESystem:
        """Constrained matrices on the independent DOFs."""
        red = self.reduction()
        m = red.reduce_matrices(self.assemble())
        return FESystem(K=m.K, M=m.M, C=m.C, D=m.D, dofs=m.dofs, reduction=red)

    def structure(self) -> Structure:
        """:class:`~modalab.core.structure.Structure` on the constrained DOFs."""
        return self.system().structure(coords=self.coords(), name=self.name)

    def modes(self, n_modes: int | None = None, *, full: bool = True, **kw):
        """Normal modes as a :class:`~modalab.core.modes.ModeSet` (see :func:`updating.fe.solvers.normal_modes`).

        ``full=True`` maps the shapes back to every model DOF (dependent DOFs
        filled in by the rigid links, constrained DOFs zero).
        """
        return modes_of(self.system(), n_modes, full=full, modal_damping=self.modal_damping, **kw)

    def frf(self, freq_hz, responses=None, references=None, *, quantity: str = "accelerance",
            method: str = "direct", n_modes: int | None = None, residual: bool = True, beta: float = 0.0,
            window_beta_per_s: float | None = None):
        """FRFs between any model DOFs: ``method='direct'`` (exact sparse solves) or ``'modal'``
        (``n_modes`` modes, the model's ``modal_damping`` table if set, residual flexibility).
        ``window_beta_per_s`` (or its older name ``beta``; 1/s, default 0): evaluate at ``s = iω + β``, as data
        measured with an exponential window of decay rate β are (pass the measured FRF's
        ``window_beta_per_s``); the result carries β.

        See :func:`updating.fe.solvers.frf_direct` and :func:`~updating.fe.solvers.frf_modal`.
        """
        if window_beta_per_s is not None:
            if beta and beta != window_beta_per_s:
                raise ModalabValueError(f"beta={beta!r} and window_beta_per_s={window_beta_per_s!r} differ; give "
                                        "one (window_beta_per_s, the FRF's field)")
            beta = window_beta_per_s
        system = self.system()
        if method == "direct":
            if self.modal_damping is not None:
                log.warning("model %r has a modal damping table, which direct FRFs cannot use; use "
                            "method='modal' to apply it", self.name)
            return frf_direct(system, freq_hz, responses, references, quantity=quantity, beta=beta)
        if method == "modal":
            return frf_modal(system, freq_hz, responses, references, n_modes=n_modes, residual=residual,
                             modal_damping=self.modal_damping, quantity=quantity, window_beta_per_s=beta)
        raise ModalabValueError(f"method {method!r}; expected 'direct' or 'modal'")

