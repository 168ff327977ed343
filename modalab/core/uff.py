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
    ID line 4  modalab fs=<sample rate, Hz> trig=<trigger index> [hp=<AC-coupling corner of the channel, Hz>]
               (hp when ``metadata['highpass_hz']`` gives the corners; read back into it)
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

import logging
import re
from collections import Counter

import numpy as np

from ._uff_common import FUNC_TYPES, _blocks, _even_axis, _guard, _parse_164, read_units, write_units
from ._uff_core import check_groups, parse_58
from ._uff_frf import assume_quantity, read_frf, write_frf
from ._uff_geometry import _parse_2420, _parse_nodes, read_frames, read_geometry, write_geometry
from ._uff_modes import _parse_55, read_modes, write_modes
from ._uff_records import read_records, write_records

log = logging.getLogger(__name__)

__all__ = ["write_frf", "read_frf", "write_records", "read_records", "write_geometry", "read_geometry",
           "write_modes", "read_modes", "write_units", "read_units", "read_frames", "assume_quantity", "info",
           "FUNC_TYPES"]


# ----------------------------------------------------------------------------- info
_HZ_RE = None


def _stated_hz(ids) -> tuple[float, float] | None:
    """A frequency an exporter wrote into the ID lines of a mode ("... 12.345 Hz" or "Freq 12.345") and the
    half-width of its last printed digit."""
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
        out["frf"] = _frf_info(path, quantity)
    if any(f.func_type == 1 for f in heads):
        out["hits"] = _hits_info(read_records(path))
    if modes55:
        out["modes"] = _modes_info(read_modes(path), [s for s in modes55 if s["analysis"] in (2, 3, 7)])
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


def _frf_info(path, quantity) -> dict:
    if quantity is not None:
        with assume_quantity(quantity):
            frf = read_frf(path)
    else:
        frf = read_frf(path)
    even = frf.n_freq > 1 and _even_axis(frf.freq_hz)[0]
    return {"responses": [str(d) for d in frf.responses], "references": [str(d) for d in frf.references],
            "quantity": frf.quantity, "units": frf.units, "lines": int(frf.n_freq),
            "freq_range_hz": [float(frf.freq_hz[0]), float(frf.freq_hz[-1])],
            "df_hz": float(frf.freq_hz[1] - frf.freq_hz[0]) if even else None,
            "coherence": frf.coherence is not None,
            "metadata": {k: v for k, v in frf.metadata.items() if k != "source"}}


def _hits_info(recs) -> dict:
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
    return {"hits": len(recs), "hammer_points": list(hammer), "hits_per_point": hammer,
            "responses": list(resp), "channels_per_hit": sorted({r.n_channels for r in recs}),
            "sample_rate_hz": sorted({float(r.sample_rate_hz) for r in recs}),
            "samples": sorted({int(r.n_samples) for r in recs}), "time_range_s": [t0, t1],
            "units": {k: sorted(v) for k, v in units.items()}}


def _modes_info(ms, sets) -> dict:
    """The mode table; for complex modes both frequencies and which one the exporter's header states."""
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
    return {"n_modes": ms.n_modes, "dofs": len(ms.dofs), "scaling": ms.scaling, "table": rows,
            "frequency": ("complex modes: freq_hz is the undamped natural frequency |lambda|/2pi; "
                          "freq_damped_hz = Im(lambda)/2pi") if any(r["complex"] for r in rows)
            else "normal modes: freq_hz as stored in record 8"}
