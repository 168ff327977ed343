"""NI-DAQmx backend: a thin translation of our channel/trigger config into the official API.

* hammer: ``ai_channels.add_ai_force_iepe_chan`` (N, mV/N, internal current excitation);
* accelerometers: ``ai_channels.add_ai_accel_chan`` (m/s², mV/g);
* AC coupling for IEPE channels (``ai_coupling = Coupling.AC``); the coupling's corner is recorded with every
  hit (``metadata['highpass_hz']``, one per channel, 0 for DC coupling: the force window keeps the coupling's
  undershoot with it).  NI-DAQmx has no channel attribute for it (AC coupling switches in a single-pole RC
  high-pass whose corner the device's specifications give; ``ai_dig_fltr_highpass_cutoff_freq`` is a digital
  filter's, another thing), so it comes from the plan's ``highpass_hz``; a hit of an AC-coupled channel
  without it records no corners, and :meth:`NidaqmxBackend.configure` warns;
* ``timing.cfg_samp_clk_timing`` finite acquisition of the record length;
* a hardware reference trigger on the hammer channel with pretrigger samples
  (``triggers.reference_trigger.cfg_anlg_edge_ref_trig``);
* ``AnalogMultiChannelReader.read_many_sample`` into a preallocated array;
* overload flags read after every record (``in_stream.overloaded_chans_exist``,
  ``in_stream.overloaded_chans``);
* optional TEDS (``PhysicalChannel.configure_teds`` then the ``add_teds_*`` variants).

nidaqmx is imported only here and only when the backend is created.  Errors
map to ours: the missing NI driver raises :class:`modalab.core.errors.DaqNotFoundError`
(not a DaqError) telling to install NI-DAQmx or use ``--backend sim``; a read
timeout raises :class:`modalab.core.errors.DaqTimeoutError` ("no hit yet", the task
stays armed); other driver errors raise :class:`modalab.core.errors.DaqError` with
the NI error code and what to check.
"""
from __future__ import annotations

import logging
from typing import Callable, Sequence

import numpy as np

from modalab.core.daqconfig import AcquisitionConfig, ChannelConfig
from modalab.core.dof import Dof
from modalab.core.errors import DaqError, DaqNotFoundError, DaqTimeoutError, PlanError
from modalab.core.records import TimeRecord
from modalab.core.units import G

log = logging.getLogger(__name__)
__all__ = ["NidaqmxBackend"]

_NO_DRIVER = ("the NI-DAQmx driver is not installed on this machine ({detail}). Install NI-DAQmx "
              "(https://www.ni.com/en/support/downloads/drivers/download.ni-daq-mx.html) or run with "
              "--backend sim to use the simulated lab")
_TIMEOUT_CODES = {-200284, -200474, -200278}  # samples not yet available, operation timed out, attempted read beyond


def _import_nidaqmx():
    try:
        import nidaqmx  # noqa: F401  # lazy: optional nidaqmx (daq extra)
        import nidaqmx.constants  # lazy: optional nidaqmx (daq extra)
        import nidaqmx.errors  # lazy: optional nidaqmx (daq extra)
        import nidaqmx.stream_readers  # lazy: optional nidaqmx (daq extra)
    except ImportError as e:  # package itself missing
        raise DaqNotFoundError(f"the python package nidaqmx is not installed ({e}): install it with "
                               f"pip install 'modalab[daq]' (and the NI-DAQmx driver), or run with --backend sim "
                               f"to use the simulated lab") from None
    return nidaqmx


def _coupling_corners(channels: Sequence[ChannelConfig]) -> list | None:
    """The AC-coupling corner (Hz) of each channel as configured: 0 for a DC-coupled one (``iepe`` off), the
    plan's ``highpass_hz`` for an AC-coupled one; None (with a warning) when an AC-coupled channel's is not
    stated: NI-DAQmx does not report it, and a guess would bias the FRFs the force window makes."""
    corners = [0.0 if not ch.iepe else ch.highpass_hz for ch in channels]
    unknown = [ch.name or ch.physical for ch, hp in zip(channels, corners) if hp is None]
    if unknown:
        log.warning("AC-coupling corner of %s not stated: the hits record no corners, and the force window will cut "
                    "the coupling's undershoot from the force (the FRFs are then off by percents below a few times "
                    "the corner). "
                    "Give highpass_hz (Hz) for each IEPE channel in the plan's [[channels]], from the DAQ module's "
                    "specifications (AC-coupling -3 dB cutoff); NI-DAQmx does not report it",
                    ", ".join(unknown))
        return None
    return [float(c) for c in corners]


class NidaqmxBackend:
    """Real NI hardware.  ``task_factory`` creates the ``nidaqmx.Task`` (tests pass an autospec'd one).

    ``use_teds`` reads sensor sensitivities from TEDS chips instead of the plan.
    """

    kind = "nidaqmx"     #: recorded with the data (session.json, UFF ID lines)

    def __init__(self, *, task_factory: Callable | None = None, use_teds: bool = False):
        self._nidaqmx = _import_nidaqmx()
        self._task_factory = task_factory or self._nidaqmx.Task
        self.use_teds = use_teds
        self._task = None
        self._channels: list[ChannelConfig] = []
        self._acq: AcquisitionConfig | None = None
        self._reader = None
        self._point: Dof | None = None
        self._hit = 0
        self._highpass: list | None = None

    # ------------------------------------------------------------------ errors
    def _translate(self, exc, action: str):
        errors = self._nidaqmx.errors
        if isinstance(exc, errors.DaqNotFoundError):
            return DaqNotFoundError(_NO_DRIVER.format(detail=str(exc).splitlines()[0] if str(exc) else "not found"))
        code = getattr(exc, "error_code", None)
        if code in _TIMEOUT_CODES:
            return DaqTimeoutError(f"no hit within the timeout while {action} (NI error {code}); "
                                   "hit the structure or lower the trigger level")
        return DaqError(f"NI-DAQmx error {code} while {action}: {str(exc).splitlines()[0] if str(exc) else exc}. "
                        "Check the device name in NI MAX, the channel ranges and the cabling")

    # -------------------------------------------------------------- protocol
    def configure(self, channels: Sequence[ChannelConfig], acq: AcquisitionConfig) -> None:
        c = self._nidaqmx.constants
        if not channels:
            raise PlanError("no channels to configure; the plan needs a force channel and at least one response channel")
        if not 0 <= acq.trigger_channel < len(channels):
            raise PlanError(f"trigger channel index {acq.trigger_channel} outside 0..{len(channels) - 1}")
        self.close()
        try:
            task = self._task_factory()
        except Exception as e:  # noqa: BLE001 - translated below
            raise self._translate(e, "creating the task") from None
        self._task = task
        try:
            for i, ch in enumerate(channels):
                name = ch.name or f"ch{i}_{ch.dof}".replace("+", "p").replace("-", "m")
                excit = c.ExcitationSource.INTERNAL if ch.iepe else c.ExcitationSource.NONE
                if self.use_teds:
                    from nidaqmx.system import PhysicalChannel  # lazy: optional nidaqmx (daq extra)

                    PhysicalChannel(ch.physical).configure_teds()
                if ch.role == "force":
                    kw = dict(name_to_assign_to_channel=name, terminal_config=c.TerminalConfiguration.DEFAULT,
                              min_val=-ch.range, max_val=ch.range, units=c.ForceUnits.NEWTONS,
                              current_excit_source=excit, current_excit_val=ch.iepe_current_a)
                    if self.use_teds:
                        chan = task.ai_channels.add_teds_ai_force_iepe_chan(ch.physical, **kw)
                    else:
                        chan = task.ai_channels.add_ai_force_iepe_chan(
                            ch.physical, sensitivity=ch.sensitivity * 1e3,
                            sensitivity_units=c.ForceIEPESensorSensitivityUnits.MILLIVOLTS_PER_NEWTON, **kw)
                else:
                    kw = dict(name_to_assign_to_channel=name, terminal_config=c.TerminalConfiguration.DEFAULT,
                              min_val=-ch.range, max_val=ch.range, units=c.AccelUnits.METERS_PER_SECOND_SQUARED,
                              current_excit_source=excit, current_excit_val=ch.iepe_current_a)
                    if self.use_teds:
                        chan = task.ai_channels.add_teds_ai_accel_chan(ch.physical, **kw)
                    else:
                        chan = task.ai_channels.add_ai_accel_chan(
                            ch.physical, sensitivity=ch.sensitivity * 1e3 * G,
                            sensitivity_units=c.AccelSensitivityUnits.MILLIVOLTS_PER_G, **kw)
                chan.ai_coupling = c.Coupling.AC if ch.iepe else c.Coupling.DC
            task.timing.cfg_samp_clk_timing(acq.sample_rate_hz, sample_mode=c.AcquisitionType.FINITE,
                                            samps_per_chan=int(acq.n_samples))
            trig = channels[acq.trigger_channel]
            slope = c.Slope.RISING if acq.trigger_slope == "rising" else c.Slope.FALLING
            task.triggers.reference_trigger.cfg_anlg_edge_ref_trig(
                trig.physical, pretrigger_samples=int(acq.pretrigger_samples), trigger_slope=slope,
                trigger_level=float(acq.trigger_level))
            self._reader = self._nidaqmx.stream_readers.AnalogMultiChannelReader(task.in_stream)
        except DaqError:
            raise
        except Exception as e:  # noqa: BLE001
            if isinstance(e, self._nidaqmx.errors.Error):
                raise self._translate(e, "configuring channels and trigger") from None
            raise
        self._channels, self._acq = list(channels), acq
        self._highpass = _coupling_corners(channels)
        log.info("configured %d channels at %g Hz, %d samples, pretrigger %d", len(channels),
                 acq.sample_rate_hz, acq.n_samples, acq.pretrigger_samples)

    def notify_point(self, dof, role: str = "force") -> None:
        self._point = Dof.parse(dof)

    def _require(self):
        if self._task is None or self._acq is None:
            raise DaqError("the backend is not configured; call configure(channels, acq) first")

    def arm(self) -> None:
        self._require()
        try:
            self._task.start()
        except self._nidaqmx.errors.Error as e:
            raise self._translate(e, "arming") from None

    def wait(self, timeout_s: float | None = None) -> TimeRecord:
        self._require()
        acq = self._acq
        n_ch = len(self._channels)
        data = np.zeros((n_ch, int(acq.n_samples)), dtype=np.float64)
        timeout = acq.timeout_s if timeout_s is None else timeout_s
        try:
            self._reader.read_many_sample(data, number_of_samples_per_channel=int(acq.n_samples), timeout=timeout)
            stream = self._task.in_stream
            overloaded = set()
            if stream.overloaded_chans_exist:
                overloaded = set(stream.overloaded_chans or [])
            self._task.stop()
        except self._nidaqmx.errors.Error as e:
            raise self._translate(e, "waiting for a hit") from None
        flags = [bool({ch.physical, ch.name} & overloaded) or
                 any(o.endswith(ch.physical) for o in overloaded) for ch in self._channels]
        self._hit += 1
        return TimeRecord(sample_rate_hz=acq.sample_rate_hz, data=data, dofs=[ch.dof for ch in self._channels],
                          roles=[ch.role for ch in self._channels], units=[ch.units for ch in self._channels],
                          sensitivity=[ch.sensitivity for ch in self._channels],
                          trigger_index=int(acq.pretrigger_samples), overload=flags, hit_id=self._hit,
                          metadata={"backend": "nidaqmx", "range": [ch.range for ch in self._channels],
                                    **({"highpass_hz": list(self._highpass)} if self._highpass is not None else {})})

    def abort(self) -> None:
        if self._task is not None:
            try:
                self._task.stop()
            except self._nidaqmx.errors.Error as e:
                log.warning("stopping the task failed: %s", e)

    def close(self) -> None:
        if self._task is not None:
            try:
                self._task.close()
            finally:
                self._task = None
                self._reader = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
