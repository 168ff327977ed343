"""Frozen configuration of the simulated lab: channels, acquisition, injected faults.

The field names follow :mod:`modalab.core.daqconfig` where the meaning is the same
(``dof``, ``role``, ``sensitivity``, ``iepe``, ``highpass_hz``, ``noise_v_rms``,
``sample_rate_hz``, ``n_samples``, ``pretrigger_samples``, ``trigger_level``,
``trigger_slope``, ``timeout_s``), so a backend can translate one into the
other field by field; :meth:`ChannelSetup.from_config` and
:meth:`AcquisitionSetup.from_config` do it by attribute name.
"""
from __future__ import annotations

from dataclasses import dataclass

from modalab.core.dof import Dof
from modalab.core.errors import ModalabValueError

from .signal_chain import AA_FILTERS, quantization_step

__all__ = ["ChannelSetup", "AcquisitionSetup", "FaultConfig"]


@dataclass(frozen=True)
class ChannelSetup:
    """One analog input channel of the simulated DAQ.

    dof : DOF measured (for the force channel: the default hammer point).
    role : 'force' or 'response'.
    sensitivity : V per N (force) or V per m/s² (acceleration).
    range_v : ADC input range ±V; inputs at or beyond it clip and raise the overload flag.
    iepe : IEPE excitation with AC coupling (True) or DC coupling (False).
    highpass_hz : corner of the AC-coupling high-pass when ``iepe`` (Hz).
    noise_v_rms : sensor + cable noise in V rms (white, at the sample rate).
    dead : fault: the sensor is dead (open or shorted), the channel reads only ADC noise.
    extra_noise_v_rms : fault: additional white noise (a loose connector, a ground loop).
    name : physical channel name, free text.
    """

    dof: Dof
    role: str
    sensitivity: float
    range_v: float = 5.0
    iepe: bool = True
    highpass_hz: float = 0.5
    noise_v_rms: float = 1e-5
    dead: bool = False
    extra_noise_v_rms: float = 0.0
    name: str = ""

    def __post_init__(self):
        object.__setattr__(self, "dof", Dof.parse(self.dof))
        if self.role not in ("force", "response"):
            raise ModalabValueError(f"channel {self.dof}: role {self.role!r}; expected 'force' or 'response'")
        if not self.sensitivity > 0:
            raise ModalabValueError(f"channel {self.dof}: sensitivity {self.sensitivity!r} V/unit must be "
                                    "positive; copy it from the calibration sheet")
        if not self.range_v > 0:
            raise ModalabValueError(f"channel {self.dof}: range_v {self.range_v!r} V must be positive")
        if self.highpass_hz < 0:
            raise ModalabValueError(f"channel {self.dof}: highpass_hz {self.highpass_hz!r} must be >= 0")
        if self.noise_v_rms < 0 or self.extra_noise_v_rms < 0:
            raise ModalabValueError(f"channel {self.dof}: noise levels must be >= 0 V rms")

    @property
    def units(self) -> str:
        return "N" if self.role == "force" else "m/s^2"

    @property
    def range(self) -> float:
        """Input range in engineering units (N or m/s²)."""
        return self.range_v / self.sensitivity

    @property
    def coupling_corner_hz(self) -> float:
        """The high-pass corner actually in effect (0 when DC coupled)."""
        return self.highpass_hz if self.iepe else 0.0

    @classmethod
    def from_config(cls, cfg, **overrides) -> "ChannelSetup":
        """Build from any object with the attributes of :class:`modalab.core.daqconfig.ChannelConfig`.

        Its range in engineering units (``range``) becomes ``range_v = range × sensitivity``
        unless the object has ``range_v`` itself.
        """
        if isinstance(cfg, cls):
            return cls(**{**cfg.__dict__, **overrides})
        try:
            sens = float(cfg.sensitivity)
            rng_v = float(cfg.range_v) if hasattr(cfg, "range_v") else float(cfg.range) * sens
            kw = dict(dof=cfg.dof, role=cfg.role, sensitivity=sens, range_v=rng_v,
                      iepe=bool(getattr(cfg, "iepe", True)),
                      noise_v_rms=float(getattr(cfg, "noise_v_rms", 1e-5)),
                      name=str(getattr(cfg, "physical", getattr(cfg, "name", ""))))
        except AttributeError as e:
            raise ModalabValueError(f"cannot read a channel from {cfg!r}: {e}; it needs dof, role, sensitivity "
                                    "and range (engineering units) or range_v") from None
        hp = getattr(cfg, "highpass_hz", None)      # None: not stated, the simulated conditioner's own corner
        if hp is not None:
            kw["highpass_hz"] = float(hp)
        kw.update(overrides)
        return cls(**kw)


@dataclass(frozen=True)
class AcquisitionSetup:
    """Timing, trigger, anti-alias filter and ADC of the simulated DAQ.

    sample_rate_hz : samples per second.
    n_samples : samples per record, pretrigger included.
    pretrigger_samples : samples kept before the trigger (``TimeRecord.trigger_index``).
    trigger_level : threshold on the force channel in N.
    trigger_slope : 'rising' or 'falling'.
    timeout_s : default wait for a hit before ``DaqTimeoutError``.
    aa_filter : 'delta-sigma' (linear phase, brick-wall), 'butterworth' (analog) or 'none'.
    aa_cutoff : pass edge (delta-sigma) or −3 dB point (Butterworth) as a fraction of fs.
    aa_order : Butterworth order.
    adc_bits : converter resolution (24); the step is ``range_v / 2**(adc_bits-1)``.
    adc_noise_v_rms : noise floor of the converter itself (also what a dead channel reads).
    """

    sample_rate_hz: float = 2048.0
    n_samples: int = 8192
    pretrigger_samples: int = 128
    trigger_level: float = 5.0
    trigger_slope: str = "rising"
    timeout_s: float = 10.0
    aa_filter: str = "delta-sigma"
    aa_cutoff: float = 0.45
    aa_order: int = 8
    adc_bits: int = 24
    adc_noise_v_rms: float = 1e-6

    def __post_init__(self):
        if not self.sample_rate_hz > 0:
            raise ModalabValueError(f"sample_rate_hz={self.sample_rate_hz!r} must be positive")
        if int(self.n_samples) != self.n_samples or self.n_samples < 16:
            raise ModalabValueError(f"n_samples={self.n_samples!r} must be an integer >= 16")
        if not (0 <= int(self.pretrigger_samples) < int(self.n_samples)):
            raise ModalabValueError(f"pretrigger_samples={self.pretrigger_samples!r} must be >= 0 and shorter than "
                                    f"the record ({self.n_samples} samples)")
        object.__setattr__(self, "n_samples", int(self.n_samples))
        object.__setattr__(self, "pretrigger_samples", int(self.pretrigger_samples))
        if self.trigger_slope not in ("rising", "falling"):
            raise ModalabValueError(f"trigger_slope={self.trigger_slope!r}; expected 'rising' or 'falling'")
        if self.aa_filter not in AA_FILTERS:
            raise ModalabValueError(f"aa_filter={self.aa_filter!r}; expected one of {', '.join(AA_FILTERS)}")
        if self.aa_filter != "none" and not 0 < self.aa_cutoff < 0.5:
            raise ModalabValueError(f"aa_cutoff={self.aa_cutoff!r} must lie in (0, 0.5) (fraction of fs)")
        quantization_step(1.0, self.adc_bits)
        if self.adc_noise_v_rms < 0 or not self.timeout_s >= 0:
            raise ModalabValueError("adc_noise_v_rms and timeout_s must be >= 0")

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.sample_rate_hz

    @classmethod
    def from_config(cls, cfg, **overrides) -> "AcquisitionSetup":
        """Build from any object with the attributes of :class:`modalab.core.daqconfig.AcquisitionConfig`."""
        if isinstance(cfg, cls):
            return cls(**{**cfg.__dict__, **overrides})
        names = ("sample_rate_hz", "n_samples", "pretrigger_samples", "trigger_level", "trigger_slope",
                 "timeout_s", "aa_filter", "aa_cutoff", "aa_order", "adc_bits", "adc_noise_v_rms")
        kw = {n: getattr(cfg, n) for n in names if hasattr(cfg, n)}
        hp = getattr(cfg, "highpass_hz", None)      # None: not stated, the simulated conditioner's own corner
        if hp is not None:
            kw["highpass_hz"] = float(hp)
        kw.update(overrides)
        return cls(**kw)


@dataclass(frozen=True)
class FaultConfig:
    """Faults to inject, by arm number (1-based, counting every ``arm()``) or by probability per arm.

    no_trigger_on / no_trigger_probability : the trigger never comes; ``wait`` raises DaqTimeoutError
        (until the next ``arm``).
    device_lost_on / device_lost_probability : the device disappears mid-record; ``wait`` raises
        DeviceLostError and every call does so until ``reconnect()``.
    overload_storm_on / overload_storm_probability / overload_storm_length : bursts of transients
        beyond the range on every channel (ESD, a loose ground) for that many consecutive arms.
    double_hit_on / double_hit_probability : the hammer rebounds into a second hit.

    Channel faults (a dead accelerometer, a noisy channel) belong to the channel:
    :attr:`ChannelSetup.dead`, :attr:`ChannelSetup.extra_noise_v_rms`.
    """

    no_trigger_on: tuple = ()
    no_trigger_probability: float = 0.0
    device_lost_on: tuple = ()
    device_lost_probability: float = 0.0
    overload_storm_on: tuple = ()
    overload_storm_probability: float = 0.0
    overload_storm_length: int = 3
    double_hit_on: tuple = ()
    double_hit_probability: float = 0.0

    def __post_init__(self):
        for name in ("no_trigger", "device_lost", "overload_storm", "double_hit"):
            p = getattr(self, f"{name}_probability")
            if not 0 <= p <= 1:
                raise ModalabValueError(f"{name}_probability={p!r} must lie in [0, 1]")
            on = tuple(int(k) for k in getattr(self, f"{name}_on"))
            if any(k < 1 for k in on):
                raise ModalabValueError(f"{name}_on={on!r}: arm numbers start at 1")
            object.__setattr__(self, f"{name}_on", on)
        if int(self.overload_storm_length) < 1:
            raise ModalabValueError(f"overload_storm_length={self.overload_storm_length!r} must be >= 1")
