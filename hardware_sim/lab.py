"""The simulated lab: a structure, a hammer, sensors and a DAQ that deliver raw hits.

:class:`SimulatedLab` produces what a real triggered DAQ delivers after a
hammer hit, as a :class:`modalab.core.records.TimeRecord` in engineering units with
overload flags and ``trigger_index = pretrigger_samples``.

How a hit is synthesised (exact for a linear structure): see :mod:`hardware_sim.synthesis`.

DAQ-style use (what a backend wraps): ``configure`` → ``notify_point`` →
``arm`` → (``fire`` for an automatic hammer) → ``wait`` → ``abort`` / ``close``.
Convenience: :meth:`SimulatedLab.hit` and :func:`simulate_roving_test`; :meth:`SimulatedLab.prepare`
computes the exact FRF columns of many points in one batched call.

All randomness comes from the one ``numpy.random.Generator`` passed in (or
seeded from an int): the same seed and the same calls give the same records.
:meth:`SimulatedLab.seed_hit` re-seeds that stream from (seed, point, hit): an
acquisition session calls it before each new hit, so a session interrupted and
resumed draws exactly the hits an uninterrupted one draws (faults scheduled by
arm number still count the arms of this lab object).
"""
from __future__ import annotations

import logging
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from modalab.core.dof import Dof, locate, parse_dofs
from modalab.core.errors import DaqError, DaqTimeoutError, DeviceLostError, ModalabValueError
from modalab.core.frf import FRF
from modalab.core.records import TimeRecord
from modalab.core.structure import ModalModel, Structure

from .hammer import Hammer
from .setup import AcquisitionSetup, ChannelSetup, FaultConfig
from .synthesis import _HitSynthesis

__all__ = ["SimulatedLab", "simulate_roving_test"]

log = logging.getLogger(__name__)


class SimulatedLab(_HitSynthesis):
    """A structure on the bench, a hammer, sensors and a triggered 24-bit DAQ, all simulated.

    Parameters
    ----------
    structure : :class:`modalab.core.structure.Structure` or :class:`modalab.core.structure.ModalModel`.
        Placement scatter needs node coordinates (``Structure.coords``); a bare
        modal model is hit exactly at the point.
    channels : sequence of :class:`ChannelSetup` (or objects with the attributes of
        ``modalab.core.daqconfig.ChannelConfig``), exactly one with role 'force'.  May be
        given later with :meth:`configure`.
    setup : :class:`AcquisitionSetup` (default: 2048 Hz, 8192 samples, 128 pretrigger).
    hammer : :class:`Hammer` (default: 0.16 kg, medium tip, manual, 200 N).
    faults : :class:`FaultConfig` (default: none).
    rng : ``numpy.random.Generator`` or an int seed (None: fresh OS entropy).
    oversample : synthesis rate as a multiple of fs; None picks 2 behind the delta-sigma filter (it leaves
        nothing above 0.55 fs) and 4 otherwise, so content up to 0.8 × oversample × fs/2 aliases as it would.
    tail_tolerance : relative amplitude the slowest decay must reach before the synthesis grid wraps.
    max_synthesis_s : cap on the synthesis grid length (s) for nearly undamped structures.
    hit_interval_s : how long after ``arm()`` the manual operator's hit comes (simulated time); a
        ``wait`` with a shorter timeout reports 'no hit yet' and a later ``wait`` gets the hit.
    sleep : optional callable ``sleep(seconds)`` to make ``wait`` take real time (e.g. ``time.sleep``);
        by default the simulation returns at once.
    hammer_points : the DOFs the hammer will visit (a roving-hammer plan's points).  The first hit that needs
        an FRF column computes those of every listed point with it, in one pass over the synthesis grid
        (:meth:`prepare`): the pole terms of every line are shared by all columns, and computing them once per
        point was most of the simulated acquisition's time (the demo: 13 passes over 153 601 lines and 1 566
        poles).  The records are the same either way; default none (each point's columns when first hit).
    """

    kind = "sim"         #: recorded with the data (session.json, UFF ID lines): simulated, not measured

    def __init__(self, structure, channels: Sequence | None = None, setup=None, *, hammer: Hammer | None = None,
                 faults: FaultConfig | None = None, rng=None, oversample: int | None = None,
                 tail_tolerance: float = 1e-7, max_synthesis_s: float = 300.0, hit_interval_s: float = 0.0,
                 sleep: Callable[[float], None] | None = None, hammer_points: Sequence = ()):
        if isinstance(structure, Structure):
            self.structure = structure
            self.model = structure.modal_model()
            self.coords = dict(structure.coords)
        elif isinstance(structure, ModalModel):
            self.structure = None
            self.model = structure
            self.coords = {}
        else:
            raise ModalabValueError(f"structure {type(structure).__name__!r} is neither a modalab Structure nor a "
                                    "ModalModel; build one with modalab.core.structure.Structure(M=..., K=..., dofs=...)")
        if oversample is not None and int(oversample) < 1:
            raise ModalabValueError(f"oversample={oversample!r} must be an integer >= 1 (or None for automatic)")
        if not hit_interval_s >= 0:
            raise ModalabValueError(f"hit_interval_s={hit_interval_s!r} must be >= 0 s")
        if not 0 < tail_tolerance < 1:
            raise ModalabValueError(f"tail_tolerance={tail_tolerance!r} must lie in (0, 1)")
        self.hammer_points = parse_dofs(hammer_points)
        locate(self.model.dofs, self.hammer_points, "hammer point", "the model")
        self.hammer = hammer if hammer is not None else Hammer()
        self.faults = faults if faults is not None else FaultConfig()
        self.oversample = None if oversample is None else int(oversample)
        self.tail_tolerance = float(tail_tolerance)
        self.max_synthesis_s = float(max_synthesis_s)
        self.hit_interval_s = float(hit_interval_s)
        self._rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self._seed = None if rng is None or isinstance(rng, np.random.Generator) else int(rng)
        self._sleep = sleep
        self._state = "unconfigured"
        self._arms = 0
        self._hits = 0
        self._storm_left = 0
        self._pending: dict | None = None
        self.channels: list[ChannelSetup] = []
        self.setup: AcquisitionSetup | None = None
        if channels is not None:
            self.configure(channels, setup)
        elif setup is not None:
            raise ModalabValueError("an acquisition setup without channels; pass channels too, or call configure()")

    def __repr__(self) -> str:
        name = self.structure.name if self.structure is not None and self.structure.name else "modal model"
        if self._state == "unconfigured":
            return f"SimulatedLab({name}, unconfigured)"
        return (f"SimulatedLab({name}: {len(self.channels)} channels at {self.setup.sample_rate_hz:g} Hz, hammer at "
                f"{self._point} ({'automatic' if self.hammer.automatic else 'manual'}, {self.hammer.tip} tip), "
                f"{self._state}, {self._hits} hits)")

    # ------------------------------------------------------------------ config
    def configure(self, channels: Sequence, setup=None) -> None:
        """Set channels and acquisition (either our setup classes or ``modalab.core.daqconfig`` ones)."""
        if self._state in ("closed", "lost"):
            self._check_usable()
        chans = [ChannelSetup.from_config(c) for c in channels]
        acq = AcquisitionSetup() if setup is None else AcquisitionSetup.from_config(setup)
        force = [i for i, c in enumerate(chans) if c.role == "force"]
        if len(force) != 1:
            raise ModalabValueError(f"{len(force)} force channels; the simulated lab needs exactly one (the hammer)")
        tc = getattr(setup, "trigger_channel", None)
        if tc is not None and int(tc) != force[0]:
            raise ModalabValueError(f"trigger_channel={tc} but the force channel is channel {force[0]}; "
                                    "the simulated lab triggers on the hammer")
        locate(self.model.dofs, [c.dof for c in chans], "channel DOF", "the model")
        # the synthesis grid and the FRF cache depend on everything but the hammer's DOF: keep them
        # when a session reconfigures per point with only the roving DOF changed
        key = (acq, tuple(replace(c, dof=Dof(0)) if c.role == "force" else c for c in chans))
        self.channels = chans
        self.setup = acq
        self._force = force[0]
        self._resp = [i for i, c in enumerate(chans) if c.role == "response"]
        self._point = chans[force[0]].dof
        if key != getattr(self, "_config_key", None):
            self._cache: dict = {}
            self._build_grid()
            self._config_key = key
        if self._state in ("unconfigured", "armed"):
            self._state = "idle"
        self._pending = None

    @property
    def point(self) -> Dof:
        """Where the hammer will hit next."""
        self._need_config()
        return self._point

    @property
    def response_dofs(self) -> list[Dof]:
        return [self.channels[i].dof for i in self._resp]

    @property
    def n_armed(self) -> int:
        """How many times the DAQ was armed (fault schedules count these)."""
        return self._arms

    @property
    def state(self) -> str:
        """'unconfigured', 'idle', 'armed', 'lost' or 'closed'."""
        return self._state

    def _need_config(self):
        if self._state == "unconfigured":
            raise DaqError("the simulated lab has no channels yet; call configure(channels, setup) first")

    def _check_usable(self):
        if self._state == "closed":
            raise DaqError("the simulated DAQ is closed; create a new SimulatedLab")
        if self._state == "lost":
            raise DeviceLostError("the simulated DAQ has disappeared (injected fault); call reconnect() "
                                  "or reopen the backend")
        self._need_config()

    # ------------------------------------------------------------------ where
    def notify_point(self, dof, role: str = "force", channel: int | None = None) -> None:
        """Move the hammer (role 'force') or a roving accelerometer (role 'response') to ``dof``.

        With several response channels give ``channel`` (index into the channel list) for the one that moves.
        """
        self._need_config()
        d = Dof.parse(dof)
        locate(self.model.dofs, [d], "point DOF", "the model")
        if role == "force":
            self._point = d
            return
        if role != "response":
            raise ModalabValueError(f"role {role!r}; expected 'force' or 'response'")
        if channel is None:
            there = [i for i in self._resp if self.channels[i].dof.same_axis(d)]
            if there:                                    # configure() already put a sensor there
                if self.channels[there[0]].dof != d:
                    self.channels[there[0]] = replace(self.channels[there[0]], dof=d)
                    self._cache.clear()
                    self._config_key = None
                return
            if len(self._resp) != 1:
                raise ModalabValueError(f"{len(self._resp)} response channels; say which one roves with channel=")
            channel = self._resp[0]
        if channel not in self._resp:
            raise ModalabValueError(f"channel {channel} is not a response channel; response channels: {self._resp}")
        self.channels[channel] = replace(self.channels[channel], dof=d)
        self._cache.clear()
        self._config_key = None

    def seed_hit(self, *key: int) -> None:
        """Draw the next hit (and its retries) from a stream of its own, seeded by (lab seed, ``*key``).

        An acquisition session passes (point index, hit number at that point): the same key always gives
        the same force pulse, placement, faults drawn by probability and noise, whatever happened before,
        so resuming an interrupted session repeats no random stream.  A lab built from a Generator (or
        None) draws its seed from that generator on the first call.
        """
        if any(int(k) < 0 for k in key):
            raise ModalabValueError(f"seed_hit{key!r}: keys are non-negative integers (point index, hit number)")
        if self._seed is None:
            self._seed = int(self._rng.integers(2 ** 63))
        self._rng = np.random.default_rng([self._seed, *(int(k) for k in key)])

    # ------------------------------------------------------------------ DAQ
    def arm(self, force_n: float | None = None) -> None:
        """Arm a triggered finite acquisition.  A manual operator then hits the current point
        (with ``force_n`` as their target, else the hammer's nominal force); an automatic
        hammer waits for :meth:`fire`."""
        self._check_usable()
        self._arms += 1
        k = self._arms
        f = self.faults
        u = self._rng.random(4)
        if self._storm_left == 0 and u[2] < f.overload_storm_probability:
            self._storm_left = int(f.overload_storm_length)
        storm = k in f.overload_storm_on or self._storm_left > 0
        if self._storm_left > 0:
            self._storm_left -= 1
        self._pending = dict(arm=k, no_trigger=k in f.no_trigger_on or u[0] < f.no_trigger_probability,
                             lost=k in f.device_lost_on or u[1] < f.device_lost_probability, storm=storm,
                             double=k in f.double_hit_on or u[3] < f.double_hit_probability,
                             force_n=force_n, hit=None,
                             remaining_s=0.0 if self.hammer.automatic else self.hit_interval_s)
        if not self.hammer.automatic:
            self._pending["hit"] = self._draw_hit(force_n, self._pending["double"])
        self._state = "armed"
        log.debug("armed (arm %d)%s", k, ", fault(s) pending" if any(
            self._pending[x] for x in ("no_trigger", "lost", "storm", "double")) else "")

    def fire(self, force_n: float | None = None) -> None:
        """Fire the automatic hammer at the current point with peak force ``force_n`` (N)."""
        self._check_usable()
        if not self.hammer.automatic:
            raise DaqError("fire() needs an automatic hammer; build the lab with Hammer(automatic=True) "
                           "or let the manual operator hit on arm()")
        if self._state != "armed":
            log.warning("the automatic hammer fired while the DAQ was not armed; the hit is lost")
            return
        if self._pending["hit"] is not None:
            log.warning("the automatic hammer fired twice in one record; the second command is ignored")
            return
        self._pending["hit"] = self._draw_hit(force_n, self._pending["double"])

    def wait(self, timeout_s: float | None = None) -> TimeRecord:
        """Block until the triggered record is complete and return it.

        Raises ``DaqTimeoutError`` when no trigger came (no hit, a hit below the trigger
        level, an automatic hammer not fired, or the injected fault), ``DeviceLostError``
        when the device disappears mid-record.
        """
        self._check_usable()
        if self._state != "armed":
            raise DaqError("wait() on a DAQ that is not armed; call arm() first")
        acq = self.setup
        timeout = acq.timeout_s if timeout_s is None else float(timeout_s)
        p = self._pending
        if p["lost"]:
            self._state = "lost"
            self._pending = None
            done = 0.3 + 0.4 * self._rng.random()
            self._pause(done * acq.duration_s)
            raise DeviceLostError(f"the simulated DAQ disappeared {done * acq.duration_s:.3g} s into the record "
                                  f"(arm {p['arm']}, injected fault); call reconnect() or reopen the backend")
        if p["no_trigger"] or p["hit"] is None:
            self._pause(timeout)
            why = ("injected fault: the trigger never comes" if p["no_trigger"]
                   else "the automatic hammer was not fired")
            raise DaqTimeoutError(f"no trigger within {timeout:g} s ({why}); fire or hit, then wait again")
        if p["remaining_s"] > timeout:
            p["remaining_s"] -= timeout
            self._pause(timeout)
            raise DaqTimeoutError(f"no trigger within {timeout:g} s (no hit yet); wait again")
        self._pause(p["remaining_s"])
        p["remaining_s"] = 0.0
        rec = self._synthesise(p)
        if rec is None:
            peak = max(q.amplitude_n for q in p["hit"]["pulses"])
            self._pause(timeout)
            if not self.hammer.automatic:          # the operator sees nothing happen and hits again
                p["hit"] = self._draw_hit(p["force_n"], p["double"])
            else:
                p["hit"] = None
            raise DaqTimeoutError(f"no trigger within {timeout:g} s: the hit of {peak:.3g} N did not cross the "
                                  f"trigger level {acq.trigger_level:g} N ({acq.trigger_slope}); hit harder or "
                                  "lower the trigger level")
        self._pause(acq.duration_s)
        self._state = "idle"
        self._pending = None
        return rec

    def abort(self) -> None:
        """Stop an armed acquisition; a pending hit is discarded."""
        if self._state == "armed":
            self._state = "idle"
        self._pending = None

    def reconnect(self) -> None:
        """Bring a lost device back (like re-plugging it); the lab is idle afterwards."""
        if self._state == "lost":
            self._state = "idle"

    def close(self) -> None:
        """Release the simulated device; further use raises ``DaqError``."""
        self._pending = None
        self._state = "closed"

    def __enter__(self) -> "SimulatedLab":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _pause(self, seconds: float) -> None:
        if self._sleep is not None and seconds > 0:
            self._sleep(seconds)

    # ------------------------------------------------------------------ convenience
    def hit(self, point=None, force_n: float | None = None, timeout_s: float | None = None) -> TimeRecord:
        """Hit ``point`` (default: the current point) once and return the record.

        Manual hammer: the operator aims at ``force_n`` (default the hammer's nominal force).
        Automatic hammer: arms, fires ``force_n`` and waits.
        """
        if point is not None:
            self.notify_point(point)
        if self.hammer.automatic:
            self.arm()
            self.fire(force_n)
        else:
            self.arm(force_n)
        return self.wait(timeout_s)

    def exact_frf(self, freq_hz, point=None, quantity: str = "accelerance") -> FRF:
        """The structure's exact FRFs from ``point`` (default: the current one) to the response channels."""
        self._need_config()
        ref = self._point if point is None else Dof.parse(point)
        return self.model.frf(freq_hz, responses=self.response_dofs, references=[ref], quantity=quantity)

def simulate_roving_test(lab: SimulatedLab, points: Sequence, hits_per_point: int = 3,
                         force_n: float | None = None, max_attempts: int = 10) -> list[TimeRecord]:
    """A roving-hammer test: ``hits_per_point`` records at each DOF of ``points``, in order.

    Hits that give no trigger are repeated up to ``max_attempts`` times per hit;
    overloaded or double hits are kept (judging them is acquisition's job; see
    ``record.overload`` and ``record.metadata['sim']``).
    """
    if int(hits_per_point) < 1:
        raise ModalabValueError(f"hits_per_point={hits_per_point!r} must be >= 1")
    records = []
    lab.prepare(points)
    for pt in parse_dofs(points):
        lab.notify_point(pt)
        for _ in range(int(hits_per_point)):
            for attempt in range(int(max_attempts)):
                try:
                    records.append(lab.hit(force_n=force_n))
                    break
                except DaqTimeoutError:
                    lab.abort()
                    if attempt == max_attempts - 1:
                        raise
    return records
