"""Nastran bulk-data fields: reading lines into cards and formatting values back.

Three formats, which may be mixed card by card in one deck (MSC/NX rules):

* **small field** — 10 fields of 8 columns: field 1 (cols 1–8) holds the card
  name or a continuation marker, fields 2–9 (cols 9–72) data, field 10
  (cols 73–80) an optional continuation marker;
* **large field** — the name ends in ``*`` (``GRID*``); a line holds four
  16-column data fields (cols 9–72) between an 8-column field 1 and an
  8-column field 10, so two lines carry the eight data fields of one small
  line; continuation lines start with ``*``;
* **free field** — fields separated by commas (any line containing a comma);
  ``GRID*,...`` lines carry four data fields, others eight; field 10 is a
  continuation marker.

Continuations: a line whose field 1 is blank, or starts with ``+`` (small) or
``*`` (large), continues the previous card (implicit continuation as
pyNastran writes it, explicit markers as Patran and Femap write them).  When
the parent line has a marker in field 10, a continuation must follow, and two
non-trivial markers must match (``+PB1`` … ``+PB1``).  Text after ``$`` is a
comment; tabs expand to 8-column stops.

Values: integers ``12``; reals need a decimal point or an exponent letter —
``1.``, ``.5``, ``1.-3`` (= 1e-3), ``.5+2`` (= 50), ``7.E3``, ``-1.2D-3``;
blank fields take the card's default.  Every problem raises
:class:`modalab.core.errors.BulkDataError` naming the card, the line and the file.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from modalab.core.errors import BulkDataError

__all__ = ["Line", "RawCard", "parse_int", "parse_real", "parse_value", "format_value", "format_real",
           "fits_exactly", "Verbatim", "group_cards", "card_lines", "REQUIRED", "BulkDataError"]

REQUIRED = object()  # sentinel: a field without default

_INT = re.compile(r"^[+-]?\d+$")
# mantissa with optional exponent (E/D with optional sign, or a bare sign)
_REAL = re.compile(r"^([+-]?(?:\d+\.\d*|\.\d+|\d+))(?:([ED])([+-]?\d+)|([+-]\d+))?$")
_NAME = re.compile(r"^[A-Z][A-Z0-9_]*\*?$")
_MAX_INT = 2 ** 31 - 1


class _FieldError(Exception):
    """Internal: a field could not be read (wrapped into BulkDataError with the card context)."""


def parse_int(text: str) -> int:
    """Parse an integer field; raise ValueError-like _FieldError when it is not one."""
    s = text.strip()
    if not _INT.match(s):
        raise _FieldError(f"{text.strip()!r} is not an integer")
    v = int(s)
    if abs(v) > _MAX_INT:
        raise _FieldError(f"integer {s} is out of Nastran's range (|i| <= {_MAX_INT})")
    return v


def parse_real(text: str) -> float:
    """Parse a Nastran real: ``1.``, ``.5``, ``1.-3``, ``.5+2``, ``7.E3``, ``-1.2D-3``.

    A decimal point or an E/D exponent is required (``5`` is an integer, not a real).
    """
    s = text.strip().upper()
    m = _REAL.match(s)
    if not m:
        raise _FieldError(f"{text.strip()!r} is not a real number")
    mant, letter, exp1, exp2 = m.groups()
    if "." not in mant and letter is None:
        raise _FieldError(f"{text.strip()!r} has no decimal point; write a real as e.g. {mant}. ")
    exp = exp1 if exp1 is not None else exp2
    try:
        v = float(mant + ("e" + exp if exp is not None else ""))
    except (ValueError, OverflowError):  # pragma: no cover - regex guarantees syntax
        raise _FieldError(f"{text.strip()!r} is not a real number") from None
    if not math.isfinite(v):
        raise _FieldError(f"{text.strip()!r} overflows a double")
    return v


def parse_value(text: str):
    """Integer, real, string (upper case) or None (blank) for a raw field."""
    s = text.strip()
    if not s:
        return None
    if _INT.match(s):
        return parse_int(s)
    try:
        return parse_real(s)
    except _FieldError:
        pass
    u = s.upper()
    if re.match(r"^[A-Z][A-Z0-9_.+\-]*$", u):
        return u
    raise _FieldError(f"{s!r} is neither a number nor a name")


# ----------------------------------------------------------------- lines, raw cards
@dataclass(frozen=True)
class Line:
    """One physical line with its 1-based number and file."""

    text: str
    lineno: int
    path: str | None = None


@dataclass
class RawCard:
    """A card as a list of field strings.

    ``fields[0]`` is the upper-case name (without ``*``); ``fields[i]`` (stripped text) for
    i ≥ 1 is the i-th data field of the small-field layout, continuation
    lines following on (``fields[9]`` is field 2 of the first continuation).
    ``comment`` holds the ``$`` lines written just before the card.
    """

    name: str
    fields: list
    line: int | None = None
    path: str | None = None
    comment: list = field(default_factory=list)
    large: bool = False
    free: bool = False

    # ----------------------------------------------------------- error helper
    def error(self, msg: str, index: int | None = None) -> BulkDataError:
        """A :class:`BulkDataError` naming this card, its line and (when given) the field."""
        text = msg
        if index is not None and index >= 1:
            k, n = (index - 1) // 8, (index - 1) % 8 + 2
            text = f"field {n}{f' of continuation line {k}' if k else ''}: {msg}"
        label = self.name
        if len(self.fields) > 1 and self.fields[1].strip():
            label = f"{self.name} {self.fields[1].strip()}"
        return BulkDataError(text, path=self.path, card=label, line=self.line)

    def raw(self, i: int) -> str:
        """Stripped text of field ``i`` ('' beyond the end)."""
        return self.fields[i] if i < len(self.fields) else ""

    def blank(self, i: int) -> bool:
        return not self.raw(i)

    def n_used(self) -> int:
        """Index of the last non-blank field plus one."""
        n = len(self.fields)
        while n > 1 and not self.fields[n - 1].strip():
            n -= 1
        return n

    # ------------------------------------------------------------- accessors
    def integer(self, i: int, what: str, default=REQUIRED):
        s = self.raw(i)
        if not s:
            if default is REQUIRED:
                raise self.error(f"{what} is required but blank; give an integer", i)
            return default
        try:
            return parse_int(s)
        except _FieldError as e:
            raise self.error(f"{what}: {e}; expected an integer", i) from None

    def real(self, i: int, what: str, default=REQUIRED):
        s = self.raw(i)
        if not s:
            if default is REQUIRED:
                raise self.error(f"{what} is required but blank; give a real number such as 1.0", i)
            return default
        try:
            return parse_real(s)
        except _FieldError as e:
            hint = " (reals need a decimal point: write 5. not 5)" if _INT.match(s) else ""
            raise self.error(f"{what}: {e}; expected a real number{hint}", i) from None

    def int_or_real(self, i: int, what: str, default=REQUIRED):
        s = self.raw(i)
        if not s:
            if default is REQUIRED:
                raise self.error(f"{what} is required but blank", i)
            return default
        if _INT.match(s):
            return self.integer(i, what)
        return self.real(i, what)

    def string(self, i: int, what: str, default=REQUIRED, choices=None):
        s = self.raw(i).upper()
        if not s:
            if default is REQUIRED:
                raise self.error(f"{what} is required but blank", i)
            return default
        if not re.match(r"^[A-Z][A-Z0-9_]*$", s):
            raise self.error(f"{what}: {s!r} is not a name (letters and digits, starting with a letter)", i)
        if choices is not None and s not in choices:
            raise self.error(f"{what}: {s!r}; expected one of {', '.join(choices)}", i)
        return s

    def value(self, i: int, what: str):
        """Any type (int, real, name) or None."""
        try:
            return parse_value(self.raw(i))
        except _FieldError as e:
            raise self.error(f"{what}: {e}", i) from None

    def components(self, i: int, what: str, default=REQUIRED, allow_zero=False) -> str:
        """Component digits ('123456' style), sorted, unique; '' when 0 is allowed and given."""
        s = self.raw(i)
        if not s:
            if default is REQUIRED:
                raise self.error(f"{what} is required but blank; give component digits such as 123", i)
            return default
        if allow_zero and s == "0":
            return ""
        if not re.match(r"^[1-6]+$", s) or len(set(s)) != len(s):
            raise self.error(f"{what}: {s!r}; expected distinct digits 1..6 such as 123456", i)
        return "".join(sorted(s))

    def check_length(self, n_max: int, what: str = "") -> None:
        """Raise when a field beyond ``n_max`` (index) is used: a wrong card length."""
        n = self.n_used()
        if n > n_max + 1:
            raise self.error(f"{self.name} takes at most {n_max} data fields{what}; field "
                             f"{n - 1} ({self.raw(n - 1)!r}) is beyond the end of the card. Remove it or "
                             "check the field widths", n - 1)


# ----------------------------------------------------------- splitting lines
def _fixed_field(text: str, a: int, b: int, raw: Line, what: str) -> str:
    s = text[a:b]
    t = s.strip()
    if " " in t:
        raise BulkDataError(f"{what} (columns {a + 1}-{b}) holds {s!r} with an embedded blank; fixed-format "
                            f"fields are {b - a} columns wide — a value probably straddles two fields. Align it "
                            "or use free format (commas)", path=raw.path, line=raw.lineno, card=None)
    return t


@dataclass
class _Head:
    kind: str          # 'card' or 'cont'
    name: str          # card name (upper, no '*') or the marker text
    large: bool
    free: bool
    data: list
    cont: str          # field-10 marker ('' when none)


def _split(line: Line) -> _Head:
    text = line.text
    if "," in text:
        parts = [p.strip() for p in text.split(",")]
        f1 = parts[0].upper()
        large = f1.startswith("*") or (f1.endswith("*") and not f1.startswith("+"))
        nd = 4 if large else 8
        data = parts[1:]
        cont = ""
        if len(data) > nd:
            cont = data[nd]
            if len(data) > nd + 1 and any(p for p in data[nd + 1:]):
                raise BulkDataError(f"free-field line has {len(data)} fields after the name; at most {nd} data "
                                    f"fields and a continuation marker fit on one line. Continue the card on a "
                                    "line starting with ',' or '+'", path=line.path, line=line.lineno,
                                    card=f1 or None)
            data = data[:nd]
        for p in data:
            if any(c.isspace() for c in p):      # a blank or a tab: Nastran permits no embedded blanks
                raise BulkDataError(f"free field {p!r} contains a blank or tab; separate fields with commas",
                                    path=line.path, line=line.lineno, card=f1 or None)
        data = data + [""] * (nd - len(data))
        free = True
    else:
        text = text.expandtabs(8)
        if len(text) > 80 and text[80:].strip():
            raise BulkDataError(f"fixed-format line is {len(text.rstrip())} columns long; text after column 80 "
                                f"({text[80:].strip()!r}) would be ignored by Nastran. Check the field widths "
                                "(8 columns, 16 for large field) or use free format", path=line.path,
                                line=line.lineno)
        f1 = text[:8].strip().upper()
        large = f1.startswith("*") or (f1.endswith("*") and not f1.startswith("+"))
        if large:
            data = [_fixed_field(text, 8 + 16 * k, 24 + 16 * k, line, f"large field {k + 2}") for k in range(4)]
        else:
            data = [_fixed_field(text, 8 * k, 8 * k + 8, line, f"field {k + 1}") for k in range(1, 9)]
        cont = text[72:80].strip()
        free = False
    if not f1 or f1[0] in "+*":
        return _Head("cont", f1, large, free, data, cont)
    name = f1[:-1] if f1.endswith("*") else f1
    if not _NAME.match(f1) or len(name) > 8:
        raise BulkDataError(f"{f1!r} is not a card name (a letter followed by letters/digits, at most 8 "
                            "characters) nor a continuation marker (+, * or a blank field 1)",
                            path=line.path, line=line.lineno)
    return _Head("card", name, large, free, data, cont)


def _marker(m: str) -> str:
    return m.lstrip("+*").strip().upper()


def group_cards(lines) -> list:
    """Group bulk-data lines into :class:`RawCard` objects (comments kept with the next card)."""
    cards: list[RawCard] = []
    comment: list[str] = []
    cur: RawCard | None = None
    pending = ""          # field-10 marker of the last line of the current card
    pending_line = None
    for ln in lines:
        text = ln.text.rstrip("\r\n")
        if "$" in text:
            c = text[text.index("$"):]
            text = text[:text.index("$")]
            if not text.strip():
                comment.append(c)
                continue
        if not text.strip():
            continue
        h = _split(Line(text, ln.lineno, ln.path))
        if h.kind == "cont":
            if cur is None:
                raise BulkDataError(f"continuation line (field 1 {h.name!r}) has no parent card; start the card "
                                    "with its name in columns 1-8", path=ln.path, line=ln.lineno)
            a, b = _marker(pending), _marker(h.name)
            if a and b and a != b:
                raise BulkDataError(f"continuation marker {h.name!r} does not match the marker {pending!r} of "
                                    f"the line before (line {pending_line}); markers must match or be a plain "
                                    "'+'/'*'", path=ln.path, line=ln.lineno, card=cur.name)
            cur.fields.extend(d.strip() for d in h.data)
            pending, pending_line = h.cont, ln.lineno
            continue
        if cur is not None and pending:
            raise BulkDataError(f"missing continuation: line {pending_line} ends with continuation marker "
                                f"{pending!r} but the next line starts a new card {h.name}; add the continuation "
                                "line or remove the marker", path=cur.path, line=pending_line,
                                card=cur.name)
        cur = RawCard(h.name, [h.name] + [d.strip() for d in h.data], ln.lineno, ln.path, comment, h.large,
                      h.free)
        comment = []
        cards.append(cur)
        pending, pending_line = h.cont, ln.lineno
    if cur is not None and pending:
        raise BulkDataError(f"missing continuation: the last line ends with continuation marker {pending!r} "
                            "but the file ends; add the continuation line or remove the marker",
                            path=cur.path, line=pending_line, card=cur.name)
    return cards


# ------------------------------------------------------------------ formatting
def _digits(x: float, sig: int | None = None):
    """(sign, digit string, exponent e) with |x| = 0.DIGITS × 10^e; shortest exact when sig is None."""
    s = repr(abs(x)) if sig is None else f"{abs(x):.{sig - 1}e}"
    if "e" in s or "E" in s:
        mant, ex = s.lower().split("e")
        ex = int(ex)
    else:
        mant, ex = s, 0
    if "." in mant:
        ip, fp = mant.split(".")
    else:
        ip, fp = mant, ""
    digits = (ip + fp).lstrip("0")
    lead = len(ip) - (len(ip + fp) - len((ip + fp).lstrip("0")))
    e = ex + lead
    digits = digits.rstrip("0") or "0"
    return ("-" if x < 0 else ""), digits, e


def _candidates(sign: str, d: str, e: int) -> list:
    out = []
    n = len(d)
    # positional
    if e <= 0:
        out.append(sign + "." + "0" * (-e) + d)
    elif e >= n:
        out.append(sign + d + "0" * (e - n) + ".")
    else:
        out.append(sign + d[:e] + "." + d[e:])
    # exponent forms: d.ddd±k and .dddd±k
    k = e - 1
    if k != 0:
        out.append(sign + d[0] + "." + d[1:] + (f"+{k}" if k > 0 else f"{k}"))
    if e != 0:
        out.append(sign + "." + d + (f"+{e}" if e > 0 else f"{e}"))
    return out


def format_real(x: float, width: int = 8) -> str:
    """Shortest Nastran real that fits ``width`` characters (exact when possible, else rounded)."""
    x = float(x)
    if not math.isfinite(x):
        raise BulkDataError(f"cannot write the non-finite real {x!r} to bulk data; give a finite value")
    if x == 0.0:
        return "0."
    sign, d, e = _digits(x)
    best = min(_candidates(sign, d, e), key=len)
    if len(best) <= width:
        return best
    for sig in range(min(len(d), 17) - 1, 0, -1):
        sign, d2, e2 = _digits(x, sig)
        c = min(_candidates(sign, d2, e2), key=len)
        if len(c) <= width:
            return c
    raise BulkDataError(f"the real {x!r} cannot be written in {width} characters; use large field format")


def fits_exactly(x: float, width: int) -> bool:
    """True when ``x`` can be written exactly (shortest round-trip form) in ``width`` characters."""
    if x == 0.0:
        return True
    sign, d, e = _digits(float(x))
    return min(len(c) for c in _candidates(sign, d, e)) <= width


class Verbatim(str):
    """Field text written exactly as read (fields of unsupported cards)."""


def format_value(v, width: int = 8) -> str:
    """Text of one field value (None → blank) in at most ``width`` characters."""
    if v is None:
        return ""
    if isinstance(v, Verbatim):
        if len(v) > width:
            raise BulkDataError(f"field text {str(v)!r} does not fit in {width} characters")
        return str(v)
    if isinstance(v, bool):
        raise BulkDataError(f"cannot write the boolean {v!r} to a bulk-data field; use an integer")
    if isinstance(v, int):
        s = str(v)
        if len(s) > width:
            raise BulkDataError(f"integer {v} does not fit in {width} characters; use large field format")
        return s
    if isinstance(v, float):
        return format_real(v, width)
    s = str(v).upper()
    if len(s) > width:
        raise BulkDataError(f"name {s!r} does not fit in {width} characters")
    return s


def card_lines(name: str, values: list, fmt: str = "small") -> list:
    """Lines of one card.  ``values`` are the data fields (index 0 = field 2), None for blank.

    fmt: 'small' (8-column), 'large' (16-column, ``NAME*`` / ``*`` lines) or 'free' (commas).
    Continuation lines carry an explicit ``+``/``*`` in field 1 so that an all-blank
    continuation is never mistaken for a blank line.
    """
    vals = list(values)
    while vals and vals[-1] is None:
        vals.pop()
    if fmt == "small":
        w, per = 8, 8
    elif fmt in ("large", "free"):
        w, per = 16, 8
    else:
        raise BulkDataError(f"unknown bulk-data format {fmt!r}; expected 'small', 'large' or 'free'")
    if fmt == "large" and len(name) > 7:
        fmt = "free"  # 'NAME*' must fit in 8 columns; free field holds 16-character values too
    texts = [format_value(v, w) for v in vals]
    chunks = [texts[i:i + per] for i in range(0, max(len(texts), 1), per)] or [[]]
    out = []
    for k, ch in enumerate(chunks):
        if fmt == "small":
            head = name if k == 0 else "+"
            out.append((head.ljust(8) + "".join(t.rjust(8) for t in ch)).rstrip())
        elif fmt == "large":
            a, b = ch[:4], ch[4:]
            head = (name + "*") if k == 0 else "*"
            out.append((head.ljust(8) + "".join(t.rjust(16) for t in a)).rstrip())
            if b or k < len(chunks) - 1:
                out.append(("*".ljust(8) + "".join(t.rjust(16) for t in b)).rstrip())
        else:
            head = name if k == 0 else "+"
            out.append(",".join([head] + ch).rstrip(","))
    return out
