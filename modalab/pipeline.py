"""Glue between the stages: what the CLI runs, callable from a notebook too.

This module (with :mod:`modalab.cli`) is the only place that sees every
stage; the stage packages never import it.  Functions take plain arguments,
write artifacts and return what they produced.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from .errors import ModalabValueError, PlanError
from .frf import FRF

log = logging.getLogger(__name__)

__all__ = ["simulate_hits", "frf_from_file", "file_info", "make_sim_backend", "acquire", "demo", "demo_lab",
           "load_model", "load_params", "load_modes"]


# ------------------------------------------------------------------------- simulated lab
def _demo_or_structure(structure):
    """The demo structure for 'demo' (or None), else a structure file (.bdf) through updating."""
    from hardware_sim import demo as hdemo

    if structure in (None, "demo"):
        return hdemo.demo_structure(), hdemo
    path = Path(structure)
    if path.suffix.lower() in (".bdf", ".dat", ".nas", ".blk"):
        from updating.bulk import read_bdf
        from updating.bulk.build import build_model

        model = build_model(read_bdf(path))
        return model.structure(), hdemo
    raise PlanError(f"structure {structure!r}: expected 'demo' or a Nastran bulk-data file (.bdf/.dat)")


def simulate_hits(out_uff, *, structure="demo", points=None, references=None, hits: int = 3, seed: int = 1,
                  force_n: float | None = None, double_hit_probability: float = 0.0,
                  sample_rate_hz: float | None = None, n_samples: int | None = None, plot_dir=None):
    """Simulate a roving-hammer test and write its raw hits (UFF 58 time records, one per channel per hit)."""
    from hardware_sim.demo import DEMO_POINTS, DEMO_REFERENCES, demo_channels, demo_setup
    from hardware_sim.lab import SimulatedLab, simulate_roving_test
    from hardware_sim.setup import FaultConfig

    from . import uff

    st, _ = _demo_or_structure(structure)
    pts = list(points or DEMO_POINTS)
    refs = list(references or DEMO_REFERENCES)
    setup_kw = {}
    if sample_rate_hz:
        setup_kw["sample_rate_hz"] = float(sample_rate_hz)
    if n_samples:
        setup_kw["n_samples"] = int(n_samples)
    faults = FaultConfig(double_hit_probability=double_hit_probability) if double_hit_probability else None
    lab = SimulatedLab(st, demo_channels(pts[0], refs), demo_setup(**setup_kw), faults=faults,
                       rng=np.random.default_rng(seed))
    recs = simulate_roving_test(lab, pts, hits_per_point=hits, force_n=force_n)
    for i, r in enumerate(recs, start=1):
        r.hit_id = i
    out = Path(out_uff)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        out.unlink()
    if getattr(st, "coords", None):
        uff.write_geometry(out, st.coords)
        uff.write_records(out, recs, append=True)
    else:
        uff.write_records(out, recs)
    if plot_dir is not None:
        from .plots import plot_hit

        plot_hit(recs[0], path=Path(plot_dir) / "first_hit.png", title=f"hit 1 at {recs[0].force_dofs[0]}")
    return out, recs, lab


def frf_from_file(in_uff, out_uff, *, estimator: str = "H1", force_fraction: float | None = 0.05,
                  exp_end_level: float | None = None, exp_beta: float | None = None, reciprocity: bool = True,
                  plot_path=None, exact=None, bandwidth_hz: float | None = None):
    """Raw hits in a UFF → H1 (H2, Hv) FRFs + coherence in a UFF; roving-hammer data reordered by reciprocity.

    Lines above ``bandwidth_hz`` (default fs/2.56, the anti-alias band) are dropped.
    """
    from acquisition.reciprocity import reorder_by_reciprocity
    from acquisition.spectral import estimate_frf_roving
    from acquisition.windows import ExponentialWindow, ForceWindow

    from . import uff

    recs = uff.read_records(in_uff)
    if not recs:
        raise ModalabValueError(f"{in_uff}: no time records (dataset 58, function type 1) to turn into FRFs; "
                                "run 'modalab info' to see what the file holds")
    fw = ForceWindow(fraction=force_fraction) if force_fraction else None
    ew = None
    if exp_beta:
        ew = ExponentialWindow(beta=exp_beta)
    elif exp_end_level:
        ew = ExponentialWindow(end_level=exp_end_level)
    frf = estimate_frf_roving(recs, estimator=estimator, force_window=fw, exp_window=ew)
    bw = bandwidth_hz or recs[0].sample_rate_hz / 2.56
    frf = frf.band(0.0, bw)
    n_ref = len(frf.references)
    if reciprocity and n_ref > len(frf.responses):
        frf = reorder_by_reciprocity(frf)
    out = Path(out_uff)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        out.unlink()
    geometry = {}
    try:
        geometry = uff.read_geometry(in_uff)
    except Exception:  # noqa: BLE001 - a file without geometry is fine
        geometry = {}
    if geometry:
        uff.write_geometry(out, geometry)
        uff.write_frf(out, frf, append=True)
    else:
        uff.write_frf(out, frf)
    if plot_path is not None:
        from .plots import plot_frf

        others = {"exact": exact} if exact is not None else None
        plot_frf(frf, path=plot_path, others=others, title=f"{frf.estimator if hasattr(frf, 'estimator') else estimator} FRFs")
    return out, frf


def file_info(path) -> dict:
    from . import uff

    return uff.info(path)


# ------------------------------------------------------------------------- acquisition
_SIM_KEYS = {"structure", "seed", "faults", "hit_interval_s", "realtime", "force_n", "tip", "double_hit_probability",
             "force_scatter", "placement_scatter_m", "dead", "noisy"}


def make_sim_backend(plan, *, seed: int | None = None):
    """A simulated DAQ (:class:`hardware_sim.lab.SimulatedLab`) for a test plan, from the plan's ``[sim]`` section.

    ``[sim]`` keys: ``structure`` ('demo' or a .bdf), ``seed``, ``hit_interval_s`` (simulated time from arm to
    the operator's hit), ``realtime`` (waits take real time), the manual hammer's ``force_n``, ``tip``,
    ``force_scatter``, ``placement_scatter_m``, ``double_hit_probability``; faults: ``[sim.faults]`` (the
    fields of :class:`hardware_sim.setup.FaultConfig`), ``dead = ["channel name", ...]`` (dead sensors) and
    ``noisy = {channel name = extra V rms}``.  With a ``[hammer] url = "simhammer://NAME"`` the lab's hammer
    is automatic and the simulated serial hammer fires it.
    """
    import time

    from hardware_sim.hammer import Hammer
    from hardware_sim.lab import SimulatedLab
    from hardware_sim.setup import ChannelSetup, FaultConfig

    sim = dict(plan.sim)
    unknown = set(sim) - _SIM_KEYS
    if unknown:
        raise PlanError(f"[sim] has unknown key(s) {sorted(unknown)}; expected some of {sorted(_SIM_KEYS)}")
    names = [c.name for c in plan.channels]
    dead = set(sim.get("dead", []))
    noisy = {str(k): float(v) for k, v in dict(sim.get("noisy", {})).items()}
    for n in dead | set(noisy):
        if n not in names:
            raise PlanError(f"[sim] dead/noisy names channel {n!r}, which the plan does not have; use one of {names}")
    st, _ = _demo_or_structure(sim.get("structure", "demo"))
    try:
        faults = FaultConfig(**sim["faults"]) if sim.get("faults") else None
    except TypeError as e:
        raise PlanError(f"[sim.faults]: {e}; see hardware_sim.setup.FaultConfig for the fields") from None
    automatic = str(plan.hammer.get("url", "")).startswith("simhammer://")
    hkw = {k: sim[k] for k in ("force_n", "tip", "force_scatter", "placement_scatter_m", "double_hit_probability")
           if k in sim}
    hammer = Hammer(automatic=automatic, **hkw)
    rng = np.random.default_rng(sim.get("seed", 1) if seed is None else seed)
    lab = SimulatedLab(st, None, None, hammer=hammer, faults=faults, rng=rng,
                       hit_interval_s=float(sim.get("hit_interval_s", 0.0)),
                       sleep=time.sleep if sim.get("realtime") else None)
    if dead or noisy:
        base_configure = lab.configure

        def configure(channels, setup=None):
            chans = [ChannelSetup.from_config(c, dead=getattr(c, "name", "") in dead,
                                              extra_noise_v_rms=noisy.get(getattr(c, "name", ""), 0.0))
                     for c in channels]
            return base_configure(chans, setup)

        lab.configure = configure
    if automatic:
        from hardware_sim import serial_devices

        serial_devices.register()
        serial_devices.device(plan.hammer["url"]).on_fire = lab.fire
    return lab


def _nidaqmx_backend():
    """The NI backend, after checking that the driver is there (a clear DaqNotFoundError otherwise)."""
    from acquisition.nidaqmx_backend import NidaqmxBackend

    from .errors import DaqNotFoundError

    be = NidaqmxBackend()
    try:
        import nidaqmx.system

        nidaqmx.system.System.local().driver_version
    except Exception as e:  # noqa: BLE001 - every failure here means: no usable driver
        be._task = None
        raise DaqNotFoundError(
            f"the NI-DAQmx driver is not available on this machine ({str(e).splitlines()[0] if str(e) else e}). "
            "Install NI-DAQmx (https://www.ni.com/en/support/downloads/drivers/download.ni-daq-mx.html) "
            "or run with --backend sim to use the simulated lab") from None
    return be


def acquire(plan_path, out_dir, *, backend: str = "sim", auto: bool = False, resume: bool = False,
            prompter=None, observer=None, seed: int | None = None, **session_kw):
    """Run ``modalab acquire``: returns (session, summary, exported UFF path or None).

    ``backend`` is 'sim' (the plan's ``[sim]`` section, :func:`make_sim_backend`), 'nidaqmx' or a ready
    backend object.  Interactive mode (``auto=False``) needs a ``prompter``.  The UFF is exported when
    every point is finished.  Extra keywords go to :class:`acquisition.session.AcquisitionSession`.
    """
    from acquisition.plan import load_plan
    from acquisition.session import AcquisitionSession

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
        from acquisition.instruments import AutoHammer, LineTransport

        if plan.hammer["url"].startswith("sim"):
            from hardware_sim import serial_devices

            serial_devices.register()
        hammer = AutoHammer(LineTransport.from_url(plan.hammer["url"], timeout=2.0))
    try:
        sess = AcquisitionSession(plan, be, out_dir, mode="auto" if auto else "interactive", prompter=prompter,
                                  hammer=hammer, observer=observer, resume=resume, **session_kw)
        summary = sess.run()
        exported = sess.export() if summary.complete and any(p.accepted for p in summary.points) else None
    finally:
        be.close()
        if hammer is not None:
            hammer.t.close()
    return sess, summary, exported


# ------------------------------------------------------------------------- the demo
def demo(out_dir, *, quick: bool = False, progress=None) -> dict:
    """The README's main job: the whole chain on the embedded demo project (``modalab.run.run_demo``).

    Falls back to :func:`demo_lab` (simulated hammer test, FRFs, plot) when the staged runner is unavailable.
    """
    try:
        from .demo_project import run_demo
    except ImportError:  # pragma: no cover - a stripped install without the updating stage
        return demo_lab(out_dir, quick=quick)
    res = run_demo(out_dir, quick=quick, progress=progress)
    out = {"report": str(res.report)}
    for stage, status in res.status.items():
        t = res.elapsed_s.get(stage)
        out[stage] = status + (f" ({t:.1f} s)" if t is not None else "")
    diag = (res.summaries.get("diagnose") or {})
    if diag.get("statement"):
        out["diagnosis"] = diag["statement"]
    return out


def demo_lab(out_dir, *, quick: bool = False) -> dict:
    """Simulated hammer test of the demo structure: raw hits, H1 FRFs + coherence and a plot against the exact FRF."""
    from hardware_sim.demo import DEMO_POINTS, DEMO_REFERENCES

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    points = list(DEMO_POINTS[:4] if quick else DEMO_POINTS)
    raw, recs, lab = simulate_hits(out / "raw_hits.uff", points=points, references=DEMO_REFERENCES,
                                   hits=2 if quick else 3, seed=1, plot_dir=out)
    first = recs[0]
    import numpy as _np

    f = _np.fft.rfftfreq(first.n_samples, first.dt)
    st = lab.structure if hasattr(lab, "structure") else None
    exact = None
    if st is not None:
        exact = st.frf(f[1:], responses=points, references=list(DEMO_REFERENCES))
    frf_path, frf = frf_from_file(raw, out / "frf.uff", exp_end_level=None, plot_path=out / "frf.png", exact=exact)
    result = {"raw hits": str(raw), "FRFs": str(frf_path), "FRF plot": str(out / "frf.png"),
              "hit plot": str(out / "first_hit.png")}
    if exact is not None:
        ex = exact.select(responses=frf.responses, references=frf.references)
        H = frf.band(f[1], f[-1]).H
        E = ex.H[..., :H.shape[-1]] if ex.n_freq >= H.shape[-1] else ex.H
        coh = frf.band(f[1], f[-1]).coherence
        good = coh > 0.99
        err = float(_np.median(_np.abs(H[good] - E[good]) / _np.abs(E[good]))) if good.any() else float("nan")
        result["median |H1-exact|/|exact| where coherence>0.99"] = f"{100 * err:.2f} %"
    (out / "demo_summary.json").write_text(json.dumps(result, indent=1))
    return result


# ------------------------------------------------------------------------- FE models and test data
def load_model(path):
    """An FE model from Nastran bulk data (``.bdf``, ``.dat``, ``.nas``, ``.blk``)."""
    from updating.bulk import build_model, read_bdf

    p = Path(path)
    if not p.exists():
        raise PlanError(f"model file {str(p)!r} does not exist; give a Nastran bulk-data file (.bdf)")
    return build_model(read_bdf(p))


def load_params(path, model):
    """Updating parameters from a TOML file, or the defaults (E and density multipliers per property group).

    File format::

        [[parameter]]
        name = "E_wing"
        field = "E"                    # E, G, nu, rho, ge, b, h, do, di, A, Iy, Iz, J, nsm, k, c, mass, ...
        properties = ["wing"]          # property names or ids (or materials = [...], elements = [...])
        mode = "factor"                # factor (p multiplies the nominal) or value (p is the SI value)
    """
    from updating.diagnosis.workflow import default_parameters

    if path is None:
        return default_parameters(model)
    from updating.parameter_file import read_parameter_file

    return read_parameter_file(path)[0]


def load_modes(path):
    """Test modes from a UFF (dataset 55) or a JSON written by ``modalab identify``."""
    from .modes import ModeSet

    p = Path(path)
    if p.suffix.lower() == ".json":
        return ModeSet.from_json(p)
    return ModeSet.from_uff(p)
