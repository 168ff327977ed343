"""UFF FRFs and coherence: dataset 58/58b, func_type 4 and 6; the assumed quantity of unlabelled files.

Part of :mod:`modalab.core.uff`.
"""
from __future__ import annotations

import contextvars
import logging
import os
from collections import Counter
from contextlib import contextmanager

import numpy as np

from ._uff_common import (FUNC_TYPES, _NUM_UNITS, _QTY_TYPE, _TYPE_QTY, _blocks, _even_axis, _frf_scale,
                          _guard, _json_lines, _json_meta, _label_si, _open_out, _units_factors)
from ._uff_core import Axis, Fn58, check_groups, date_line, format_58, parse_58
from ._uff_geometry import _node_rotations
from .dof import Dof, locate, parse_dofs
from .errors import ModalabError, UffError
from .frf import FRF
from .units import QUANTITY_UNITS, check_quantity

log = logging.getLogger("modalab.core.uff")


_ASSUMED_QUANTITY = contextvars.ContextVar("modalab_assumed_quantity", default=None)


@contextmanager
def assume_quantity(quantity: str | None):
    """Within the block, :func:`read_frf` takes FRFs whose file does not state their quantity (ordinate data
    type 0 or 1 without a recognised units label) as ``quantity``, and refuses files that state another one.
    The command line's ``--quantity`` sets it for the whole command.  It is also put in the environment
    variable ``MODALAB_QUANTITY`` for the block, so that worker processes (campaigns) read alike; the
    variable set by the user has the same effect."""
    if quantity is None:
        yield
        return
    q = check_quantity(quantity)
    token = _ASSUMED_QUANTITY.set(q)
    old = os.environ.get("MODALAB_QUANTITY")
    os.environ["MODALAB_QUANTITY"] = q
    try:
        yield
    finally:
        _ASSUMED_QUANTITY.reset(token)
        if old is None:
            os.environ.pop("MODALAB_QUANTITY", None)
        else:
            os.environ["MODALAB_QUANTITY"] = old


def _assumed_quantity() -> str | None:
    q = _ASSUMED_QUANTITY.get()
    if q is None and os.environ.get("MODALAB_QUANTITY"):
        try:
            q = check_quantity(os.environ["MODALAB_QUANTITY"])
        except ModalabError:
            raise UffError(f"MODALAB_QUANTITY={os.environ['MODALAB_QUANTITY']!r}; expected accelerance, mobility "
                           "or receptance") from None
    return q


def _quantity_from_labels(fn: Fn58) -> str | None:
    """The quantity of an FRF set from its numerator units label when record 9's data type does not say
    (types 0 and 1): 'm' receptance, 'm/s' mobility, 'm/s^2' (or 'g', 'mm/s^2'...) accelerance."""
    if fn.axes[1].spec not in (0, 1):
        return None
    num = fn.axes[1].units
    if "/" in num and fn.axes[2].units.strip().upper() in ("", "NONE"):
        num = num.rsplit("/", 1)[0]
    conv = _label_si(num)
    return {"m": "receptance", "m/s": "mobility", "m/s^2": "accelerance"}.get(conv[1]) if conv else None


# ----------------------------------------------------------------------------- FRF
def write_frf(path, frf: FRF, *, binary: bool = True, append: bool = False) -> None:
    """Write FRFs (func_type 4) and coherence (func_type 6) as dataset 58b (58 with ``binary=False``).

    One set per (response, reference) pair, the signed DOF labels in the node/direction
    fields, the quantity in the ordinate/denominator data types (see the module docstring
    for the exact layout).  ``append=True`` adds the sets to an existing file.
    """
    if not isinstance(frf, FRF):
        raise UffError(f"write_frf needs a modalab.FRF; got {type(frf).__name__}. Build one with FRF.from_arrays")
    x = np.asarray(frf.freq_hz, dtype=float)
    if x.size == 0:
        raise UffError("the FRF has no frequency lines; nothing to write", path=path)
    even, x0, dx = _even_axis(x)
    if not even and not binary:
        log.warning("%s: uneven frequency lines are stored with 6 digits in ASCII dataset 58 (E13.5); "
                    "write binary=True for exact frequencies", path)
    qty = frf.quantity
    num_axis = Axis(_QTY_TYPE[qty], 0, 0, 0, "NONE", _NUM_UNITS[qty])
    den_axis = Axis(13, 0, 0, 0, "NONE", "N")
    abs_axis = Axis(18, 0, 0, 0, "Frequency", "Hz")
    coh_axes = [abs_axis, Axis(0, 0, 0, 0, "Coherence", "NONE"), Axis(0), Axis(0)]
    frf_axes = [abs_axis, num_axis, den_axis, Axis(0)]
    meta = dict(frf.metadata)
    if frf.window_beta_per_s:
        # the window's decay rate travels in the file under its historic key (FRF.window_beta_per_s)
        meta = {"exp_window_beta": frf.window_beta_per_s, **meta}
    id4, id5 = _json_lines(meta, "FRF")
    id2 = f"modalab x0={x0!r} dx={dx!r}" if even else "modalab"
    n_sets = frf.n_out * frf.n_in * (1 if frf.coherence is None else 2)
    date = date_line(n_sets, "f")
    fid = 0
    with _open_out(path, append) as fh:
        for func, arr, axes, title in ((4, frf.H, frf_axes, "H"), (6, frf.coherence, coh_axes, "Coherence")):
            if arr is None:
                continue
            for i, r in enumerate(frf.responses):
                for j, q in enumerate(frf.references):
                    fid += 1
                    y = np.array(arr[i, j], dtype=complex if func == 4 else float)
                    fh.write(format_58(binary=binary, ids=[f"{title} {r}/{q}", id2, date, id4, id5],
                                       func_type=func, func_id=fid, load_case=0,
                                       rsp_node=r.node, rsp_dir=r.direction, ref_node=q.node, ref_dir=q.direction,
                                       x=x, y=y, even=even, x0=x0, dx=dx, axes=axes))


def _functions(blocks, cur, func_types, header_only=False) -> list[Fn58]:
    out = []
    for b in blocks:
        if b.number != 58:
            continue
        cur.block = b
        fn = parse_58(b, header_only=True)
        if func_types is None or fn.func_type in func_types:
            out.append(fn if header_only else parse_58(b, header=fn))
    cur.block = None
    return out


def _same_axis(a: Fn58, b: Fn58) -> bool:
    if a.n != b.n:
        return False
    return bool(np.array_equal(a.x, b.x) or np.allclose(a.x, b.x, rtol=1e-9, atol=1e-12 * max(1.0, abs(a.x[-1]))))


def read_frf(path, *, quantity: str | None = None, responses=None, references=None) -> FRF:
    """Read FRFs (func_type 4) and coherence (func_type 6) from dataset 58/58b into an :class:`FRF`.

    Sets are gathered into the ``(n_out, n_in, n_freq)`` matrix in order of first
    appearance.  A DOF stored with both signs is labelled as first seen and the
    other sets negated.  The quantity comes from the ordinate data type (8, 11, 12
    over 13); ``quantity=`` overrides it.  ``responses``/``references`` read a
    sub-matrix (labels; signs are applied as in :meth:`FRF.select`).
    """
    with _guard(path) as cur:
        blocks = _blocks(path, cur)
        lf, ff = _units_factors(blocks)
        check_groups([(f.tags, f.line, f.func_type in (4, 6)) for f in _functions(blocks, cur, None, True)],
                     path, "FRF/coherence", "f")
        fns = _functions(blocks, cur, (4, 6))
        frfs = [f for f in fns if f.func_type == 4]
        if not frfs:
            _no_frfs(blocks, cur, path)
        first = frfs[0]
        mat = _FrfMatrix(frfs)
        qty = None if quantity is None else check_quantity(quantity)
        for f in frfs:
            cur.block = None
            _check_set(f, first, quantity, path)
            if quantity is None:
                qty = _set_quantity(f, qty, path)
            mat.put(f, _frf_scale(f, lf, ff), path)
        if not np.all(np.isfinite(first.x)) or (first.n > 1 and np.any(np.diff(first.x) <= 0)):
            raise UffError(f"the frequency axis ({first.x0!r} + k*{first.dx!r}) does not increase strictly",
                           path=path, dataset=58, line=first.line + 7)
        coh = _coherence([f for f in fns if f.func_type == 6], first, mat, path)
        meta = _json_meta(first.tags)
        meta.setdefault("source", str(path))
        beta = meta.pop("exp_window_beta", None)
        full_r, full_c, H, seen = mat.responses, mat.references, mat.H, mat.seen
        rot = _node_rotations(blocks, path, cur)
        if rot:
            done = _rotate_frf(H, coh, full_r, full_c, rot, path, seen)
            if done:
                meta["rotated_to_global"] = done
        if responses is not None or references is not None:
            full_r, full_c, H, seen, coh = _submatrix(full_r, full_c, responses, references, H, seen, coh)
        missing = [(full_r[i], full_c[j]) for i, j in zip(*np.nonzero(seen == 0))]
        if missing:
            txt = ", ".join(f"{a}/{b}" for a, b in missing[:12]) + (" ..." if len(missing) > 12 else "")
            raise UffError(f"the response x reference matrix ({len(full_r)} x {len(full_c)}) is incomplete: "
                           f"{len(missing)} FRFs missing ({txt}). Add the missing FRFs to the file, or pass "
                           "responses=[...] and references=[...] to read_frf to read a complete sub-matrix",
                           path=path, dataset=58)
        return FRF(freq_hz=first.x.copy(), H=H, responses=full_r, references=full_c, coherence=coh,
                   quantity=qty, units=QUANTITY_UNITS[qty], metadata=meta,
                   window_beta_per_s=0.0 if beta is None else beta)


def held_functions(blocks, cur) -> Counter:
    """How many functions (dataset 58) of each kind the file holds, by :data:`FUNC_TYPES` name."""
    return Counter(FUNC_TYPES.get(f.func_type, str(f.func_type)) for f in
                   _functions(blocks, cur, range(100), header_only=True))


def held_text(kinds: Counter) -> str:
    """:func:`held_functions` as the error messages say it ('3 FRF, 1 time response'; '' for none)."""
    return ", ".join(f"{v} {k}" for k, v in kinds.items())


def _no_frfs(blocks, cur, path):
    """Raise the error for a file without FRFs, saying what it holds instead."""
    kinds = held_functions(blocks, cur)
    hint = (" (raw hits: make FRFs of them with 'modalab frf', or uff.read_records in Python)"
            if "time response" in kinds else "")
    held = held_text(kinds) or "no dataset 58"
    raise UffError(f"no FRFs (dataset 58, function type 4) in the file; it holds {held}{hint}", path=path)


class _FrfMatrix:
    """The response x reference matrix the FRF sets fill, labelled in order of first appearance."""

    def __init__(self, frfs):
        self.rows: dict = {}
        self.cols: dict = {}
        for f in frfs:
            self.rows.setdefault((f.rsp_node, abs(f.rsp_dir)), Dof(f.rsp_node, f.rsp_dir))
            self.cols.setdefault((f.ref_node, abs(f.ref_dir)), Dof(f.ref_node, f.ref_dir))
        self.ri = {k: i for i, k in enumerate(self.rows)}
        self.ci = {k: i for i, k in enumerate(self.cols)}
        self.H = np.zeros((len(self.rows), len(self.cols), frfs[0].n), complex)
        self.seen = np.zeros((len(self.rows), len(self.cols)), int)       # line of the set, 0 = missing

    @property
    def responses(self) -> list:
        return list(self.rows.values())

    @property
    def references(self) -> list:
        return list(self.cols.values())

    def index(self, f):
        """(i, j) of a set, or None when its DOFs are not in the matrix."""
        kr, kc = (f.rsp_node, abs(f.rsp_dir)), (f.ref_node, abs(f.ref_dir))
        if kr not in self.ri or kc not in self.ci:
            return None
        return self.ri[kr], self.ci[kc]

    def put(self, f, scale: float, path):
        i, j = self.index(f)
        r, c = self.responses[i], self.references[j]
        if self.seen[i, j]:
            raise UffError(f"FRF {r}/{c} appears twice (second at line {f.line}); "
                           "keep one set per response/reference pair", path=path, dataset=58, line=f.line)
        self.seen[i, j] = f.line
        sign = (1 if f.rsp_dir * r.direction >= 0 else -1) * (1 if f.ref_dir * c.direction >= 0 else -1)
        fac = sign * scale
        self.H[i, j] = f.y if fac == 1 else f.y * fac


def _check_set(f, first, quantity, path):
    """One FRF set fits the first one's axis, is per unit force (unless ``quantity`` says otherwise) and
    names its reference."""
    if not _same_axis(first, f):
        raise UffError(f"the FRF {Dof(f.rsp_node, f.rsp_dir)}/{Dof(f.ref_node, f.ref_dir)} (line {f.line}) has "
                       f"{f.n} lines {f.x[0]:.6g}..{f.x[-1]:.6g} Hz but the first FRF (line {first.line}) has "
                       f"{first.n} lines {first.x[0]:.6g}..{first.x[-1]:.6g} Hz. Split the file or resample "
                       "the FRFs to a common frequency axis", path=path, dataset=58, line=f.line)
    den = f.axes[2].spec
    if den not in (0, 1, 9, 13) and quantity is None:
        raise UffError(f"FRF {Dof(f.rsp_node, f.rsp_dir)}/{Dof(f.ref_node, f.ref_dir)} has denominator data "
                       f"type {den} (record 10), not force (13): it is not a response per unit force. "
                       "Pass quantity= to read it anyway", path=path, dataset=58, line=f.line + 10)
    if f.ref_node == 0 and f.ref_dir == 0:
        raise UffError(f"FRF {Dof(f.rsp_node, f.rsp_dir)} has no reference DOF (reference node 0 or "
                       "negative): an FRF needs the excitation DOF", path=path, dataset=58, line=f.line + 6)


def _set_quantity(f, qty, path) -> str:
    """The quantity of the file so far (``qty``, None before the first set) checked against set ``f``'s:
    from its ordinate type or units label, else the one :func:`assume_quantity` gives."""
    q = _TYPE_QTY.get(f.axes[1].spec) or _quantity_from_labels(f)
    assumed = _assumed_quantity()
    if assumed is not None and q is not None and q != assumed:
        raise UffError(f"the FRFs are {q} (record 9 of the set at line {f.line}) but --quantity says "
                       f"{assumed}; drop --quantity or convert the FRFs", path=path, dataset=58,
                       line=f.line + 9)
    q = q or assumed
    if q is None:
        raise UffError(f"ordinate data type {f.axes[1].spec} (record 9, units "
                       f"{f.axes[1].units!r}) is not displacement (8), velocity (11) or acceleration "
                       "(12); say what the FRFs are: on the command line --quantity accelerance (or "
                       "mobility, receptance), in Python read_frf(..., quantity='accelerance')",
                       path=path, dataset=58, line=f.line + 9)
    if qty is not None and q != qty:
        raise UffError(f"the file mixes {qty} and {q} FRFs; read it with quantity= set and convert "
                       "with FRF.to()", path=path, dataset=58, line=f.line + 9)
    return q


def _coherence(cohs, first, mat: _FrfMatrix, path):
    """The coherence sets on the FRF matrix (NaN where a set is missing, with a warning), or None."""
    if not cohs:
        return None
    coh = np.full(mat.H.shape, np.nan)
    cseen = np.zeros(mat.seen.shape, bool)
    for c in cohs:
        ij = mat.index(c)
        if ij is None:
            log.warning("%s: coherence %s/%s at line %d has no FRF; ignored", path,
                        Dof(c.rsp_node, c.rsp_dir), Dof(c.ref_node, c.ref_dir), c.line)
            continue
        if not _same_axis(first, c):
            raise UffError(f"coherence at line {c.line} has a different frequency axis from the FRFs; "
                           "resample it to the FRF lines", path=path, dataset=58, line=c.line)
        coh[ij] = np.real(c.y)
        cseen[ij] = True
    has = mat.seen > 0
    if not cseen[has].all():
        resp, refs = mat.responses, mat.references
        lack = [f"{resp[i]}/{refs[j]}" for i, j in zip(*np.nonzero(~cseen & has))]
        log.warning("%s: no coherence for %s; those entries are NaN", path, ", ".join(lack[:10]))
    return coh


def _rotate_frf(H, coh, rows, cols, rot, path, seen=None) -> list[int]:
    """Rotate FRF rows (responses) and columns (references) measured in local displacement frames into the
    global frame, in place; a node in a rotated frame needs its X, Y and Z all present (else UffError).
    Coherence of a rotated triad is the lowest of its three.  Returns the rotated nodes."""
    done = []
    for axis, labels in ((0, rows), (1, cols)):
        by_node: dict = {}
        for k, d in enumerate(labels):
            if d.node in rot:
                by_node.setdefault(d.node, {})[abs(d.direction)] = (k, 1 if d.direction > 0 else -1)
        for node, comp in by_node.items():
            if not all(c in comp for c in (1, 2, 3)) or any(c > 3 for c in comp):
                what = "response" if axis == 0 else "reference"
                raise UffError(f"{what} node {node} is measured in a rotated displacement frame (dataset 2420) but "
                               f"the file holds its directions {sorted(comp)} only; X, Y and Z are needed to rotate "
                               "it into the global frame. Export the FRFs in the global frame", path=path, dataset=58)
            idx = [comp[c][0] for c in (1, 2, 3)]
            if seen is not None:
                part = seen[idx] if axis == 0 else seen[:, idx].T
                gaps = (part == 0).any(axis=0) & (part != 0).any(axis=0)
                if gaps.any():
                    # a partial triad cannot be rotated: those FRFs count as missing (an error if they are read)
                    other = cols if axis == 0 else rows
                    bad = [str(other[j]) for j in np.nonzero(gaps)[0]]
                    log.warning("%s: node %d is in a rotated displacement frame (dataset 2420) but its X, Y, Z FRFs "
                                "with %s are incomplete; they cannot be rotated into the global frame and are left "
                                "out", path, node, ", ".join(bad[:10]))
                    if axis == 0:
                        seen[np.ix_(idx, np.nonzero(gaps)[0])] = 0
                    else:
                        seen[np.ix_(np.nonzero(gaps)[0], idx)] = 0
            sg = np.array([comp[c][1] for c in (1, 2, 3)], float)
            S = np.diag(sg)
            T = S @ rot[node].T @ S                    # label-signed local -> label-signed global
            if axis == 0:
                H[idx] = np.einsum("ij,jkf->ikf", T, H[idx])
                if coh is not None:
                    coh[idx] = np.min(coh[idx], axis=0, keepdims=True)
            else:
                H[:, idx] = np.einsum("ij,kjf->kif", T, H[:, idx])
                if coh is not None:
                    coh[:, idx] = np.min(coh[:, idx], axis=1, keepdims=True)
            done.append(node)
    if done:
        log.info("%s: FRFs of node(s) %s rotated from their local displacement frames into the global frame",
                 path, sorted(set(done))[:10])
    return sorted(set(done))


def _submatrix(rows, cols, responses, references, H, seen, coh):

    ii, si = (list(range(len(rows))), [1] * len(rows)) if responses is None else locate(rows, responses, "response DOF")
    jj, sj = (list(range(len(cols))), [1] * len(cols)) if references is None else locate(cols, references,
                                                                                          "reference DOF")
    ix = np.ix_(ii, jj)
    Hs = H[ix] * np.outer(si, sj)[:, :, None]
    r = rows if responses is None else parse_dofs(responses)
    c = cols if references is None else parse_dofs(references)
    return r, c, Hs, seen[ix], None if coh is None else coh[ix]


def _frf_from_uff(cls, path, **kw) -> FRF:
    """Read FRFs (dataset 58/58b, func_type 4) and coherence (func_type 6) from a universal file
    (:func:`read_frf`)."""
    return read_frf(path, **kw)


def _frf_to_uff(self, path, **kw) -> None:
    """Write FRFs and coherence as dataset 58 (binary 58b by default; :func:`write_frf`)."""
    write_frf(path, self, **kw)


FRF.from_uff = classmethod(_frf_from_uff)
FRF.to_uff = _frf_to_uff
