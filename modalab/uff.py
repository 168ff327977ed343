"""Universal file (UFF) I/O: FRFs, raw hits, geometry, mode shapes, units.

Reading and writing by task
---------------------------
FRFs (dataset 58/58b, func_type 4; coherence func_type 6)
    :func:`write_frf`, :func:`read_frf`
Raw hammer hits (dataset 58/58b, func_type 1 time records)
    :func:`write_records`, :func:`read_records`
Geometry (datasets 2411 and 15)
    :func:`write_geometry`, :func:`read_geometry`
Mode shapes (dataset 55)
    :func:`write_modes`, :func:`read_modes`
Units (dataset 164)
    :func:`write_units`, :func:`read_units`
What a file holds
    :func:`info`

Our own 58/58b writer and reader replace pyuff's for speed and exactness
(pyuff 2.5.8 truncates binary files in ``'overwrite'`` mode, writes half the
byte count for complex 58b data, writes the abscissa with 6 digits, modifies
input arrays and writes in time quadratic in the number of sets).  The files
we write are standard and pyuff reads them.  Writing is linear in the number of
sets; binary files round-trip bit for bit; ASCII files carry 13 significant
digits (the E20.12 field of the standard).

Layout of the datasets modalab writes
-------------------------------------
ID lines that start with ``modalab`` carry ``key=value`` tokens (floats
written with ``repr``, so they read back exactly); other programs show them as
text.  Record 7 also holds the abscissa minimum and increment, to the 6-7
digits its E13 fields allow; on reading, the exact ``x0``/``dx`` tokens are
used when they agree with record 7.

FRF and coherence sets (dataset 58b, or 58 with ``binary=False``), one per
(response, reference) pair, FRF first then coherence::

    ID line 1  H <response>/<reference>        e.g. "H 12+Z/1+Z"  ("Coherence ..." for func_type 6)
    ID line 2  modalab x0=<Hz> dx=<Hz>          exact abscissa (even spacing)
    ID line 3  DD-MMM-YY HH:MM:SS modalab w=<write id>f ns=<number of sets of this write>
    ID line 4  modalab m=<json>                  FRF metadata (estimator, n_averages,
    ID line 5  modalab m+=<json continued>       exp_window_beta, force_window, ...), compact JSON
    Record 6   func_type 4 (FRF) or 6 (coherence), load case 0,
               response node/direction and reference node/direction = the signed DOF labels
    Record 7   ordinate type 6 (complex double) for FRFs, 4 (real double) for coherence;
               even abscissa in Hz (uneven lines: spacing 0, abscissa stored with the data)
    Record 8   abscissa type 18 (frequency), units "Hz"
    Record 9   ordinate type 8/11/12 (displacement/velocity/acceleration) for receptance/
               mobility/accelerance, units "m", "m/s", "m/s^2"; coherence: 0, units "NONE"
    Record 10  denominator type 13 (excitation force), units "N"; coherence: 0

Raw hits (``write_records``): one time record (func_type 1) per channel per hit::

    ID line 1  hit <hit_id> ch <k> <role> <dof>  e.g. "hit 3 ch 0 force 1+Z"
    ID line 2  modalab role=<force|response> sens=<V per unit> ovl=<0|1> ch=<k> nch=<n_channels>
    ID line 3  DD-MMM-YY HH:MM:SS modalab w=<write id>r ns=<records of this write>
    ID line 4  modalab fs=<sample rate, Hz> trig=<trigger index>
    ID line 5  modalab m=<json of TimeRecord.metadata> (or NONE when empty or longer than the line)
    Record 6   func_type 1, function id k+1, load case id = hit_id,
               response node/direction = the channel's DOF,
               reference node/direction = the hammer DOF (first force channel of the hit)
    Record 7   ordinate type 4 (real double), even abscissa in s starting at
               -trigger_index/fs, increment 1/fs
    Record 8   abscissa type 17 (time), units "s"
    Record 9   ordinate type 13 (force, "N") or 12 (acceleration, "m/s^2"); other units: 11 "m/s",
               8 "m", otherwise 0 with the unit text as the units label
    A hit is the set of records sharing a load case id; channels are ordered by ``ch``.

Mode shapes (``write_modes``): one dataset 55 per mode, analysis type 2 (real,
record 8 = frequency, modal mass, viscous damping ratio, 0) or 3 (complex,
record 8 = eigenvalue, modal A, modal B), 3 or 6 values per node (X Y Z [RX
RY RZ]); a DOF labelled ``12-Z`` is stored as the negated value at node 12 +Z.
ID line 2 holds ``modalab f=<Hz> z=<damping ratio>``, ID line 3 the date and
``modalab w=<write id>m ns=<modes of this write>``, ID line 4 ``modalab scaling=<scaling>``.
With ``exact=True`` (default) numbers are written in 25-character fields (17
significant digits, read back bit for bit); ``exact=False`` writes the standard
6E13.5 fields every reader (pyuff, ME'scope) accepts.  Unit modal mass scaling
writes modal mass 1; otherwise ``indicators['modal_mass']`` when present, else 0.
Participation factors are not stored.

Geometry: dataset 2411 (4I10 / 3E25.16, exact) by default, 15 (4I10, 3E13.5) on request.
Units: dataset 164, SI (code 1, factors 1, 1, 1, offset 273.15).

Every write call tags its datasets with a random write id ``w`` (8 hex digits
and a kind letter: f FRF, r records, m modes) and their count ``ns``; the
readers check that each write's datasets are all present and of their kind, so
a dataset lost to a corrupted number or delimiter is an error, not a silently
smaller result.  FRF metadata beyond the 139 characters of ID lines 4-5 is
dropped with a logged warning.

Reading other writers' files
----------------------------
ASCII 58 with fixed-width or blank-separated fields, Fortran ``D`` exponents,
CRLF line ends; 58b little or big endian, single or double precision, with
or without a line break before the closing ``-1`` and with wrong byte counts
in the header (pyuff, some exporters).  Units: ordinate and denominator unit
labels (``g``, ``mm/s^2``, ``lbf``...) or else dataset 164 factors convert to SI.
A truncated or malformed file raises :class:`~modalab.errors.UffError` naming
the file, the dataset and the line.
"""
from __future__ import annotations

import json
import logging
import os
import tempfile
from collections import Counter
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ._uff_core import (Axis, Block, Fn58, check_groups, date_line, e13, format_58, id_line, parse_58, parse_floats, parse_ints,
                        parse_tags, scan, tokens_exact)
from .dof import Dof
from .errors import DofError, ModalabError, UffError
from .frf import FRF
from .modes import ModeSet
from .records import TimeRecord
from .units import G, QUANTITY_UNITS, check_quantity

__all__ = ["write_frf", "read_frf", "write_records", "read_records", "write_geometry", "read_geometry",
           "write_modes", "read_modes", "write_units", "read_units", "info", "FUNC_TYPES"]

log = logging.getLogger(__name__)

FUNC_TYPES = {0: "general", 1: "time response", 2: "auto spectrum", 3: "cross spectrum", 4: "FRF",
              5: "transmissibility", 6: "coherence", 7: "auto correlation", 8: "cross correlation", 9: "PSD",
              12: "spectrum", 26: "multiple coherence"}
_QTY_TYPE = {"receptance": 8, "mobility": 11, "accelerance": 12}
_TYPE_QTY = {8: "receptance", 11: "mobility", 12: "accelerance"}
_NUM_UNITS = {"receptance": "m", "mobility": "m/s", "accelerance": "m/s^2"}
_UNIT_TYPE = {"N": 13, "m/s^2": 12, "m/s": 11, "m": 8}
#: unit label -> (factor to SI, dimension) for labels found in other writers' files
_LABEL_SI = {
    "m": (1.0, "m"), "mm": (1e-3, "m"), "um": (1e-6, "m"), "in": (0.0254, "m"), "ft": (0.3048, "m"),
    "m/s": (1.0, "m/s"), "mm/s": (1e-3, "m/s"), "in/s": (0.0254, "m/s"),
    "m/s^2": (1.0, "m/s^2"), "m/s2": (1.0, "m/s^2"), "m/s**2": (1.0, "m/s^2"), "m/s²": (1.0, "m/s^2"),
    "mm/s^2": (1e-3, "m/s^2"), "mm/s2": (1e-3, "m/s^2"), "g": (G, "m/s^2"),
    "in/s^2": (0.0254, "m/s^2"), "in/s2": (0.0254, "m/s^2"),
    "n": (1.0, "N"), "kn": (1e3, "N"), "lbf": (4.4482216152605, "N"), "lb": (4.4482216152605, "N"),
}
_SPEC_SI = {8: "m", 11: "m/s", 12: "m/s^2", 13: "N", 9: "N"}
_META_KEYS = ("estimator", "n_averages", "exp_window_beta", "force_window")


# ----------------------------------------------------------------------------- helpers
def _read_bytes(path) -> bytes:
    try:
        with open(path, "rb") as fh:
            return fh.read()
    except OSError as exc:
        raise UffError(f"cannot read the file ({exc.strerror or exc}); check the path", path=path) from None


class _Cursor:
    """Where the reader is, so unexpected low-level errors can be located."""

    def __init__(self, path):
        self.path, self.block = path, None


@contextmanager
def _guard(path):
    """Turn any low-level failure while reading into a located :class:`UffError`."""
    cur = _Cursor(path)
    try:
        yield cur
    except (UffError, DofError):
        raise          # DofError: a label the caller asked for (responses=, dofs=) is not in the file
    except (ModalabError, ValueError, IndexError, KeyError, TypeError, OverflowError, ZeroDivisionError,
            AttributeError, UnicodeError, MemoryError) as exc:
        b = cur.block
        raise UffError(f"unreadable content ({type(exc).__name__}: {exc}); the dataset is malformed or "
                       "mislabelled", path=path,
                       dataset=None if b is None else b.label, line=None if b is None else b.line) from exc


#: datasets found in modal-test files; others are skipped with a warning (a corrupted number shows up here)
_KNOWN = {15, 18, 55, 58, 82, 151, 164, 259, 1858, 2400, 2411, 2412, 2414, 2420, 2429, 2430, 2467, 2477}


def _blocks(path, cur) -> list[Block]:
    blocks = scan(_read_bytes(path), path)
    for b in blocks:
        if b.number not in _KNOWN:
            if any("modalab w=" in ln for ln in b.lines[:12]):
                raise UffError(f"dataset number {b.label} is not a known dataset, yet the dataset carries modalab "
                               "write tags: its number is corrupt", path=path, dataset=b.label, line=b.line)
            log.warning("%s: dataset %s at line %d is not a universal-file dataset modalab knows; skipped",
                        path, b.label, b.line)
    return blocks


@contextmanager
def _open_out(path, append: bool):
    """Write to a temporary file then replace ``path`` (append: write in place)."""
    path = Path(path)
    try:
        if append:
            fh = open(path, "ab")
        else:
            fd, tmp = tempfile.mkstemp(dir=str(path.parent), prefix=path.name + ".", suffix=".tmp")
    except OSError as exc:
        raise UffError(f"cannot write the file ({exc.strerror or exc}); check that the folder exists and is "
                       "writable", path=path) from None
    if append:
        with fh:
            yield fh
        return
    try:
        with os.fdopen(fd, "wb") as fh:
            yield fh
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _even_axis(x: np.ndarray):
    """(even, x0, dx) such that x0 + arange(n)*dx reproduces x to a few ulps."""
    n = x.size
    if n == 1:
        return True, float(x[0]), 0.0
    k = np.arange(n)
    tol = 4 * np.finfo(float).eps * float(np.max(np.abs(x)))
    best = None
    cands = []
    for d0 in ((x[-1] - x[0]) / (n - 1), x[1] - x[0]):
        cands.append(d0)
        up = dn = d0
        for _ in range(3):
            up, dn = np.nextafter(up, np.inf), np.nextafter(dn, -np.inf)
            cands += [up, dn]
    for dx in cands:
        err = float(np.max(np.abs(x[0] + k * dx - x)))
        if err == 0.0:
            return True, float(x[0]), float(dx)
        if best is None or err < best[0]:
            best = (err, float(dx))
    if best[0] <= tol:
        return True, float(x[0]), best[1]
    return False, 0.0, 0.0


def _json_lines(meta: dict, what: str) -> tuple[str, str]:
    """Compact JSON of ``meta`` split over two ID lines; drops keys that do not fit (with a warning)."""
    def clean(v):
        if isinstance(v, dict):
            return {str(k): clean(w) for k, w in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(w) for w in v]
        if isinstance(v, np.ndarray):
            return clean(v.tolist())
        if isinstance(v, np.generic):
            return v.item()
        return v

    keep = {}
    dropped = []
    order = [k for k in _META_KEYS if k in meta] + [k for k in meta if k not in _META_KEYS]
    for k in order:
        trial = dict(keep)
        try:
            trial[k] = clean(meta[k])
            s = _compact_json(trial)
        except (TypeError, ValueError):
            dropped.append(k)
            continue
        if len(s) <= 70 + 69:
            keep = trial
        else:
            dropped.append(k)
    if dropped:
        log.info("%s metadata %s not written to the UFF ID lines (too long or not JSON); "
                 "keep them in a side file if needed", what, dropped)
    if not keep:
        return "NONE", "NONE"
    s = _compact_json(keep)
    a, b = s[:70], s[70:]
    return "modalab m=" + a, ("modalab m+=" + b) if b else "NONE"


def _compact_json(obj) -> str:
    """JSON without blanks (blanks inside strings escaped as \\u0020) so it survives blank-splitting."""
    return json.dumps(obj, separators=(",", ":"), allow_nan=True).replace(" ", "\\u0020")


def _json_meta(tags: dict) -> dict:
    if "m" not in tags:
        return {}
    try:
        out = json.loads(tags["m"])
        return out if isinstance(out, dict) else {}
    except ValueError:
        log.warning("modalab metadata in the ID lines is not valid JSON; ignored")
        return {}


def _label_si(label: str) -> tuple[float, str] | None:
    """(factor to SI, SI unit) of a units label, None when absent or unknown."""
    s = (label or "").strip()
    if not s or s.upper() == "NONE":
        return None
    return _LABEL_SI.get(s) if s in _LABEL_SI else _LABEL_SI.get(s.lower())


def _label_factor(label: str) -> float | None:
    conv = _label_si(label)
    return None if conv is None else conv[0]


def _units_factors(blocks) -> tuple[float, float]:
    """(length, force) factors of the last dataset 164 (1, 1 when absent)."""
    lf = ff = 1.0
    for b in blocks:
        if b.number == 164:
            u = _parse_164(b)
            lf, ff = u["length"], u["force"]
    return lf, ff


def _frf_scale(fn: Fn58, lf: float, ff: float) -> float:
    """Factor converting the ordinate of an FRF set to SI."""
    num, den = fn.axes[1].units, fn.axes[2].units
    if "/" in num and (den.strip().upper() in ("", "NONE")):
        num, den = num.rsplit("/", 1)
    fn_num, fn_den = _label_factor(num), _label_factor(den)
    rotational = abs(fn.rsp_dir) >= 4
    if fn_num is None:
        fn_num = 1.0 if rotational else 1.0 / lf
    if fn_den is None:
        fn_den = 1.0 / ff
    return fn_num / fn_den


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
    id4, id5 = _json_lines(frf.metadata, "FRF")
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
        cohs = [f for f in fns if f.func_type == 6]
        if not frfs:
            kinds = Counter(FUNC_TYPES.get(f.func_type, str(f.func_type)) for f in
                            _functions(blocks, cur, range(100), header_only=True))
            raise UffError(f"no FRFs (dataset 58, function type 4) in the file; it holds "
                           f"{dict(kinds) or 'no dataset 58'}. Use read_records for time data", path=path)
        first = frfs[0]
        rows: dict = {}
        cols: dict = {}
        for f in frfs:
            rows.setdefault((f.rsp_node, abs(f.rsp_dir)), Dof(f.rsp_node, f.rsp_dir))
            cols.setdefault((f.ref_node, abs(f.ref_dir)), Dof(f.ref_node, f.ref_dir))
        rkeys, ckeys = list(rows), list(cols)
        ri = {k: i for i, k in enumerate(rkeys)}
        ci = {k: i for i, k in enumerate(ckeys)}
        nf = first.n
        H = np.zeros((len(rkeys), len(ckeys), nf), complex)
        seen = np.zeros((len(rkeys), len(ckeys)), int)
        # quantity
        qty = None
        if quantity is not None:
            qty = check_quantity(quantity)
        for f in frfs:
            cur.block = None
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
            q = _TYPE_QTY.get(f.axes[1].spec)
            if quantity is None:
                if q is None:
                    raise UffError(f"ordinate data type {f.axes[1].spec} (record 9) is not displacement (8), velocity "
                                   "(11) or acceleration (12); pass quantity='accelerance' (or 'mobility', "
                                   "'receptance') to read_frf", path=path, dataset=58, line=f.line + 9)
                if qty is None:
                    qty = q
                elif q != qty:
                    raise UffError(f"the file mixes {qty} and {q} FRFs; read it with quantity= set and convert "
                                   "with FRF.to()", path=path, dataset=58, line=f.line + 9)
            i, j = ri[(f.rsp_node, abs(f.rsp_dir))], ci[(f.ref_node, abs(f.ref_dir))]
            if seen[i, j]:
                raise UffError(f"FRF {rows[rkeys[i]]}/{cols[ckeys[j]]} appears twice (second at line {f.line}); "
                               "keep one set per response/reference pair", path=path, dataset=58, line=f.line)
            seen[i, j] = f.line
            sign = (1 if f.rsp_dir * rows[rkeys[i]].direction >= 0 else -1) * \
                   (1 if f.ref_dir * cols[ckeys[j]].direction >= 0 else -1)
            fac = sign * _frf_scale(f, lf, ff)
            H[i, j] = f.y if fac == 1 else f.y * fac
        if not np.all(np.isfinite(first.x)) or (first.n > 1 and np.any(np.diff(first.x) <= 0)):
            raise UffError(f"the frequency axis ({first.x0!r} + k*{first.dx!r}) does not increase strictly",
                           path=path, dataset=58, line=first.line + 7)
        missing = [(rows[rkeys[i]], cols[ckeys[j]]) for i, j in zip(*np.nonzero(seen == 0))]
        coh = None
        if cohs:
            coh = np.full(H.shape, np.nan)
            cseen = np.zeros(seen.shape, bool)
            for c in cohs:
                key_r, key_c = (c.rsp_node, abs(c.rsp_dir)), (c.ref_node, abs(c.ref_dir))
                if key_r not in ri or key_c not in ci:
                    log.warning("%s: coherence %s/%s at line %d has no FRF; ignored", path,
                                Dof(c.rsp_node, c.rsp_dir), Dof(c.ref_node, c.ref_dir), c.line)
                    continue
                if not _same_axis(first, c):
                    raise UffError(f"coherence at line {c.line} has a different frequency axis from the FRFs; "
                                   "resample it to the FRF lines", path=path, dataset=58, line=c.line)
                i, j = ri[key_r], ci[key_c]
                coh[i, j] = np.real(c.y)
                cseen[i, j] = True
            if not cseen[seen > 0].all():
                lack = [f"{rows[rkeys[i]]}/{cols[ckeys[j]]}" for i, j in zip(*np.nonzero(~cseen & (seen > 0)))]
                log.warning("%s: no coherence for %s; those entries are NaN", path, ", ".join(lack[:10]))
        meta = _json_meta(first.tags)
        meta.setdefault("source", str(path))
        full_r = [rows[k] for k in rkeys]
        full_c = [cols[k] for k in ckeys]
        if responses is not None or references is not None:
            sub = _submatrix(full_r, full_c, responses, references, H, seen, coh)
            full_r, full_c, H, seen, coh = sub
            missing = [(full_r[i], full_c[j]) for i, j in zip(*np.nonzero(seen == 0))]
        if missing:
            txt = ", ".join(f"{a}/{b}" for a, b in missing[:12]) + (" ..." if len(missing) > 12 else "")
            raise UffError(f"the response x reference matrix ({len(full_r)} x {len(full_c)}) is incomplete: "
                           f"{len(missing)} FRFs missing ({txt}). Add the missing FRFs to the file, or pass "
                           "responses=[...] and references=[...] to read_frf to read a complete sub-matrix",
                           path=path, dataset=58)
        return FRF(freq_hz=first.x.copy(), H=H, responses=full_r, references=full_c, coherence=coh,
                   quantity=qty, units=QUANTITY_UNITS[qty], metadata=meta)


def _submatrix(rows, cols, responses, references, H, seen, coh):
    from .dof import locate, parse_dofs

    ii, si = (list(range(len(rows))), [1] * len(rows)) if responses is None else locate(rows, responses, "response DOF")
    jj, sj = (list(range(len(cols))), [1] * len(cols)) if references is None else locate(cols, references,
                                                                                          "reference DOF")
    ix = np.ix_(ii, jj)
    Hs = H[ix] * np.outer(si, sj)[:, :, None]
    r = rows if responses is None else parse_dofs(responses)
    c = cols if references is None else parse_dofs(references)
    return r, c, Hs, seen[ix], None if coh is None else coh[ix]


# ----------------------------------------------------------------------------- time records
def write_records(path, records, *, binary: bool = True, append: bool = False) -> None:
    """Write raw hits as dataset 58b/58 time records (func_type 1), one per channel per hit.

    See the module docstring for the layout: the hit number is the load case id,
    the channel DOF the response node/direction, the hammer DOF the reference.
    """
    if isinstance(records, TimeRecord):
        records = [records]
    recs = list(records)
    if not all(isinstance(r, TimeRecord) for r in recs):
        raise UffError("write_records needs TimeRecord objects (one per hit)", path=path)
    ids = [r.hit_id for r in recs]
    dup = [h for h, c in Counter(ids).items() if c > 1]
    if dup:
        raise UffError(f"hit ids {dup} appear more than once; a hit is the set of records sharing a load case id, "
                       "so give every hit its own hit_id", path=path)
    date = date_line(sum(r.n_channels for r in recs), "r")
    with _open_out(path, append) as fh:
        for rec in recs:
            fs = float(rec.sample_rate_hz)
            dt = 1.0 / fs
            x0 = -rec.trigger_index * dt
            hammer = rec.force_dofs[0] if rec.force_dofs else Dof(0, 0)
            m4 = f"modalab fs={fs!r} trig={rec.trigger_index}"
            meta_line = "NONE"
            if rec.metadata:
                # keep the entries that fit the 80-character ID line (point, backend...); large ones such as
                # the simulator's ground truth stay out of the file
                kept: dict = {}
                for key, value in rec.metadata.items():
                    try:
                        trial = "modalab m=" + _compact_json({**kept, key: value})
                    except (TypeError, ValueError):
                        continue
                    if len(trial) <= 80:
                        kept[key] = value
                if kept:
                    meta_line = "modalab m=" + _compact_json(kept)
                if len(kept) < len(rec.metadata):
                    log.debug("hit %d: metadata %s not written (too long for an ID line or not JSON)", rec.hit_id,
                              sorted(set(rec.metadata) - set(kept)))
            for k in range(rec.n_channels):
                d, role, unit = rec.dofs[k], rec.roles[k], str(rec.units[k])
                spec = 13 if role == "force" else _UNIT_TYPE.get(unit, 0)
                unit_lab = unit if unit.strip() else "NONE"
                if " " in unit_lab or len(unit_lab) > 20:
                    raise UffError(f"unit {unit!r} of channel {k} must be one word of at most 20 characters",
                                   path=path)
                ids_ = [f"hit {rec.hit_id} ch {k} {role} {d}",
                        f"modalab role={role} sens={float(rec.sensitivity[k])!r} ovl={int(bool(rec.overload[k]))} "
                        f"ch={k} nch={rec.n_channels}",
                        date, m4, meta_line]
                axes = [Axis(17, 0, 0, 0, "Time", "s"), Axis(spec, 0, 0, 0, "NONE", unit_lab), Axis(0), Axis(0)]
                fh.write(format_58(binary=binary, ids=ids_, func_type=1, func_id=k + 1, load_case=rec.hit_id,
                                   rsp_node=d.node, rsp_dir=d.direction, ref_node=hammer.node,
                                   ref_dir=hammer.direction, x=None, y=rec.data[k], even=True, x0=x0, dx=dt,
                                   axes=axes))


def read_records(path) -> list[TimeRecord]:
    """Read time records (func_type 1) back into one :class:`TimeRecord` per hit (load case id)."""
    with _guard(path) as cur:
        blocks = _blocks(path, cur)
        lf, ff = _units_factors(blocks)
        check_groups([(f.tags, f.line, f.func_type == 1) for f in _functions(blocks, cur, None, True)],
                     path, "time record", "r")
        fns = _functions(blocks, cur, (1,))
        if not fns:
            raise UffError("no time records (dataset 58, function type 1) in the file", path=path)
        hits: dict[int, list[Fn58]] = {}
        for f in fns:
            hits.setdefault(f.load_case, []).append(f)
        out = []
        for hit, chans in hits.items():
            def order(f):
                try:
                    return int(f.tags.get("ch", 10 ** 9)), f.line
                except ValueError:
                    return 10 ** 9, f.line
            chans.sort(key=order)
            c0 = chans[0]
            for f in chans:
                if not f.even:
                    raise UffError(f"time record of hit {hit} is unevenly sampled; records must be evenly sampled",
                                   path=path, dataset=58, line=f.line + 7)
                if f.n != c0.n or f.dx != c0.dx or f.x0 != c0.x0:
                    raise UffError(f"the channels of hit {hit} differ in length or sampling (line {c0.line}: "
                                   f"{c0.n} samples, dt={c0.dx!r}; line {f.line}: {f.n} samples, dt={f.dx!r}); "
                                   "a hit's records must share their time axis", path=path, dataset=58, line=f.line)
                if f.is_complex:
                    raise UffError("time record holds complex data; expected real samples", path=path,
                                   dataset=58, line=f.line + 7)
            if "nch" in c0.tags:
                try:
                    nch = int(c0.tags["nch"])
                except ValueError:
                    raise UffError(f"channel count {c0.tags['nch']!r} is not an integer", path=path, dataset=58,
                                   line=c0.line + 2) from None
                if nch != len(chans):
                    raise UffError(f"hit {hit} has {len(chans)} channel records but was written with {nch}; "
                                   "the file is incomplete or mislabelled", path=path, dataset=58, line=c0.line)
            t4 = c0.tags
            if c0.dx <= 0:
                raise UffError(f"time increment {c0.dx!r} must be positive", path=path, dataset=58,
                               line=c0.line + 7)
            try:
                fs = float(t4["fs"]) if "fs" in t4 else 1.0 / c0.dx
                trig = int(t4["trig"]) if "trig" in t4 else None
            except ValueError:
                raise UffError("sample rate / trigger tokens in ID line 4 are not numbers", path=path,
                               dataset=58, line=c0.line + 4) from None
            if not np.isfinite(fs) or fs <= 0 or abs(fs * c0.dx - 1) > 1e-5:
                raise UffError(f"sample rate {fs!r} Hz disagrees with the time increment {c0.dx!r} s", path=path,
                               dataset=58, line=c0.line + 7)
            meta = _json_meta(c0.tags)
            if trig is None:
                r = -c0.x0 * fs
                trig = int(round(r)) if r > 0 else 0
                if abs(r - round(r)) > 1e-3 and r > 0:
                    log.warning("%s: hit %d starts at %g s, not a whole number of samples before the trigger",
                                path, hit, c0.x0)
                if r < 0:
                    meta.setdefault("t0", c0.x0)
            elif abs(-trig / fs - c0.x0) > 1e-5 * max(abs(c0.x0), 1.0 / fs):
                raise UffError(f"trigger index {trig} disagrees with the start time {c0.x0!r} s of record 7",
                               path=path, dataset=58, line=c0.line + 4)
            data = np.empty((len(chans), c0.n))
            dofs, roles, units, sens, ovl = [], [], [], [], []
            for k, f in enumerate(chans):
                role = f.tags.get("role")
                if role not in ("force", "response"):
                    role = "force" if f.axes[1].spec in (13, 9) else "response"
                label, spec = f.axes[1].units, f.axes[1].spec
                conv = _label_si(label)
                if conv is not None:                       # a recognised units label wins
                    fac, unit = conv
                elif label.strip().upper() in ("", "NONE"):  # SI or dataset 164 units by data type
                    unit = _SPEC_SI.get(spec, "N" if role == "force" else "m/s^2")
                    fac = 1.0 / ff if unit == "N" else (1.0 / lf if abs(f.rsp_dir) <= 3 else 1.0)
                else:
                    fac, unit = 1.0, label
                    log.warning("%s: unit %r of the record at line %d is not one modalab converts; "
                                "values kept as stored", path, label, f.line)
                data[k] = f.y * fac
                dofs.append(Dof(f.rsp_node, f.rsp_dir))
                roles.append(role)
                units.append(unit)
                try:
                    sens.append(float(f.tags.get("sens", 1.0)))
                    ovl.append(bool(int(f.tags.get("ovl", 0))))
                except ValueError:
                    raise UffError("sensitivity / overload tokens in ID line 2 are not numbers", path=path,
                                   dataset=58, line=f.line + 2) from None
            out.append(TimeRecord(sample_rate_hz=fs, data=data, dofs=dofs, roles=roles, units=units,
                                  sensitivity=sens, trigger_index=trig, overload=ovl, hit_id=hit, metadata=meta))
        return out


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


def _parse_nodes(b: Block) -> dict[int, tuple]:
    out = {}
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
    for node, xyz in out.items():
        if node < 0 or not np.all(np.isfinite(xyz)):
            raise b.error(f"node {node} has an invalid id or non-finite coordinates {xyz}")
    return out


def read_geometry(path) -> dict[int, tuple[float, float, float]]:
    """Node coordinates from datasets 2411 and 15: ``{node: (x, y, z)}``."""
    with _guard(path) as cur:
        blocks = _blocks(path, cur)
        out: dict = {}
        found = False
        for b in blocks:
            if b.number in (2411, 15):
                cur.block = b
                found = True
                nodes = _parse_nodes(b)
                clash = [n for n in nodes if n in out and out[n] != nodes[n]]
                if clash:
                    raise UffError(f"nodes {clash[:10]} are defined again with different coordinates; keep one "
                                   "definition per node", path=path, dataset=b.number, line=b.line)
                out.update(nodes)
        if not found:
            raise UffError("no node coordinates (dataset 2411 or 15) in the file", path=path)
        return out


# ----------------------------------------------------------------------------- units
def write_units(path, *, append: bool = False) -> None:
    """Write dataset 164 declaring SI units (m, N, K)."""
    text = ("    -1\n%6i%74s\n%10i%-20s%10i\n%25.16E%25.16E%25.16E\n%25.16E\n    -1\n"
            % (164, "", 1, "  SI - m, N, s, K", 2, 1.0, 1.0, 1.0, 273.15))
    with _open_out(path, append) as fh:
        fh.write(text.encode("latin-1"))


def _parse_164(b: Block) -> dict:
    if len(b.lines) < 2:
        raise b.error("dataset 164 needs a units code line and a factors line", len(b.lines))
    first = b.lines[0].ljust(40)
    code = parse_ints(first[:10], 1, "units code", b, 0)[0]
    desc = first[10:30].strip()
    vals = parse_floats(" ".join(b.lines[1:]))
    if vals.size < 3 or tokens_exact(" ".join(b.lines[1:])) is None:
        raise b.error("dataset 164 must hold length, force and temperature factors", 1)
    if np.any(~np.isfinite(vals[:3])) or np.any(vals[:3] == 0):
        raise b.error(f"unit factors {vals[:3].tolist()} must be finite and non-zero", 1)
    return {"code": code, "description": desc, "length": float(vals[0]), "force": float(vals[1]),
            "temperature": float(vals[2]), "temperature_offset": float(vals[3]) if vals.size > 3 else 0.0}


def read_units(path) -> dict | None:
    """The last dataset 164 of the file as a dict (factors divide file values to give SI), or None."""
    with _guard(path) as cur:
        res = None
        for b in _blocks(path, cur):
            if b.number == 164:
                cur.block = b
                res = _parse_164(b)
        return res


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
    ndv = 1 if axes == {0} else (6 if max(axes) > 3 else 3)
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
        sets, all55, coords = [], [], {}
        for b in _blocks(path, cur):
            if b.number in (2411, 15):
                cur.block = b
                coords.update(_parse_nodes(b))
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
            raise UffError("no mode shapes (dataset 55, analysis type 2, 3 or 7) in the file", path=path)
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
            r = s["reals"]
            if s["analysis"] == 2:
                if len(r) < 3:
                    raise UffError("normal-mode record 8 needs frequency, modal mass and damping", path=path,
                                   dataset=55, line=s["line"] + 8)
                f, mm[m], z = r[0], r[1], r[2]
            else:
                if len(r) < 2:
                    raise UffError("complex-mode record 8 needs the eigenvalue", path=path, dataset=55,
                                   line=s["line"] + 8)
                lam = complex(r[0], r[1])
                w = abs(lam)
                f, z = w / (2 * np.pi), (-lam.real / w if w > 0 else 0.0)
            t = s["tags"]
            try:
                if "f" in t and "z" in t:
                    ef, ez = float(t["f"]), float(t["z"])
                    if abs(ef - f) <= 1e-5 * max(abs(ef), 1e-300) + 1e-12 and abs(ez - z) <= 1e-5 + 1e-5 * abs(ez):
                        f, z = ef, ez
                    else:
                        log.warning("%s: mode at line %d: ID line f=%s z=%s disagrees with record 8; using record 8",
                                    path, s["line"], t["f"], t["z"])
            except ValueError:
                pass
            freq[m], damp[m] = f, z
            if "scaling" in t and t["scaling"] in ("unit_modal_mass", "unit_max", "arbitrary"):
                scaling = t["scaling"]
        if not np.all(np.isfinite(freq)) or not np.all(np.isfinite(damp)):
            raise UffError("mode frequencies or damping are not finite", path=path, dataset=55)
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
        ms = ModeSet(freq_hz=freq, damping=damp, shapes=shapes if labels else None, dofs=labels, scaling=scaling,
                     indicators=indicators, metadata={"source": str(path)}, coordinates=coords)
        if dofs is not None:
            ms = ms.select_dofs(dofs)
        return ms


# ----------------------------------------------------------------------------- info
def info(path) -> dict:
    """What a universal file holds, for ``modalab info``.

    Returns ``{'path', 'datasets': {'58b': n, '2411': n, ...}, 'functions': {'FRF': n, ...},
    'responses': [...], 'references': [...], 'hits': n, 'frequency_range_hz': (lo, hi) | None,
    'time_range_s': (lo, hi) | None, 'sample_rate_hz': float | None, 'units': {...} (dataset 164) | None,
    'unit_labels': [...] (ordinate/denominator unit labels of the 58 sets), 'quantity': str | None,
    'nodes': n, 'modes': n}``.  Reads only the headers of 58/58b sets, so it is fast on large files.
    """
    with _guard(path) as cur:
        blocks = _blocks(path, cur)
        counts = Counter(b.label for b in blocks)
        funcs = Counter()
        resp, ref = {}, {}
        hits = set()
        frange = trange = None
        fs = None
        units = None
        qty = None
        nodes: set = set()
        n_modes = 0
        unit_labels = set()
        for b in blocks:
            cur.block = b
            if b.number == 58:
                fn = parse_58(b, header_only=True)
                funcs[FUNC_TYPES.get(fn.func_type, f"type {fn.func_type}")] += 1
                resp.setdefault((fn.rsp_node, fn.rsp_dir), None)
                if fn.ref_node or fn.ref_dir:
                    ref.setdefault((fn.ref_node, fn.ref_dir), None)
                lo = fn.x0 if fn.even else None
                hi = fn.x0 + (fn.n - 1) * fn.dx if fn.even else None
                if not fn.even:
                    full = parse_58(b)
                    lo, hi = float(full.x[0]), float(full.x[-1])
                if fn.func_type == 1:
                    hits.add(fn.load_case)
                    trange = (lo, hi) if trange is None else (min(trange[0], lo), max(trange[1], hi))
                    if fn.even and fn.dx > 0:
                        fs = float(fn.tags["fs"]) if "fs" in fn.tags else 1.0 / fn.dx
                else:
                    frange = (lo, hi) if frange is None else (min(frange[0], lo), max(frange[1], hi))
                    if fn.func_type == 4:
                        qty = qty or _TYPE_QTY.get(fn.axes[1].spec)
                for a in fn.axes[1:3]:
                    if a.units.upper() != "NONE":
                        unit_labels.add(a.units)
            elif b.number in (2411, 15):
                nodes.update(_parse_nodes(b))
            elif b.number == 55:
                s = _parse_55(b)
                if s["analysis"] in (2, 3, 7):
                    n_modes += 1
            elif b.number == 164:
                units = _parse_164(b)
        return {"path": str(path), "datasets": dict(counts), "functions": dict(funcs),
                "responses": [str(Dof(n, d)) for n, d in resp], "references": [str(Dof(n, d)) for n, d in ref],
                "hits": len(hits), "frequency_range_hz": frange, "time_range_s": trange, "sample_rate_hz": fs,
                "units": units, "unit_labels": sorted(unit_labels), "quantity": qty, "nodes": len(nodes),
                "modes": n_modes}
