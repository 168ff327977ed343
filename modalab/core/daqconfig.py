"""DAQ configuration types shared by the acquisition backends and the simulated lab.

Both :mod:`acquisition` (the real NI-DAQmx backend) and :mod:`hardware_sim`
(the simulated twin) are configured with these frozen dataclasses, so the
simulator can implement acquisition's backend protocol while depending on the
core only.  Values are SI / engineering units: a force channel's ``range`` is
the largest expected force in N, an accelerometer's in m/s².
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .dof import Dof
from .errors import PlanError
from .units import G

__all__ = ["ChannelConfig", "AcquisitionConfig", "sensitivity_to_si", "sensitivity_quantity", "SENSITIVITY_UNITS"]

#: the sensitivity units each measured quantity takes, as written on calibration sheets (for messages)
SENSITIVITY_UNITS = {"force": ("mV/N", "V/N"),
                     "acceleration": ("mV/g", "V/g", "mV/(m/s^2)", "V/(m/s^2)")}
#: normalised unit -> (factor to V per SI unit, the quantity it is a sensitivity to)
_SENSITIVITY_TABLE = {"mv/n": (1e-3, "force"), "v/n": (1.0, "force"),
                      "mv/g": (1e-3 / G, "acceleration"), "v/g": (1.0 / G, "acceleration"),
                      "mv/(m/s^2)": (1e-3, "acceleration"), "v/(m/s^2)": (1.0, "acceleration"),
                      "mv/m/s^2": (1e-3, "acceleration"), "v/m/s^2": (1.0, "acceleration")}


def _sensitivity_entry(unit: str) -> tuple:
    u = unit.replace(" ", "").replace("**", "^").lower()
    if u not in _SENSITIVITY_TABLE:
        every = ", ".join(x for units in SENSITIVITY_UNITS.values() for x in units)
        raise PlanError(f"sensitivity unit {unit!r} unknown; expected one of {every}. "
                        "Copy it from the sensor's calibration sheet")
    return _SENSITIVITY_TABLE[u]


def sensitivity_quantity(unit: str) -> str:
    """The quantity a sensitivity unit measures: ``'force'`` (mV/N, V/N) or ``'acceleration'`` (mV/g, V/g,
    mV/(m/s^2), V/(m/s^2)); an unknown unit is the same error as in :func:`sensitivity_to_si`."""
    return _sensitivity_entry(unit)[1]


def sensitivity_to_si(value: float, unit: str) -> float:
    """Convert a data-sheet sensitivity to V per SI unit.

    Accepts ``mV/N``, ``V/N``, ``mV/g``, ``V/g``, ``mV/(m/s^2)``, ``V/(m/s^2)``
    (:data:`SENSITIVITY_UNITS`; which quantity a unit measures: :func:`sensitivity_quantity`).
    """
    factor = _sensitivity_entry(unit)[0]
    v = float(value) * factor
    if not v > 0:
        raise PlanError(f"sensitivity {value} {unit} must be positive")
    return v


@dataclass(frozen=True)
class ChannelConfig:
    """One analog input channel.

    physical : device channel name ('cDAQ1Mod1/ai0'; anything for the simulator).
    dof : the DOF this channel measures (the hammer's impact DOF for the force channel).
    role : 'force' or 'response'.
    sensitivity : V per N (force) or V per m/s² (acceleration).
    range : largest expected absolute value in engineering units (N or m/s²); sets the ADC range.
    units : 'N' or 'm/s^2'.
    iepe : constant-current excitation on (AC coupled) or off (DC).
    iepe_current_a : excitation current in A.
    highpass_hz : AC-coupling corner (-3 dB, Hz) of the input an IEPE channel is wired to, from the DAQ module's
        specifications (NI-DAQmx does not report it); None: not stated (the simulator then uses its own
        conditioner's corner; the NI backend records the hits' corners as unknown and says so).
    noise_v_rms : channel noise (simulator only).
    """

    physical: str
    dof: Dof
    role: str
    sensitivity: float
    range: float
    units: str = ""
    iepe: bool = True
    iepe_current_a: float = 0.004
    highpass_hz: float | None = None
    noise_v_rms: float = 2e-5
    name: str = ""

    def __post_init__(self):
        object.__setattr__(self, "dof", Dof.parse(self.dof))
        if self.role not in ("force", "response"):
            raise PlanError(f"channel {self.physical}: role {self.role!r}; expected 'force' or 'response'")
        if not self.units:
            object.__setattr__(self, "units", "N" if self.role == "force" else "m/s^2")
        if not (self.sensitivity > 0):
            raise PlanError(f"channel {self.physical}: sensitivity {self.sensitivity} V/unit must be positive")
        if not (self.range > 0):
            raise PlanError(f"channel {self.physical}: range {self.range} {self.units} must be positive")
        if self.highpass_hz is not None and not (math.isfinite(self.highpass_hz) and self.highpass_hz >= 0):
            raise PlanError(f"channel {self.physical}: highpass_hz {self.highpass_hz!r} must be an AC-coupling corner "
                            ">= 0 Hz")

    @property
    def range_v(self) -> float:
        """Input range in volts that the range in engineering units needs."""
        return self.range * self.sensitivity


@dataclass(frozen=True)
class AcquisitionConfig:
    """Timing and trigger of a triggered finite acquisition.

    sample_rate_hz : samples per second.
    n_samples : samples per record (per channel), pretrigger included.
    pretrigger_samples : samples kept before the trigger.
    trigger_channel : index into the channel list (normally the hammer).
    trigger_level : trigger threshold in the channel's engineering units (N).
    trigger_slope : 'rising' or 'falling'.
    timeout_s : how long ``wait`` blocks for a hit before reporting 'no hit yet'.
    """

    sample_rate_hz: float
    n_samples: int
    pretrigger_samples: int = 0
    trigger_channel: int = 0
    trigger_level: float = 5.0
    trigger_slope: str = "rising"
    timeout_s: float = 10.0

    def __post_init__(self):
        if not (self.sample_rate_hz > 0):
            raise PlanError(f"sample rate {self.sample_rate_hz} Hz must be positive")
        if int(self.n_samples) < 16:
            raise PlanError(f"record length {self.n_samples} samples is too short; use at least 16")
        if not (0 <= int(self.pretrigger_samples) < int(self.n_samples)):
            raise PlanError(f"pretrigger of {self.pretrigger_samples} samples must be shorter than the record "
                            f"({self.n_samples} samples); shorten the pretrigger or lengthen the record")
        if self.trigger_slope not in ("rising", "falling"):
            raise PlanError(f"trigger slope {self.trigger_slope!r}; expected 'rising' or 'falling'")

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.sample_rate_hz
