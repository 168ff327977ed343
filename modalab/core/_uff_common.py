"""UFF I/O internals shared by every dataset: constants, file access, JSON ID lines, unit labels, units (164).

Part of :mod:`modalab.core.uff` (the public interface and the layout of the datasets are described there).
"""
from __future__ import annotations

import json
import logging
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ._output import atomic_path, check_not_input
from ._uff_core import Block, Fn58, parse_floats, parse_ints, scan, tokens_exact
from .errors import DofError, ModalabError, UffError
from .units import G

log = logging.getLogger("modalab.core.uff")


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


_META_KEYS = ("backend", "estimator", "n_averages", "exp_window_beta", "force_window")


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
