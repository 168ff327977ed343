"""UFF mode shapes: dataset 55, real (analysis type 2) and complex (3).

Part of :mod:`modalab.core.uff`.
"""
from __future__ import annotations

import logging

import numpy as np

from ._uff_common import _blocks, _guard, _open_out
from ._uff_core import (Block, check_groups, date_line, e13, id_line, parse_floats, parse_ints, parse_tags,
                        tokens_exact)
from ._uff_frf import held_functions, held_text
from ._uff_geometry import _global_nodes, _node_rotations, write_geometry
from .dof import Dof
from .errors import UffError
from .modes import ModeSet

log = logging.getLogger("modalab.core.uff")


# ----------------------------------------------------------------------------- modes
def write_modes(path, modes: ModeSet, *, append: bool = False, exact: bool = True) -> None:
    """Write mode shapes as dataset 55, one set per mode (real: analysis type 2, complex: 3).

    ``exact=True`` writes 17 significant digits in 25-character fields (read back
    bit for bit by :func:`read_modes`); ``exact=False`` writes the standard 6E13.5.
    """
    if not isinstance(modes, ModeSet):
        raise UffError(f"write_modes needs a ModeSet; got {type(modes).__name__}")
    phi = np.asarray(modes.shapes)
    cplx = np.iscomplexobj(phi)
    axes = {d.axis for d in modes.dofs} or {1, 2, 3}           # a frequency-only set: no node records
    if 0 in axes and len(axes) > 1:
        raise UffError("the mode set mixes scalar DOFs with directional ones; write them as two files",
                       path=path)
    # a frequency-only set (no DOFs) is written as modes with no node records
    ndv = 3 if not axes else 1 if axes == {0} else (6 if max(axes) > 3 else 3)
    data_ch = {1: 1, 3: 2, 6: 3}[ndv]
    nodes: dict[int, int] = {}
    for d in modes.dofs:
        nodes.setdefault(d.node, len(nodes))
    table = np.zeros((len(nodes), ndv, modes.n_modes), complex if cplx else float)
    filled = np.zeros((len(nodes), ndv), bool)
    for r, d in enumerate(modes.dofs):
        i, c = nodes[d.node], max(d.axis, 1) - 1
        if filled[i, c]:
            raise UffError(f"DOF {d} appears twice in the mode set", path=path)
        filled[i, c] = True
        table[i, c] = d.sign * phi[r]
    fnum = (lambda v: "%25.16E" % v) if exact else e13
    node_ids = list(nodes)
    mm = None
    if modes.scaling == "unit_modal_mass":
        mm = np.ones(modes.n_modes)
    elif "modal_mass" in modes.indicators and np.size(modes.indicators["modal_mass"]) == modes.n_modes:
        mm = np.asarray(modes.indicators["modal_mass"], dtype=float).reshape(-1)
    date = date_line(modes.n_modes, "m")
    chunks = []
    for k in range(modes.n_modes):
        f, z = float(modes.freq_hz[k]), float(modes.damping[k])
        ids = [f"Mode {k + 1}", f"modalab f={f!r} z={z!r}", date, f"modalab scaling={modes.scaling}", "NONE"]
        lines = ["    -1", "%6i%74s" % (55, "")] + ["%-80s" % id_line(s) for s in ids]
        lines.append("%10i%10i%10i%10i%10i%10i" % (1, 3 if cplx else 2, data_ch, 8, 5 if cplx else 2, ndv))
        if cplx:
            lam = modes.poles[k]
            lines.append("%10i%10i%10i%10i" % (2, 6, 1, k + 1))
            lines.append("".join(fnum(v) for v in (lam.real, lam.imag, 0.0, 0.0, 0.0, 0.0)))
        else:
            lines.append("%10i%10i%10i%10i" % (2, 4, 1, k + 1))
            lines.append("".join(fnum(v) for v in (f, 0.0 if mm is None else mm[k], z, 0.0)))
        for i, node in enumerate(node_ids):
            lines.append("%10i" % node)
            v = table[i, :, k]
            vals = np.column_stack([v.real, v.imag]).reshape(-1) if cplx else v
            per = 6
            for a in range(0, vals.size, per):
                lines.append("".join(fnum(x) for x in vals[a:a + per]))
        lines.append("    -1\n")
        chunks.append("\n".join(lines))
    with _open_out(path, append) as fh:
        fh.write("".join(chunks).encode("latin-1"))
    if getattr(modes, "coordinates", None):
        write_geometry(path, modes.coordinates, append=True)


def _parse_55(b: Block):
    if len(b.lines) < 8:
        raise b.error(f"dataset 55 needs 8 header records; found {len(b.lines)}: the dataset is truncated",
                      len(b.lines))
    ids = [b.lines[k].rstrip() for k in range(5)]
    model, analysis, data_ch, spec, dtype, ndv = parse_ints(b.lines[5], 6, "record 6 (data definition)", b, 5)
    if dtype not in (2, 5):
        raise b.error(f"data type {dtype}; expected 2 (real) or 5 (complex)", 5)
    if ndv < 1 or ndv > 9:
        raise b.error(f"{ndv} data values per node; expected 1..9", 5)
    r7 = parse_ints(b.lines[6], 2, "record 7", b, 6)
    nint, nreal = r7
    ints = parse_ints(b.lines[6], 2 + nint, "record 7", b, 6)
    # record 8: nreal numbers, possibly over several lines
    k = 7
    reals: list[float] = []
    while len(reals) < nreal:
        if k >= len(b.lines):
            raise b.error(f"record 8 needs {nreal} numbers; the dataset ends first", k)
        toks = tokens_exact(b.lines[k])
        if toks is None:
            raise b.error(f"record 8 {b.lines[k].strip()!r} is not numeric", k)
        reals += [float(t) for t in toks]
        k += 1
    if len(reals) != nreal:
        raise b.error(f"record 8 holds {len(reals)} numbers; record 7 says {nreal}", k - 1)
    body = "\n".join(b.lines[k:])
    if tokens_exact(body) is None:
        bad = next(i for i, ln in enumerate(b.lines[k:]) if tokens_exact(ln) is None)
        raise b.error(f"node data line {b.lines[k + bad].strip()!r} is not numeric", k + bad)
    vals = parse_floats(body)
    per = ndv * (2 if dtype == 5 else 1)
    if vals.size % (per + 1):
        raise b.error(f"node data holds {vals.size} numbers, not a multiple of {per + 1} (node id + {per} values): "
                      "the dataset is truncated or NDV is wrong", k)
    rows = vals.reshape(-1, per + 1)
    node_ids = rows[:, 0]
    if np.any(node_ids != np.round(node_ids)) or np.any(node_ids < 0):
        raise b.error("node ids in the data section are not non-negative integers", k)
    v = rows[:, 1:]
    if dtype == 5:
        v = v[:, 0::2] + 1j * v[:, 1::2]
    return dict(ids=ids, analysis=analysis, ndv=ndv, data_ch=data_ch, ints=ints[2:], reals=reals,
                nodes=node_ids.astype(int), values=v, tags=parse_tags(ids))


def read_modes(path, *, dofs=None) -> ModeSet:
    """Read mode shapes (dataset 55, analysis types 2, 3 and 7) into a :class:`ModeSet`.

    Rows are the node components that are non-zero in some mode (labels with + signs,
    nodes in file order, X Y Z RX RY RZ within a node).  ``dofs=`` returns exactly those
    labels instead (a label ``12-Z`` gives the negated +Z values), so
    ``read_modes(p, dofs=m.dofs)`` reproduces a written ModeSet ``m``.
    """
    with _guard(path) as cur:
        blocks = _blocks(path, cur)
        coords = _global_nodes(blocks, path, cur) or {}
        sets = _mode_sets(blocks, cur, path)
        ndv = max(s["ndv"] for s in sets)
        node_order: dict[int, int] = {}
        for s in sets:
            for nd in s["nodes"]:
                node_order.setdefault(int(nd), len(node_order))
        cplx = any(np.iscomplexobj(s["values"]) for s in sets)
        table = np.zeros((len(node_order), ndv, len(sets)), complex if cplx else float)
        freq, damp, mm = np.zeros(len(sets)), np.zeros(len(sets)), np.zeros(len(sets))
        scaling = None
        for m, s in enumerate(sets):
            idx = [node_order[int(nd)] for nd in s["nodes"]]
            if len(set(idx)) != len(idx):
                raise UffError(f"mode at line {s['line']} lists a node twice", path=path, dataset=55, line=s["line"])
            table[idx, :s["ndv"], m] = s["values"]
            freq[m], damp[m], mm[m] = _frequency_damping(s, path)
            if s["tags"].get("scaling") in ("unit_modal_mass", "unit_max", "arbitrary"):
                scaling = s["tags"]["scaling"]
        if not np.all(np.isfinite(freq)) or not np.all(np.isfinite(damp)):
            raise UffError("mode frequencies or damping are not finite", path=path, dataset=55)
        rotated = _rotate_to_global(table, node_order, _node_rotations(blocks, path, cur), ndv, path)
        scaling, indicators = _scaling(scaling, mm)
        scalar = ndv == 1 and all(s["data_ch"] == 1 for s in sets)
        labels, rows = [], []
        for node, i in node_order.items():
            for c in range(ndv):
                labels.append(Dof(node, 0 if scalar else c + 1))
                rows.append(table[i, c])
        shapes = np.array(rows).reshape(len(rows), len(sets))
        if dofs is None:
            keep = np.any(shapes != 0, axis=1)
            labels = [d for d, kk in zip(labels, keep) if kk]
            shapes = shapes[keep]
        meta = {"source": str(path)}
        if rotated:
            meta["rotated_to_global"] = rotated
        ms = ModeSet(freq_hz=freq, damping=damp, shapes=shapes if labels else None, dofs=labels, scaling=scaling,
                     indicators=indicators, metadata=meta, coordinates=coords)
        if dofs is not None:
            ms = ms.select_dofs(dofs)
        return ms


def _mode_sets(blocks, cur, path) -> list[dict]:
    """The parsed datasets 55 of analysis type 2, 3 or 7 (each write checked complete)."""
    sets, all55 = [], []
    for b in blocks:
        if b.number == 55:
            cur.block = b
            s = _parse_55(b)
            all55.append((s["tags"], b.line, s["analysis"] in (2, 3, 7)))
            if s["analysis"] in (2, 3, 7):
                s["line"] = b.line
                sets.append(s)
    cur.block = None
    check_groups(all55, path, "mode", "m")
    if not sets:
        raise UffError(f"no mode shapes (dataset 55, analysis type 2, 3 or 7) in the file{_what_instead(blocks, cur)}",
                       path=path)
    return sets


def _what_instead(blocks, cur) -> str:
    """What a file without mode shapes holds, and the command that makes modes of it: '' when it holds no
    function (dataset 58) either."""
    kinds = held_functions(blocks, cur)
    if not kinds:
        return ""
    held = held_text(kinds)
    if "FRF" in kinds:
        return f"; it holds {held}: identify modes from them with 'modalab identify'"
    if "time response" in kinds:
        return f"; it holds {held} (raw hits): make FRFs with 'modalab frf', then modes with 'modalab identify'"
    return f"; it holds {held}"


def _frequency_damping(s: dict, path) -> tuple[float, float, float]:
    """Frequency (Hz), damping ratio and modal mass of a mode from record 8; the exact values of the ID line
    (modalab's ``f=``/``z=`` tokens) when they agree with it."""
    r = s["reals"]
    mm = 0.0
    if s["analysis"] == 2:
        if len(r) < 3:
            raise UffError("normal-mode record 8 needs frequency, modal mass and damping", path=path,
                           dataset=55, line=s["line"] + 8)
        f, mm, z = r[0], r[1], r[2]
    else:
        if len(r) < 2:
            raise UffError("complex-mode record 8 needs the eigenvalue", path=path, dataset=55,
                           line=s["line"] + 8)
        lam = complex(r[0], r[1])
        w = abs(lam)
        f, z = w / (2 * np.pi), (-lam.real / w if w > 0 else 0.0)
    t = s["tags"]
    if "f" in t and "z" in t:
        try:
            ef, ez = float(t["f"]), float(t["z"])
        except ValueError:
            log.warning("%s: mode at line %d: ID line f=%s z=%s are not numbers; using record 8",
                        path, s["line"], t["f"], t["z"])
            return f, z, mm
        if abs(ef - f) <= 1e-5 * max(abs(ef), 1e-300) + 1e-12 and abs(ez - z) <= 1e-5 + 1e-5 * abs(ez):
            f, z = ef, ez
        else:
            log.warning("%s: mode at line %d: ID line f=%s z=%s disagrees with record 8; using record 8",
                        path, s["line"], t["f"], t["z"])
    return f, z, mm


def _rotate_to_global(table, node_order: dict, rot: dict, ndv: int, path) -> list:
    """Rotate, in place, the shapes of nodes with local displacement frames (dataset 2420); their node ids."""
    rotated = [nd for nd in node_order if nd in rot]
    if not rotated:
        return rotated
    if ndv < 3:
        raise UffError(f"nodes {rotated[:10]} use rotated displacement frames (dataset 2420) but the modes "
                       f"hold {ndv} value(s) per node; the three components needed to rotate them into the "
                       "global frame are missing. Export the shapes in the global frame", path=path, dataset=55)
    for nd in rotated:
        i, R = node_order[nd], rot[nd]
        for c0 in range(0, 6 if ndv >= 6 else 3, 3):
            table[i, c0:c0 + 3] = R.T @ table[i, c0:c0 + 3]
    log.info("%s: shapes of %d node(s) rotated from their local displacement frames (dataset 2420) into "
             "the global frame", path, len(rotated))
    return rotated


def _scaling(scaling, mm) -> tuple[str, dict]:
    """The shapes' scaling (stated, or unit modal mass when every modal mass is 1) and the modal masses to keep."""
    indicators = {}
    if scaling is None:
        if np.all(mm == 1.0):
            scaling = "unit_modal_mass"
        else:
            scaling = "arbitrary"
            if np.any(mm != 0):
                indicators["modal_mass"] = mm
    elif scaling != "unit_modal_mass" and np.any(mm != 0):
        indicators["modal_mass"] = mm
    return scaling, indicators


def _modes_from_uff(cls, path, **kw) -> ModeSet:
    """Read mode shapes from dataset 55 (:func:`read_modes`)."""
    return read_modes(path, **kw)


def _modes_to_uff(self, path, **kw) -> None:
    """Write mode shapes as dataset 55, one set per mode (:func:`write_modes`)."""
    write_modes(path, self, **kw)


ModeSet.from_uff = classmethod(_modes_from_uff)
ModeSet.to_uff = _modes_to_uff
