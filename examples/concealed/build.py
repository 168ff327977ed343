"""Build the concealed-physics demonstration set (deterministic, seeded).

Each case directory holds

``nominal.bdf``
    the nominal FE model (Nastran bulk data, written by :func:`updating.fe.bulk.write_bdf`);
``measured.uff``
    FRFs (UFF 58, accelerance, with coherence) of a *truth* structure measured by a full simulated
    roving-hammer test (:mod:`hardware_sim`: hammer pulse, sensor and ADC noise, anti-alias filter,
    24-bit quantisation, 3 averaged hits per point, H1 estimate with an exponential window whose decay
    β is carried in the file), re-ordered by reciprocity so that the hit points are the responses and the
    fixed accelerometers the references;
``truth.json``
    what was concealed (category, place, value), the background parameter errors and the measured noise
    level.  It is **not** an input of the diagnosis: only the tests read it.

The truth structures use a mesh twice as fine as the nominal (extra grids numbered from 1000) and small
background parameter errors (a few per cent per property, ±1 % per element), so that the nominal model
is wrong in its parameters everywhere and additionally leaves out one effect.

Structures: a suspended aluminium bar (planar, 8 elements nominal), a stepped steel beam (two sections
joined at node 5, suspended), a cantilevered steel strip (clamped at node 1).  The GARTEUR frame is not
used here: its diagnosis takes minutes rather than seconds (see ``benchmarks/diagnose_timing.py``).

Run ``python examples/concealed/build.py`` (about a minute); it overwrites the case directories.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parents[1]) not in sys.path:  # running from a checkout
    sys.path.insert(0, str(HERE.parents[1]))

from acquisition.reciprocity import reorder_by_reciprocity  # noqa: E402
from acquisition.spectral import estimate_frf_roving  # noqa: E402
from acquisition.windows import ExponentialWindow  # noqa: E402
from hardware_sim import AcquisitionSetup, ChannelSetup, Hammer, SimulatedLab, simulate_roving_test  # noqa: E402
from modalab.core import uff  # noqa: E402
from updating.fe.bulk import write_bdf  # noqa: E402
from updating.fe import Beam3D, BeamProperty, FEModel, LumpedMass, Material, RectangularSection, Spring  # noqa: E402

G0 = 9.80665

# ----------------------------------------------------------------------------------------- structures


def _beam(name, segments, n_el, *, refine=1, cords=(), clamp=None, errors=None, rng=None, global_ge=0.02):
    """A planar (x-z) beam of ``segments`` = [(length, b, h, E, rho, n_elements)], nodes 1.. along x.

    With ``refine`` > 1 every nominal element is split into ``refine`` elements (new grids from 1000);
    ``errors`` = {pid: (E factor, rho factor)} background errors, plus ±1 % per element when ``rng``.
    """
    m = FEModel(name, global_ge=global_ge)
    x = 0.0
    nid = 1
    m.add_node(1, (0.0, 0.0, 0.0))
    extra = 1000
    eid = 1
    for pid, (length, b, h, E, rho, ne) in enumerate(segments, start=1):
        fE, fr = (errors or {}).get(pid, (1.0, 1.0))
        m.add_material(Material(pid, E=E * fE, nu=0.33, rho=rho * fr))
        m.add_property(BeamProperty(pid, pid, RectangularSection(b, h), name=f"seg{pid}"))
        dl = length / ne
        for _ in range(ne):
            a = nid
            nid += 1
            m.add_node(nid, (x + dl, 0.0, 0.0))
            mids = []
            for k in range(1, refine):
                extra += 1
                m.add_node(extra, (x + k * dl / refine, 0.0, 0.0))
                mids.append(extra)
            chain = [a] + mids + [nid]
            for n1, n2 in zip(chain[:-1], chain[1:]):
                pe = pid
                if rng is not None:
                    # ±1 % element scatter: an own material per element
                    mid = 100 + eid
                    m.add_material(Material(mid, E=E * fE * (1 + 0.01 * rng.uniform(-1, 1)), nu=0.33,
                                            rho=rho * fr * (1 + 0.01 * rng.uniform(-1, 1))))
                    pe = 100 + eid
                    m.add_property(BeamProperty(pe, mid, RectangularSection(b, h), name=f"seg{pid}"))
                m.add_element(Beam3D(eid, n1, n2, pe, orientation=(0.0, 1.0, 0.0)))
                eid += 1
            x += dl
    # planar motion in x-z: every grid keeps w (3) and θy (5) only (the Nastran way: SPC the rest)
    for n in sorted(m.nodes):
        m.add_spc(n, "1246")
    for node, k in cords:
        m.add_element(Spring(900 + node, (node, 3), None, k, group="cords"))
    if clamp is not None:
        m.add_spc(clamp, "35")
    return m


BAR = [(1.6, 0.04, 0.008, 70e9, 2700.0, 8)]                                       # aluminium bar 40 x 8
STEPPED = [(0.8, 0.03, 0.010, 210e9, 7850.0, 4), (0.8, 0.03, 0.006, 210e9, 7850.0, 4)]   # steel, 10 / 6 mm
STRIP = [(0.6, 0.03, 0.005, 210e9, 7850.0, 6)]                                      # steel strip 30 x 5
CORDS_BAR = ((1, 150.0), (9, 150.0))


def _structures(refine, rng=None, errors=None):
    return {
        "bar": lambda: _beam("suspended aluminium bar", BAR, 8, refine=refine, cords=CORDS_BAR, errors=errors,
                             rng=rng),
        "stepped": lambda: _beam("suspended stepped steel beam", STEPPED, 8, refine=refine, cords=CORDS_BAR,
                                 errors=errors, rng=rng),
        "strip": lambda: _beam("cantilevered steel strip", STRIP, 6, refine=refine, clamp=1, errors=errors, rng=rng),
    }


# ----------------------------------------------------------------------------------------- concealed effects

def _add_ground_spring(m, node, k):
    m.add_element(Spring(950 + node, (node, 3), None, k, group="concealed"))


def _add_mass(m, node, mass):
    m.add_element(LumpedMass(960 + node, node, mass=mass, group="concealed"))


def _add_local_damping(m, nominal_elements, refine, ge):
    """Hysteretic loss factor on the truth elements that replace the given nominal elements."""
    import dataclasses
    for e in nominal_elements:
        for k in range(refine):
            teid = (e - 1) * refine + 1 + k
            el = m.elements[teid]
            prop = m.properties[el.pid]
            new = dataclasses.replace(prop, pid=5000 + teid, ge=ge)
            m.add_property(new)
            m.elements[teid] = dataclasses.replace(el, pid=5000 + teid)
    m._changed()


def _add_joint(m, node, k_rot, refine):
    """Split ``node``: elements to its right attach to a new grid joined by RBE2 in z and a spring in RY."""
    import dataclasses
    nn = 3000 + node
    m.add_node(nn, m.nodes[node].xyz)
    for eid, el in list(m.elements.items()):
        if isinstance(el, Beam3D) and el.n1 == node:
            m.elements[eid] = dataclasses.replace(el, n1=nn)
    m.add_rbe2(3500 + node, node, (nn,), "12346")
    m.add_element(Spring(3600 + node, (node, 5), (nn, 5), k_rot, group="concealed"))
    m._changed()


def _release_clamp(m, node, k_rot):
    m.spcs = [s for s in m.spcs if not (s.node == node and 5 in s.components)]
    m.add_spc(node, "3")
    m.add_element(Spring(3700 + node, (node, 5), None, k_rot, group="concealed"))
    m._changed()


CASES = {
    # name: (structure, category, effect description, effect function, truth record)
    "bar_ground_spring": ("bar", "ground_spring", lambda m, r: _add_ground_spring(m, 4, 3000.0),
                          {"nodes": [4], "dofs": ["4+Z"], "elements": [], "value": 3000.0, "unit": "N/m"}),
    "bar_added_mass": ("bar", "added_mass", lambda m, r: _add_mass(m, 7, 0.12),
                       {"nodes": [7], "dofs": ["7+Z"], "elements": [], "value": 0.12, "unit": "kg"}),
    "bar_local_damping": ("bar", "local_damping", lambda m, r: _add_local_damping(m, (3, 4), r, 0.25),
                          {"nodes": [3, 4, 5], "dofs": [], "elements": [3, 4], "value": 0.25, "unit": "-"}),
    "stepped_joint_flexibility": ("stepped", "joint_flexibility", lambda m, r: _add_joint(m, 5, 300.0, r),
                                  {"nodes": [5], "dofs": ["5+RY"], "elements": [], "value": 300.0,
                                   "unit": "N·m/rad"}),
    "stepped_ground_spring": ("stepped", "ground_spring", lambda m, r: _add_ground_spring(m, 6, 5000.0),
                              {"nodes": [6], "dofs": ["6+Z"], "elements": [], "value": 5000.0, "unit": "N/m"}),
    "strip_boundary_flexibility": ("strip", "boundary_flexibility", lambda m, r: _release_clamp(m, 1, 150.0),
                                   {"nodes": [1], "dofs": ["1+RY"], "elements": [], "value": 150.0,
                                    "unit": "N·m/rad"}),
    "strip_added_mass": ("strip", "added_mass", lambda m, r: _add_mass(m, 5, 0.05),
                         {"nodes": [5], "dofs": ["5+Z"], "elements": [], "value": 0.05, "unit": "kg"}),
    "bar_control": ("bar", None, lambda m, r: None, None),
}

SENSORS = {"bar": ("2+Z", "6+Z"), "stepped": ("3+Z", "8+Z"), "strip": ("4+Z", "7+Z")}
REFINE = 2
NOISE_V = 1e-4          # sensor + cable noise (V rms) on every channel: about 1 % random FRF error near resonances


def measure(truth: FEModel, points, sensors, seed: int):
    """Full simulated roving-hammer test of ``truth``; FRFs re-ordered by reciprocity (accelerance)."""
    st = truth.structure()
    chans = [ChannelSetup(dof=points[0], role="force", sensitivity=2.25e-3, range_v=5.0, noise_v_rms=NOISE_V,
                          iepe=False, name="hammer")]
    for i, d in enumerate(sensors, start=1):
        chans.append(ChannelSetup(dof=d, role="response", sensitivity=0.01 / G0, range_v=5.0, noise_v_rms=NOISE_V,
                                  iepe=False, name=f"acc{i}"))
    setup = AcquisitionSetup(sample_rate_hz=512.0, n_samples=4096, pretrigger_samples=64, trigger_level=5.0)
    hammer = Hammer(mass_kg=0.1, tip="soft", force_n=100.0, placement_scatter_m=0.001, double_hit_probability=0.0)
    lab = SimulatedLab(st, chans, setup, hammer=hammer, rng=seed)
    recs = simulate_roving_test(lab, points, hits_per_point=3)
    frf = estimate_frf_roving(recs, exp_window=ExponentialWindow(end_level=0.05))
    frf = reorder_by_reciprocity(frf)
    # the deliverable: the anti-alias pass band (0.45 fs), without the DC line
    return frf.band(0.5, 0.43 * setup.sample_rate_hz), lab


def build_case(name: str, out: Path, seed: int) -> dict:
    kind, category, effect, rec = CASES[name]
    rng = np.random.default_rng(seed)
    nominal = _structures(1)[kind]()
    n_nominal_nodes = sorted(n for n in nominal.nodes if n < 1000)
    errors = {pid: (1 + rng.uniform(-0.05, 0.05), 1 + rng.uniform(-0.03, 0.03)) for pid in nominal.properties}
    truth = _structures(REFINE, rng=rng, errors=errors)[kind]()
    effect(truth, REFINE)
    points = [f"{n}+Z" for n in n_nominal_nodes if not (kind == "strip" and n == 1)]
    frf, lab = measure(truth, points, SENSORS[kind], seed)
    ok = (frf.freq_hz > 1.0) & (frf.freq_hz < 0.4 * 512)
    beta = float(frf.window_beta_per_s)
    # random error of an H1 estimate from n averages: ε ≈ √((1 − γ²) / (2 n γ²)) (Bendat & Piersol)
    coh = np.clip(frf.coherence[..., ok], 1e-6, 1.0)
    noise = float(np.median(np.sqrt((1 - coh) / (2 * 3 * coh))))
    out.mkdir(parents=True, exist_ok=True)
    write_bdf(nominal, out / "nominal.bdf")
    p = out / "measured.uff"
    if p.exists():
        p.unlink()
    uff.write_frf(p, frf)
    info = {"case": name, "structure": nominal.name, "category": category, "seed": seed,
            "concealed": ([] if rec is None else [dict(rec, physics=category)]),
            "background_errors": {nominal.properties[pid].name: {"E": e, "rho": r} for pid, (e, r) in errors.items()},
            "truth_mesh": f"{REFINE}x finer than the nominal (extra grids from 1000)",
            "measurement": {"points": points, "sensors": list(SENSORS[kind]), "hits_per_point": 3,
                            "sample_rate_hz": 512.0, "n_samples": 4096, "exp_window_beta": beta,
                            "median_random_error_from_coherence": noise,
                            "mean_coherence": float(np.mean(frf.coherence[..., ok]))}}
    (out / "truth.json").write_text(json.dumps(info, indent=1))
    return info


def main(names=None):
    names = names or list(CASES)
    for k, name in enumerate(CASES):
        if name in names:
            info = build_case(name, HERE / name, seed=100 + k)
            print(f"{name}: {info['measurement']['mean_coherence']:.3f} mean coherence")


if __name__ == "__main__":
    main(sys.argv[1:] or None)
