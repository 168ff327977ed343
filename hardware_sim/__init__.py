"""hardware_sim — a simulated impact-testing lab that depends on the modalab core only.

It produces what a real bench produces: raw triggered records of hammer hits on
a structure, with the sensors, conditioners and 24-bit DAQ in between, and the
faults that happen on real benches.  Acquisition's ``sim`` backend presents it
as a device; every acquisition path is tested against it.

The lab (:mod:`hardware_sim.lab`; how a hit is synthesised: :mod:`hardware_sim.synthesis`)
    :class:`SimulatedLab` — structure + channels + hammer + DAQ; DAQ-style
    ``configure`` / ``notify_point`` / ``arm`` / ``fire`` / ``wait`` / ``abort`` /
    ``reconnect`` / ``close``, and ``hit(point, force_n)``; ``exact_frf`` for checks.
    :func:`simulate_roving_test` — hits per point over a list of points.
    :meth:`SimulatedLab.seed_hit` — draw the next hit from (seed, point, hit) (resumable sessions).
    :func:`lab_from_sim` (:mod:`hardware_sim.bench`) — the lab a test plan's ``[sim]`` section describes.
Configuration (frozen dataclasses)
    :class:`ChannelSetup` — DOF, role, sensitivity, ADC range (±V), IEPE AC coupling,
    noise, channel faults (dead, extra noise).
    :class:`AcquisitionSetup` — sample rate, record length, pretrigger, trigger,
    anti-alias filter, ADC bits and noise.
    :class:`FaultConfig` — no trigger, device lost, overload storms, double hits,
    by arm number or probability.
    :class:`Hammer` — mass, tip (hard/medium/soft), force and placement scatter,
    double hits, manual or automatic.
Signal chain (pure functions, :mod:`hardware_sim.signal_chain`)
    :func:`half_sine`, :func:`half_sine_spectrum`, :func:`iepe_highpass`,
    :func:`antialias_response`, :func:`quantization_step`, :func:`quantize`,
    :func:`synthesis_taper`.
Demo structure (:mod:`hardware_sim.demo`)
    :func:`demo_structure` — aluminium aeroplane cross on bungees, 45 DOFs;
    :func:`demo_channels`, :func:`demo_setup`, :func:`demo_lab`, ``DEMO_POINTS``, ``DEMO_HAMMER``;
    :func:`grillage`, :class:`BeamSection` to build similar structures.
Serial twins (:mod:`hardware_sim.serial_devices`)
    ``simcond://`` and ``simhammer://`` pyserial URL handlers.

Example
-------
>>> from hardware_sim import demo_lab, simulate_roving_test
>>> lab = demo_lab(rng=1)
>>> rec = lab.hit("14+Z", force_n=150.0)
>>> rec.trigger_index, rec.units
(128, ['N', 'm/s^2', 'm/s^2', 'm/s^2'])
"""
from .bench import lab_from_sim
from .demo import (DEMO_HAMMER, DEMO_POINTS, DEMO_REFERENCES, BeamSection, demo_channels, demo_lab, demo_setup,
                   demo_structure, grillage)
from .hammer import TIP_STIFFNESS_N_PER_M, Hammer, Pulse, contact_time_s
from .lab import SimulatedLab, simulate_roving_test
from .setup import AcquisitionSetup, ChannelSetup, FaultConfig
from .signal_chain import (antialias_response, half_sine, half_sine_spectrum, iepe_highpass, quantization_step,
                           quantize, synthesis_taper)

__all__ = ["SimulatedLab", "simulate_roving_test", "lab_from_sim", "ChannelSetup", "AcquisitionSetup", "FaultConfig", "Hammer",
           "Pulse", "TIP_STIFFNESS_N_PER_M", "contact_time_s", "half_sine", "half_sine_spectrum", "iepe_highpass",
           "antialias_response", "quantization_step", "quantize", "synthesis_taper", "demo_structure",
           "demo_channels", "demo_setup", "demo_lab", "grillage", "BeamSection", "DEMO_HAMMER", "DEMO_POINTS",
           "DEMO_REFERENCES"]
