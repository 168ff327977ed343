"""A simulated bench from a test plan's ``[sim]`` section: the one builder (``modalab acquire``, ``run``).

:func:`lab_from_sim` turns the section's keys (:data:`acquisition.plan.SIM_KEYS`; the plan parser checks the
names and types) into a :class:`~hardware_sim.lab.SimulatedLab`:

* ``seed``: the lab's seed; every hit is drawn from (seed, point, hit) (:meth:`SimulatedLab.seed_hit`);
* ``hit_interval_s``, ``realtime``: simulated (or real, with ``realtime = true``) time from arm to the hit;
* the operator's hammer: ``force_n``, ``hammer_tip`` ('hard' | 'medium' | 'soft'), ``hammer_mass_kg`` —
  head mass and tip stiffness set the contact time ``T = π √(m/k)`` and so the bandwidth of the force
  spectrum (:mod:`hardware_sim.hammer`) —, ``force_scatter``, ``placement_scatter_m``,
  ``double_hit_probability``;
* faults: ``[sim.faults]`` (fields of :class:`~hardware_sim.setup.FaultConfig`), ``dead = ["acc1"]``
  (dead sensors), ``noisy = {acc1 = 1e-3}`` (extra noise, V rms).

The structure is given by the caller (loading a bulk-data file needs ``updating``, above this layer).
"""
from __future__ import annotations

import dataclasses
import difflib
import time
from typing import Sequence

from modalab.core.dof import locate, parse_dofs
from modalab.core.errors import DofError, PlanError

from .hammer import Hammer
from .lab import SimulatedLab
from .setup import ChannelSetup, FaultConfig

__all__ = ["lab_from_sim", "HAMMER_KEYS"]

#: [sim] key -> Hammer field
HAMMER_KEYS = {"force_n": "force_n", "hammer_tip": "tip", "hammer_mass_kg": "mass_kg",
               "force_scatter": "force_scatter", "placement_scatter_m": "placement_scatter_m",
               "double_hit_probability": "double_hit_probability"}


def _faults(spec, source: str) -> FaultConfig | None:
    if not spec:
        return None
    if not isinstance(spec, dict):
        raise PlanError(f"{source}: [sim] faults = {spec!r}; expected a table, e.g. faults = {{ double_hit_on = [2] }}")
    valid = [f.name for f in dataclasses.fields(FaultConfig)]
    for k in spec:
        if k not in valid:
            close = difflib.get_close_matches(k, valid, n=1, cutoff=0.6)
            hint = f"did you mean sim.faults.{close[0]}?" if close else f"valid keys: {', '.join(valid)}"
            raise PlanError(f"{source}: unknown key sim.faults.{k}; {hint}")
    try:
        return FaultConfig(**spec)
    except (TypeError, ValueError) as e:
        raise PlanError(f"{source}: [sim.faults]: {e}") from None


def lab_from_sim(sim: dict, structure, *, channel_names: Sequence[str] = (), automatic: bool = False,
                 seed: int | None = None, source: str = "plan", dofs: Sequence = (),
                 hammer_points: Sequence = ()) -> SimulatedLab:
    """The simulated lab a plan's ``[sim]`` section describes, on ``structure`` (a Structure or ModalModel).

    ``channel_names``: the plan's channel names (``dead``/``noisy`` must name them); ``automatic``: the plan
    has an automatic hammer (``[hammer] url = "simhammer://..."``); ``seed`` overrides ``sim['seed']``;
    ``source`` (the plan file) prefixes error messages; ``dofs`` (the plan's points and fixed sensor DOFs)
    must exist in the structure, checked now so that a wrong label fails before a session folder is made;
    ``hammer_points``: the points a roving hammer will visit (:class:`SimulatedLab`'s, a speed-up only).
    """
    names = list(channel_names)
    dead = set(sim.get("dead", []))
    noisy = {str(k): float(v) for k, v in dict(sim.get("noisy", {})).items()}
    for n in sorted(dead | set(noisy)):
        if n not in names:
            raise PlanError(f"{source}: [sim] dead/noisy names channel {n!r}, which the plan does not have; use one of {names}")
    hkw = {field: sim[key] for key, field in HAMMER_KEYS.items() if key in sim}
    seed = int(sim.get("seed", 1) if seed is None else seed)
    if seed < 0:
        raise PlanError(f"{source}: seed {seed} must be a whole number >= 0")
    try:
        hammer = Hammer(automatic=automatic, **hkw)
    except (TypeError, ValueError) as e:
        raise PlanError(f"{source}: [sim] hammer: {e}") from None
    lab = SimulatedLab(structure, None, None, hammer=hammer, faults=_faults(sim.get("faults"), source),
                       rng=seed,
                       hit_interval_s=float(sim.get("hit_interval_s", 0.0)),
                       sleep=time.sleep if sim.get("realtime") else None)
    for d in list(dofs) + list(hammer_points):
        try:
            locate(lab.model.dofs, [d], "DOF", "the model")
        except DofError:
            nodes = sorted({x.node for x in lab.model.dofs})
            raise PlanError(f"{source}: DOF {d} is not in the simulated structure (nodes {nodes[0]}..{nodes[-1]}, "
                            f"{len(nodes)} in all); fix the label or set [sim] structure to the structure the plan "
                            "was written for") from None
    lab.hammer_points = parse_dofs(hammer_points)
    if dead or noisy:
        base_configure = lab.configure

        def configure(channels, setup=None):
            chans = [ChannelSetup.from_config(c, dead=getattr(c, "name", "") in dead,
                                              extra_noise_v_rms=noisy.get(getattr(c, "name", ""), 0.0))
                     for c in channels]
            return base_configure(chans, setup)

        lab.configure = configure
    return lab
