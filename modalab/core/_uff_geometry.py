"""UFF geometry: node coordinates (2411, 15), coordinate frames (2420) and node rotations.

Part of :mod:`modalab.core.uff`.
"""
from __future__ import annotations

import logging

import numpy as np

from ._uff_common import _blocks, _guard, _open_out
from ._uff_core import Block, e13, parse_floats, parse_ints, tokens_exact
from .errors import UffError

log = logging.getLogger("modalab.core.uff")


# ----------------------------------------------------------------------------- geometry
def write_geometry(path, coords, *, append: bool = False, dataset: int = 2411) -> None:
    """Write node coordinates (m) as dataset 2411 (double precision, default) or 15 (single precision).

    ``coords`` maps node id to ``(x, y, z)``.
    """
    if dataset not in (2411, 15):
        raise UffError(f"dataset {dataset} is not a node dataset; use 2411 (exact) or 15")
    try:
        items = [(int(k), np.asarray(v, dtype=float).reshape(3)) for k, v in dict(coords).items()]
    except (TypeError, ValueError):
        raise UffError("coords must map node ids to (x, y, z) triples", path=path) from None
    for k, v in items:
        if k < 1 or k > 2 ** 31 - 1:
            raise UffError(f"node id {k} must be a positive integer below 2**31", path=path)
    lines = ["    -1", "%6i%74s" % (dataset, "")]
    if dataset == 2411:
        for k, v in items:
            lines.append("%10i%10i%10i%10i" % (k, 1, 1, 11))
            lines.append("%25.16E%25.16E%25.16E" % tuple(v))
    else:
        for k, v in items:
            lines.append("%10i%10i%10i%10i%s%s%s" % (k, 0, 0, 11, e13(v[0]), e13(v[1]), e13(v[2])))
    lines.append("    -1\n")
    with _open_out(path, append) as fh:
        fh.write("\n".join(lines).encode("latin-1"))


def _parse_nodes(b: Block, cs: dict | None = None) -> dict[int, tuple]:
    """``{node: (x, y, z)}`` as stored; ``cs`` (when given) receives ``{node: (definition CS, displacement CS)}``."""
    out = {}
    if cs is None:
        cs = {}
    body = [ln for ln in b.lines if ln.strip()]
    if b.number == 2411:
        if len(body) % 2:
            raise b.error(f"dataset 2411 has {len(body)} lines; node records come in pairs (ids, coordinates): "
                          "the dataset is truncated", len(b.lines) - 1)
        for k in range(0, len(body), 2):
            ints = parse_ints(body[k], 4, "node record 1", b, k, minimum=1)
            vals = parse_floats(body[k + 1])
            if vals.size != 3 or tokens_exact(body[k + 1]) is None:
                raise b.error(f"node {ints[0]}: expected three coordinates, found {body[k + 1].strip()!r}", k + 1)
            if ints[0] in out:
                raise b.error(f"node {ints[0]} is listed twice in one dataset", k)
            out[ints[0]] = tuple(float(v) for v in vals)
            cs[ints[0]] = (ints[1] if len(ints) > 1 else 0, ints[2] if len(ints) > 2 else 0)
    else:
        for k, ln in enumerate(body):
            toks = tokens_exact(ln)
            if toks is None or len(toks) != 7:
                raise b.error(f"dataset 15 node line {ln.strip()!r} must hold node id, 3 integers and "
                              "3 coordinates", k)
            node = float(toks[0])
            if node != int(node):
                raise b.error(f"node id {toks[0]!r} is not an integer", k)
            if int(node) in out:
                raise b.error(f"node {int(node)} is listed twice in one dataset", k)
            out[int(node)] = tuple(float(t) for t in toks[4:7])
            cs[int(node)] = (int(float(toks[1])), int(float(toks[2])))
    for node, xyz in out.items():
        if node < 0 or not np.all(np.isfinite(xyz)):
            raise b.error(f"node {node} has an invalid id or non-finite coordinates {xyz}")
    return out


def _parse_2420(b: Block) -> dict[int, dict]:
    """Coordinate systems of dataset 2420: ``{label: {'type', 'name', 'rotation', 'origin', 'identity'}}``.

    The transformation matrix's rows 1-3 are the local X, Y, Z axes in global coordinates and row 4 the
    origin (I-DEAS row-vector convention: ``x_global = x_local @ T[:3] + T[3]``, directions
    ``v_global = T[:3].T @ v_local``; the convention of SDynPy's ``global_deflection`` too).
    """
    lines = b.lines
    if len(lines) < 2:
        raise b.error("dataset 2420 needs a part UID and a part name line", len(lines))
    out = {}
    k = 2
    while k < len(lines):
        if not lines[k].strip():
            k += 1
            continue
        if k + 6 > len(lines):
            raise b.error(f"coordinate system record at line {b.line + 1 + k} has {len(lines) - k} of its 6 lines: "
                          "the dataset is truncated", k)
        label, typ = parse_ints(lines[k], 3, "coordinate system label/type/colour", b, k, minimum=2)[:2]
        rows = []
        for j in range(4):
            toks = tokens_exact(lines[k + 2 + j])
            if toks is None or len(toks) != 3:
                raise b.error(f"transformation matrix row {j + 1} of coordinate system {label} must hold 3 numbers, "
                              f"found {lines[k + 2 + j].strip()!r}", k + 2 + j)
            rows.append([float(t) for t in toks])
        T = np.array(rows)
        if not np.all(np.isfinite(T)):
            raise b.error(f"coordinate system {label} has non-finite numbers", k + 2)
        R = T[:3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-5):
            raise b.error(f"coordinate system {label}: rows 1-3 of the transformation matrix are not orthonormal "
                          "axes", k + 2)
        out[label] = {"type": typ, "name": lines[k + 1].strip(), "rotation": R, "origin": T[3],
                      "identity": bool(np.allclose(R, np.eye(3), atol=1e-12))}
        k += 6
    return out


def _frames(blocks, path, cur=None) -> dict[int, dict]:
    """Coordinate systems of all datasets 2420 of a file (label -> :func:`_parse_2420` entry)."""
    out: dict = {}
    for b in blocks:
        if b.number == 2420:
            if cur is not None:
                cur.block = b
            out.update(_parse_2420(b))
    if cur is not None:
        cur.block = None
    return out


def read_frames(path) -> dict[int, dict]:
    """Coordinate systems (dataset 2420) of a file: ``{label: {'type', 'name', 'rotation', 'origin', 'identity'}}``
    with ``rotation`` rows = local axes in global coordinates; ``{}`` when the file defines none."""
    with _guard(path) as cur:
        return _frames(_blocks(path, cur), path, cur)


def _node_rotations(blocks, path, cur=None) -> dict[int, np.ndarray]:
    """``{node: R}`` for the nodes whose displacement coordinate system (dataset 2411/15 record 1 field 3)
    is a rotated frame of dataset 2420: ``v_global = R.T @ v_local``.  Frames 0 and 1 without a 2420
    definition are the global frame; an undefined other frame is assumed global with a warning; a
    cylindrical or spherical displacement frame is refused."""
    frames = _frames(blocks, path, cur)
    out: dict = {}
    undefined: dict = {}
    for b in blocks:
        if b.number not in (2411, 15):
            continue
        if cur is not None:
            cur.block = b
        cs: dict = {}
        _parse_nodes(b, cs)
        for nd, (_, disp) in cs.items():
            fr = frames.get(disp)
            if fr is None:
                if disp not in (0, 1):
                    undefined.setdefault(disp, []).append(nd)
                continue
            if fr["type"] != 0 and not fr["identity"]:
                raise UffError(f"node {nd} uses displacement coordinate system {disp} ({fr['name'] or 'unnamed'}), "
                               f"which is {'cylindrical' if fr['type'] == 1 else 'spherical'}: modalab applies "
                               "Cartesian frames only. Export the data in the global frame",
                               path=path, dataset=b.number, line=b.line)
            if not fr["identity"]:
                out[nd] = fr["rotation"]
    if cur is not None:
        cur.block = None
    for disp, nodes in undefined.items():
        log.warning("%s: nodes %s use displacement coordinate system %d, which the file does not define "
                    "(dataset 2420); their directions are taken as global", path, nodes[:10], disp)
    return out


def read_geometry(path, *, required: bool = True) -> dict[int, tuple[float, float, float]]:
    """Node coordinates from datasets 2411 and 15: ``{node: (x, y, z)}``.

    A file without a node dataset is an error, or ``{}`` with ``required=False``; a damaged node dataset is
    always an error."""
    with _guard(path) as cur:
        out = _global_nodes(_blocks(path, cur), path, cur)
        if out is None:
            if not required:
                return {}
            raise UffError("no node coordinates (dataset 2411 or 15) in the file", path=path)
        return out


def _global_nodes(blocks, path, cur) -> dict | None:
    """Node coordinates of datasets 2411/15 in the global frame (dataset 2420 frames applied); None when the
    file has no node dataset."""
    out: dict = {}
    found = False
    frames = _frames(blocks, path, cur)
    for b in blocks:
        if b.number in (2411, 15):
            cur.block = b
            found = True
            cs: dict = {}
            nodes = _parse_nodes(b, cs)
            for nd, (def_cs, _) in cs.items():
                fr = frames.get(def_cs)
                if fr is not None and not fr["identity"]:
                    xyz = fr["rotation"].T @ np.asarray(nodes[nd]) + fr["origin"]
                    nodes[nd] = tuple(float(v) for v in xyz)
            clash = [n for n in nodes if n in out and out[n] != nodes[n]]
            if clash:
                raise UffError(f"nodes {clash[:10]} are defined again with different coordinates; keep one "
                               "definition per node", path=path, dataset=b.number, line=b.line)
            out.update(nodes)
    cur.block = None
    return out if found else None
