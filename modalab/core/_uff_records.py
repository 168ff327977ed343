"""UFF raw hammer hits: dataset 58/58b time records (func_type 1), one per channel per hit.

Part of :mod:`modalab.core.uff`.
"""
from __future__ import annotations

import logging
from collections import Counter

import numpy as np

from ._uff_common import (_SPEC_SI, _UNIT_TYPE, _blocks, _compact_json, _guard, _json_meta, _label_si,
                          _open_out, _units_factors)
from ._uff_core import Axis, Fn58, check_groups, date_line, format_58
from ._uff_frf import _functions
from ._uff_geometry import _node_rotations
from .dof import Dof
from .errors import ModalabValueError, UffError
from .records import TimeRecord

log = logging.getLogger("modalab.core.uff")

#: metadata written first into a hit's ID line 5 (the rest as long as the 80 characters allow)
_FIRST_META = ("point", "backend")


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
            hp = _highpass(rec, path)
            meta_line = "NONE"
            if rec.metadata:
                # keep the entries that fit the 80-character ID line (point, backend...); large ones such as
                # the simulator's ground truth stay out of the file
                kept: dict = {}
                # the point and the backend first: what took the hits must survive a long entry (range_v ...)
                for key, value in sorted(rec.metadata.items(), key=lambda kv: kv[0] not in _FIRST_META):
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
                        date, m4 if hp is None else f"{m4} hp={hp[k]!r}", meta_line]
                axes = [Axis(17, 0, 0, 0, "Time", "s"), Axis(spec, 0, 0, 0, "NONE", unit_lab), Axis(0), Axis(0)]
                fh.write(format_58(binary=binary, ids=ids_, func_type=1, func_id=k + 1, load_case=rec.hit_id,
                                   rsp_node=d.node, rsp_dir=d.direction, ref_node=hammer.node,
                                   ref_dir=hammer.direction, x=None, y=rec.data[k], even=True, x0=x0, dx=dt,
                                   axes=axes))


def _highpass(rec: TimeRecord, path) -> list | None:
    """The channels' AC-coupling corners (Hz) from ``metadata['highpass_hz']``, written to ID line 4 as ``hp=``
    (the FRF estimator's force window needs them, :func:`acquisition.windows.windowed_force`); None when the
    record does not say."""
    try:
        return rec.highpass_hz()
    except ModalabValueError as e:
        raise UffError(str(e), path=path) from None


def read_records(path) -> list[TimeRecord]:
    """Read time records (func_type 1) back into one :class:`TimeRecord` per hit (load case id)."""
    with _guard(path) as cur:
        blocks = _blocks(path, cur)
        lf, ff = _units_factors(blocks)
        check_groups([(f.tags, f.line, f.func_type == 1) for f in _functions(blocks, cur, None, True)],
                     path, "time record", "r")
        fns = _functions(blocks, cur, (1,))
        if not fns:
            n_frf = len(_functions(blocks, cur, (4,)))
            raise UffError("no time records (dataset 58, function type 1) in the file" + (
                f"; it holds {n_frf} FRFs (function type 4): FRFs already, not raw hits (identify takes them)"
                if n_frf else ""), path=path)
        rot = _node_rotations(blocks, path, cur)
        local = sorted({f.rsp_node for f in fns if f.rsp_node in rot})
        if local:
            raise UffError(f"channels at nodes {local[:10]} are measured in rotated displacement frames "
                           "(dataset 2420); modalab does not rotate raw time records. Export them in the global "
                           "frame", path=path, dataset=58)
        hits: dict[int, list[Fn58]] = {}
        for f in fns:
            hits.setdefault(f.load_case, []).append(f)
        return [_hit(hit, sorted(chans, key=_channel_order), lf, ff, path) for hit, chans in hits.items()]


def _channel_order(f):
    try:
        return int(f.tags.get("ch", 10 ** 9)), f.line
    except ValueError:
        return 10 ** 9, f.line


def _hit(hit: int, chans: list, lf: float, ff: float, path) -> TimeRecord:
    """One hit from its channel records (in channel order), checked to share one time axis."""
    c0 = chans[0]
    _check_channels(hit, chans, path)
    fs, trig, meta = _timing(hit, c0, path)
    data = np.empty((len(chans), c0.n))
    dofs, roles, units, sens, ovl = [], [], [], [], []
    for k, f in enumerate(chans):
        role = f.tags.get("role")
        if role not in ("force", "response"):
            role = "force" if f.axes[1].spec in (13, 9) else "response"
        fac, unit = _channel_units(f, role, lf, ff, path)
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
    hp = [f.tags.get("hp") for f in chans]
    if any(c is not None for c in hp):
        bad = [f for f, c in zip(chans, hp) if not _is_number(c)]
        if bad:
            raise UffError(f"hit {hit}: AC-coupling corner hp={bad[0].tags.get('hp')!r} in ID line 4 is not a "
                           "number (or missing on this channel while others give it)", path=path, dataset=58,
                           line=bad[0].line + 4)
        corners = [float(c) for c in hp]
        if not all(np.isfinite(c) and c >= 0 for c in corners):
            raise UffError(f"hit {hit}: AC-coupling corners {corners} in ID line 4 must be >= 0 Hz", path=path,
                           dataset=58, line=c0.line + 4)
        meta["highpass_hz"] = corners
    return TimeRecord(sample_rate_hz=fs, data=data, dofs=dofs, roles=roles, units=units,
                      sensitivity=sens, trigger_index=trig, overload=ovl, hit_id=hit, metadata=meta)


def _is_number(text) -> bool:
    try:
        float(text)
    except (TypeError, ValueError):
        return False
    return True


def _check_channels(hit: int, chans: list, path) -> None:
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


def _timing(hit: int, c0, path) -> tuple[float, int, dict]:
    """Sample rate, trigger index and metadata of a hit from its first record, checked against record 7."""
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
    return fs, trig, meta


def _channel_units(f, role: str, lf: float, ff: float, path) -> tuple[float, str]:
    """Factor to SI and unit of a channel: a recognised units label wins; else SI or dataset 164 units by data
    type; an unknown label keeps the values as stored (logged)."""
    label, spec = f.axes[1].units, f.axes[1].spec
    conv = _label_si(label)
    if conv is not None:
        return conv
    if label.strip().upper() in ("", "NONE"):
        unit = _SPEC_SI.get(spec, "N" if role == "force" else "m/s^2")
        return (1.0 / ff if unit == "N" else (1.0 / lf if abs(f.rsp_dir) <= 3 else 1.0)), unit
    log.warning("%s: unit %r of the record at line %d is not one modalab converts; "
                "values kept as stored", path, label, f.line)
    return 1.0, label
