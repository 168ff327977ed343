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
    sensitivity_unit = "mV/N"
    range = 500.0               # N

    [[channels]]
    name = "acc1"
    physical = "cDAQ1Mod1/ai1"
    role = "response"
    dof = "3+Z"
    sensitivity = 100.0
    sensitivity_unit = "mV/g"
    range = 500.0               # m/s^2

    [roving]
    pattern = "hammer"          # or "accelerometer" (then `channel` names the roving sensor)
    points = ["1+Z", "2+Z", "3+Z"]

    [geometry]                  # optional node coordinates in m
    1 = [0.0, 0.0, 0.0]

    [hammer]                    # optional automatic hammer (serial)
    url = "simhammer://bench"
    force_n = 100.0

    [sim]                       # only for --backend sim (all keys: modalab.pipeline.make_sim_backend)
    structure = "demo"          # built-in demo structure
    seed = 1
    hit_interval_s = 0.0        # simulated time from arm to the operator's hit
    # faults = { double_hit_on = [2], device_lost_on = [7] }; dead = ["acc1"]; noisy = { acc1 = 0.05 }

Ready-made plans for the demo structure: ``examples/plans/demo_roving_hammer.toml``,
``demo_roving_accelerometer.toml`` and ``demo_auto_hammer.toml`` (automatic hammer ``simhammer://bench``).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from modalab.daqconfig import AcquisitionConfig, ChannelConfig, sensitivity_to_si
from modalab.dof import Dof
from modalab.errors import DofError, PlanError

__all__ = ["TestPlan", "load_plan", "PlanChannel"]

ROVING = "roving"


@dataclass(frozen=True)
class PlanChannel:
    name: str
    physical: str
    role: str
    dof: str                     # a DOF label or 'roving'
    sensitivity: float           # V per SI unit
    range: float
    iepe: bool = True

    def config(self, dof: Dof) -> ChannelConfig:
        return ChannelConfig(self.physical, dof, self.role, sensitivity=self.sensitivity, range=self.range,
                             iepe=self.iepe, name=self.name)


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
    conditioner: dict = field(default_factory=dict)
    sim: dict = field(default_factory=dict)
    raw: dict = field(default_factory=dict, repr=False, compare=False)

    # ----------------------------------------------------------------- build
    @classmethod
    def from_dict(cls, d: dict, source: str = "plan") -> "TestPlan":
        def need(section, key, kind=float):
            sec = d.get(section, {})
            if key not in sec:
                raise PlanError(f"{source}: [{section}] {key} is missing; add it (see the example in the README)")
            try:
                return kind(sec[key])
            except (TypeError, ValueError):
                raise PlanError(f"{source}: [{section}] {key} = {sec[key]!r} is not a valid {kind.__name__}") from None

        known = {"acquisition", "trigger", "windows", "channels", "roving", "geometry", "hammer", "conditioner", "sim"}
        unknown = set(d) - known
        if unknown:
            raise PlanError(f"{source}: unknown section(s) {sorted(unknown)}; expected {sorted(known)}")
        a = d.get("acquisition", {})
        fs = need("acquisition", "sample_rate_hz")
        if fs <= 0:
            raise PlanError(f"{source}: sample_rate_hz = {fs} must be positive")
        bw = float(a.get("bandwidth_hz", fs / 2.56))
        if bw * 2.56 > fs * (1 + 1e-9):
            raise PlanError(f"{source}: bandwidth {bw} Hz needs a sample rate of at least {2.56 * bw:g} Hz "
                            f"(2.56 x bandwidth, anti-alias margin); got {fs:g} Hz")
        if "n_samples" in a:
            n = int(a["n_samples"])
        elif "record_s" in a:
            n = int(round(float(a["record_s"]) * fs))
        else:
            raise PlanError(f"{source}: [acquisition] needs record_s or n_samples")
        if "pretrigger_samples" in a:
            pre = int(a["pretrigger_samples"])
        else:
            pre = int(round(float(a.get("pretrigger_s", 0.0)) * fs))
        if pre >= n:
            raise PlanError(f"{source}: pretrigger ({pre} samples = {pre / fs:g} s) is not shorter than the record "
                            f"({n} samples = {n / fs:g} s); shorten pretrigger_s or lengthen record_s")
        averages = int(a.get("averages", 3))
        max_hits = int(a.get("max_hits", max(averages, math.ceil(1.5 * averages))))
        if averages < 1 or max_hits < averages:
            raise PlanError(f"{source}: averages = {averages} and max_hits = {max_hits}: need 1 <= averages <= max_hits")

        chans = d.get("channels", [])
        if not chans:
            raise PlanError(f"{source}: no [[channels]]; add a force channel and at least one response channel")
        parsed = []
        for i, c in enumerate(chans):
            where = f"{source}: channel {i + 1} ({c.get('name', c.get('physical', '?'))})"
            for key in ("physical", "role", "dof", "sensitivity", "range"):
                if key not in c:
                    raise PlanError(f"{where}: '{key}' is missing")
            role = str(c["role"])
            if role not in ("force", "response"):
                raise PlanError(f"{where}: role {role!r}; expected 'force' or 'response'")
            unit = c.get("sensitivity_unit", "mV/N" if role == "force" else "mV/g")
            try:
                sens = sensitivity_to_si(float(c["sensitivity"]), unit)
            except (TypeError, ValueError) as e:
                raise PlanError(f"{where}: {e}") from None
            dof = str(c["dof"])
            if dof != ROVING:
                try:
                    dof = str(Dof.parse(dof))
                except DofError as e:
                    raise PlanError(f"{where}: {e}") from None
            rng = float(c["range"])
            if rng <= 0:
                raise PlanError(f"{where}: range {rng} must be positive (N for force, m/s^2 for acceleration)")
            parsed.append(PlanChannel(name=str(c.get("name", f"ch{i}")), physical=str(c["physical"]), role=role,
                                      dof=dof, sensitivity=sens, range=rng, iepe=bool(c.get("iepe", True))))
        names = [c.name for c in parsed]
        if len(set(names)) != len(names):
            raise PlanError(f"{source}: channel names repeat: {names}")
        forces = [c for c in parsed if c.role == "force"]
        if not forces:
            raise PlanError(f"{source}: no force channel; add the hammer with role = 'force'")
        if not any(c.role == "response" for c in parsed):
            raise PlanError(f"{source}: no response channel; add at least one accelerometer")

        r = d.get("roving", {})
        pattern = str(r.get("pattern", "hammer"))
        if pattern not in ("hammer", "accelerometer"):
            raise PlanError(f"{source}: roving pattern {pattern!r}; expected 'hammer' or 'accelerometer'")
        pts = r.get("points", [])
        if not pts:
            raise PlanError(f"{source}: [roving] points is empty; list the DOFs to hit (e.g. ['1+Z', '2+Z'])")
        try:
            points = tuple(str(Dof.parse(p)) for p in pts)
        except DofError as e:
            raise PlanError(f"{source}: [roving] points: {e}") from None
        if len(set(points)) != len(points):
            raise PlanError(f"{source}: [roving] points repeat a DOF: {list(points)}")
        roving_role = "force" if pattern == "hammer" else "response"
        rov = [c for c in parsed if c.dof == ROVING]
        if len(rov) != 1 or rov[0].role != roving_role:
            raise PlanError(f"{source}: pattern '{pattern}' needs exactly one {roving_role} channel with dof = 'roving'; "
                            f"found {[c.name for c in rov] or 'none'}")
        roving_channel = rov[0].name

        t = d.get("trigger", {})
        trig_name = str(t.get("channel", forces[0].name))
        if trig_name not in names:
            raise PlanError(f"{source}: trigger channel {trig_name!r} is not a channel name; use one of {names}")
        trig_idx = names.index(trig_name)
        level = float(t.get("level", 0.02 * parsed[trig_idx].range))
        if not 0 < level < parsed[trig_idx].range:
            raise PlanError(f"{source}: trigger level {level} must lie between 0 and the channel range "
                            f"{parsed[trig_idx].range} {('N' if parsed[trig_idx].role == 'force' else 'm/s^2')}")

        w = d.get("windows", {})
        ff = float(w.get("force_fraction", 0.05))
        if not 0 < ff <= 1:
            raise PlanError(f"{source}: force_fraction {ff} must be in (0, 1]")
        exp_beta = w.get("exp_beta")
        exp_end = float(w.get("exp_end_level", 0.0))
        if exp_beta is None and not 0 <= exp_end < 1:
            raise PlanError(f"{source}: exp_end_level {exp_end} must be in [0, 1) (0 switches the window off)")

        geometry = {}
        for k, v in d.get("geometry", {}).items():
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
        hammer = dict(d.get("hammer", {}))
        if hammer:
            fmax = float(hammer.get("force_n", 0))
            frange = parsed[names.index(forces[0].name)].range
            if fmax > frange:
                raise PlanError(f"{source}: hammer force_n = {fmax} N exceeds the force channel range {frange} N; "
                                "raise the range or lower the force")
        acq = AcquisitionConfig(sample_rate_hz=fs, n_samples=n, pretrigger_samples=pre, trigger_channel=trig_idx,
                                trigger_level=level, trigger_slope=str(t.get("slope", "rising")),
                                timeout_s=float(a.get("timeout_s", 10.0)))
        return cls(acq=acq, bandwidth_hz=bw, averages=averages, max_hits=max_hits, channels=tuple(parsed),
                   pattern=pattern, points=points, roving_channel=roving_channel, force_fraction=ff,
                   force_taper=float(w.get("force_taper", 0.25)), exp_end_level=exp_end,
                   exp_beta=None if exp_beta is None else float(exp_beta), geometry=geometry, hammer=hammer,
                   conditioner=dict(d.get("conditioner", {})), sim=dict(d.get("sim", {})), raw=d)

    # ------------------------------------------------------------- helpers
    def channel_configs(self, point: str) -> list[ChannelConfig]:
        """Channel configuration for one roving point."""
        return [c.config(Dof.parse(point) if c.dof == ROVING else Dof.parse(c.dof)) for c in self.channels]

    @property
    def fixed_dofs(self) -> list[str]:
        return [c.dof for c in self.channels if c.dof != ROVING]


def load_plan(path) -> TestPlan:
    """Read and validate a TOML test plan."""
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as e:
        raise PlanError(f"cannot read test plan {str(p)!r}: {e.strerror}; check the path") from None
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise PlanError(f"test plan {str(p)!r} is not valid TOML: {e}") from None
    return TestPlan.from_dict(d, source=str(p))
