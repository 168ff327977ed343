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
A truncated or malformed file raises :class:`~modalab.core.errors.UffError` naming
the file, the dataset and the line.
"""
from __future__ import annotations

import contextvars
import json
import logging
import os
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
           "write_modes", "read_modes", "write_units", "read_units", "read_frames", "assume_quantity", "info",
           "FUNC_TYPES"]

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
    """Write to a temporary file then replace ``path`` (append: write in place).

    The file gets the user's umask permissions and is never a protected input (:mod:`modalab.core._output`).
    """
    from ._output import atomic_path, check_not_input

    path = Path(path)
    if append:
        check_not_input(path)
        try:
            fh = open(path, "ab")
        except OSError as exc:
            raise UffError(f"cannot write the file ({exc.strerror or exc}); check that the folder exists and is "
                           "writable", path=path) from None
        with fh:
            yield fh
        return
    if not path.parent.is_dir():
        raise UffError("cannot write the file: its folder does not exist", path=path)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        yield fh


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
        cohs = [f for f in fns if f.func_type == 6]
        if not frfs:
            kinds = Counter(FUNC_TYPES.get(f.func_type, str(f.func_type)) for f in
                            _functions(blocks, cur, range(100), header_only=True))
            hint = (" (raw hits: make FRFs of them with 'modalab frf', or uff.read_records in Python)"
                    if "time response" in kinds else "")
            held = ", ".join(f"{v} {k}" for k, v in kinds.items()) or "no dataset 58"
            raise UffError(f"no FRFs (dataset 58, function type 4) in the file; it holds {held}{hint}", path=path)
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
            if f.ref_node == 0 and f.ref_dir == 0:
                raise UffError(f"FRF {Dof(f.rsp_node, f.rsp_dir)} has no reference DOF (reference node 0 or "
                               "negative): an FRF needs the excitation DOF", path=path, dataset=58, line=f.line + 6)
            q = _TYPE_QTY.get(f.axes[1].spec) or _quantity_from_labels(f)
            assumed = _assumed_quantity()
            if quantity is None and assumed is not None and q is not None and q != assumed:
                raise UffError(f"the FRFs are {q} (record 9 of the set at line {f.line}) but --quantity says "
                               f"{assumed}; drop --quantity or convert the FRFs", path=path, dataset=58,
                               line=f.line + 9)
            if quantity is None:
                q = q or assumed
                if q is None:
                    raise UffError(f"ordinate data type {f.axes[1].spec} (record 9, units "
                                   f"{f.axes[1].units!r}) is not displacement (8), velocity (11) or acceleration "
                                   "(12); say what the FRFs are: on the command line --quantity accelerance (or "
                                   "mobility, receptance), in Python read_frf(..., quantity='accelerance')",
                                   path=path, dataset=58, line=f.line + 9)
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
        beta = meta.pop("exp_window_beta", None)
        full_r = [rows[k] for k in rkeys]
        full_c = [cols[k] for k in ckeys]
        rot = _node_rotations(blocks, path, cur)
        if rot:
            done = _rotate_frf(H, coh, full_r, full_c, rot, path, seen)
            if done:
                meta["rotated_to_global"] = done
            missing = [(full_r[i], full_c[j]) for i, j in zip(*np.nonzero(seen == 0))]
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
                   quantity=qty, units=QUANTITY_UNITS[qty], metadata=meta,
                   window_beta_per_s=0.0 if beta is None else beta)


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
        rot = _node_rotations(blocks, path, cur)
        local = sorted({f.rsp_node for f in fns if f.rsp_node in rot})
        if local:
            raise UffError(f"channels at nodes {local[:10]} are measured in rotated displacement frames "
                           "(dataset 2420); modalab does not rotate raw time records. Export them in the global "
                           "frame", path=path, dataset=58)
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
        sets, all55 = [], []
        blocks = _blocks(path, cur)
        coords = _global_nodes(blocks, path, cur) or {}
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
        rot = _node_rotations(blocks, path, cur)
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
        rotated = [nd for nd in node_order if nd in rot]
        if rotated:
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
        meta = {"source": str(path)}
        if rotated:
            meta["rotated_to_global"] = rotated
        ms = ModeSet(freq_hz=freq, damping=damp, shapes=shapes if labels else None, dofs=labels, scaling=scaling,
                     indicators=indicators, metadata=meta, coordinates=coords)
        if dofs is not None:
            ms = ms.select_dofs(dofs)
        return ms


# ----------------------------------------------------------------------------- info
_HZ_RE = None


def _stated_hz(ids) -> tuple[float, float] | None:
    """A frequency an exporter wrote into the ID lines of a mode ("... 12.345 Hz" or "Freq 12.345") and the
    half-width of its last printed digit."""
    import re

    global _HZ_RE
    if _HZ_RE is None:
        _HZ_RE = re.compile(r"(?:freq\w*\s*[=:]?\s*([-+]?\d+\.?\d*(?:[eE][-+]?\d+)?))|"
                            r"(?:([-+]?\d+\.?\d*(?:[eE][-+]?\d+)?)\s*hz\b)", re.IGNORECASE)
    for ln in ids:
        if ln.strip().startswith("modalab") or "modalab f=" in ln:
            continue
        m = _HZ_RE.search(ln)
        if m:
            txt = m.group(1) or m.group(2)
            try:
                v = float(txt)
            except ValueError:
                return None
            mant = txt.lower().split("e")[0]
            decimals = len(mant.split(".")[1]) if "." in mant else 0
            exp = int(txt.lower().split("e")[1]) if "e" in txt.lower() else 0
            return v, 0.5 * 10.0 ** (exp - decimals)          # the value and its rounding half-width
    return None


def info(path, *, quantity: str | None = None) -> dict:
    """What a universal file holds, for ``modalab info``, validated by the readers themselves.

    Every dataset is decoded in full by the same parsers :func:`read_frf`, :func:`read_records`,
    :func:`read_modes`, :func:`read_geometry` and :func:`read_units` use, and the content is then read by
    those functions: a file they refuse is refused here with the same :class:`~modalab.core.errors.UffError`
    (truncated data, point counts, lost datasets...).  ``quantity``: what FRFs whose file does not state it
    are (see :func:`assume_quantity`).

    Returns a JSON-ready dict: ``path``, ``datasets`` (``{'58b': n, ...}``), ``functions`` (``{'FRF': n,
    ...}``) and, for what the file holds, ``frf`` (responses, references, quantity, units, lines, band,
    coherence, metadata), ``hits`` (hits, hammer points, response channels, sampling, units), ``modes``
    (frequencies, damping; for complex modes both the undamped ``|lambda|/2pi`` and the damped
    ``Im(lambda)/2pi`` frequency and which one the file's header states), ``nodes``, ``units``
    (dataset 164).
    """
    with _guard(path) as cur:
        blocks = _blocks(path, cur)
        counts = Counter(b.label for b in blocks)
        heads, others = [], []
        modes55 = []
        for b in blocks:
            cur.block = b
            if b.number == 58:
                fn = parse_58(b, header_only=True)
                parse_58(b, header=fn)                # the data too: counts and numbers are checked
                heads.append(fn)
            elif b.number in (2411, 15):
                _parse_nodes(b)
            elif b.number == 55:
                s55 = _parse_55(b)
                s55["line"] = b.line
                modes55.append(s55)
            elif b.number == 164:
                _parse_164(b)
            elif b.number == 2420:
                _parse_2420(b)
        cur.block = None
        check_groups([(f.tags, f.line, f.func_type in (4, 6)) for f in heads], path, "FRF/coherence", "f")
        check_groups([(f.tags, f.line, f.func_type == 1) for f in heads], path, "time record", "r")
        check_groups([(s["tags"], s["line"], s["analysis"] in (2, 3, 7)) for s in modes55], path, "mode", "m")
        funcs = Counter(FUNC_TYPES.get(f.func_type, f"type {f.func_type}") for f in heads)
        others = sorted({FUNC_TYPES.get(f.func_type, f"type {f.func_type}") for f in heads
                         if f.func_type not in (1, 4, 6)})
    out: dict = {"path": str(path), "datasets": dict(counts), "functions": dict(funcs)}
    if others:
        out["other_functions"] = others
    if any(f.func_type == 4 for f in heads):
        if quantity is not None:
            with assume_quantity(quantity):
                frf = read_frf(path)
        else:
            frf = read_frf(path)
        even = frf.n_freq > 1 and _even_axis(frf.freq_hz)[0]
        out["frf"] = {"responses": [str(d) for d in frf.responses], "references": [str(d) for d in frf.references],
                      "quantity": frf.quantity, "units": frf.units, "lines": int(frf.n_freq),
                      "freq_range_hz": [float(frf.freq_hz[0]), float(frf.freq_hz[-1])],
                      "df_hz": float(frf.freq_hz[1] - frf.freq_hz[0]) if even else None,
                      "coherence": frf.coherence is not None,
                      "metadata": {k: v for k, v in frf.metadata.items() if k != "source"}}
    if any(f.func_type == 1 for f in heads):
        recs = read_records(path)
        hammer: dict = {}
        resp: dict = {}
        units: dict = {}
        for r in recs:
            for d, role, u in zip(r.dofs, r.roles, r.units):
                (hammer if role == "force" else resp).setdefault(str(d), 0)
                units.setdefault(role, set()).add(str(u))
            for d in r.force_dofs[:1]:
                hammer[str(d)] = hammer.get(str(d), 0) + 1
        t0 = min(-r.trigger_index / r.sample_rate_hz for r in recs)
        t1 = max((r.n_samples - 1 - r.trigger_index) / r.sample_rate_hz for r in recs)
        out["hits"] = {"hits": len(recs), "hammer_points": list(hammer), "hits_per_point": hammer,
                       "responses": list(resp), "channels_per_hit": sorted({r.n_channels for r in recs}),
                       "sample_rate_hz": sorted({float(r.sample_rate_hz) for r in recs}),
                       "samples": sorted({int(r.n_samples) for r in recs}), "time_range_s": [t0, t1],
                       "units": {k: sorted(v) for k, v in units.items()}}
    if modes55:
        ms = read_modes(path)
        sets = [s for s in modes55 if s["analysis"] in (2, 3, 7)]
        rows = []
        for k, s in enumerate(sets):
            f, z = float(ms.freq_hz[k]), float(ms.damping[k])
            row = {"mode": k + 1, "freq_hz": f, "damping": z, "complex": s["analysis"] != 2}
            if s["analysis"] != 2:
                lam = complex(s["reals"][0], s["reals"][1])
                fd = abs(lam.imag) / (2 * np.pi)
                row.update(freq_undamped_hz=f, freq_damped_hz=fd)
                stated = _stated_hz(s["ids"])
                if stated is not None:
                    stated, half = stated
                    dd, du = abs(stated - fd), abs(stated - f)
                    tol = 1.01 * half + 1e-5 * abs(stated)   # the header's digits (and our E13.5 reading)
                    row["header_hz"] = stated
                    row["header_states"] = ("neither" if min(dd, du) > tol else
                                            "either (they agree to the header's digits)" if abs(f - fd) <= tol
                                            else "damped" if dd < du else "undamped")
            rows.append(row)
        out["modes"] = {"n_modes": ms.n_modes, "dofs": len(ms.dofs), "scaling": ms.scaling, "table": rows,
                        "frequency": ("complex modes: freq_hz is the undamped natural frequency |lambda|/2pi; "
                                      "freq_damped_hz = Im(lambda)/2pi") if any(r["complex"] for r in rows)
                        else "normal modes: freq_hz as stored in record 8"}
    if counts.get("2411") or counts.get("15"):
        geo = read_geometry(path)
        out["nodes"] = len(geo)
        frames = read_frames(path)
        if frames:
            out["coordinate_systems"] = {str(k): ("identity" if np.allclose(v["rotation"], np.eye(3)) else
                                                  "rotated") for k, v in frames.items()}
    if counts.get("164"):
        out["units"] = read_units(path)
    return out
