"""The simulated lab: a structure, a hammer, sensors and a DAQ that deliver raw hits.

:class:`SimulatedLab` produces what a real triggered DAQ delivers after a
hammer hit, as a :class:`modalab.records.TimeRecord` in engineering units with
overload flags and ``trigger_index = pretrigger_samples``.

How a hit is synthesised (exact for a linear structure)
-------------------------------------------------------
1. The hammer draws its pulses (:meth:`Hammer.draw_pulses`): half-sines whose
   width is ``π√(m/k_tip)``, with force, width and placement scatter and an
   optional rebound.  A hit that misses its point by ``δ`` is applied partly
   at the nearest node with the same direction (linear interpolation of the
   force, weight ``δ/d``; needs node coordinates).
2. The continuous spectrum of the force (:func:`half_sine_spectrum`, exact)
   is multiplied by the structure's exact accelerance, ``structure.modal_model().frf``
   (viscous or hysteretic damping alike), on a long grid sampled at
   ``oversample × fs``.  The grid is long enough that every pole, and the
   AC-coupling pole, has decayed to ``tail_tolerance`` before the periodic
   inverse transform wraps around; the record is cut from its start.  So there
   is no wrap-around beyond ``tail_tolerance`` (≈ the 24-bit step).
3. Per channel: sensitivity (V/unit), IEPE AC-coupling high-pass, anti-alias
   filter; the oversampled signal is decimated to fs (content between fs/2 and
   ``0.8·oversample·fs/2`` aliases as it would; the simulated front end's analog
   bandwidth rolls off above that, :func:`synthesis_taper`).
4. Noise (sensor + converter), optional overload-storm transients, clipping to
   the ADC range (overload flag; the analog input before the anti-alias filter
   is checked too, as a delta-sigma modulator overloads on it), 24-bit
   quantisation, division by the sensitivity.
5. The trigger is the first sample of the digitised force crossing
   ``trigger_level`` with the set slope; the record keeps
   ``pretrigger_samples`` before it.  A hit too weak to cross the level gives
   no record (``DaqTimeoutError``), like a real DAQ.

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
import math
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np
import scipy.fft as sfft

from modalab.dof import Dof, locate, parse_dofs
from modalab.errors import DaqError, DaqTimeoutError, DeviceLostError, ModalabValueError
from modalab.frf import FRF
from modalab.records import TimeRecord
from modalab.structure import ModalModel, Structure

from .hammer import Hammer
from .setup import AcquisitionSetup, ChannelSetup, FaultConfig
from .signal_chain import (antialias_response, half_sine_spectrum, iepe_highpass, quantization_step, quantize,
                           synthesis_taper)

__all__ = ["SimulatedLab", "simulate_roving_test"]

log = logging.getLogger(__name__)

_GUARD = 32          # samples between the pretrigger and the nominal hit (room for pre-ringing)


class SimulatedLab:
    """A structure on the bench, a hammer, sensors and a triggered 24-bit DAQ, all simulated.

    Parameters
    ----------
    structure : :class:`modalab.structure.Structure` or :class:`modalab.structure.ModalModel`.
        Placement scatter needs node coordinates (``Structure.coords``); a bare
        modal model is hit exactly at the point.
    channels : sequence of :class:`ChannelSetup` (or objects with the attributes of
        ``modalab.daqconfig.ChannelConfig``), exactly one with role 'force'.  May be
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
    """

    def __init__(self, structure, channels: Sequence | None = None, setup=None, *, hammer: Hammer | None = None,
                 faults: FaultConfig | None = None, rng=None, oversample: int | None = None,
                 tail_tolerance: float = 1e-7, max_synthesis_s: float = 300.0, hit_interval_s: float = 0.0,
                 sleep: Callable[[float], None] | None = None):
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
                                    "ModalModel; build one with modalab.structure.Structure(M=..., K=..., dofs=...)")
        if oversample is not None and int(oversample) < 1:
            raise ModalabValueError(f"oversample={oversample!r} must be an integer >= 1 (or None for automatic)")
        if not hit_interval_s >= 0:
            raise ModalabValueError(f"hit_interval_s={hit_interval_s!r} must be >= 0 s")
        if not 0 < tail_tolerance < 1:
            raise ModalabValueError(f"tail_tolerance={tail_tolerance!r} must lie in (0, 1)")
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
        """Set channels and acquisition (either our setup classes or ``modalab.daqconfig`` ones)."""
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
        locate(self.model.dofs, [c.dof for c in chans], "channel DOF")
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

    def _build_grid(self) -> None:
        acq = self.setup
        fs = acq.sample_rate_hz
        poles = np.asarray(self.model.poles)
        sig = [abs(poles.real).min()] if poles.size else []
        sig += [2 * np.pi * c.coupling_corner_hz for c in self.channels if c.coupling_corner_hz > 0]
        if acq.aa_filter == "butterworth":
            sig.append(2 * np.pi * acq.aa_cutoff * fs * math.sin(math.pi / (2 * acq.aa_order)))
        sigma = min(sig) if sig else np.inf
        tail_s = math.log(1 / self.tail_tolerance) / sigma if sigma > 0 else np.inf
        self._lead = acq.pretrigger_samples + _GUARD
        self._search = int(math.ceil(self.hammer.max_width_s * fs)) + 2
        self._window = self._lead + self._search + acq.n_samples
        need = self._window + (int(math.ceil(tail_s * fs)) if np.isfinite(tail_s) else 0)
        cap = int(self.max_synthesis_s * fs)
        if not np.isfinite(tail_s) or need > cap:
            need = max(cap, self._window + acq.n_samples)
            log.warning("the slowest decay (%.3g 1/s) needs %.3g s of synthesis; capped at %.3g s, so the "
                        "response wraps around above the %.1e tolerance", sigma, tail_s, need / fs,
                        self.tail_tolerance)
        os_ = self.oversample_used
        ns = sfft.next_fast_len(need, real=True)
        self._ns = ns
        self._nos = ns * os_
        self._fs_os = fs * os_
        self._freq = sfft.rfftfreq(self._nos, 1.0 / self._fs_os)
        aa = antialias_response(self._freq, fs, acq.aa_filter, acq.aa_cutoff, acq.aa_order)
        taper = synthesis_taper(self._freq, self._fs_os / 2)
        self._pre_chain = [c.sensitivity * taper * iepe_highpass(self._freq, c.coupling_corner_hz)
                           for c in self.channels]
        self._chain = [p * aa for p in self._pre_chain]
        log.debug("synthesis grid: %d samples at %g Hz (%.3g s, slowest decay %.3g 1/s)",
                  self._nos, self._fs_os, self._nos / self._fs_os, sigma)

    @property
    def oversample_used(self) -> int:
        """Synthesis rate / fs: ``oversample`` if given, else 2 behind a delta-sigma filter and 4 otherwise."""
        if self.oversample is not None:
            return self.oversample
        return 2 if self.setup is not None and self.setup.aa_filter == "delta-sigma" else 4

    @property
    def synthesis_duration_s(self) -> float:
        """Length of the synthesis grid (s): record + the time for every decay to reach ``tail_tolerance``."""
        self._need_config()
        return self._nos / self._fs_os

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
        locate(self.model.dofs, [d], "point DOF")
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

    # ------------------------------------------------------------------ synthesis
    def _draw_hit(self, force_n, double) -> dict:
        pulses = self.hammer.draw_pulses(self._rng, force_n, force_double=double)
        miss, u_dir = self.hammer.draw_placement(self._rng)
        u_sub = float(self._rng.random())
        neighbour, weight = self._neighbour(self._point, miss, u_dir)
        return dict(pulses=pulses, point=self._point, neighbour=neighbour, weight=weight, miss_m=miss, u_sub=u_sub)

    def _neighbour(self, point: Dof, miss: float, u_dir: float):
        """The node a miss of ``miss`` m leans towards, and the weight of the force there."""
        if miss <= 0 or point.node not in self.coords:
            return None, 0.0
        here = np.asarray(self.coords[point.node], float)
        cands = []
        for d in self.model.dofs:
            if d.axis == point.axis and d.node != point.node and d.node in self.coords:
                cands.append((float(np.linalg.norm(np.asarray(self.coords[d.node], float) - here)), d.node))
        cands = sorted(c for c in cands if c[0] > 0)[:2]
        if not cands:
            return None, 0.0
        dist, node = cands[min(int(u_dir * len(cands)), len(cands) - 1)]
        return Dof(node, point.direction), min(miss / dist, 0.5)

    def _candidates(self, point: Dof) -> list[Dof]:
        """The DOFs a miss at ``point`` can lean towards (its two nearest same-axis nodes)."""
        if point.node not in self.coords or self.hammer.placement_scatter_m == 0 or self.hammer.automatic:
            return []
        out = []
        for u in (0.0, 0.99):
            d, _ = self._neighbour(point, 1.0, u)
            if d is not None and d not in out:
                out.append(d)
        return out

    def prepare(self, points) -> None:
        """Compute the exact FRF columns of ``points`` (and of the nodes a miss can reach) in batches.

        Optional: hits compute what they need on first use, but one batched call is much
        faster than one per point.  Costs ``n_response × n_lines × 16`` bytes per DOF.
        """
        self._need_config()
        want = []
        for p in parse_dofs(points):
            locate(self.model.dofs, [p], "point DOF")
            for d in [p] + self._candidates(p):
                if d not in self._cache and d not in want:
                    want.append(d)
        for a in range(0, len(want), 32):
            batch = want[a:a + 32]
            H = self.model.frf(self._freq, responses=self.response_dofs, references=batch,
                               quantity="accelerance", chunk=8192).H
            for j, d in enumerate(batch):
                self._cache[d] = np.ascontiguousarray(H[:, j, :])

    def _column(self, dof: Dof) -> np.ndarray:
        """Exact accelerance from ``dof`` to every response channel on the synthesis grid (cached)."""
        if dof not in self._cache:
            self.prepare([dof])
        return self._cache[dof]

    def _synthesise(self, p: dict) -> TimeRecord | None:
        acq = self.setup
        h = p["hit"]
        fs, os_ = acq.sample_rate_hz, self.oversample_used
        n, pre, W = acq.n_samples, acq.pretrigger_samples, self._window
        t0 = (self._lead + h["u_sub"]) / fs
        F = np.zeros(self._freq.size, complex)
        for q in h["pulses"]:
            F += half_sine_spectrum(self._freq, q.amplitude_n, q.width_s, t0 + q.delay_s)
        col = self._column(h["point"])
        if h["weight"] > 0:
            col = (1 - h["weight"]) * col + h["weight"] * self._column(h["neighbour"])
        n_ch = len(self.channels)
        v = np.zeros((n_ch, W))
        analog = [None] * n_ch
        check_analog = acq.aa_filter != "none"
        for c, ch in enumerate(self.channels):
            if ch.dead:
                continue
            X = F if c == self._force else col[self._resp.index(c)] * F
            v[c] = sfft.irfft(X * self._chain[c], n=self._nos)[: W * os_: os_] * self._fs_os
            if check_analog:
                analog[c] = sfft.irfft(X * self._pre_chain[c], n=self._nos)[: W * os_] * self._fs_os
        sigma = np.array([acq.adc_noise_v_rms if ch.dead else
                          math.sqrt(ch.noise_v_rms ** 2 + ch.extra_noise_v_rms ** 2 + acq.adc_noise_v_rms ** 2)
                          for ch in self.channels])
        v += self._rng.standard_normal((n_ch, W)) * sigma[:, None]
        if p["storm"]:
            self._add_storm(v)
        rng_v = np.array([ch.range_v for ch in self.channels])
        sens = np.array([ch.sensitivity for ch in self.channels])
        vq = np.empty_like(v)
        for c, ch in enumerate(self.channels):
            vq[c], _ = quantize(v[c], ch.range_v, acq.adc_bits)
        force = vq[self._force] / sens[self._force]
        first = max(pre, 1)
        seg = force[first - 1: self._lead + self._search]
        lvl = acq.trigger_level
        if acq.trigger_slope == "rising":
            cross = np.flatnonzero((seg[1:] >= lvl) & (seg[:-1] < lvl))
        else:
            cross = np.flatnonzero((seg[1:] <= lvl) & (seg[:-1] > lvl))
        if cross.size == 0:
            return None
        i = first + int(cross[0])
        a, b = i - pre, i - pre + n
        over = np.abs(v[:, a:b]).max(axis=1) >= rng_v
        for c in range(n_ch):
            if analog[c] is not None and np.abs(analog[c][a * os_: b * os_]).max() >= rng_v[c]:
                over[c] = True
        data = vq[:, a:b] / sens[:, None]
        self._hits += 1
        starts = [t0 + q.delay_s - i / fs for q in h["pulses"]]
        sim = dict(arm=p["arm"], point=str(h["point"]), pulse_starts_s=starts,
                   pulse_peaks_n=[q.amplitude_n for q in h["pulses"]],
                   pulse_widths_s=[q.width_s for q in h["pulses"]], double_hit=len(h["pulses"]) > 1,
                   miss_m=h["miss_m"], neighbour=None if h["neighbour"] is None else str(h["neighbour"]),
                   neighbour_weight=h["weight"], overload_storm=bool(p["storm"]),
                   dead_channels=[c for c, ch in enumerate(self.channels) if ch.dead],
                   tip=self.hammer.tip if self.hammer.tip_stiffness_n_per_m is None else "custom",
                   automatic=self.hammer.automatic)
        meta = {"point": str(h["point"]), "range": [ch.range for ch in self.channels],
                "range_v": rng_v.tolist(), "quantization_step_v": [quantization_step(r, acq.adc_bits) for r in rng_v],
                "highpass_hz": [ch.coupling_corner_hz for ch in self.channels], "aa_filter": acq.aa_filter,
                "source": "hardware_sim", "sim": sim}
        dofs = [h["point"] if c == self._force else ch.dof for c, ch in enumerate(self.channels)]
        log.debug("hit %d at %s: %.1f N peak%s", self._hits, h["point"], sim["pulse_peaks_n"][0],
                  ", OVERLOAD" if over.any() else "")
        return TimeRecord(sample_rate_hz=fs, data=data, dofs=dofs, roles=[ch.role for ch in self.channels],
                          units=[ch.units for ch in self.channels], sensitivity=sens, trigger_index=pre,
                          overload=over, hit_id=self._hits, metadata=meta)

    def _add_storm(self, v: np.ndarray) -> None:
        """Transients beyond the range on every channel inside the record (ESD, a loose ground)."""
        lo = self._lead
        hi = max(lo + 1, self._lead + self.setup.n_samples - self.setup.pretrigger_samples - 16)
        shape = np.exp(-np.arange(12) / 2.0)
        for c, ch in enumerate(self.channels):
            k = int(self._rng.integers(3, 9))
            pos = self._rng.integers(lo, hi, size=k)
            amp = ch.range_v * self._rng.uniform(1.2, 3.0, size=k) * self._rng.choice([-1.0, 1.0], size=k)
            for p_, a_ in zip(pos, amp):
                m = min(shape.size, v.shape[1] - p_)
                v[c, p_: p_ + m] += a_ * shape[:m]


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
