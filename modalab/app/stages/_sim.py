"""The sim stage: a simulated roving-hammer test (and, on request, the FE model of what was simulated)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from modalab.core.errors import PlanError
from modalab.app.outputs import write_text
from modalab.app.stages._common import StageResult, _tuple, load_model
from hardware_sim import demo as hdemo
from hardware_sim.demo import _demo_geometry
from updating.fe import Beam3D, BeamProperty, FEModel, GeneralSection, Material, Spring
from updating.fe.bulk import to_bulk, write_bdf
from updating.diagnosis.priors import default_parameters
from hardware_sim.demo import DEMO_POINTS, DEMO_REFERENCES, demo_channels, demo_setup
from hardware_sim.lab import SimulatedLab, simulate_roving_test
from hardware_sim.setup import FaultConfig
from modalab.core import uff
from modalab.core.plots import plot_hit


#: the lowest sampling rate ``modalab sim`` accepts (Hz): a hammer impact lasts about a millisecond, and below
#: 100 samples per second no sample sees it cross the trigger level
MIN_SAMPLE_RATE_HZ = 100.0
#: samples the simulated record keeps before the trigger (:func:`hardware_sim.demo.demo_setup`), and the
#: shortest record accepted: twice that
PRETRIGGER_SAMPLES = demo_setup().pretrigger_samples
MIN_SAMPLES = 2 * PRETRIGGER_SAMPLES


@dataclass(frozen=True)
class SimOptions:
    """``modalab sim``: the structure ('demo' or a bulk-data file), hammer points, fixed accelerometers, hits
    per point, random seed, peak force (N), double-hit probability, sampling rate (Hz), samples per record."""

    structure: str = "demo"
    points: tuple | None = None
    references: tuple | None = None
    hits: int = 3
    seed: int = 1
    force_n: float | None = None
    double_hit_probability: float = 0.0
    sample_rate_hz: float | None = None
    n_samples: int | None = None

    def __post_init__(self):
        object.__setattr__(self, "points", _tuple(self.points))
        object.__setattr__(self, "references", _tuple(self.references))
        # checked before any simulation (a bad value once failed after the first point's progress line, or
        # ran silently: --samples 0 meant the default); the messages name the options of modalab sim
        for opt, dofs in (("--points", self.points), ("--references", self.references)):
            twice = sorted({d for d in dofs or () if list(dofs).count(d) > 1})
            if twice:
                raise PlanError(f"{opt}: {', '.join(twice)} given twice; expected each DOF once (repeat hits with "
                                "--hits)" if opt == "--points" else f"{opt}: {', '.join(twice)} given twice; "
                                "expected each accelerometer DOF once")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise PlanError(f"--seed {self.seed}: expected a whole number >= 0; give e.g. --seed 1")
        if isinstance(self.hits, bool) or not isinstance(self.hits, int) or self.hits < 1:
            raise PlanError(f"--hits {self.hits}: expected at least 1 hit per point; give e.g. --hits 3")
        fs = self.sample_rate_hz
        if fs is not None and not (np.isfinite(fs) and fs >= MIN_SAMPLE_RATE_HZ):
            raise PlanError(f"--sample-rate {fs:g}: expected at least {MIN_SAMPLE_RATE_HZ:g} Hz (samples per second; "
                            "an impact lasts about a millisecond); give e.g. --sample-rate 2048")
        n = self.n_samples
        if n is not None and n < MIN_SAMPLES:
            raise PlanError(f"--samples {n}: expected at least {MIN_SAMPLES} samples per record (the record keeps "
                            f"{PRETRIGGER_SAMPLES} before the trigger); give e.g. --samples 8192")
        if self.force_n is not None and not (np.isfinite(self.force_n) and self.force_n > 0):
            raise PlanError(f"--force {self.force_n:g}: expected a peak force above 0 N; give e.g. --force 100")
        p2 = self.double_hit_probability
        if not (np.isfinite(p2) and 0 <= p2 <= 1):
            raise PlanError(f"--double-hits {p2:g}: expected a probability from 0 to 1; give e.g. --double-hits 0.1")


def _sim_structure(structure):
    """The structure to simulate: the demo grillage, or the FE model of a bulk-data file; and that model.

    The demo is simulated with its hysteretic damping (``D = η K_beam + η_s K_springs``), the damping that
    bulk data express exactly (PARAM G and the springs' GE, :func:`demo_fe_model`): data simulated by
    ``modalab sim`` are then data of the exported ``model.bdf`` itself, and an exact model stays exact
    (χ²/N about 1 in the diagnosis).  The viscous demo's ζ rising with frequency has no bulk-data
    equivalent that the FRF fits use (a constant loss factor left χ²/N at 12-14 on it)."""

    if structure in (None, "demo"):
        return hdemo.demo_structure("hysteretic"), None
    path = Path(structure)
    if path.suffix.lower() in (".bdf", ".dat", ".nas", ".blk"):
        model = load_model(path)
        return model.structure(), model
    raise PlanError(f"structure {structure!r}: expected 'demo' or a Nastran bulk-data file (.bdf/.dat)")


def demo_fe_model():
    """The demo aeroplane cross (:mod:`hardware_sim.demo`) as an FE model for bulk data: the same grillage of
    aluminium bars as 3-D beams (CBAR/PBAR, out-of-plane bending and torsion; in-plane DOFs held by SPC),
    the four bungees as springs to ground, and the damping of the simulated demo (``damping='hysteretic'``):
    PARAM G = η = 0.01 and GE = η_s − η on the bungees (their loss factor η_s = 0.06 in all)."""

    coords, members, springs = _demo_geometry()
    m = FEModel("modalab demo aeroplane", coupled_mass=True, global_ge=hdemo.ETA_BEAM)
    for n, xyz in sorted(coords.items()):
        m.add_node(n, tuple(float(v) for v in xyz))
        m.add_spc(n, "126")
    sections = {}
    for eid, (a, b, sec) in enumerate(members, start=1):
        if id(sec) not in sections:
            pid = len(sections) + 1
            m.add_material(Material(pid, E=sec.E, G=sec.G, nu=sec.E / (2 * sec.G) - 1, rho=sec.rho))
            # v = Z: local y (plane 1) is global Z, so out-of-plane bending uses I1 = Iz; in-plane Iy = Ip - I
            m.add_property(BeamProperty(pid, pid, GeneralSection(A=sec.A, Iy=sec.Ip - sec.I, Iz=sec.I, J=sec.J),
                                        name="fuselage" if pid == 1 else "wing"))
            sections[id(sec)] = pid
        m.add_element(Beam3D(eid, a, b, sections[id(sec)], orientation=(0.0, 0.0, 1.0)))
    for k, (n, kz) in enumerate(sorted(springs.items()), start=100):
        m.add_element(Spring(k, a=(n, 3), b=None, k=float(kz), ge=hdemo.ETA_BUNGEE - hdemo.ETA_BEAM,
                             group="bungee"))
    return m


def _export_model(folder: Path, model) -> list:
    """``model.bdf`` and ``params.toml`` (E and density multipliers per property, bounded 0.5-2) in ``folder``."""

    folder.mkdir(parents=True, exist_ok=True)
    bdf = write_text(folder / "model.bdf", "$ " + (model.name or "modalab model") + " (modalab sim --export-model)\n"
                     + write_bdf(to_bulk(model)))
    lines = ["# Updating parameters of model.bdf: multipliers of the nominal values (1 = nominal)."]
    for p in default_parameters(model):
        sel = ", ".join(f'"{s}"' if isinstance(s, str) else str(s) for s in p.properties)
        lines += ["", "[[parameter]]", f'name = "{p.name}"', f'field = "{p.field}"', f"properties = [{sel}]",
                  "lower = 0.5", "upper = 2.0"]
    toml = write_text(folder / "params.toml", "\n".join(lines) + "\n")
    return [bdf, toml]


def sim(out_uff, opts: SimOptions = SimOptions(), *, plot_path=None, export_model=None,
        progress: Callable | None = None) -> StageResult:
    """Simulate a roving-hammer test and write its raw hits (UFF 58 time records, one per channel per hit).

    plot_path : figure of the first hit (force and responses against time), e.g. ``hits_first_hit.png`` next
        to the UFF (None: no figure).
    export_model : folder for ``model.bdf`` and ``params.toml`` of the simulated structure (the demo
        structure's FE model, :func:`demo_fe_model`, or the given bulk data), ready for correlate/update/diagnose.
    progress : callable ``(points done, points in all, point)``.
    """


    st, model = _sim_structure(opts.structure)
    pts = list(opts.points or DEMO_POINTS)
    refs = list(opts.references or DEMO_REFERENCES)
    setup_kw = {}
    if opts.sample_rate_hz is not None:
        setup_kw["sample_rate_hz"] = float(opts.sample_rate_hz)
    if opts.n_samples is not None:
        setup_kw["n_samples"] = int(opts.n_samples)
    p2 = opts.double_hit_probability
    faults = FaultConfig(double_hit_probability=p2) if p2 else None
    lab = SimulatedLab(st, demo_channels(pts[0], refs), demo_setup(**setup_kw), faults=faults,
                       rng=np.random.default_rng(opts.seed))
    lab.prepare(pts)                       # exact FRF columns of every point in one batch
    recs = []
    for k, pt in enumerate(pts):           # point by point (the same random stream as one call) for progress
        recs += simulate_roving_test(lab, [pt], hits_per_point=opts.hits, force_n=opts.force_n)
        if progress:
            progress(k + 1, len(pts), pt)
    for i, r in enumerate(recs, start=1):
        r.hit_id = i
        r.metadata = {**(r.metadata or {}), "backend": "sim"}     # simulated data say so in the UFF
    out = Path(out_uff)
    out.parent.mkdir(parents=True, exist_ok=True)
    if getattr(st, "coords", None):
        uff.write_geometry(out, st.coords)
        uff.write_records(out, recs, append=True)
    else:
        uff.write_records(out, recs)
    files = [out]
    if plot_path is not None:
        plot_hit(recs[0], path=Path(plot_path), title=f"hit 1 at {recs[0].force_dofs[0]}")
        files.append(Path(plot_path))
    if export_model is not None:
        files += _export_model(Path(export_model), demo_fe_model() if model is None else model)
    return StageResult(recs, tuple(files), {"hits": len(recs) // max(len(pts), 1), "points": len(pts),
                                            "channels": recs[0].n_channels})
