"""Per-hit quality checks for impact testing.

:func:`check_hit` inspects one :class:`modalab.core.records.TimeRecord` and returns a
:class:`HitReport`; every threshold lives in the frozen :class:`HitCheckConfig`.
The checks (Ewins 2000, ch. 3; Brandt 2011, ch. 13):

double hit
    *Time domain*: after the main force pulse has ended (the force has fallen below
    ``pulse_end_level`` × peak) and ``guard_samples`` more (the anti-alias filter of a
    delta-sigma ADC rings around a pulse only a few samples wide), a second pulse of the same
    polarity above ``double_hit_level`` × peak.  *Spectral heuristic*: a single pulse has a smooth,
    monotonically falling force spectrum over its main lobe; a double hit modulates it with
    notches spaced 1/Δt apart.  The depth of the deepest notch within the main lobe (down to
    ``lobe_db`` below the low-frequency level) of the force from the pulse start over
    ``spectral_window_s`` (or 20 pulse widths) is reported and flagged above ``dip_db``.  It sees a
    second pulse whose delay puts a notch inside the main lobe; one that merges with the first
    pulse (delay shorter than about one pulse width) is beyond both checks.
overload
    The device's flags (``record.overload``), samples within ``rail_fraction`` of the channel's
    range (``ranges=`` or ``record.metadata['range']``: ±value or (lo, hi) per channel, in
    engineering units), and — without a known range — a flat top: ``flat_top_samples`` or more
    samples sitting at the channel's extreme value.
weak / missing trigger
    Force peak below ``min_peak_force_n`` (weak), or below ``min_peak_snr`` × the pretrigger noise
    RMS (missing: the record holds no hit).
response not decayed
    RMS of the last ``end_fraction`` of each response over its peak above ``max_end_ratio``:
    leakage; use an exponential window or a longer record.
pretrigger content
    Force in the pretrigger (before the pulse began, less ``guard_samples``) above
    ``max_pretrigger_ratio`` × peak (the hit
    started before the record or an earlier hit), and response RMS in the pretrigger above the same
    ratio × its peak (the structure was still ringing).

References
----------
D. J. Ewins, *Modal Testing*, 2nd ed., 2000, ch. 3 (impact excitation: double hits, overloads).
A. Brandt, *Noise and Vibration Analysis*, Wiley 2011, ch. 13.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from modalab.core.errors import ModalabValueError
from modalab.core.records import TimeRecord

__all__ = ["HitCheckConfig", "HitReport", "check_hit", "check_hits", "FLAGS"]

log = logging.getLogger(__name__)

FLAGS = ("double_hit", "double_hit_spectral", "overload", "weak_trigger", "missing_trigger", "not_decayed",
         "pretrigger_force", "pretrigger_response")


@dataclass(frozen=True)
class HitCheckConfig:
    """Thresholds of :func:`check_hit` (dimensionless ratios unless the name carries a unit)."""

    double_hit_level: float = 0.1        #: second pulse / first pulse peak that counts as a double hit
    pulse_end_level: float = 0.05        #: the pulse has ended when |force| falls below this × peak
    guard_samples: int = 4               #: samples skipped after the pulse end / before its start (filter ringing)
    dip_db: float = 6.0                  #: notch depth in the force spectrum's main lobe that flags, dB
    lobe_db: float = 20.0                #: the main lobe extends down to this far below its low-frequency level, dB
    spectral_window_s: float = 0.02      #: force analysed for notches: from the pulse start, max(this, 20 pulse widths)
    rail_fraction: float = 0.98          #: |x| >= rail_fraction × range counts as at the rail
    rail_samples: int = 1                #: samples at the rail needed to flag an overload
    flat_top_samples: int = 3            #: consecutive samples at the extreme value that flag a clipped top
    min_peak_force_n: float = 1.0        #: below this peak force (N) the hit is weak
    min_peak_snr: float = 10.0           #: peak / pretrigger noise RMS below this: no hit at all
    end_fraction: float = 0.05           #: tail of the record used for the decay check
    max_end_ratio: float = 0.01          #: end RMS / peak above this: response not decayed
    max_pretrigger_ratio: float = 0.05   #: pretrigger content / peak above this flags

    def __post_init__(self):
        for name in ("double_hit_level", "pulse_end_level", "rail_fraction", "end_fraction", "max_end_ratio",
                     "max_pretrigger_ratio"):
            v = getattr(self, name)
            if not (0 < v < 1):
                raise ModalabValueError(f"HitCheckConfig.{name}={v!r} must lie in (0, 1)")
        for name in ("dip_db", "lobe_db", "min_peak_force_n", "min_peak_snr", "spectral_window_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ModalabValueError(f"HitCheckConfig.{name}={v!r} must be >= 0")
        if int(self.guard_samples) < 0:
            raise ModalabValueError(f"HitCheckConfig.guard_samples={self.guard_samples!r} must be >= 0")
        for name in ("rail_samples", "flat_top_samples"):
            if int(getattr(self, name)) < 1:
                raise ModalabValueError(f"HitCheckConfig.{name}={getattr(self, name)!r} must be >= 1")


@dataclass(frozen=True)
class HitReport:
    """Result of :func:`check_hit`.  ``ok`` is True when no flag is raised; ``messages`` explain each flag."""

    hit_id: int
    flags: tuple = ()
    messages: tuple = ()
    peak_force: float = float("nan")              #: N (per force channel: the largest)
    pulse_width_s: float = float("nan")           #: duration of the main pulse above pulse_end_level × peak
    double_hit_ratio: float = 0.0                 #: largest later pulse / peak
    double_hit_delay_s: float = float("nan")      #: time of that pulse after the main peak
    spectral_dip_db: float = 0.0                  #: deepest notch in the force spectrum's main lobe
    overloaded_channels: tuple = ()               #: indices of channels flagged overloaded
    end_ratio: tuple = ()                         #: per response channel: end RMS / peak
    pretrigger_force_ratio: float = 0.0
    pretrigger_response_ratio: tuple = ()
    details: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.flags

    def summary(self) -> str:
        if self.ok:
            return f"hit {self.hit_id}: ok (peak {self.peak_force:.4g} N)"
        return f"hit {self.hit_id}: " + "; ".join(self.messages)


def _ranges_for(record: TimeRecord, ranges):
    r = ranges if ranges is not None else record.metadata.get("range")
    if r is None:
        return [None] * record.n_channels
    r = list(r) if isinstance(r, (list, tuple, np.ndarray)) else [r] * record.n_channels
    if len(r) != record.n_channels:
        raise ModalabValueError(f"{len(r)} channel ranges for {record.n_channels} channels; give one range "
                                "(±value or (lo, hi) in engineering units) per channel")
    out = []
    for v in r:
        if v is None:
            out.append(None)
        elif np.ndim(v) == 0:
            out.append((-abs(float(v)), abs(float(v))))
        else:
            lo, hi = (float(x) for x in v)
            out.append((lo, hi))
    return out


def _longest_run(mask: np.ndarray) -> int:
    if not mask.any():
        return 0
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    return int((ends - starts).max())


def _spectral_dip_db(pulse: np.ndarray, fs: float, lobe_db: float) -> float:
    """Deepest notch (dB) of |F(f)| inside its main lobe, measured against the spectrum further up."""
    n = pulse.size
    nfft = int(2 ** np.ceil(np.log2(max(8 * n, 256))))
    S = np.abs(np.fft.rfft(pulse, n=nfft))
    if S[0] <= 0 or not np.isfinite(S[0]):
        return 0.0
    ref = S[: max(2, nfft // 1000)].max()
    below = np.flatnonzero(S < ref * 10 ** (-lobe_db / 20))
    end = below[0] if below.size else S.size
    lobe = S[:end]
    if lobe.size < 3:
        return 0.0
    env = np.maximum.accumulate(lobe[::-1])[::-1]   # highest level at or above each line
    with np.errstate(divide="ignore"):
        depth = 20 * np.log10(env / np.maximum(lobe, 1e-300))
    return float(depth.max())


class _Flags:
    """The flags raised so far (each once, in order) and every message, in order."""

    def __init__(self):
        self.flags: list[str] = []
        self.msgs: list[str] = []

    def __contains__(self, name) -> bool:
        return name in self.flags

    def flag(self, name, msg):
        if name not in self.flags:
            self.flags.append(name)
        self.msgs.append(msg)


def _check_overload(record: TimeRecord, cfg: HitCheckConfig, ranges, out: _Flags) -> set:
    """Overload: device flags, samples at the rail of a known range, or a flat (clipped) top.  The channels."""
    over = set(int(i) for i in np.flatnonzero(record.overload))
    for i in sorted(over):
        out.msgs.append(f"channel {i} ({record.dofs[i]}) overload flagged by the device")
    for i, rng in enumerate(_ranges_for(record, ranges)):
        x = record.data[i]
        if rng is not None:
            lo, hi = rng
            at_rail = (x >= cfg.rail_fraction * hi) | (x <= cfg.rail_fraction * lo)
            if int(at_rail.sum()) >= cfg.rail_samples:
                over.add(i)
                out.msgs.append(f"channel {i} ({record.dofs[i]}): {int(at_rail.sum())} samples at the rail of "
                                f"[{lo:g}, {hi:g}] {record.units[i]}; raise the range")
        else:
            peak = np.abs(x).max()
            if peak > 0:
                top = np.abs(np.abs(x) - peak) <= 1e-9 * peak
                run = _longest_run(top)
                if run >= cfg.flat_top_samples:
                    over.add(i)
                    out.msgs.append(f"channel {i} ({record.dofs[i]}): flat top of {run} samples at "
                                    f"{peak:.4g} {record.units[i]} (clipped)")
    if over:
        out.flags.insert(0, "overload")
    return over


def _main_force(record: TimeRecord):
    """(channel, force less its pretrigger baseline and turned so that the main pulse is positive, peak index)
    of the force channel with the largest pulse."""
    ti = record.trigger_index
    best = None
    for i in record.force_channels:
        f = record.data[i]
        base = float(np.median(f[:ti])) if ti >= 8 else 0.0
        fc = f - base
        k = int(np.argmax(np.abs(fc)))
        if best is None or abs(fc[k]) > abs(best[1][best[2]]):
            best = (i, fc, k)
    i, fc, k = best
    sgn = np.sign(fc[k]) or 1.0
    return i, fc * sgn, k


def _check_trigger(g, k: int, ti: int, cfg: HitCheckConfig, trigger_level, out: _Flags, details: dict) -> float:
    """Missing (peak within the pretrigger noise) or weak (below the trigger level) hit.  The peak force."""
    peak_force = float(g[k])
    noise = float(np.sqrt(np.mean(g[:ti] ** 2))) if ti >= 8 else 0.0
    details["pretrigger_noise_rms"] = noise
    if peak_force < cfg.min_peak_snr * noise or peak_force <= 0:
        out.flag("missing_trigger", f"force peak {peak_force:.3g} N is within the noise "
                                    f"({noise:.3g} N RMS): no hit in this record")
    else:
        level = max(cfg.min_peak_force_n, 0.0 if trigger_level is None else abs(float(trigger_level)))
        if peak_force < level:
            out.flag("weak_trigger", f"peak force {peak_force:.3g} N is below {level:g} N; hit harder "
                                     "or lower the trigger level")
    return peak_force


def _pulse_bounds(g, k: int, peak_force: float, cfg: HitCheckConfig) -> tuple:
    """(start, end) samples of the main pulse: where the force last/first falls below pulse_end_level × peak."""
    lvl = cfg.pulse_end_level * peak_force
    after = np.flatnonzero(g[k:] < lvl)
    end = k + int(after[0]) if after.size else g.size
    before = np.flatnonzero(g[:k] < lvl)
    start = int(before[-1]) + 1 if before.size else 0
    return start, end


def _check_double_hit(g, k: int, end: int, peak_force: float, fs: float, cfg: HitCheckConfig,
                      out: _Flags) -> tuple:
    """Time-domain double hit: a later pulse of the same polarity.  (ratio to the peak, delay s)."""
    dh_ratio, dh_delay = 0.0, float("nan")
    gs = int(cfg.guard_samples)
    if end + gs < g.size:
        tail = g[end + gs:]
        j = int(np.argmax(tail))
        dh_ratio = float(tail[j] / peak_force) if peak_force > 0 else 0.0
        dh_delay = (end + gs + j - k) / fs
        if dh_ratio > cfg.double_hit_level and "missing_trigger" not in out:
            out.flag("double_hit", f"second force pulse of {100 * dh_ratio:.0f} % of the peak "
                                   f"{1e3 * dh_delay:.3g} ms after the first; repeat the hit")
    return dh_ratio, dh_delay


def _check_double_hit_spectral(g, start: int, end: int, fs: float, cfg: HitCheckConfig, out: _Flags) -> float:
    """Spectral heuristic on the force from the pulse start over a force-window-like span.  The notch depth, dB."""
    span = max(int(round(cfg.spectral_window_s * fs)), 20 * (end - start))
    seg = g[start:start + span]
    dip = 0.0
    if "missing_trigger" not in out:
        dip = _spectral_dip_db(seg, fs, cfg.lobe_db)
        if dip > cfg.dip_db:
            out.flag("double_hit_spectral", f"notch of {dip:.1f} dB in the force spectrum's main lobe "
                                            "(double hit or a bouncing hammer)")
    return dip


def _check_pretrigger_force(g, start: int, ti: int, peak_force: float, cfg: HitCheckConfig, out: _Flags) -> float:
    """Force before the pulse started (and before the trigger), as a fraction of the peak."""
    pre_force = 0.0
    pre_end = min(start - int(cfg.guard_samples), ti)
    if pre_end > 0 and peak_force > 0:
        pre_force = float(np.abs(g[:pre_end]).max() / peak_force)
        if pre_force > cfg.max_pretrigger_ratio:
            out.flag("pretrigger_force", f"force of {100 * pre_force:.0f} % of the peak before the pulse: the hit "
                                         "began before the record or an earlier hit; increase the pretrigger")
    return pre_force


def _check_force(record: TimeRecord, cfg: HitCheckConfig, trigger_level, out: _Flags, details: dict) -> dict:
    """The force checks in order: trigger, double hit (time, spectrum), pretrigger force."""
    res = dict(peak_force=float("nan"), pulse_width_s=float("nan"), double_hit_ratio=0.0,
               double_hit_delay_s=float("nan"), spectral_dip_db=0.0, pretrigger_force_ratio=0.0)
    if not record.force_channels:
        out.flag("missing_trigger", "no force channel in the record; mark the hammer channel with role 'force'")
        return res
    fs, ti = record.sample_rate_hz, record.trigger_index
    i, g, k = _main_force(record)
    details["force_channel"] = i
    peak_force = _check_trigger(g, k, ti, cfg, trigger_level, out, details)
    start, end = _pulse_bounds(g, k, peak_force, cfg)
    dh_ratio, dh_delay = _check_double_hit(g, k, end, peak_force, fs, cfg, out)
    res.update(peak_force=peak_force, pulse_width_s=(end - start) / fs, double_hit_ratio=dh_ratio,
               double_hit_delay_s=dh_delay,
               spectral_dip_db=_check_double_hit_spectral(g, start, end, fs, cfg, out),
               pretrigger_force_ratio=_check_pretrigger_force(g, start, ti, peak_force, cfg, out))
    return res


def _check_responses(record: TimeRecord, cfg: HitCheckConfig, out: _Flags) -> tuple:
    """Per response channel, in order: not decayed at the record end, then still moving before the trigger.
    (end ratios, pretrigger ratios)."""
    n, ti = record.n_samples, record.trigger_index
    end_ratio, pre_resp = [], []
    m_end = max(1, int(round(cfg.end_fraction * n)))
    for i in record.response_channels:
        yc = record.data[i]          # responses are AC-coupled: no baseline removed (motion before the trigger is data)
        pk = float(np.abs(yc).max())
        er = float(np.sqrt(np.mean(yc[-m_end:] ** 2)) / pk) if pk > 0 else 0.0
        end_ratio.append(er)
        if er > cfg.max_end_ratio:
            out.flag("not_decayed", f"response {record.dofs[i]} still at {100 * er:.2g} % of its peak at the record "
                                    "end; use an exponential window or a longer record")
        pr = float(np.sqrt(np.mean(yc[:ti] ** 2)) / pk) if (ti >= 8 and pk > 0) else 0.0
        pre_resp.append(pr)
        if pr > cfg.max_pretrigger_ratio:
            out.flag("pretrigger_response", f"response {record.dofs[i]} RMS before the trigger is {100 * pr:.2g} % "
                                            "of its peak: the structure was still moving; wait longer between hits")
    return end_ratio, pre_resp


def check_hit(record: TimeRecord, config: HitCheckConfig | None = None, *, ranges=None,
              trigger_level: float | None = None) -> HitReport:
    """Quality checks of one hit; see the module docstring for what each flag means.

    Parameters
    ----------
    record : the hit.
    config : thresholds (default :class:`HitCheckConfig()`).
    ranges : per-channel input range in engineering units (±value or (lo, hi)); default
        ``record.metadata['range']`` when present.
    trigger_level : the DAQ's trigger threshold on the force, N; a peak below it is a weak trigger
        (the record was not started by this hit).  The stricter of it and
        ``config.min_peak_force_n`` applies.

    Returns
    -------
    HitReport with ``flags`` (subset of :data:`FLAGS`) and human-readable ``messages``.
    """
    if not isinstance(record, TimeRecord):
        raise ModalabValueError(f"check_hit expects a TimeRecord; got {type(record).__name__}")
    cfg = HitCheckConfig() if config is None else config
    out = _Flags()
    details: dict = {}
    over = _check_overload(record, cfg, ranges, out)
    force = _check_force(record, cfg, trigger_level, out, details)
    end_ratio, pre_resp = _check_responses(record, cfg, out)
    rep = HitReport(hit_id=record.hit_id, flags=tuple(out.flags), messages=tuple(out.msgs),
                    overloaded_channels=tuple(sorted(over)), end_ratio=tuple(end_ratio),
                    pretrigger_response_ratio=tuple(pre_resp), details=details, **force)
    if out.flags:
        log.info("%s", rep.summary())
    return rep


def check_hits(records, config: HitCheckConfig | None = None, *, ranges=None,
               trigger_level: float | None = None) -> list[HitReport]:
    """:func:`check_hit` for each record."""
    return [check_hit(r, config, ranges=ranges, trigger_level=trigger_level) for r in records]
