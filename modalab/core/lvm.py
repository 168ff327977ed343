"""Read LabVIEW measurement files (``.lvm``, text) into :class:`~modalab.core.records.TimeRecord`.

An LVM file (National Instruments, "Specification for the LabVIEW Measurement File") has a file
header (``LabVIEW Measurement`` … ``***End_of_Header***``) with ``Separator`` (Tab/Comma),
``Decimal_Separator`` (``.`` or ``,``), ``Multi_Headings`` and ``X_Columns`` (No/One/Multi), then one or
more segments, each with its own header (``Channels``, ``Samples``, ``Y_Unit_Label``, ``X0``,
``Delta_X`` … ``***End_of_Header***``), a column-name line (``X_Value``, channel names,
``Comment``) and the data rows.

:func:`parse_lvm` returns the parsed content (:class:`LvmFile`); :func:`read_lvm` turns one segment
into a :class:`TimeRecord` in SI units.  Roles, DOFs and units may be given by the caller; when not
given, a channel whose name contains "force" or "hammer" (or whose unit is N/Newtons/lbf) is the
force channel, every other channel a response; unit labels are mapped (``g`` → m/s² with the data
multiplied by 9.80665, ``Newtons`` → N).  A malformed or truncated file raises
:class:`LvmError` naming the file and the line.
"""
from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .dof import Dof, parse_dofs
from .errors import ModalabError
from .records import TimeRecord
from .units import G, to_si

__all__ = ["LvmError", "LvmSegment", "LvmFile", "parse_lvm", "read_lvm"]

log = logging.getLogger(__name__)

_END = "***End_of_Header***"

#: LVM unit label -> (SI unit name, factor)
_UNIT_MAP = {
    "g": ("m/s^2", G), "gs": ("m/s^2", G), "m/s^2": ("m/s^2", 1.0), "m/s2": ("m/s^2", 1.0), "m/s²": ("m/s^2", 1.0),
    "mm/s^2": ("m/s^2", 1e-3), "m/s": ("m/s", 1.0), "mm/s": ("m/s", 1e-3), "in/s": ("m/s", 0.0254),
    "m": ("m", 1.0), "mm": ("m", 1e-3), "um": ("m", 1e-6), "µm": ("m", 1e-6),
    "n": ("N", 1.0), "newton": ("N", 1.0), "newtons": ("N", 1.0), "kn": ("N", 1e3), "lbf": ("N", 4.4482216152605),
    "lbs": ("N", 4.4482216152605), "v": ("V", 1.0), "volts": ("V", 1.0), "mv": ("V", 1e-3),
}


class LvmError(ModalabError, ValueError):
    """An LVM file is malformed or truncated; names the file and the line."""

    def __init__(self, message: str, *, path=None, line=None):
        where = []
        if path is not None:
            where.append(f"file {str(path)!r}")
        if line is not None:
            where.append(f"line {line}")
        super().__init__((", ".join(where) + ": " if where else "") + message)
        self.path, self.line = path, line


@dataclass
class LvmSegment:
    """One data segment: ``data`` (n_channels, n_samples), channel ``names``, unit ``labels`` as written."""

    names: list
    unit_labels: list
    x0: list
    delta_x: list
    data: np.ndarray
    header: dict = field(default_factory=dict)
    line: int = 0

    @property
    def sample_rate_hz(self) -> float:
        return 1.0 / self.delta_x[0]


@dataclass
class LvmFile:
    """Parsed file: the file ``header`` (key → value string) and its ``segments``."""

    path: str
    header: dict
    segments: list


def _num(s: str, dec: str, path, line) -> float:
    t = s.strip()
    if dec == ",":
        t = t.replace(",", ".")
    try:
        return float(t)
    except ValueError:
        raise LvmError(f"cannot read the number {s!r}; expected a value with decimal separator {dec!r}",
                       path=path, line=line) from None


def parse_lvm(path) -> LvmFile:
    """Parse an LVM text file (every segment).  Raises :class:`LvmError` on malformed content."""
    p = Path(path)
    lines = _read_lines(p)
    header, k, sep, dec, xcols = _file_header(lines, p)
    segments = []
    while k < len(lines):
        # skip blank lines between segments
        while k < len(lines) and not lines[k].strip(sep + " \r"):
            k += 1
        if k >= len(lines):
            break
        segment, k = _segment(lines, k, sep, dec, xcols, p)
        segments.append(segment)
    if not segments:
        raise LvmError("no data segment after the file header (truncated file?)", path=p, line=len(lines))
    return LvmFile(path=str(p), header=header, segments=segments)


def _read_lines(p: Path) -> list:
    """The file's lines, after checking it is readable and starts like an LVM file."""
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise LvmError(f"cannot read the file ({e.strerror}); check the path", path=p) from None
    lines = text.splitlines()
    if not lines or not lines[0].startswith("LabVIEW Measurement"):
        first = lines[0][:40] if lines else ""
        raise LvmError(f"first line is {first!r}; an LVM file starts with 'LabVIEW Measurement'", path=p, line=1)
    return lines


def _file_header(lines: list, p: Path):
    """The file header: ``(header dict, index of the first line after it, separator, decimal separator,
    X_Columns)``."""
    header: dict = {}
    k = 1
    sep = "\t"
    while k < len(lines) and not lines[k].startswith(_END):
        parts = re.split(r"[\t,]", lines[k], maxsplit=1)    # keys hold neither tabs nor commas
        if parts[0].strip():
            header[parts[0].strip()] = parts[1].strip() if len(parts) > 1 else ""
        k += 1
    if k >= len(lines):
        raise LvmError("the file header has no '***End_of_Header***' line (truncated file?)", path=p, line=k)
    sep = {"Tab": "\t", "Comma": ","}.get(header.get("Separator", "Tab"))
    if sep is None:
        raise LvmError(f"Separator {header.get('Separator')!r} unknown; expected Tab or Comma", path=p)
    dec = header.get("Decimal_Separator", ".") or "."
    if dec not in (".", ","):
        raise LvmError(f"Decimal_Separator {dec!r} unknown; expected '.' or ','", path=p)
    if sep == "," and dec == ",":
        raise LvmError("Separator Comma with Decimal_Separator ',' is ambiguous", path=p)
    xcols = header.get("X_Columns", "One")
    if xcols not in ("No", "One", "Multi"):
        raise LvmError(f"X_Columns {xcols!r} unknown; expected No, One or Multi", path=p)
    k += 1
    return header, k, sep, dec, xcols


def _segment(lines: list, k: int, sep: str, dec: str, xcols: str, p: Path):
    """One data segment starting at line index ``k`` (its header, column names and data rows):
    ``(LvmSegment, index of the line after it)``."""
    # long: one segment's header, channel table and data rows share the same cursor and error context
    seg_line = k + 1
    sh: dict = {}
    while k < len(lines) and not lines[k].startswith(_END):
        parts = lines[k].split(sep)
        if parts[0].strip():
            sh[parts[0].strip()] = [v for v in parts[1:]]
        k += 1
    if k >= len(lines):
        raise LvmError("a segment header has no '***End_of_Header***' line (truncated file?)",
                       path=p, line=seg_line)
    k += 1
    if k >= len(lines):
        raise LvmError("the segment has no column-name line and no data (truncated file?)", path=p, line=k)
    try:
        n_ch = int(sh["Channels"][0])
    except (KeyError, IndexError, ValueError):
        raise LvmError("segment header lacks a valid 'Channels' entry", path=p, line=seg_line) from None
    if n_ch < 1:
        raise LvmError(f"Channels = {n_ch}; expected at least 1", path=p, line=seg_line)

    def per_channel(key, default=None, conv=None):
        vals = sh.get(key)
        if vals is None:
            if default is None:
                raise LvmError(f"segment header lacks '{key}'", path=p, line=seg_line)
            return [default] * n_ch
        vals = [v for v in vals][:n_ch]
        if len(vals) < n_ch or any(not v.strip() for v in vals):
            raise LvmError(f"'{key}' gives {len([v for v in vals if v.strip()])} values for {n_ch} channels",
                           path=p, line=seg_line)
        return [conv(v) if conv else v.strip() for v in vals]

    samples = per_channel("Samples", conv=lambda v: int(v))
    dx = per_channel("Delta_X", conv=lambda v: _num(v, dec, p, seg_line))
    x0 = per_channel("X0", default="0", conv=lambda v: _num(v, dec, p, seg_line))
    units = per_channel("Y_Unit_Label", default="")
    if any(d <= 0 for d in dx):
        raise LvmError(f"Delta_X {dx} must be positive (s per sample)", path=p, line=seg_line)
    names_line = lines[k].split(sep)
    name_row = k + 1
    if names_line[0].strip() != "X_Value":
        raise LvmError(f"expected the column-name line starting with 'X_Value'; got {lines[k][:40]!r}",
                       path=p, line=name_row)
    k += 1
    # column 0 is X (empty when X_Columns = No); with Multi every channel has its own X column
    cols = [2 * c + 1 for c in range(n_ch)] if xcols == "Multi" else [1 + c for c in range(n_ch)]
    raw_names = [v.strip() for v in names_line]
    names = [raw_names[c] if c < len(raw_names) else f"channel {i}" for i, c in enumerate(cols)]
    n_max = max(samples)
    data = np.empty((n_ch, n_max))
    r = 0
    while k < len(lines) and r < n_max:
        row = lines[k]
        if not row.strip(sep + " \r"):
            break
        if row.startswith("LabVIEW Measurement") or row.split(sep)[0].strip() in ("Channels",):
            break
        parts = row.split(sep)
        if len(parts) <= cols[-1]:
            raise LvmError(f"data row has {len(parts)} fields; expected at least {cols[-1] + 1} for "
                           f"{n_ch} channels", path=p, line=k + 1)
        for i, c in enumerate(cols):
            data[i, r] = _num(parts[c], dec, p, k + 1)
        r += 1
        k += 1
    if r < n_max:
        raise LvmError(f"the segment declares {n_max} samples but holds {r} data rows (truncated file?)",
                       path=p, line=k + 1 if k < len(lines) else len(lines))
    if len(set(samples)) != 1:
        log.warning("%s: channels have different sample counts %s; shorter ones are padded with NaN", p, samples)
        for i, s in enumerate(samples):
            data[i, s:] = np.nan
    segment = LvmSegment(names=names, unit_labels=units, x0=x0, delta_x=dx, data=data,
                         header=sh, line=seg_line)
    return segment, k


def _infer_role(name: str, unit_si: str) -> str:
    n = name.lower()
    if "force" in n or "hammer" in n or unit_si == "N":
        return "force"
    return "response"


def read_lvm(path, *, segment: int = 0, dofs=None, roles=None, units=None, trigger_index="auto",
             trigger_level: float = 0.05, hit_id: int = 1) -> TimeRecord:
    """One LVM segment as a :class:`TimeRecord` in SI units.

    Parameters
    ----------
    path : the .lvm file.
    segment : which data segment (0 = first).
    dofs : DOF label per channel; default scalar points ``1``, ``2``, … in channel order
        (pass real labels such as ``['5+Z', '1+Z']`` for a test).
    roles : 'force' / 'response' per channel; default inferred from the channel names and units.
    units : unit per channel *of the file's values* (overrides ``Y_Unit_Label``); converted to SI.
    trigger_index : sample of the trigger; ``'auto'`` takes the first sample where the force departs
        from its initial level by more than ``trigger_level`` × its peak (the file stores no trigger).
    trigger_level : fraction of the force peak for ``trigger_index='auto'``.
    hit_id : hit number to give the record.

    Returns
    -------
    TimeRecord with data in N and m/s² (or m/s, m), ``metadata`` holding the channel names, the
    original unit labels, the file and segment, and how the trigger was found.
    """
    lf = parse_lvm(path)
    if not (0 <= int(segment) < len(lf.segments)):
        raise LvmError(f"segment {segment} requested but the file has {len(lf.segments)}", path=path)
    seg = lf.segments[int(segment)]
    n_ch = seg.data.shape[0]
    if len(set(seg.delta_x)) != 1:
        raise LvmError(f"channels have different Delta_X {seg.delta_x}; resample them to one rate first", path=path,
                       line=seg.line)
    if np.isnan(seg.data).any():
        raise LvmError("channels have different sample counts; a TimeRecord needs equal lengths", path=path,
                       line=seg.line)
    labels = list(units) if units is not None else list(seg.unit_labels)
    if len(labels) != n_ch:
        raise LvmError(f"{len(labels)} units for {n_ch} channels; give one unit per channel", path=path)
    si_units, data = [], seg.data.copy()
    for i, lab in enumerate(labels):
        key = str(lab).strip()
        hit = _UNIT_MAP.get(key.lower()) or _UNIT_MAP.get(key)
        if hit is None:
            try:
                factor = float(to_si(1.0, key))
                hit = (key, factor)
            except ModalabError:
                raise LvmError(f"channel {seg.names[i]!r} has unit label {lab!r} that modalab does not know; pass "
                               "units=[...] (e.g. 'g', 'N', 'm/s^2') for every channel", path=path,
                               line=seg.line) from None
        si_units.append(hit[0])
        data[i] *= hit[1]
    rl = list(roles) if roles is not None else [_infer_role(nm, u) for nm, u in zip(seg.names, si_units)]
    if len(rl) != n_ch:
        raise LvmError(f"{len(rl)} roles for {n_ch} channels", path=path)
    dl = parse_dofs(dofs) if dofs is not None else [Dof(i + 1, 0) for i in range(n_ch)]
    fs = 1.0 / seg.delta_x[0]
    how = "given"
    if isinstance(trigger_index, str):
        if trigger_index != "auto":
            raise LvmError(f"trigger_index={trigger_index!r}; give an integer or 'auto'", path=path)
        fidx = [i for i, r in enumerate(rl) if str(r).lower() == "force"]
        ti = 0
        if fidx:
            f = data[fidx[0]]
            base = np.median(f[: max(1, min(32, f.size // 10))])
            g = np.abs(f - base)
            pk = g.max()
            if pk > 0:
                ti = int(np.argmax(g > trigger_level * pk))
        how = f"auto: first sample above {trigger_level:g} x force peak"
    else:
        ti = int(trigger_index)
    meta = {"source": str(path), "segment": int(segment), "channel_names": list(seg.names),
            "unit_labels": list(seg.unit_labels), "trigger": how, "x0": list(seg.x0),
            "lvm_header": dict(lf.header)}
    return TimeRecord(sample_rate_hz=fs, data=data, dofs=dl, roles=rl, units=si_units, trigger_index=ti,
                      hit_id=hit_id, metadata=meta)
