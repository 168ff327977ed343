"""Map measured (test) DOF labels onto model DOFs.

Correlation (thesis section 2.2) and expansion (section 2.1.2) compare a test
mode shape measured at ``n`` sensor DOFs with an analytical shape on the ``N``
model DOFs.  Both are related by a linear observation matrix ``C`` (n × N),

    x_test = C x_model,

which :class:`DofMap` builds from labels.  A row of ``C`` is

* a signed selection when the test DOF sits on a model DOF (same node number,
  or a node or DOF given in the map; ``"101+Z" -> "12-Z"`` flips the sign);
* a linear combination of the translational (or rotational) model DOFs of one
  node when the sensor axis is oblique: either given explicitly
  (``{"14+X": 0.7071, "14+Y": 0.7071}``) or as a direction vector, or because
  the test node or the model node has its own coordinate system.

Coordinate systems are rotation matrices ``R`` with ``v_global = R @ v_local``
(the columns of ``R`` are the local axes written in global components).  A
sensor along local axis ``a`` of test node ``t`` (sign ``s``) reads the global
direction ``g = s R_t[:, a]``; a model node ``n`` whose displacement system
is ``R_n`` (Nastran's CD) carries ``u_global = R_n u_local``, so the sensor
reads ``gᵀ R_n u_local``: the row of ``C`` is ``R_nᵀ g`` over the node's X, Y, Z
(or RX, RY, RZ) DOFs.

Files (:meth:`DofMap.from_file`)
--------------------------------
TOML::

    same_nodes = true           # unmapped test DOFs use the same node number (default)
    [nodes]                     # test node -> model node, all directions
    "101" = 12
    [dofs]                      # test DOF -> model DOF, with signs
    "102+Z" = "13-Z"
    "103+X" = { "14+X" = 0.7071, "14+Y" = 0.7071 }         # linear combination
    "104+Z" = { node = 15, direction = [0.0, 0.6, 0.8] }   # oblique sensor, global direction
    [test_frames]               # rotation matrices of test nodes (v_global = R @ v_local)
    "105" = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    [model_frames]              # displacement coordinate systems of model nodes
    "16" = [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]

CSV, one row per term (repeat a test DOF for a linear combination; factor 1
when omitted; ``#`` starts a comment; an optional header row is skipped)::

    test_dof,model_dof,factor
    101+Z,12+Z
    102+Z,13-Z
    103+X,14+X,0.7071
    103+X,14+Y,0.7071
"""
from __future__ import annotations

import csv
import difflib
import itertools
import logging
import tomllib
from pathlib import Path
from typing import Mapping

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from modalab.core.dof import Dof, parse_dofs
from modalab.core.errors import DofError, ModalabValueError, ShapeError
from modalab.core.modes import ModeSet

__all__ = ["DofMap", "as_dofmap", "observation_matrix", "geometry_map"]

log = logging.getLogger(__name__)

_ZERO = 1e-12


def _rotation(value, what: str) -> np.ndarray:
    try:
        R = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ModalabValueError(f"{what}: got {value!r}; expected a 3x3 rotation matrix of numbers. "
                                "Give it as [[r11, r12, r13], [r21, r22, r23], [r31, r32, r33]]") from None
    if R.shape != (3, 3):
        raise ShapeError(f"{what}: got an array of shape {R.shape}; expected a 3x3 rotation matrix. "
                         "Give three rows of three numbers")
    err = np.abs(R.T @ R - np.eye(3)).max()
    if not np.isfinite(err) or err > 1e-6:
        raise ModalabValueError(f"{what}: the matrix is not orthonormal (max |RᵀR - I| = {err:.3g}); expected a "
                                "rotation matrix whose columns are the local axes in global components. "
                                "Normalise the axes or check the matrix")
    return R


def _parse_term_dict(test: Dof, spec: Mapping) -> tuple:
    if "node" in spec or "direction" in spec:
        if set(spec) - {"node", "direction", "rotation"} or "node" not in spec or "direction" not in spec:
            raise ModalabValueError(
                f"DOF map entry for {test}: got keys {sorted(spec)}; expected 'node' and 'direction' "
                "(and optionally 'rotation = true'). Write e.g. {{ node = 15, direction = [0, 0.6, 0.8] }}")
        try:
            v = np.asarray(spec["direction"], dtype=float).reshape(-1)
        except (TypeError, ValueError):
            v = np.zeros(0)
        nv = np.linalg.norm(v) if v.size == 3 else 0.0
        if v.size != 3 or not np.isfinite(nv) or nv == 0:
            raise ModalabValueError(f"DOF map entry for {test}: direction {spec['direction']!r}; expected a "
                                    "non-zero 3-vector in global components such as [0, 0.6, 0.8]")
        try:
            node = int(spec["node"])
        except (TypeError, ValueError):
            raise ModalabValueError(f"DOF map entry for {test}: node {spec['node']!r} is not an integer node id") \
                from None
        return ("vector", node, v / nv, bool(spec.get("rotation", False)))
    terms = []
    for k, c in spec.items():
        try:
            coef = float(c)
        except (TypeError, ValueError):
            raise ModalabValueError(f"DOF map entry for {test}: coefficient {c!r} of {k!r} is not a number; "
                                    "write e.g. {{ \"14+X\" = 0.7071 }}") from None
        d = Dof.parse(k)
        terms.append((d.positive, coef * d.sign))
    if not terms:
        raise ModalabValueError(f"DOF map entry for {test} is empty; give a model DOF such as '12+Z'")
    return ("terms", tuple(terms))


def _entry(k, spec) -> tuple:
    """``(test DOF, entry)`` of one ``[dofs]`` item, the entry relative to the positive test direction."""
    t = Dof.parse(k)
    if t.axis == 0:
        raise DofError(f"test DOF {k!r} has no direction; expected a label such as '101+Z'")
    if isinstance(spec, (str, Dof, tuple)):
        m = Dof.parse(spec)
        entry = ("terms", ((m.positive, float(m.sign)),))
    elif isinstance(spec, Mapping):
        entry = _parse_term_dict(t, spec)
    else:
        raise ModalabValueError(f"DOF map entry for {t}: got {spec!r}; expected a model DOF label, a dict "
                                "of model DOF coefficients or {'node': n, 'direction': [x, y, z]}")
    return t, (_negate(entry) if t.sign < 0 else entry)


class DofMap:
    """Mapping of test DOF labels to (combinations of) model DOFs.

    Parameters (keyword-only)
    ----------
    dofs : {test label: spec}; spec is a model label (``"12-Z"``), a dict
        ``{model label: coefficient}`` or ``{"node": n, "direction": [x, y, z]}``
        (a sensor along a global direction at model node ``n``; add
        ``"rotation": True`` for a rotational sensor).
    nodes : {test node: model node} used for every direction of that node.
    same_nodes : when True (default), a test DOF that is in neither ``dofs`` nor
        ``nodes`` maps onto the model node with the same number.
    test_frames, model_frames : {node: 3x3 rotation matrix}, ``v_global = R @ v_local``.
    """

    def __init__(self, *, dofs: Mapping | None = None, nodes: Mapping | None = None, same_nodes: bool = True,
                 test_frames: Mapping | None = None, model_frames: Mapping | None = None, name: str = ""):
        self._entries: dict[tuple[int, int], tuple] = {}
        for k, spec in (dofs or {}).items():
            try:
                t, entry = _entry(k, spec)
            except (DofError, ModalabValueError) as e:
                # the key the message is about (a file's reader adds the file)
                raise type(e)(f"[dofs] {str(k)!r}: {e}") from None
            key = (t.node, t.axis)
            if key in self._entries:
                raise ModalabValueError(f"test DOF {t} appears twice in the DOF map; keep one entry per DOF "
                                        "(use a dict of coefficients for a linear combination)")
            self._entries[key] = entry
        self.nodes = {int(a): int(b) for a, b in (nodes or {}).items()}
        self.same_nodes = bool(same_nodes)
        self.test_frames = {int(n): _rotation(R, f"coordinate system of test node {n}")
                            for n, R in (test_frames or {}).items()}
        self.model_frames = {int(n): _rotation(R, f"coordinate system of model node {n}")
                             for n, R in (model_frames or {}).items()}
        self.name = name

    def __repr__(self) -> str:
        return (f"DofMap({self.name or 'unnamed'}: {len(self._entries)} DOF entries, {len(self.nodes)} node entries, "
                f"same_nodes={self.same_nodes}, {len(self.test_frames)}+{len(self.model_frames)} frames)")

    # ------------------------------------------------------------ construction
    @classmethod
    def from_dict(cls, data: Mapping) -> "DofMap":
        """Build from the dict layout of the TOML file (keys ``dofs``, ``nodes``, ``same_nodes``, frames)."""
        known = {"dofs", "nodes", "same_nodes", "test_frames", "model_frames", "name"}
        extra = sorted(set(data) - known)
        if extra:
            close = difflib.get_close_matches(extra[0], sorted(known), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ModalabValueError(f"unknown key {extra[0]!r}{hint} (expected some of {sorted(known)})")
        return cls(dofs=data.get("dofs"), nodes=data.get("nodes"), same_nodes=data.get("same_nodes", True),
                   test_frames=data.get("test_frames"), model_frames=data.get("model_frames"),
                   name=data.get("name", ""))

    @classmethod
    def from_file(cls, path) -> "DofMap":
        """Read a TOML (``.toml``) or CSV (any other suffix) DOF map; see the module docstring for the layouts."""
        p = Path(path)
        if not p.is_file():
            raise ModalabValueError(f"DOF map file {str(p)!r} does not exist; give the path of a .toml or .csv map")
        if p.suffix.lower() == ".toml":
            try:
                with open(p, "rb") as fh:
                    data = tomllib.load(fh)
            except tomllib.TOMLDecodeError as e:
                raise ModalabValueError(f"DOF map file {str(p)!r} is not valid TOML ({e}); fix the syntax") from None
            try:
                out = cls.from_dict(data)
            except (DofError, ModalabValueError) as e:
                raise type(e)(f"DOF map {str(p)!r}: {e}") from None
        else:
            out = cls._from_csv(p)
        out.name = out.name or p.name
        return out

    @classmethod
    def _from_csv(cls, p: Path) -> "DofMap":
        rows: dict[str, dict[str, float]] = {}
        with open(p, newline="") as fh:
            for lineno, row in enumerate(csv.reader(fh), start=1):
                cells = [c.strip() for c in row]
                if not cells or not cells[0] or cells[0].startswith("#"):
                    continue
                if lineno == 1 and cells[0].lower().replace(" ", "_") in ("test_dof", "test", "test_dofs"):
                    continue
                if len(cells) < 2 or len(cells) > 3 or not cells[1]:
                    arrow = "->" in ",".join(cells)
                    fix = f"; write '{cells[0].replace('->', ',').replace(' ', '')}'" if arrow else ""
                    raise ModalabValueError(f"DOF map {str(p)!r} line {lineno}: got {row!r}; expected "
                                            f"'test_dof,model_dof[,factor]' such as '101+Z,12-Z'{fix}")
                try:
                    t, m = Dof.parse(cells[0]), Dof.parse(cells[1])
                except DofError as e:
                    raise DofError(f"DOF map {str(p)!r} line {lineno}: {e}") from None
                try:
                    f = float(cells[2]) if len(cells) == 3 and cells[2] else 1.0
                except ValueError:
                    raise ModalabValueError(f"DOF map {str(p)!r} line {lineno}: factor {cells[2]!r} is not a "
                                            "number") from None
                terms = rows.setdefault(str(t), {})
                key = str(m.positive)
                terms[key] = terms.get(key, 0.0) + f * m.sign
        return cls(dofs=rows)

    # ------------------------------------------------------------------ lookup
    def terms(self, test_dof) -> list[tuple[Dof, float]]:
        """Model DOFs (positive directions) and coefficients that one test DOF reads."""
        t = Dof.parse(test_dof)
        if t.axis == 0:
            raise DofError(f"test DOF {t} has no direction; expected a label such as '101+Z'")
        entry = self._entries.get((t.node, t.axis))
        if entry is None:
            if t.node in self.nodes:
                model_node = self.nodes[t.node]
            elif self.same_nodes:
                model_node = t.node
            else:
                raise DofError(f"test DOF {t} is not in the DOF map and same_nodes is off; add it under [dofs] "
                               f"(e.g. \"{t.positive}\" = \"12+Z\") or its node under [nodes]")
            rot = t.axis > 3
            local = np.zeros(3)
            local[(t.axis - 1) % 3] = 1.0
            R_t = self.test_frames.get(t.node, np.eye(3))
            entry = ("vector", model_node, R_t @ local, rot)
        kind = entry[0]
        if kind == "terms":
            out = list(entry[1])
        else:
            _, node, g, rot = entry
            c = self.model_frames.get(node, np.eye(3)).T @ g
            base = 4 if rot else 1
            out = [(Dof(node, base + k), float(c[k])) for k in range(3) if abs(c[k]) > _ZERO]
        return [(d, c * t.sign) for d, c in out]

    def matrix(self, test_dofs, model_dofs) -> sp.csr_matrix:
        """Observation matrix ``C`` (n_test × n_model) with ``x_test = C x_model``.

        Raises :class:`~modalab.core.errors.DofError` naming every test DOF whose model DOFs are missing.
        """
        tl = parse_dofs(test_dofs)
        ml = parse_dofs(model_dofs)
        table = {}
        for j, d in enumerate(ml):
            table.setdefault((d.node, d.axis), (j, d.sign))
        rows, cols, vals, missing = [], [], [], []
        for i, t in enumerate(tl):
            terms = self.terms(t)
            absent = [d for d, _ in terms if (d.node, d.axis) not in table]
            if absent:
                missing.append(f"{t} -> {', '.join(str(d) for d in absent)}")
                continue
            for d, c in terms:
                j, s = table[(d.node, d.axis)]
                rows.append(i)
                cols.append(j)
                vals.append(c * s)
        if missing:
            avail = ", ".join(str(d) for d in ml[:10]) + (" ..." if len(ml) > 10 else "")
            raise DofError(f"{len(missing)} test DOF(s) have no model counterpart: {'; '.join(missing[:10])}"
                           f"{' ...' if len(missing) > 10 else ''}. The model has {len(ml)} DOFs ({avail}). "
                           "Add the test DOFs to the DOF map (--map) or remove them from the test data"
                           + (f" (DOF map {self.name})" if self.name else ""))
        C = sp.csr_matrix((vals, (rows, cols)), shape=(len(tl), len(ml)))
        C.sum_duplicates()
        C.eliminate_zeros()
        return C

    def selection(self, test_dofs, model_dofs) -> tuple[np.ndarray, np.ndarray]:
        """Model row index and factor of each test DOF when each reads exactly one model DOF.

        Raises :class:`~modalab.core.errors.ModalabValueError` for oblique test DOFs (a combination of model DOFs).
        """
        C = self.matrix(test_dofs, model_dofs).tocsr()
        tl = parse_dofs(test_dofs)
        idx, fac = np.empty(len(tl), int), np.empty(len(tl))
        for i in range(len(tl)):
            a, b = C.indptr[i], C.indptr[i + 1]
            nz = [k for k in range(a, b) if abs(C.data[k]) > _ZERO]
            if len(nz) != 1:
                raise ModalabValueError(
                    f"test DOF {tl[i]} reads {len(nz)} model DOFs (an oblique sensor); this method needs each test "
                    "DOF on a single model DOF. Use SEREP or analytical-mode expansion, which accept oblique "
                    "sensors, or map the DOF onto one model DOF")
            idx[i], fac[i] = C.indices[nz[0]], C.data[nz[0]]
        return idx, fac

    def model_labels(self, test_dofs, model_dofs) -> tuple[list[Dof], np.ndarray]:
        """Signed model labels read by selection-type test DOFs and the remaining scale factors.

        ``x_test[i] = scale[i] * x_model[label[i]]`` where a label of negative sign
        negates; ``scale`` is 1 for plain (signed) selections.
        """
        ml = parse_dofs(model_dofs)
        idx, fac = self.selection(test_dofs, ml)
        c = fac * np.array([ml[i].sign for i in idx], float)       # coefficient on the positive model axis
        labels = [Dof(ml[i].node, ml[i].axis * (1 if ci > 0 else -1)) for i, ci in zip(idx, c)]
        return labels, np.abs(c)

    def apply(self, modes: ModeSet, test_dofs) -> ModeSet:
        """Model modes observed at the test DOFs: ``shapes = C @ modes.shapes`` on the test labels."""
        tl = parse_dofs(test_dofs)
        C = self.matrix(tl, modes.dofs)
        out = modes.copy()
        out.shapes = np.asarray(C @ modes.shapes)
        out.dofs = tl
        if out.scaling == "unit_max":
            out.scaling = "arbitrary"
        return out


def _negate(entry: tuple) -> tuple:
    if entry[0] == "terms":
        return ("terms", tuple((d, -c) for d, c in entry[1]))
    _, node, g, rot = entry
    return ("vector", node, -g, rot)


def as_dofmap(value) -> DofMap:
    """Accept None (same node numbers), a :class:`DofMap`, a dict (TOML layout) or a file path."""
    if value is None:
        return DofMap()
    if isinstance(value, DofMap):
        return value
    if isinstance(value, Mapping):
        return DofMap.from_dict(value)
    if isinstance(value, (str, Path)):
        return DofMap.from_file(value)
    raise ModalabValueError(f"DOF map: got {type(value).__name__}; expected None, a DofMap, a dict or the path "
                            "of a .toml/.csv file")


def observation_matrix(test_dofs, model_dofs, dofmap=None) -> sp.csr_matrix:
    """``C`` with ``x_test = C x_model`` for the given labels (see :meth:`DofMap.matrix`)."""
    return as_dofmap(dofmap).matrix(test_dofs, model_dofs)


def _kabsch(P, Q):
    """Rotation R and translation t minimising Σ‖R p + t − q‖² (proper rotation)."""
    cp, cq = P.mean(axis=0), Q.mean(axis=0)
    H = (P - cp).T @ (Q - cq)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return R, cq - R @ cp


def _axis_rotations() -> list:
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            R = np.zeros((3, 3))
            for i, (j, sg) in enumerate(zip(perm, signs)):
                R[i, j] = sg
            if np.linalg.det(R) > 0:
                out.append(R)
    return out


def geometry_map(test_coords: Mapping, model_coords: Mapping, test_nodes=None, *, tol: float | None = None,
                 max_iter: int = 50) -> tuple[DofMap, dict]:
    """Map test nodes onto model nodes by geometry: nearest model node after a best-fit rigid transform.

    ``test_coords``/``model_coords`` are ``{node: (x, y, z)}`` in m (test geometry from UFF
    dataset 2411, model grids from the bulk data).  The test geometry is first compared as it
    is (same frame); if some node is farther than ``tol`` from every model node, a rigid
    transform is fitted by iterated closest points (Kabsch, deterministic, started from the
    identity and from the centroid alignment) and used when it brings every node within
    ``tol``; the sensor directions are then rotated with it (``test_frames``).  ``tol``
    defaults to 2 % of the model's largest extent.

    Returns the :class:`DofMap` (``same_nodes=False``: every test node is mapped) and a report
    ``{"rotation", "translation", "tol_m", "max_distance_m", "rms_distance_m", "nodes":
    {test node: {"model_node", "distance_m"}}}``.  Raises :class:`~modalab.core.errors.DofError`
    naming the nodes that have no model node within ``tol``, or two test nodes that land on the
    same model node.
    """
    nodes, P, mids, Q = _checked_coordinates(test_coords, model_coords, test_nodes)
    ext = float(np.ptp(Q, axis=0).max()) if len(Q) > 1 else 1.0
    tol = 0.02 * max(ext, 1e-12) if tol is None else float(tol)
    R, t, d, j = _rigid_placement(nodes, P, Q, tol, ext, max_iter)
    mapped = [mids[k] for k in j]
    dup = {}
    for n, m in zip(nodes, mapped):
        dup.setdefault(m, []).append(n)
    clash = {m: ns for m, ns in dup.items() if len(ns) > 1}
    if clash:
        m, ns = sorted(clash.items())[0]
        raise DofError(f"test nodes {ns} all map onto model node {m} by geometry; the test mesh is finer than the "
                       "model or the geometry is off: give a DOF map (--map)")
    rotated = not np.allclose(R, np.eye(3), atol=1e-9)
    dm = DofMap(nodes=dict(zip(nodes, mapped)), same_nodes=False,
                test_frames={n: R for n in nodes} if rotated else None, name="geometry")
    report = {"rotation": R.tolist(), "translation": t.tolist(), "tol_m": tol,
              "max_distance_m": float(d.max()), "rms_distance_m": float(np.sqrt(np.mean(d ** 2))),
              "nodes": {str(n): {"model_node": int(m), "distance_m": float(dd)} for n, m, dd in zip(nodes, mapped, d)}}
    return dm, report


def _checked_coordinates(test_coords, model_coords, test_nodes):
    """The test nodes (sorted) and their coordinates ``P``, the model nodes (sorted) and theirs ``Q``; a
    :class:`~modalab.core.errors.DofError` for a node without coordinates, none at all, or NaN/inf."""
    nodes = sorted(int(n) for n in (test_coords if test_nodes is None else test_nodes))
    missing = [n for n in nodes if n not in {int(k) for k in test_coords}]
    if missing:
        raise DofError(f"test node(s) {missing[:10]} have no coordinates; give the test geometry (UFF dataset 2411) "
                       "for every measured node, or a DOF map (--map)")
    if not nodes:
        raise DofError("no test nodes to map by geometry")
    tc = {int(k): v for k, v in test_coords.items()}
    P = np.array([tc[n] for n in nodes], float)
    mids = sorted(int(k) for k in model_coords)
    if not mids:
        raise DofError("the model has no node coordinates to map the test nodes onto")
    Q = np.array([model_coords[m] for m in mids], float)
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(Q))):
        raise DofError("node coordinates contain NaN or inf")
    return nodes, P, mids, Q


def _rigid_placement(nodes, P, Q, tol, ext, max_iter):
    """``(R, t, d, j)``: the rotation and translation placing the test nodes ``P`` on the model nodes ``Q``, the
    distances and the nearest model node of each.  The identity when every node is within ``tol``; else
    iterated closest points (Kabsch) from the 24 axis-aligned rotations and the identity, the one rigid
    placement that fits (an error when none fits, or several that map differently)."""
    tree = cKDTree(Q)

    def fit(R, t):
        for _ in range(max_iter):
            d, j = tree.query(P @ R.T + t)
            if len(nodes) < 3:
                return R, t, d, j
            R2, t2 = _kabsch(P, Q[j])
            if np.allclose(R2, R, atol=1e-12) and np.allclose(t2, t, atol=1e-12 * max(ext, 1)):
                break
            R, t = R2, t2
        d, j = tree.query(P @ R.T + t)
        return R, t, d, j

    I3 = np.eye(3)
    d0, j0 = tree.query(P)
    candidates = [(I3, np.zeros(3), d0, j0)]
    if d0.max() > tol:
        # iterated closest points from the 24 axis-aligned proper rotations, centroids aligned (deterministic)
        for R0 in _axis_rotations():
            candidates.append(fit(R0, Q.mean(axis=0) - R0 @ P.mean(axis=0)))
        candidates.append(fit(I3, np.zeros(3)))
    # the simplest candidate that fits: identity first, then the rigid fits by RMS distance
    ok = [c for c in candidates if c[2].max() <= tol]
    if not ok:
        best = min(candidates, key=lambda c: float(np.sqrt(np.mean(c[2] ** 2))))
        far = [(n, float(dd)) for n, dd in zip(nodes, best[2]) if dd > tol]
        far.sort(key=lambda t: -t[1])
        raise DofError(f"{len(far)} test node(s) have no model node within {tol:.3g} m even after a best-fit rigid "
                       f"transform (worst: {', '.join(f'{n} at {dd:.3g} m' for n, dd in far[:5])}); the test geometry "
                       "does not match the model: give a DOF map (--map) or check units and frames")
    if ok[0] is candidates[0]:
        R, t, d, j = ok[0]                      # the test geometry is already in the model's frame
    else:
        maps = {}
        for c in ok:
            maps.setdefault(tuple(int(k) for k in c[3]), c)
        if len(maps) > 1:
            raise DofError(f"the test geometry fits the model in {len(maps)} different ways after a rigid transform "
                           "(a symmetric structure or sensor layout): the mapping is ambiguous; give a DOF map (--map) "
                           "or the test geometry in the model's frame")
        R, t, d, j = next(iter(maps.values()))
    return R, t, d, j
