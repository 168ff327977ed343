"""The acquire stage: run a test plan on the simulated lab or NI hardware (``modalab acquire``, ``modalab run``).

:func:`acquire` runs the plan and exports the session's UFF; :func:`make_sim_backend` builds the simulated DAQ
of a plan.  The backend that took the data ('sim' or 'nidaqmx') is recorded in ``session.json`` and in the
UFF's ID lines (:class:`acquisition.session.AcquisitionSession`).
"""
from __future__ import annotations

import logging

from modalab.core.errors import DaqNotFoundError, PlanError
from modalab.app.stages._sim import _sim_structure
from hardware_sim.bench import lab_from_sim
from acquisition.nidaqmx_backend import NidaqmxBackend
from acquisition.plan import load_plan
from acquisition.session import AcquisitionSession
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
                       source=plan.source, dofs=list(plan.points) + plan.fixed_dofs)
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


def acquire(plan_path, out_dir, *, backend: str = "sim", auto: bool = False, resume: bool = False,
            prompter=None, observer=None, seed: int | None = None, on_ready=None, export: bool = True,
            **session_kw):
    """Run ``modalab acquire``: returns (session, summary, exported UFF path or None).

    ``backend`` is 'sim' (the plan's ``[sim]`` section, :func:`make_sim_backend`), 'nidaqmx' or a ready
    backend object.  Interactive mode (``auto=False``) needs a ``prompter``.  The UFF is exported into the
    session folder when every point is finished (``export=False``: not here; the caller exports it).
    ``on_ready``: called without arguments once every check has passed (plan, backend, hammer, session folder
    and resume), before the first hit (the CLI says there which backend runs).  Extra keywords go to
    :class:`acquisition.session.AcquisitionSession`.
    """

    plan = load_plan(plan_path)
    if backend == "sim":
        be = make_sim_backend(plan, seed=seed)
    elif backend == "nidaqmx":
        be = _nidaqmx_backend()
    elif isinstance(backend, str):
        raise PlanError(f"backend {backend!r}; expected 'sim' or 'nidaqmx'")
    else:
        be = backend
    hammer = None
    if plan.hammer.get("url"):
        if plan.hammer["url"].startswith("sim"):
            serial_devices.register()
        hammer = AutoHammer(LineTransport.from_url(plan.hammer["url"], timeout=2.0))
    try:
        sess = AcquisitionSession(plan, be, out_dir, mode="auto" if auto else "interactive", prompter=prompter,
                                  hammer=hammer, observer=observer, resume=resume, **session_kw)
        if on_ready is not None:
            on_ready()
        summary = sess.run()
        exported = sess.export() if export and summary.complete and any(p.accepted for p in summary.points) \
            else None
    finally:
        be.close()
        if hammer is not None:
            hammer.t.close()
    return sess, summary, exported
