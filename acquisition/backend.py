"""The DAQ backend protocol and the factory that opens a backend by name.

A backend configures channels, timing and trigger, arms a triggered finite
acquisition, waits for one record (a hit), and aborts or closes.  Two
implementations exist: :class:`acquisition.nidaqmx_backend.NidaqmxBackend`
(real NI hardware) and :class:`hardware_sim.daq.SimDaqBackend` (the simulated
lab, which depends on the core only and satisfies this protocol structurally).

``wait`` returns a :class:`modalab.core.records.TimeRecord` in engineering units
with per-channel overload flags, or raises
:class:`modalab.core.errors.DaqTimeoutError` when no hit arrived in time (the
session then simply waits again).  ``notify_point`` tells the backend where the
operator will excite or where the roving sensor sits; real hardware ignores it
and the simulator uses it to place the hit.
"""
from __future__ import annotations

from typing import Protocol, Sequence, runtime_checkable

from modalab.core.daqconfig import AcquisitionConfig, ChannelConfig
from modalab.core.dof import Dof
from modalab.core.errors import PlanError
from modalab.core.records import TimeRecord

from .nidaqmx_backend import NidaqmxBackend

__all__ = ["DaqBackend", "open_backend", "BACKENDS"]

BACKENDS = ("sim", "nidaqmx")


@runtime_checkable
class DaqBackend(Protocol):
    """What the acquisition session needs from a DAQ."""

    def configure(self, channels: Sequence[ChannelConfig], acq: AcquisitionConfig) -> None:
        """Create channels, timing and the reference trigger."""

    def notify_point(self, dof: Dof, role: str = "force") -> None:
        """Where the next excitation (role 'force') or the roving sensor (role 'response') is."""

    def arm(self) -> None:
        """Start a triggered finite acquisition; returns at once."""

    def wait(self, timeout_s: float | None = None) -> TimeRecord:
        """Block until the triggered record is complete; DaqTimeoutError when no hit came."""

    def abort(self) -> None:
        """Stop an armed acquisition."""

    def close(self) -> None:
        """Release the device."""

    def __enter__(self): ...

    def __exit__(self, *exc): ...


def open_backend(name: str, **kw) -> DaqBackend:
    """Open a backend by name: ``'nidaqmx'`` (kw: device options) or ``'sim'`` (kw: ``lab=SimulatedLab``...)."""
    if name == "nidaqmx":
        return NidaqmxBackend(**kw)
    if name == "sim":
        raise PlanError("the 'sim' backend is built by the caller from hardware_sim (acquisition may not import "
                        "it); use modalab.app.stages.make_sim_backend(plan) or the CLI's --backend sim")
    raise PlanError(f"backend {name!r} unknown; expected one of {', '.join(BACKENDS)}")
