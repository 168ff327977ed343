"""Test plans: what an impact test measures and how (a TOML file).

Example (every key documented; the README carries the same example)::

    [acquisition]
    sample_rate_hz = 2048.0     # samples per second
    bandwidth_hz = 800.0        # analysis band; sample_rate_hz must be >= 2.56 x bandwidth
    record_s = 2.0              # record length (or n_samples = 4096)
    pretrigger_s = 0.02         # kept before the trigger (or pretrigger_samples = 40)
    averages = 3                # accepted hits per point (N)
    max_hits = 5                # --auto: best N of at most M valid hits by coherence
    timeout_s = 10.0            # wait for a hit this long before asking again

    [trigger]
    channel = "hammer"          # channel name
    level = 10.0                # N
    slope = "rising"

    [windows]
    force_fraction = 0.05       # force window: rectangular over this fraction of the record after the trigger
    force_taper = 0.25          # cosine taper as a fraction of the window
    exp_end_level = 0.01        # exponential window down to 1 % at the record end (0 = off); or exp_beta = 2.3 (1/s)

    [[channels]]
    name = "hammer"
    physical = "cDAQ1Mod1/ai0"
    role = "force"
    dof = "roving"              # the roving hammer takes the DOF of the current point
    sensitivity = 2.25
    sensitivity_unit = "mV/N"   # a force channel: mV/N or V/N
    range = 500.0               # N

    [[channels]]
    name = "acc1"
    physical = "cDAQ1Mod1/ai1"
    role = "response"
    dof = "3+Z"
    sensitivity = 100.0
    sensitivity_unit = "mV/g"   # a response channel: mV/g, V/g, mV/(m/s^2) or V/(m/s^2)
    range = 500.0               # m/s^2

    [roving]
    pattern = "hammer"          # or "accelerometer" (then `channel` names the roving sensor)
    points = ["1+Z", "2+Z", "3+Z"]

    [geometry]                  # optional node coordinates in m (then every DOF's node needs them)
    1 = [0.0, 0.0, 0.0]
    2 = [0.5, 0.0, 0.0]
    3 = [1.0, 0.0, 0.0]

    [hammer]                    # optional automatic hammer (serial)
    url = "simhammer://bench"
    force_n = 100.0

    [sim]                       # only for --backend sim (all keys: SIM_KEYS; hardware_sim.bench.lab_from_sim)
    structure = "demo"          # built-in demo structure, or a .bdf (a relative path is read from the plan's folder)
    seed = 1                    # every hit is drawn from (seed, point, hit): a resumed session repeats nothing
    hit_interval_s = 0.0        # simulated time from arm to the operator's hit
    force_n = 100.0             # the operator's hammer: nominal peak force (N),
    hammer_tip = "medium"       # tip 'hard' | 'medium' | 'soft' and head mass: the contact time is
    hammer_mass_kg = 0.16       # pi sqrt(m/k), which sets the force spectrum's bandwidth
    # faults = { double_hit_on = [2], device_lost_on = [7] }; dead = ["acc1"]; noisy = { acc1 = 0.05 }

Every section accepts only the keys shown (:data:`SECTION_KEYS`, :data:`CHANNEL_KEYS`): a misspelt key is
an error naming the file, ``section.key`` and the closest valid key; a value of the wrong type likewise.
A channel's ``sensitivity_unit`` must be a sensitivity to what its role measures (:data:`ROLE_QUANTITY`):
a hammer in mV/g, or an accelerometer in mV/N, is an error naming the file, the channel and the units expected.

Ready-made plans for the demo structure: ``examples/plans/demo_roving_hammer.toml``,
``demo_roving_accelerometer.toml`` and ``demo_auto_hammer.toml`` (automatic hammer ``simhammer://bench``).
"""
from __future__ import annotations

import difflib
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from modalab.core.daqconfig import (SENSITIVITY_UNITS, AcquisitionConfig, ChannelConfig, sensitivity_quantity,
                                    sensitivity_to_si)
from modalab.core.dof import Dof
from modalab.core.errors import DofError, ModalabValueError, PlanError
from .windows import ExponentialWindow

__all__ = ["TestPlan", "load_plan", "PlanChannel", "exponential_window", "SECTION_KEYS", "CHANNEL_KEYS", "SIM_KEYS"]

ROVING = "roving"

#: the sections of a plan ([geometry] holds node ids, checked separately)
SECTIONS = ("acquisition", "trigger", "windows", "channels", "roving", "geometry", "hammer", "sim")
#: the keys each section may hold; anything else is a typo and an error (with the closest valid key)
SIM_KEYS = frozenset({"structure", "seed", "faults", "hit_interval_s", "realtime", "force_n", "hammer_tip",
                      "hammer_mass_kg", "double_hit_probability", "force_scatter", "placement_scatter_m", "dead",
                      "noisy"})
SECTION_KEYS = {
    "acquisition": frozenset({"sample_rate_hz", "bandwidth_hz", "record_s", "n_samples", "pretrigger_s",
                              "pretrigger_samples", "averages", "max_hits", "timeout_s"}),
    "trigger": frozenset({"channel", "level", "slope"}),
    "windows": frozenset({"force_fraction", "force_taper", "exp_end_level", "exp_beta"}),
    "roving": frozenset({"pattern", "points"}),
    "hammer": frozenset({"url", "force_n"}),
    "sim": SIM_KEYS,
}
CHANNEL_KEYS = frozenset({"name", "physical", "role", "dof", "sensitivity", "sensitivity_unit", "range", "iepe",
                          "highpass_hz"})
#: the simulated hammer's tips (hardware_sim.hammer.TIP_STIFFNESS_N_PER_M; a test keeps the two equal)
HAMMER_TIPS = ("hard", "medium", "soft")
#: the quantity each channel role measures; its sensitivity_unit must be a sensitivity to that quantity
ROLE_QUANTITY = {"force": "force", "response": "acceleration"}
_REQUIRED = object()


def _check_keys(source: str, section: str | None, table: dict, valid) -> None:
    """A key outside ``valid`` is an error naming the file, ``section.key`` and the closest valid key."""
    for key in table:
        if key in valid:
            continue
        what = f"section [{key}]" if section is None else f"key {section}.{key}"
        if section is None and key == "conditioner":
            raise PlanError(f"{source}: section [conditioner] is not read by modalab acquire; set the conditioner up "
                            "with acquisition.IEPEConditioner (serial) and remove the section")
        close = difflib.get_close_matches(str(key), sorted(valid), n=1, cutoff=0.6)
        prefix = "" if section is None else f"{section.split('[')[0]}."
        hint = (f"did you mean {prefix}{close[0]}?" if close
                else f"valid {'sections' if section is None else 'keys'}: {', '.join(sorted(valid))}")
        raise PlanError(f"{source}: unknown {what}; {hint}")


def exponential_window(exp_beta: float | None = None, exp_end_level: float | None = None):
    """The exponential window for a decay rate ``exp_beta`` (1/s) or an end level, or None when it is off.

    The single rule used by test plans (:meth:`TestPlan.exp_window`) and by ``modalab frf``:
    ``exp_beta`` > 0 gives the window of that decay rate; ``exp_end_level`` in (0, 1) the window that
    falls to that level at the record end; ``None`` or 0 for both means no window; both non-zero is an
    error (they would disagree).  The FRF of a windowed record is the structure's at s = iω + β.
    """

    beta = None if exp_beta is None else float(exp_beta)
    end = None if exp_end_level is None else float(exp_end_level)
    if beta is not None and not (math.isfinite(beta) and beta >= 0):
        raise ModalabValueError(f"exp_beta = {exp_beta!r} must be a decay rate >= 0 in 1/s (0 = no window)")
    if end is not None and not 0 <= end < 1:
        raise ModalabValueError(f"exp_end_level = {exp_end_level!r} must be in [0, 1) (0 = no window)")
    if beta and end:
        raise ModalabValueError(f"exp_beta = {beta:g} and exp_end_level = {end:g} both given; keep one")
    if beta:
        return ExponentialWindow(beta=beta)
    if end:
        return ExponentialWindow(end_level=end)
    return None


@dataclass(frozen=True)
class PlanChannel:
    name: str
    physical: str
    role: str
    dof: str                     # a DOF label or 'roving'
    sensitivity: float           # V per SI unit
    range: float
    iepe: bool = True
    highpass_hz: float | None = None     # the input's AC-coupling corner (Hz) from the module's specifications

    def config(self, dof: Dof) -> ChannelConfig:
        return ChannelConfig(self.physical, dof, self.role, sensitivity=self.sensitivity, range=self.range,
                             iepe=self.iepe, highpass_hz=self.highpass_hz, name=self.name)


@dataclass(frozen=True)
class TestPlan:
    """A validated test plan.  Build with :func:`load_plan` or :meth:`from_dict`."""

    __test__ = False  # not a pytest class

    acq: AcquisitionConfig
    bandwidth_hz: float
    averages: int
    max_hits: int
    channels: tuple
    pattern: str
    points: tuple
    roving_channel: str
    force_fraction: float = 0.05
    force_taper: float = 0.25
    exp_end_level: float = 0.0
    exp_beta: float | None = None
    geometry: dict = field(default_factory=dict)
    hammer: dict = field(default_factory=dict)
    sim: dict = field(default_factory=dict)
    raw: dict = field(default_factory=dict, repr=False, compare=False)
    source: str = field(default="plan", compare=False)     # the plan file (for messages)

    # ----------------------------------------------------------------- build
    @classmethod
    def from_dict(cls, d: dict, source: str = "plan", base_dir=None) -> "TestPlan":
        """Validate a parsed plan.  ``base_dir``: folder against which a relative ``[sim] structure`` path is
        read (:func:`load_plan` passes the plan file's folder; default: the current directory).

        One parser per section, called in the order in which their errors take precedence."""
        _check_layout(d, source)
        get = _Reader(d, source)
        a = _parse_acquisition(get)
        parsed = _parse_channels(get)
        pattern, points, roving_channel = _parse_roving(get, parsed)
        trig_idx, level, slope = _parse_trigger(get, parsed)
        ff, taper, exp_beta, exp_end = _parse_windows(get)
        geometry = _parse_geometry(get, parsed, points)
        hammer = _parse_hammer(get, parsed)
        sim = _parse_sim(get, base_dir)
        acq = AcquisitionConfig(sample_rate_hz=a["fs"], n_samples=a["n"], pretrigger_samples=a["pre"],
                                trigger_channel=trig_idx, trigger_level=level, trigger_slope=slope,
                                timeout_s=a["timeout_s"])
        return cls(acq=acq, bandwidth_hz=a["bw"], averages=a["averages"], max_hits=a["max_hits"],
                   channels=tuple(parsed), pattern=pattern, points=points, roving_channel=roving_channel,
                   force_fraction=ff, force_taper=taper, exp_end_level=0.0 if exp_end is None else exp_end,
                   exp_beta=exp_beta, geometry=geometry, hammer=hammer, sim=sim, raw=d, source=str(source))

    def exp_window(self):
        """The plan's exponential window (:class:`acquisition.windows.ExponentialWindow`), or None when off.

        The one rule (:func:`exponential_window`): ``exp_beta`` > 0 (1/s) or ``exp_end_level`` in (0, 1);
        0 or absent switches the window off; both at once is an error.
        """
        return exponential_window(self.exp_beta, self.exp_end_level)

    # ------------------------------------------------------------- helpers
    def channel_configs(self, point: str) -> list[ChannelConfig]:
        """Channel configuration for one roving point."""
        return [c.config(Dof.parse(point) if c.dof == ROVING else Dof.parse(c.dof)) for c in self.channels]

    @property
    def fixed_dofs(self) -> list[str]:
        return [c.dof for c in self.channels if c.dof != ROVING]


# ------------------------------------------------------------------ section parsers (TestPlan.from_dict)
def _check_layout(d, source: str) -> None:
    """The plan is a non-empty table of known sections, each of the right shape and holding only known keys."""
    if not isinstance(d, dict):
        raise PlanError(f"{source}: a test plan is a TOML table of sections; got {type(d).__name__}")
    if not d:
        raise PlanError(f"{source}: the test plan is empty; write one after the example in the README or "
                        "examples/plans/")
    _check_keys(source, None, d, SECTIONS)
    for sec in SECTIONS:
        if sec == "channels":
            if not isinstance(d.get(sec, []), list) or not all(isinstance(c, dict) for c in d.get(sec, [])):
                raise PlanError(f"{source}: channels must be a list of [[channels]] tables")
        elif not isinstance(d.get(sec, {}), dict):
            raise PlanError(f"{source}: [{sec}] must be a table (a [{sec}] section), not {d[sec]!r}")
    for sec, valid in SECTION_KEYS.items():
        _check_keys(source, sec, d.get(sec, {}), valid)
    for i, c in enumerate(d.get("channels", [])):
        _check_keys(source, f"channels[{i + 1}]", c, CHANNEL_KEYS)


class _Reader:
    """Typed reads of ``section.key`` from a parsed plan ``d``; a wrong type is an error naming the key."""

    def __init__(self, d: dict, source: str):
        self.d = d
        self.source = source

    def __call__(self, section, key, default=None, kind=float, table=None):
        source = self.source
        sec = self.d.get(section, {}) if table is None else table
        if key not in sec:
            if default is _REQUIRED:
                raise PlanError(f"{source}: {section}.{key} is missing; add it (see the example in the README)")
            return default
        v = sec[key]
        if kind not in (str, bool) and isinstance(v, (bool, str)):
            v = None                       # "3" or true where a number belongs: refuse, do not coerce
        try:
            if kind in (str, bool) and not isinstance(v, kind):
                raise ValueError
            out = kind(v)
            if kind is float and not math.isfinite(out):
                raise ValueError
            if kind is int and isinstance(v, float) and v != int(v):
                raise ValueError
            return out
        except (TypeError, ValueError, OverflowError):
            what = {float: "number", int: "whole number", str: "string", bool: "true or false"}[kind]
            raise PlanError(f"{source}: {section}.{key} = {sec[key]!r} is not a valid {what}") from None


def _parse_acquisition(get: _Reader) -> dict:
    """[acquisition]: sample rate, band, record and pretrigger lengths (samples), averages, timeout."""
    source = get.source
    fs = get("acquisition", "sample_rate_hz", _REQUIRED)
    if fs <= 0:
        raise PlanError(f"{source}: acquisition.sample_rate_hz = {fs} must be positive")
    bw = get("acquisition", "bandwidth_hz", fs / 2.56)
    if not bw > 0:
        raise PlanError(f"{source}: acquisition.bandwidth_hz = {bw} must be positive")
    if bw * 2.56 > fs * (1 + 1e-9):
        raise PlanError(f"{source}: bandwidth {bw} Hz needs a sample rate of at least {2.56 * bw:g} Hz "
                        f"(2.56 x bandwidth, anti-alias margin); got {fs:g} Hz: raise sample_rate_hz or lower "
                        "bandwidth_hz")
    a = get.d.get("acquisition", {})
    if "n_samples" in a and "record_s" in a:
        raise PlanError(f"{source}: [acquisition] gives both record_s and n_samples; keep one")
    if "n_samples" in a:
        n = get("acquisition", "n_samples", kind=int)
    elif "record_s" in a:
        n = int(round(get("acquisition", "record_s") * fs))
    else:
        raise PlanError(f"{source}: [acquisition] needs record_s or n_samples")
    if n < 16:
        raise PlanError(f"{source}: the record has {n} samples; lengthen acquisition.record_s")
    if "pretrigger_samples" in a and "pretrigger_s" in a:
        raise PlanError(f"{source}: [acquisition] gives both pretrigger_s and pretrigger_samples; keep one")
    if "pretrigger_samples" in a:
        pre = get("acquisition", "pretrigger_samples", kind=int)
    else:
        pre = int(round(get("acquisition", "pretrigger_s", 0.0) * fs))
    if pre < 0:
        raise PlanError(f"{source}: the pretrigger ({pre} samples) must not be negative")
    if pre >= n:
        raise PlanError(f"{source}: pretrigger ({pre} samples = {pre / fs:g} s) is not shorter than the record "
                        f"({n} samples = {n / fs:g} s); shorten pretrigger_s or lengthen record_s")
    averages = get("acquisition", "averages", 3, int)
    max_hits = get("acquisition", "max_hits", max(averages, math.ceil(1.5 * averages)), int)
    if averages < 1 or max_hits < averages:
        raise PlanError(f"{source}: averages = {averages} and max_hits = {max_hits}: need 1 <= averages <= max_hits")
    timeout_s = get("acquisition", "timeout_s", 10.0)
    if not timeout_s > 0:
        raise PlanError(f"{source}: acquisition.timeout_s = {timeout_s} must be positive (s)")
    return dict(fs=fs, bw=bw, n=n, pre=pre, averages=averages, max_hits=max_hits, timeout_s=timeout_s)


def _parse_channel(get: _Reader, i: int, c: dict) -> "PlanChannel":
    """One [[channels]] table (the ``i``-th, from 0)."""
    where = f"{get.source}: channel {i + 1} ({c.get('name', c.get('physical', '?'))})"
    sec = f"channels[{i + 1}]"
    for key in ("physical", "role", "dof", "sensitivity", "range"):
        if key not in c:
            raise PlanError(f"{where}: '{key}' is missing")
    role = get(sec, "role", kind=str, table=c)
    if role not in ("force", "response"):
        raise PlanError(f"{where}: role {role!r}; expected 'force' or 'response'")
    unit = get(sec, "sensitivity_unit", "mV/N" if role == "force" else "mV/g", str, table=c)
    try:
        sens = sensitivity_to_si(get(sec, "sensitivity", table=c), unit)
    except (TypeError, ValueError) as e:
        raise PlanError(f"{where}: {e}") from None
    _check_unit_matches_role(where, role, unit)
    dof = get(sec, "dof", kind=str, table=c)
    if dof != ROVING:
        try:
            dof = str(Dof.parse(dof))
        except DofError as e:
            raise PlanError(f"{where}: {e}") from None
    rng = get(sec, "range", table=c)
    if rng <= 0:
        raise PlanError(f"{where}: range {rng} must be positive (N for force, m/s^2 for acceleration)")
    iepe = get(sec, "iepe", True, bool, table=c)
    hp = get(sec, "highpass_hz", None, table=c)
    if hp is not None and hp < 0:
        raise PlanError(f"{where}: highpass_hz {hp} must be the input's AC-coupling corner in Hz (>= 0)")
    if hp and not iepe:
        raise PlanError(f"{where}: highpass_hz {hp} is the AC-coupling corner of an IEPE input, but this channel "
                        "has iepe = false (DC coupled, no corner); remove highpass_hz or set iepe = true")
    return PlanChannel(name=get(sec, "name", f"ch{i}", str, table=c),
                       physical=get(sec, "physical", kind=str, table=c), role=role, dof=dof,
                       sensitivity=sens, range=rng, iepe=iepe, highpass_hz=hp)


def _check_unit_matches_role(where: str, role: str, unit: str) -> None:
    """A sensitivity to another quantity than the role measures (a hammer in mV/g) is an error: the volts would
    be read as the wrong quantity, silently, in every hit."""
    want, got = ROLE_QUANTITY[role], sensitivity_quantity(unit)
    if got == want:
        return
    other = next(r for r, q in ROLE_QUANTITY.items() if q == got)
    raise PlanError(f"{where}: sensitivity_unit = {unit!r} is a sensitivity to {got}, but role = {role!r} measures "
                    f"{want}; expected one of {', '.join(SENSITIVITY_UNITS[want])}: copy the value and its unit "
                    f"from the sensor's calibration sheet (or set role = {other!r} if this sensor measures {got})")


def _parse_channels(get: _Reader) -> list:
    """[[channels]]: uniquely named, at least one force and one response channel."""
    source = get.source
    chans = get.d.get("channels", [])
    if not chans:
        raise PlanError(f"{source}: no [[channels]]; add a force channel and at least one response channel")
    parsed = [_parse_channel(get, i, c) for i, c in enumerate(chans)]
    names = [c.name for c in parsed]
    if len(set(names)) != len(names):
        raise PlanError(f"{source}: channel names repeat: {names}")
    if not any(c.role == "force" for c in parsed):
        raise PlanError(f"{source}: no force channel; add the hammer with role = 'force'")
    if not any(c.role == "response" for c in parsed):
        raise PlanError(f"{source}: no response channel; add at least one accelerometer")
    return parsed


def _parse_roving(get: _Reader, parsed: list) -> tuple:
    """[roving]: (pattern, points, name of the roving channel)."""
    source = get.source
    r = get.d.get("roving", {})
    pattern = get("roving", "pattern", "hammer", str)
    if pattern not in ("hammer", "accelerometer"):
        raise PlanError(f"{source}: roving pattern {pattern!r}; expected 'hammer' or 'accelerometer'")
    pts = r.get("points", [])
    if not pts:
        raise PlanError(f"{source}: [roving] points is empty; list the DOFs to hit (e.g. ['1+Z', '2+Z'])")
    if not isinstance(pts, list):
        raise PlanError(f"{source}: roving.points = {pts!r}; expected a list of DOFs, e.g. ['1+Z', '2+Z']")
    try:
        points = tuple(str(Dof.parse(str(p))) for p in pts)
    except DofError as e:
        raise PlanError(f"{source}: [roving] points: {e}") from None
    if len(set(points)) != len(points):
        raise PlanError(f"{source}: [roving] points repeat a DOF: {list(points)}")
    roving_role = "force" if pattern == "hammer" else "response"
    rov = [c for c in parsed if c.dof == ROVING]
    if len(rov) != 1 or rov[0].role != roving_role:
        raise PlanError(f"{source}: pattern '{pattern}' needs exactly one {roving_role} channel with dof = 'roving'; "
                        f"found {[c.name for c in rov] or 'none'}")
    return pattern, points, rov[0].name


def _parse_trigger(get: _Reader, parsed: list) -> tuple:
    """[trigger]: (index of the trigger channel, level, slope); by default the first force channel at 2 % range."""
    source = get.source
    names = [c.name for c in parsed]
    forces = [c for c in parsed if c.role == "force"]
    trig_name = get("trigger", "channel", forces[0].name, str)
    if trig_name not in names:
        raise PlanError(f"{source}: trigger channel {trig_name!r} is not a channel name; use one of {names}")
    trig_idx = names.index(trig_name)
    level = get("trigger", "level", 0.02 * parsed[trig_idx].range)
    if not 0 < level < parsed[trig_idx].range:
        raise PlanError(f"{source}: trigger level {level} must lie between 0 and the channel range "
                        f"{parsed[trig_idx].range} {('N' if parsed[trig_idx].role == 'force' else 'm/s^2')}")
    slope = get("trigger", "slope", "rising", str)
    if slope not in ("rising", "falling"):
        raise PlanError(f"{source}: trigger.slope = {slope!r}; expected 'rising' or 'falling'")
    return trig_idx, level, slope


def _parse_windows(get: _Reader) -> tuple:
    """[windows]: (force_fraction, force_taper, exp_beta, exp_end_level); the exponential-window rule checked."""
    source = get.source
    ff = get("windows", "force_fraction", 0.05)
    if not 0 < ff <= 1:
        raise PlanError(f"{source}: force_fraction {ff} must be in (0, 1]")
    taper = get("windows", "force_taper", 0.25)
    if not 0 <= taper <= 1:
        raise PlanError(f"{source}: windows.force_taper = {taper} must be in [0, 1]")
    exp_beta = get("windows", "exp_beta", None)
    exp_end = get("windows", "exp_end_level", None)
    try:
        exponential_window(exp_beta, exp_end)
    except ModalabValueError as e:
        raise PlanError(f"{source}: [windows] {e}") from None
    return ff, taper, exp_beta, exp_end


def _parse_geometry(get: _Reader, parsed: list, points: tuple) -> dict:
    """[geometry]: node id -> (x, y, z); when given, every DOF's node must be in it."""
    source = get.source
    geometry = {}
    for k, v in get.d.get("geometry", {}).items():
        try:
            geometry[int(k)] = tuple(float(x) for x in v)
        except (TypeError, ValueError):
            raise PlanError(f"{source}: [geometry] {k} = {v!r}; expected node id = [x, y, z] in m") from None
        if len(geometry[int(k)]) != 3:
            raise PlanError(f"{source}: [geometry] {k} needs three coordinates")
    if geometry:
        fixed = [c.dof for c in parsed if c.dof != ROVING]
        for lbl in list(points) + fixed:
            if Dof.parse(lbl).node not in geometry:
                raise PlanError(f"{source}: DOF {lbl} refers to node {Dof.parse(lbl).node}, which [geometry] "
                                "does not define; add its coordinates or fix the label")
    return geometry


def _parse_hammer(get: _Reader, parsed: list) -> dict:
    """[hammer] (optional automatic hammer): url, and a force within the first force channel's range."""
    source = get.source
    hammer = dict(get.d.get("hammer", {}))
    if hammer:
        if "url" not in hammer:
            raise PlanError(f"{source}: [hammer] needs url (the automatic hammer's serial port, e.g. "
                            "'simhammer://bench' or 'COM3'); remove [hammer] for a manual hammer")
        get("hammer", "url", kind=str)
        fmax = get("hammer", "force_n", 0.0)
        frange = next(c for c in parsed if c.role == "force").range
        if fmax > frange:
            raise PlanError(f"{source}: hammer force_n = {fmax} N exceeds the force channel range {frange} N; "
                            "raise the range or lower the force")
    return hammer


def _parse_sim(get: _Reader, base_dir) -> dict:
    """[sim] (only for --backend sim): numbers as floats, faults/dead/noisy shapes, tip, structure path resolved."""
    source = get.source
    sim = dict(get.d.get("sim", {}))
    if "seed" in sim and get("sim", "seed", kind=int) < 0:
        raise PlanError(f"{source}: sim.seed = {sim['seed']} must be a whole number >= 0")
    for key in ("hit_interval_s", "force_n", "hammer_mass_kg", "force_scatter", "placement_scatter_m",
                "double_hit_probability"):
        if key in sim:
            sim[key] = get("sim", key)
    if "realtime" in sim:
        get("sim", "realtime", kind=bool)
    if not isinstance(sim.get("dead", []), list) or not all(isinstance(x, str) for x in sim.get("dead", [])):
        raise PlanError(f"{source}: sim.dead = {sim['dead']!r}; expected a list of channel names, e.g. ['acc1']")
    noisy = sim.get("noisy", {})
    if not isinstance(noisy, dict) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                              and v >= 0 for v in noisy.values()):
        raise PlanError(f"{source}: sim.noisy = {noisy!r}; expected a table of channel = extra noise in V rms "
                        "(>= 0), e.g. { acc1 = 1e-3 }")
    if not isinstance(sim.get("faults", {}), dict):
        raise PlanError(f"{source}: sim.faults = {sim['faults']!r}; expected a table, e.g. "
                        "{ double_hit_on = [2] }")
    if "hammer_tip" in sim:
        tip = get("sim", "hammer_tip", kind=str)
        if tip not in HAMMER_TIPS:
            raise PlanError(f"{source}: sim.hammer_tip = {tip!r}; expected one of {', '.join(HAMMER_TIPS)}")
    if "hammer_mass_kg" in sim and not sim["hammer_mass_kg"] > 0:
        raise PlanError(f"{source}: sim.hammer_mass_kg = {sim['hammer_mass_kg']} must be positive (kg)")
    if "structure" in sim:
        stc = get("sim", "structure", kind=str)
        if stc != "demo":
            path = Path(stc).expanduser()
            if not path.is_absolute():
                path = (Path(base_dir if base_dir is not None else ".") / path).resolve()
            if not path.is_file():
                raise PlanError(f"{source}: sim.structure = {stc!r}: no such file {str(path)!r} (a relative path "
                                "is read from the plan's folder); give 'demo' or a Nastran bulk-data file")
            sim["structure"] = str(path)
    return sim


def load_plan(path) -> TestPlan:
    """Read and validate a TOML test plan (a relative ``[sim] structure`` is read from the plan's folder)."""
    p = Path(path)
    if p.is_dir():
        raise PlanError(f"test plan {str(p)!r} is a directory; give the plan's .toml file")
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise PlanError(f"cannot read test plan {str(p)!r}: {e.strerror}; check the path") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise PlanError(f"test plan {str(p)!r} is not a text file (byte {e.start} is not UTF-8); give the plan's "
                        ".toml file") from None
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise PlanError(f"test plan {str(p)!r} is not valid TOML: {e}") from None
    return TestPlan.from_dict(d, source=str(p), base_dir=p.parent)
