"""The acquire stage: run a test plan on the simulated lab or NI hardware (``modalab acquire``, ``modalab run``).

:func:`acquire` runs the plan (:class:`AcquireOptions`) and exports the session's UFF;
:func:`make_sim_backend` builds the simulated DAQ of a plan.  The backend that took the data ('sim' or 'nidaqmx') is recorded in ``session.json`` and in the
UFF's ID lines (:class:`acquisition.session.AcquisitionSession`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from modalab.core.errors import DaqNotFoundError, PlanError
from modalab.app.stages._common import StageResult
from modalab.app.stages._sim import _sim_structure
from hardware_sim.bench import lab_from_sim
from acquisition.nidaqmx_backend import NidaqmxBackend
from acquisition.plan import load_plan
from acquisition.checks import HitCheckConfig
from acquisition.session import AcquisitionSession
from acquisition.session_summary import SessionSummary
from hardware_sim import serial_devices
from acquisition.instruments import AutoHammer, LineTransport

log = logging.getLogger(__name__)


def make_sim_backend(plan, *, seed: int | None = None, structure=None):
    """A simulated DAQ (:class:`hardware_sim.lab.SimulatedLab`) for a test plan, from the plan's ``[sim]`` section.

    The keys are read by :func:`hardware_sim.bench.lab_from_sim` (listed there); ``structure`` is 'demo' or
    a bulk-data file, loaded here, unless a ready Structure is given (``modalab run``'s ``[test] truth``
    builder).  With a ``[hammer] url = "simhammer://NAME"`` the lab's hammer is automatic and the simulated
    serial hammer fires it.
    """

    st = _sim_structure(plan.sim.get("structure", "demo"))[0] if structure is None else structure
    automatic = str(plan.hammer.get("url", "")).startswith("simhammer://")
    lab = lab_from_sim(plan.sim, st, channel_names=[c.name for c in plan.channels], automatic=automatic, seed=seed,
                       source=plan.source, dofs=list(plan.points) + plan.fixed_dofs,
                       hammer_points=list(plan.points) if plan.pattern == "hammer" else ())
    if automatic:
        serial_devices.register()
        serial_devices.device(plan.hammer["url"]).on_fire = lab.fire
    return lab


def _nidaqmx_backend():
    """The NI backend, after checking that the driver is there (a clear DaqNotFoundError otherwise)."""


    be = NidaqmxBackend()
    try:
        import nidaqmx.system  # lazy: optional nidaqmx (daq extra)

        nidaqmx.system.System.local().driver_version
    except Exception as e:  # noqa: BLE001 - every failure here means: no usable driver
        be._task = None
        raise DaqNotFoundError(
            f"the NI-DAQmx driver is not available on this machine ({str(e).splitlines()[0] if str(e) else e}). "
            "Install NI-DAQmx (https://www.ni.com/en/support/downloads/drivers/download.ni-daq-mx.html) "
            "or run with --backend sim to use the simulated lab") from None
    return be


@dataclass(frozen=True)
class AcquireOptions:
    """``modalab acquire``: backend ('sim': the simulated lab of the plan's ``[sim]`` section, 'nidaqmx': NI
    hardware), automatic mode (best N of M hits by coherence; otherwise a prompter decides each hit), resume the
    session stored in the folder, the simulated lab's random seed, export the UFF into the session folder once
    every point is finished (False: the caller exports it), and the session's limits
    (:class:`acquisition.session.AcquisitionSession`; None: the session's default)."""

    backend: str = "sim"
    auto: bool = False
    resume: bool = False
    seed: int | None = None
    export: bool = True
    max_timeouts: int | None = None
    waits_per_arm: int | None = None
    max_attempts_factor: int | None = None
    max_reconnects: int | None = None
    check_config: HitCheckConfig | None = None

    def __post_init__(self):
        if self.backend not in ("sim", "nidaqmx"):
            raise PlanError(f"backend {self.backend!r}; expected 'sim' or 'nidaqmx'")

    def session_limits(self) -> dict:
        """The limits given, as keywords of :class:`acquisition.session.AcquisitionSession`."""
        return {k: getattr(self, k) for k in ("max_timeouts", "waits_per_arm", "max_attempts_factor",
                                              "max_reconnects", "check_config") if getattr(self, k) is not None}


@dataclass(frozen=True)
class Acquisition:
    """What :func:`acquire` produced (its :attr:`StageResult.result`): the session, its summary (also in the
    folder's ``summary.json``) and the exported UFF (None: not exported)."""

    session: AcquisitionSession
    summary: SessionSummary
    uff: Path | None = None


def acquire(plan_path, out_dir, opts: AcquireOptions = AcquireOptions(), *, daq=None, prompter=None, observer=None,
            on_ready=None) -> StageResult:
    """Run a test plan into the session folder ``out_dir`` (``modalab acquire``, ``modalab run``).

    Returns a :class:`StageResult`: ``result`` an :class:`Acquisition` (session, summary, exported UFF or None),
    ``files`` the session folder, its ``summary.json`` and the exported UFF, ``summary`` the session summary as
    written to ``summary.json``.

    ``opts.backend`` is 'sim' (the plan's ``[sim]`` section, :func:`make_sim_backend`) or 'nidaqmx'; ``daq``: a
    ready backend object instead (a test double, or ``modalab run``'s simulated bench carrying the ``[test]
    truth``).  Interactive mode (``opts.auto`` False) needs a ``prompter``.  The UFF is exported into the session
    folder when every point is finished (``opts.export`` False: not here; the caller exports it).  ``on_ready``:
    called without arguments once every check has passed (plan, backend, hammer, session folder and resume),
    before the first hit (the CLI says there which backend runs).
    """

    plan = load_plan(plan_path)
    if daq is not None:
        be = daq
    elif opts.backend == "sim":
        be = make_sim_backend(plan, seed=opts.seed)
    else:
        be = _nidaqmx_backend()
    hammer = None
    if plan.hammer.get("url"):
        if plan.hammer["url"].startswith("sim"):
            serial_devices.register()
        hammer = AutoHammer(LineTransport.from_url(plan.hammer["url"], timeout=2.0))
    try:
        sess = AcquisitionSession(plan, be, out_dir, mode="auto" if opts.auto else "interactive",
                                  prompter=prompter, hammer=hammer, observer=observer, resume=opts.resume,
                                  **opts.session_limits())
        if on_ready is not None:
            on_ready()
        summary = sess.run()
        exported = sess.export() if opts.export and summary.complete and any(p.accepted for p in summary.points) \
            else None
    finally:
        be.close()
        if hammer is not None:
            hammer.t.close()
    files = (sess.out_dir, sess.out_dir / "summary.json") + ((Path(exported),) if exported else ())
    return StageResult(Acquisition(sess, summary, exported), files, summary.to_dict())
