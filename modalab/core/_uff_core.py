"""Low-level universal-file machinery: block scanner, number parsing, dataset 58/58b codec.

Private to :mod:`modalab.core.uff`.  The scanner splits a file into datasets
without guessing: ASCII datasets end at the next ``-1`` line, binary 58b
datasets are skipped by their byte count (computed from record 7, with the
header's byte count as a fallback for writers that get it wrong), so a
``    -1`` pattern inside binary data cannot cut a dataset short.  Every
problem raises :class:`modalab.core.errors.UffError` naming the file, the dataset
and the line.
"""
from __future__ import annotations

import datetime as _dt
import logging
import os
import re
import warnings
from dataclasses import dataclass, field

import numpy as np

from .errors import UffError

log = logging.getLogger(__name__)

_FLOAT_RE = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[EeDd][-+]?\d+)?|[-+]?(?:nan|inf(?:inity)?)", re.IGNORECASE)
_END_RE = re.compile(rb"\n[ \t]*-1[ \t]*\r?(?=\n|\Z)")   # a '-1' line (6x faster than ^...$ with MULTILINE)
_ID_RE = re.compile(rb"^\s*(\d+)\s*([bB]?)(.*)$")

#: values per abscissa point in the data section, by (complex, uneven)
_VALS_PER_POINT = {(False, False): 1, (False, True): 2, (True, False): 2, (True, True): 3}


# ----------------------------------------------------------------------------- blocks
class Block:
    """One dataset of a universal file.

    ``line`` is the 1-based line of the dataset-number line; ``lines`` the text lines after
    it (ASCII datasets: all of them, split lazily; 58b: the ASCII header); ``payload`` the
    binary data of a 58b dataset.
    """

    def __init__(self, number: int, binary: bool, line: int, lines=None, *, text: str | None = None,
                 payload=None, byte_order: str = "<", path=None):
        self.number, self.binary, self.line = number, binary, line
        self._lines, self.text = lines, text
        self.payload, self.byte_order, self.path = payload, byte_order, path

    @property
    def lines(self) -> list:
        if self._lines is None:
            t = self.text[:-1] if self.text.endswith("\n") else self.text
            self._lines = [ln.rstrip("\r") for ln in t.split("\n")] if t else []
        return self._lines

    def head(self, k: int) -> tuple[list, str]:
        """First ``k`` lines (as :attr:`lines` splits them) and the rest as one string, without a full split."""
        if self.text is None:
            return self.lines[:k], ""
        cached = getattr(self, "_head", None)
        if cached is None or cached[0] != k:
            t = self.text[:-1] if self.text.endswith("\n") else self.text
            parts = t.split("\n", k) if t else []
            cached = (k, [ln.rstrip("\r") for ln in parts[:k]], parts[k] if len(parts) > k else "")
            self._head = cached
        return cached[1], cached[2]

    @property
    def hdr(self) -> list:
        """The 11 header records of a dataset 58 (fewer when truncated)."""
        return self.head(11)[0]

    def error(self, message: str, offset: int | None = None) -> UffError:
        """UffError located at header line ``offset`` (0 = first line after the dataset number)."""
        line = self.line if offset is None else self.line + 1 + offset
        return UffError(message, path=self.path, dataset=self.label, line=line)

    @property
    def label(self) -> str:
        return f"{self.number}{'b' if self.binary else ''}"


def _decode(b: bytes) -> str:
    return b.decode("latin-1")


def scan(raw: bytes, path) -> list[Block]:
    """Split the file content into :class:`Block` objects (no dataset parsing except 58b lengths)."""
    blocks: list[Block] = []
    n = len(raw)
    pos = 0
    counted, lines_before = 0, 0   # newlines in raw[:counted] (incremental: linear in the file size)
    while True:
        # skip blank lines between datasets
        while pos < n:
            eol = raw.find(b"\n", pos)
            end = n if eol < 0 else eol
            if raw[pos:end].strip():
                break
            pos = end + 1
        if pos >= n:
            break
        lines_before += raw.count(b"\n", counted, pos)
        counted = pos
        line_no = lines_before + 1
        eol = raw.find(b"\n", pos)
        end = n if eol < 0 else eol
        first = raw[pos:end]
        if first.strip() != b"-1":
            head = first[:40]
            if any(c < 9 or 13 < c < 32 or c > 126 for c in head):
                raise UffError("expected the '    -1' line that opens a dataset, found binary data: the file is not "
                               "a universal file" + ("" if not blocks else " or an earlier dataset is corrupt"),
                               path=path, line=line_no)
            raise UffError(f"expected the '    -1' line that opens a dataset, found {_decode(head).strip()!r}. "
                           "The file is not a universal file or an earlier dataset is corrupt",
                           path=path, line=line_no)
        if eol < 0:
            raise UffError("the file ends right after a '    -1' line: it is truncated", path=path, line=line_no)
        pos = eol + 1
        eol = raw.find(b"\n", pos)
        id_line = raw[pos:(n if eol < 0 else eol)].rstrip(b"\r")
        m = _ID_RE.match(id_line)
        if not m:
            raise UffError(f"the dataset-number line {_decode(id_line[:40])!r} does not start with a dataset number",
                           path=path, line=line_no + 1)
        number, is_bin = int(m.group(1)), bool(m.group(2))
        if eol < 0:
            raise UffError(f"dataset {number} is truncated after its number line", path=path,
                           dataset=number, line=line_no + 1)
        pos = eol + 1
        if is_bin:
            block, pos = _scan_binary(raw, pos, number, m.group(3), path, line_no + 1)
        else:
            mend = _END_RE.search(raw, pos - 1)          # raw[pos - 1] is the newline ending the number line
            if mend is None:
                raise UffError(f"dataset {number} opened at line {line_no} is not closed by a '    -1' line: "
                               "the file is truncated", path=path, dataset=number, line=line_no)
            text = _decode(raw[pos:mend.start() + 1])
            block = Block(number, False, line_no + 1, text=text, path=path)
            pos = mend.end()
            if raw[pos:pos + 1] == b"\n":
                pos += 1
        blocks.append(block)
    if not blocks:
        raise UffError("the file holds no datasets (it is empty or blank); expected '    -1' / dataset number "
                       "/ ... / '    -1' blocks", path=path, line=1)
    return blocks


def _scan_binary(raw: bytes, pos: int, number: int, rest: bytes, path, id_line_no: int):
    toks = rest.split()
    try:
        bo, fp, n_ascii, n_bytes = (int(t) for t in toks[:4])
    except ValueError:
        raise UffError(f"binary dataset header {_decode(rest).strip()!r} is not four integers "
                       "(byte order, floating-point format, ASCII lines, bytes)",
                       path=path, dataset=f"{number}b", line=id_line_no) from None
    if len(toks) < 4:
        raise UffError("binary dataset header lacks byte order, format, line and byte counts",
                       path=path, dataset=f"{number}b", line=id_line_no)
    if bo not in (1, 2):
        raise UffError(f"byte-ordering code {bo} unknown; expected 1 (little endian) or 2 (big endian)",
                       path=path, dataset=f"{number}b", line=id_line_no)
    if fp != 2:
        raise UffError(f"floating-point format {fp} is not supported; only IEEE 754 (2) is. "
                       "Re-export the file with IEEE floats or as ASCII", path=path, dataset=f"{number}b",
                       line=id_line_no)
    if n_ascii < 0 or n_ascii > 1000 or n_bytes < 0:
        raise UffError(f"binary dataset header counts {n_ascii} lines / {n_bytes} bytes are impossible",
                       path=path, dataset=f"{number}b", line=id_line_no)
    lines = []
    n = len(raw)
    for k in range(n_ascii):
        eol = raw.find(b"\n", pos)
        if eol < 0:
            raise UffError(f"header of binary dataset {number}b ends after {k} of {n_ascii} lines: "
                           "the file is truncated", path=path, dataset=f"{number}b", line=id_line_no + k + 1)
        lines.append(_decode(raw[pos:eol].rstrip(b"\r")))
        pos = eol + 1
    block = Block(number, True, id_line_no, lines, byte_order="<" if bo == 1 else ">", path=path)
    candidates = []
    if number == 58:
        computed = _binary_length_58(block)
        candidates.append(computed)
    if n_bytes not in candidates:
        candidates.append(n_bytes)
    for length in candidates:
        end = pos + length
        if end > n:
            continue
        after = end
        # tolerate a line break between the data and the closing -1
        for sep in (b"\r\n", b"\n", b"\r"):
            if raw.startswith(sep, after):
                after += len(sep)
                break
        eol = raw.find(b"\n", after)
        closing = raw[after:(n if eol < 0 else eol)]
        if closing.strip() == b"-1":
            if length != n_bytes:
                log.debug("%s: dataset %sb at line %d declares %d bytes but holds %d (writer bug); using %d",
                          path, number, id_line_no, n_bytes, length, length)
            block.payload = memoryview(raw)[pos:end]
            return block, (n if eol < 0 else eol + 1)
    exp = candidates[0]
    have = n - pos
    if have < exp:
        raise UffError(f"binary data holds {have} bytes but the header calls for {exp}: the file is truncated",
                       path=path, dataset=f"{number}b", line=id_line_no)
    raise UffError(f"no closing '    -1' after the {exp} bytes of binary data the header calls for "
                   f"(header byte count {n_bytes}); the point count or data type in record 7 is wrong "
                   "or the data is corrupt", path=path, dataset=f"{number}b", line=id_line_no)


# ----------------------------------------------------------------------------- numbers
def parse_floats(text: str) -> np.ndarray:
    """All numbers in ``text`` (Fortran D exponents and touching fixed-width fields allowed)."""
    s = text.replace("D", "E").replace("d", "E") if ("D" in text or "d" in text) else text
    if not s.strip():
        return np.zeros(0)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")            # numpy warns (and stops) at the first bad token
            return np.fromstring(s, dtype=float, sep=" ")
    except (ValueError, DeprecationWarning):
        toks = _FLOAT_RE.findall(s)
        return np.array(toks, dtype=float) if toks else np.zeros(0)


def tokens_exact(text: str) -> list[str] | None:
    """Number tokens of ``text``, or None when something that is not a number is in it."""
    s = text.replace("D", "E").replace("d", "E")
    toks = _FLOAT_RE.findall(s)
    if _FLOAT_RE.sub("", s).strip():
        return None
    return toks


def parse_ints(text: str, count: int, what: str, block: Block, offset: int, minimum: int | None = None) -> list[int]:
    toks = tokens_exact(text)
    need = count if minimum is None else minimum
    if toks is None or len(toks) < need:
        raise block.error(f"{what}: expected {need} integers, found {text.strip()!r}", offset)
    out = []
    for t in toks[:count]:
        v = float(t)
        if not np.isfinite(v) or v != int(v):
            raise block.error(f"{what}: {t!r} is not an integer", offset)
        out.append(int(v))
    return out


def e13(v: float) -> str:
    """A 13-character E field with a leading blank and as many digits as fit (7 for positive values)."""
    for fmt in ("%13.6E", "%13.5E", "%13.4E", "%13.3E"):
        s = fmt % v
        if len(s) == 13 and s[0] == " ":
            return s
    return "%13.2E" % v


def parse_tags(lines) -> dict[str, str]:
    """``key=value`` tokens of ID lines that start with ``modalab`` (see :mod:`modalab.core.uff`)."""
    tags: dict[str, str] = {}
    for ln in lines:
        s = ln.strip()
        at = s.find("modalab ") if not s.startswith("modalab") else 0
        if at < 0:
            continue
        for tok in s[at + len("modalab"):].split():
            if "=" in tok:
                k, v = tok.split("=", 1)
                if k.endswith("+"):
                    tags[k[:-1]] = tags.get(k[:-1], "") + v
                else:
                    tags[k] = v
    return tags


def check_groups(items, path, what: str, kind: str) -> None:
    """Every write call tags its sets ``w=<id><kind> ns=<count>``; all of them must be present and intact.

    ``items``: (tags, line, relevant) for every dataset of the type read (58 or 55);
    ``relevant`` says whether the dataset is of the function the reader wants.  Groups of
    ``kind`` ('f' FRF/coherence, 'r' time records, 'm' modes) must consist of exactly ``ns``
    relevant datasets.  Catches datasets lost to a corrupted dataset number, delimiter or
    function type, which would otherwise vanish silently.
    """
    groups: dict[str, list] = {}
    for tags, line, relevant in items:
        w = tags.get("w", "")
        if w.endswith(kind):
            groups.setdefault(w, []).append((tags.get("ns"), line, relevant))
    for w, members in groups.items():
        bad = [ln for _, ln, rel in members if not rel]
        if bad:
            raise UffError(f"the dataset at line {bad[0]} belongs to a {what} write ({w}) but its function or "
                           "analysis type says otherwise: the file is corrupt or was edited",
                           path=path, line=bad[0])
        try:
            ns = {int(v) for v, _, _ in members}
        except (TypeError, ValueError):
            raise UffError(f"set count tag ns={members[0][0]!r} in ID line 3 is not an integer", path=path,
                           line=members[0][1] + 4) from None
        if len(ns) != 1 or ns.pop() != len(members):
            raise UffError(f"{len(members)} {what} datasets of write {w} found but the writer wrote "
                           f"{members[0][0]}; datasets were lost, truncated or mislabelled (first at line "
                           f"{members[0][1]})", path=path, line=members[0][1])


def id_line(text: str, what: str = "ID line") -> str:
    s = str(text)
    if "\n" in s or "\r" in s or len(s) > 80:
        raise UffError(f"{what} {s!r} must be one line of at most 80 characters")
    return s if s.strip() else "NONE"


def date_line(n_sets: int | None = None, kind: str = "") -> str:
    """ID line 3: date and time; with ``n_sets`` also ``modalab w=<write id><kind> ns=<sets written together>``."""
    now = _dt.datetime.now()
    if n_sets is not None:
        return f"{date_line()} modalab w={os.urandom(4).hex()}{kind} ns={n_sets}"
    months = ["JAN", "FEB", "MAR", "APR", "MAY", "JUN", "JUL", "AUG", "SEP", "OCT", "NOV", "DEC"]
    return f"{now.day:02d}-{months[now.month - 1]}-{now.year % 100:02d} {now:%H:%M:%S}"


# ----------------------------------------------------------------------------- dataset 58
@dataclass
class Axis:
    spec: int = 0
    len_exp: int = 0
    force_exp: int = 0
    temp_exp: int = 0
    label: str = "NONE"
    units: str = "NONE"


@dataclass
class Fn58:
    """One dataset 58/58b function, header fields by name."""

    ids: list
    func_type: int
    func_id: int
    ver_num: int
    load_case: int
    rsp_name: str
    rsp_node: int
    rsp_dir: int
    ref_name: str
    ref_node: int
    ref_dir: int
    ord_type: int
    n: int
    even: bool
    x0: float
    dx: float
    z: float
    axes: list                      # abscissa, ordinate numerator, ordinate denominator, z axis
    line: int = 0
    binary: bool = False
    tags: dict = field(default_factory=dict)
    x: np.ndarray | None = None
    y: np.ndarray | None = None

    @property
    def is_complex(self) -> bool:
        return self.ord_type in (5, 6)


def _binary_length_58(block: Block) -> int:
    """Bytes of data a 58b block must hold according to its record 7."""
    if len(block.hdr) < 7:
        raise block.error(f"binary dataset header has {len(block.hdr)} lines; record 7 is missing")
    ord_type, n, spacing = _record7(block)[:3]
    size = 4 if ord_type in (2, 5) else 8
    return n * size * _VALS_PER_POINT[(ord_type in (5, 6), spacing == 0)]


def _record7(block: Block):
    text = block.hdr[6]
    toks = tokens_exact(text)
    if toks is None or len(toks) < 5:
        raise block.error(f"record 7 (data form) {text.strip()!r} must hold data type, number of points, "
                          "spacing, abscissa minimum and increment", 6)
    vals = [float(t) for t in toks[:6]]
    for k in range(3):
        if not np.isfinite(vals[k]) or vals[k] != int(vals[k]):
            raise block.error(f"record 7 field {k + 1} {toks[k]!r} is not an integer", 6)
    ord_type, n, spacing = int(vals[0]), int(vals[1]), int(vals[2])
    if ord_type not in (2, 4, 5, 6):
        raise block.error(f"ordinate data type {ord_type} unknown; expected 2, 4 (real) or 5, 6 (complex)", 6)
    if n < 1 or n > 2 ** 31:
        raise block.error(f"number of data points {n} is impossible", 6)
    if spacing not in (0, 1):
        raise block.error(f"abscissa spacing {spacing}; expected 0 (uneven) or 1 (even)", 6)
    x0, dx = vals[3], vals[4]
    z = vals[5] if len(vals) > 5 else 0.0
    if not (np.isfinite(x0) and np.isfinite(dx)):
        raise block.error(f"abscissa minimum/increment {x0}/{dx} are not finite", 6)
    return ord_type, n, spacing, x0, dx, z


def _record6(block: Block):
    text = block.hdr[5]
    toks = text.split()
    if len(toks) == 10:
        try:
            v = [int(toks[i]) for i in (0, 1, 2, 3, 5, 6, 8, 9)]
            return v[0], v[1], v[2], v[3], toks[4], v[4], v[5], toks[7], v[6], v[7]
        except ValueError:
            pass
    padded = text.ljust(80)
    try:
        ints = [int(padded[a:b]) for a, b in ((0, 5), (5, 15), (15, 20), (20, 30), (41, 51), (51, 55),
                                              (66, 76), (76, 80))]
        return (ints[0], ints[1], ints[2], ints[3], padded[31:41].strip(), ints[4], ints[5],
                padded[56:66].strip(), ints[6], ints[7])
    except ValueError:
        pass
    if len(toks) == 8:
        try:
            v = [int(t) for t in toks]
            return v[0], v[1], v[2], v[3], "NONE", v[4], v[5], "NONE", v[6], v[7]
        except ValueError:
            pass
    raise block.error(f"record 6 (DOF identification) {text.strip()!r} cannot be read; expected function type, "
                      "function id, version, load case, response name/node/direction, "
                      "reference name/node/direction", 5)


def _axis(block: Block, k: int) -> Axis:
    text = block.hdr[k]
    padded = text.ljust(80)
    try:
        spec = int(padded[0:10])
        exps = []
        for a, b in ((10, 15), (15, 20), (20, 25)):
            s = padded[a:b].strip()
            exps.append(int(s) if s else 0)
        label, units = padded[26:46].strip(), padded[47:67].strip()
        return Axis(spec, *exps, label or "NONE", units or "NONE")
    except ValueError:
        pass
    toks = text.split()
    try:
        spec = int(toks[0])
        exps = [int(t) for t in toks[1:4]] + [0] * (3 - len(toks[1:4]))
        rest = toks[4:]
        return Axis(spec, *exps, rest[0] if rest else "NONE", rest[1] if len(rest) > 1 else "NONE")
    except (ValueError, IndexError):
        raise block.error(f"record {k + 2} (data characteristics) {text.strip()!r} must start with the specific "
                          "data type and three unit exponents", k) from None


def parse_58(block: Block, header_only: bool = False, header: Fn58 | None = None) -> Fn58:
    """Decode one dataset 58/58b block (``header``: its already decoded header, to skip re-parsing)."""
    if header is None:
        header = _parse_58_header(block)
    if header_only:
        return header
    return _parse_58_data(block, header)


def _parse_58_header(block: Block) -> Fn58:
    if len(block.hdr) < 11:
        raise block.error(f"dataset 58 needs 11 header records after the dataset number; found {len(block.hdr)}. "
                          "The dataset is truncated", len(block.hdr))
    ids = [block.hdr[k].rstrip() for k in range(5)]
    r6 = _record6(block)
    ord_type, n, spacing, x0, dx, z = _record7(block)
    axes = [_axis(block, k) for k in range(7, 11)]
    if r6[8] <= 0:
        # a zero or negative reference node (-1 in several exporters) means "no reference"
        r6 = r6[:8] + (0, 0)
    for name, d in (("response", r6[6]), ("reference", r6[9])):
        if d < -6 or d > 6:
            raise block.error(f"{name} direction {d} is outside -6..6", 5)
    if r6[5] < 0:
        raise block.error(f"response node {r6[5]} is negative; expected a node id >= 0", 5)
    fn = Fn58(ids, *r6, ord_type, n, spacing == 1, x0, dx, z, axes, line=block.line, binary=block.binary,
              tags=parse_tags(ids))
    # exact abscissa written by modalab (record 7 holds it to 6-7 digits only)
    if fn.even and "x0" in fn.tags and "dx" in fn.tags:
        try:
            ex0, edx = float(fn.tags["x0"]), float(fn.tags["dx"])
        except ValueError:
            ex0 = edx = np.nan
        scale = max(abs(edx), 1e-300)
        if (np.isfinite(ex0) and np.isfinite(edx) and abs(ex0 - x0) <= 1e-5 * max(abs(ex0), scale)
                and abs(edx - dx) <= 1e-5 * scale):
            fn.x0, fn.dx = ex0, edx
        else:
            log.warning("%s: dataset 58 at line %d: ID line abscissa x0=%s dx=%s disagrees with record 7 "
                        "(%g, %g); using record 7", block.path, block.line, fn.tags.get("x0"), fn.tags.get("dx"),
                        x0, dx)
    return fn


def _parse_58_data(block: Block, head: Fn58) -> Fn58:
    fn = Fn58(**{k: getattr(head, k) for k in head.__dataclass_fields__})
    n, ord_type = fn.n, fn.ord_type
    k = _VALS_PER_POINT[(fn.is_complex, not fn.even)]
    need = n * k
    if block.binary:
        dt = np.dtype(block.byte_order + ("f4" if ord_type in (2, 5) else "f8"))
        if len(block.payload) != need * dt.itemsize:
            raise block.error(f"binary data holds {len(block.payload)} bytes; record 7 calls for "
                              f"{need * dt.itemsize}", 6)
        values = np.frombuffer(block.payload, dtype=dt).astype(float)
    else:
        body = block.head(11)[1]
        values = parse_floats(body)
        if values.size != need:
            raise block.error(_count_message(block, values.size, need, n), 11)
    if fn.even:
        fn.x = fn.x0 + np.arange(n) * fn.dx
        fn.y = np.ascontiguousarray(values).view(np.complex128) if fn.is_complex else values
    else:
        fn.x = values[0::k].copy()
        fn.y = values[1::3] + 1j * values[2::3] if fn.is_complex else values[1::2].copy()
    return fn


def _count_message(block: Block, found: int, need: int, n: int) -> str:
    bad = None
    for i, ln in enumerate(block.lines[11:]):
        if tokens_exact(ln) is None:
            bad = (i, ln)
            break
    if bad is not None:
        return (f"data line {bad[1].strip()[:60]!r} (line {block.line + 12 + bad[0]}) is not numeric; "
                "the data section is corrupt")
    return (f"found {found} numbers in the data section but record 7 calls for {need} ({n} points); "
            "the dataset is truncated or its point count is wrong")


def format_58(*, binary: bool, ids, func_type: int, func_id: int, load_case: int, rsp_node: int, rsp_dir: int,
              ref_node: int, ref_dir: int, x, y, even: bool, x0: float, dx: float, axes) -> bytes:
    """One dataset 58 (ASCII) or 58b (little-endian IEEE double) as bytes; y real or complex."""
    y = np.asarray(y)
    is_c = np.iscomplexobj(y)
    n = y.shape[0]
    ord_type = 6 if is_c else 4
    if even:
        vals = np.empty(2 * n) if is_c else np.asarray(y, dtype=float)
        if is_c:
            vals[0::2], vals[1::2] = y.real, y.imag
    else:
        k = 3 if is_c else 2
        vals = np.empty(k * n)
        vals[0::k] = x
        if is_c:
            vals[1::3], vals[2::3] = y.real, y.imag
        else:
            vals[1::2] = y
    head = ["    -1"]
    if binary:
        nbytes = vals.size * 8
        head.append("%6i%1s%6i%6i%12i%12i%6i%6i%12i%12i" % (58, "b", 1, 2, 11, nbytes, 0, 0, 0, 0))
    else:
        head.append("%6i%74s" % (58, ""))
    head += ["%-80s" % id_line(s) for s in ids]
    head.append("%5i%10i%5i%10i %-10s%10i%4i %-10s%10i%4i" % (func_type, func_id, 0, load_case, "NONE", rsp_node,
                                                               rsp_dir, "NONE", ref_node, ref_dir))
    head.append("%10i%10i%10i%s%s%s" % (ord_type, n, 1 if even else 0, e13(x0 if even else 0.0),
                                        e13(dx if even else 0.0), e13(0.0)))
    for a in axes:
        head.append("%10i%5i%5i%5i %-20s %-20s" % (a.spec, a.len_exp, a.force_exp, a.temp_exp,
                                                   a.label[:20], a.units[:20]))
    header = ("\n".join(head) + "\n").encode("latin-1")
    if binary:
        return header + np.ascontiguousarray(vals, dtype="<f8").tobytes() + b"    -1\n"
    return header + _ascii_values(vals, even, is_c).encode("latin-1") + b"    -1\n"


def _ascii_values(vals: np.ndarray, even: bool, is_c: bool) -> str:
    a = np.abs(vals[np.isfinite(vals)])
    wide_exp = bool(np.any((a >= 1e100) | ((a < 1e-99) & (a > 0))))
    f20 = "%20.11E" if wide_exp else "%20.12E"
    if even:
        per, fmt = 4, f20 * 4
    elif is_c:
        per, fmt = 3, "%13.5E" + f20 * 2
    else:
        per, fmt = 4, ("%13.5E" + f20) * 2
    nfull = vals.size // per
    out = ((fmt + "\n") * nfull) % tuple(vals[:nfull * per].tolist())
    rem = vals.size - nfull * per
    if rem:
        if even:
            rfmt = f20 * rem
        else:
            rfmt = ("%13.5E" + f20)  # real uneven: one pair left
        out += (rfmt + "\n") % tuple(vals[nfull * per:].tolist())
    return out
