"""One concealed-physics case from one seed: topology, truth structure, concealed effect, simulated test.

Case ``i`` uses ``numpy.random.default_rng(i)`` only.  The topology cycles with ``i // 2`` so that the even
(tuning) and odd (held-out) halves see every topology; ``(i // 2) % 6 == 5`` are controls (parameter errors
only: 10 of seeds 0..59, five in each half).  The truth is built by :mod:`truthsim` (no project code).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .topologies import Frame, build_topology
from .truthsim import TruthModel, box, tube

__all__ = ["Case", "make_case", "build_truth", "TOPOLOGY_ORDER", "KINDS"]

TOPOLOGY_ORDER = ["free_frame", "clamped_post", "suspended_frame", "clamped_portal", "mounted_frame",
                  "planar_frame", "space_frame", "t_joint"]
KINDS = ["ground_spring", "added_mass", "joint_flexibility", "local_damping", "boundary_flexibility"]
TWIN0 = 5000            # truth-only twin nodes of a flexible joint: TWIN0 + joint node
FINE0 = 1000            # truth-only interior grids: FINE0 + 1, 2, ...
G_ACC = 9.81


@dataclass
class Case:
    seed: int
    name: str
    frame: Frame
    refine: int
    errors: dict                     # section -> {"E": factor, "rho": factor}
    eta: dict                        # section -> hysteretic loss factor of the truth
    physics: dict | None             # the concealed effect (None: control)
    element_card: str                # CBAR or CBEAM
    nominal_damping: str             # "TABDMP1" or "none"
    band_hz: tuple
    n_lines: int
    hits: list                       # [(node, signed dir 1..3)] roving hammer points (responses by reciprocity)
    sensors: list                    # [(node, signed dir)] fixed accelerometers (references)
    noise: float                     # output noise, fraction of the channel's RMS
    n_avg: int
    binary: bool
    info: dict = field(default_factory=dict)


def _sec(frame, name):
    s = frame.sections[name]
    return tube(*s["dims"]) if s["kind"] == "TUBE" else box(*s["dims"])


def total_mass(frame) -> float:
    m = 0.0
    for _, a, b, mi in frame.elements():
        sec = _sec(frame, frame.members[mi]["section"])
        m += frame.material["rho"] * sec.A * float(np.linalg.norm(frame.nodes[b] - frame.nodes[a]))
    return m + sum(mm for _, mm in frame.masses)


def build_truth(frame: Frame, refine: int, errors: dict, eta: dict, physics: dict | None = None) -> TruthModel:
    """The truth structure: each nominal element cut into ``refine`` Timoshenko elements, per-section E and
    density errors and loss factors, the supports of the frame, the suspension cords and the physics."""
    t = TruthModel()
    for nid in sorted(frame.nodes):
        t.add_node(nid, frame.nodes[nid])
    ph = physics or {}
    kind = ph.get("physics")
    twin_of = {}
    if kind == "joint_flexibility":
        j = ph["nodes"][0]
        t.twin(j, TWIN0 + j, ph["axis"])
        twin_of = {(j, ph["member"]): TWIN0 + j}
    mat = frame.material
    nxt = FINE0 + 1
    for eid, a, b, mi in frame.elements():
        mem = frame.members[mi]
        sname = mem["section"]
        sec = _sec(frame, sname)
        E = mat["E"] * errors[sname]["E"]
        G = E / (2 * (1 + mat["nu"]))
        rho = mat["rho"] * errors[sname]["rho"]
        e_eta = eta[sname] + (ph["value"] if kind == "local_damping" and eid in ph["elements"] else 0.0)
        xa, xb = frame.nodes[a], frame.nodes[b]
        chain = [twin_of.get((a, mi), a)]
        for k in range(1, refine):
            t.add_node(nxt, xa + (xb - xa) * k / refine)
            chain.append(nxt)
            nxt += 1
        chain.append(twin_of.get((b, mi), b))
        for p, q in zip(chain, chain[1:]):
            t.beam(p, q, mem["vref"], sec, E, G, rho, e_eta, tag=eid)
    if kind == "joint_flexibility":
        j = ph["nodes"][0]
        t.spring(t.dof(j, 4 + ph["axis"]), t.dof(TWIN0 + j, 4 + ph["axis"]), ph["value"], eta=0.0)
    for n in frame.clamps:
        if kind == "boundary_flexibility" and n in ph["nodes"]:
            for c in (1, 2, 3):
                t.spring(t.dof(n, c), None, ph["k_translation"], eta=0.02)
            for c in (4, 5, 6):
                t.spring(t.dof(n, c), None, ph["value"], eta=0.02)
        else:
            t.fix(n)
    for n, c, k, ge in frame.mounts:
        t.spring(t.dof(n, c), None, k, eta=ge)
    for n, m in frame.masses:
        t.mass(n, m)
    for n, kv, kh in frame.cords:
        t.spring(t.dof(n, 3), None, kv, eta=0.05)
        t.spring(t.dof(n, 1), None, kh, eta=0.05)
        t.spring(t.dof(n, 2), None, kh, eta=0.05)
    if kind == "ground_spring":
        t.spring(t.dof(ph["nodes"][0], ph["comp"]), None, ph["value"], eta=0.02)
    elif kind == "added_mass":
        t.mass(ph["nodes"][0], ph["value"])
    return t


def _sig(x, n=3):
    """x rounded to n significant digits (what a person would type)."""
    if x == 0:
        return 0.0
    return float(f"{x:.{n - 1}e}")


def _n_rigid(frame):
    return 6 if frame.free_free else 0


def _shift(frame, refine, errors, eta, physics, f0, fmax):
    f = build_truth(frame, refine, errors, eta, physics).frequencies(len(f0))
    r = _n_rigid(frame)
    sel = np.arange(r, len(f0))
    sel = sel[f0[sel] <= fmax]
    return float(np.max(np.abs(f[sel] - f0[sel]) / f0[sel]))


def _magnitude(frame, refine, errors, eta, phys, f0, fmax, lo, hi, target, increasing):
    """Value (log-bisection in [lo, hi]) whose largest in-band frequency shift equals target; None if the place
    cannot give a 0.5 % shift."""
    def g(v):
        return _shift(frame, refine, errors, eta, dict(phys, value=v, **_extra(phys, v)), f0, fmax)
    strong = hi if increasing else lo
    gmax = g(strong)
    if gmax < 0.005:
        return None
    target = min(target, 0.8 * gmax)
    a, b = math.log(lo), math.log(hi)
    for _ in range(22):
        m = 0.5 * (a + b)
        s = g(math.exp(m))
        if (s < target) == increasing:
            a = m
        else:
            b = m
    return _sig(math.exp(0.5 * (a + b)))


def _extra(phys, v):
    if phys["physics"] == "boundary_flexibility":
        return {"k_translation": _sig(v * phys["kt_ratio"])}
    return {}


def _choose_physics(case_rng, frame, refine, errors, eta, f0, fmax, kind):
    rng = case_rng
    clamps = set(frame.clamps)
    free_nodes = [n for n in sorted(frame.nodes) if n not in clamps]
    elems = frame.elements()
    edge_nodes = {eid: (a, b) for eid, a, b, _ in elems}
    for _attempt in range(30):
        target = float(np.exp(rng.uniform(np.log(0.005), np.log(0.08))))
        if kind == "ground_spring":
            n = int(rng.choice(free_nodes))
            comp = int(rng.integers(1, 4))
            phys = {"physics": kind, "nodes": [n], "comp": comp, "dofs": [f"{n}+{'XYZ'[comp - 1]}"],
                    "elements": [], "unit": "N/m"}
            v = _magnitude(frame, refine, errors, eta, phys, f0, fmax, 10.0, 1e9, target, True)
        elif kind == "added_mass":
            n = int(rng.choice(free_nodes))
            phys = {"physics": kind, "nodes": [n], "dofs": [f"{n}"], "elements": [], "unit": "kg"}
            v = _magnitude(frame, refine, errors, eta, phys, f0, fmax, 1e-4, 5 * total_mass(frame), target, True)
        elif kind == "joint_flexibility":
            joints = frame.joints()
            if not joints:
                return None
            n = int(rng.choice(sorted(joints)))
            m = int(rng.choice(joints[n]))
            mem = frame.members[m]
            axis_vec = frame.nodes[mem["nodes"][-1]] - frame.nodes[mem["nodes"][0]]
            perp = [a for a in range(3) if abs(axis_vec[a]) < 1e-9 * np.linalg.norm(axis_vec) + 1e-12]
            ax = int(rng.choice(perp))
            phys = {"physics": kind, "nodes": [n], "member": m, "member_name": mem["name"], "axis": ax,
                    "dofs": [f"{n}+R{'XYZ'[ax]}"], "elements": [], "unit": "N*m/rad"}
            v = _magnitude(frame, refine, errors, eta, phys, f0, fmax, 1.0, 1e9, target, False)
        elif kind == "boundary_flexibility":
            if not clamps:
                return None
            n = int(rng.choice(sorted(clamps)))
            ratio = float(np.exp(rng.uniform(np.log(100.0), np.log(2000.0))))     # kt/kr (1/m^2)
            phys = {"physics": kind, "nodes": [n], "kt_ratio": ratio,
                    "dofs": [f"{n}+{c}" for c in ("X", "Y", "Z", "RX", "RY", "RZ")], "elements": [],
                    "unit": "N*m/rad"}
            v = _magnitude(frame, refine, errors, eta, phys, f0, fmax, 10.0, 1e10, target, False)
        elif kind == "local_damping":
            t = build_truth(frame, refine, errors, eta)
            f, phi = t.modes(len(f0))
            r = _n_rigid(frame)
            sel = np.arange(r, len(f))
            sel = sel[f0[sel] <= fmax]
            fr = t.energy_fractions(phi[:, sel])
            best = {eid: float(np.max(fr.get(eid, np.zeros(1)))) for eid, *_ in elems}
            weights = np.array([best[eid] * (3.0 if frame.members[mi]["name"] == "brace" else 1.0)
                                for eid, _, _, mi in elems])
            ok = weights >= 0.03
            if not ok.any():
                return None
            eid = int(rng.choice(np.array([e[0] for e in elems])[ok]))
            d_eta = float(np.exp(rng.uniform(np.log(0.003), np.log(0.02))))      # modal loss factor increase
            v = _sig(min(0.5, d_eta / best[eid]))
            phys = {"physics": kind, "nodes": list(edge_nodes[eid]), "elements": [eid], "dofs": [],
                    "unit": "loss factor", "max_modal_loss_increase": _sig(v * best[eid]),
                    "energy_fraction": _sig(best[eid])}
            phys["value"] = v
            return phys
        else:
            raise ValueError(kind)
        if v is None:
            continue
        phys["value"] = v
        phys.update(_extra(phys, v))
        phys["target_shift"] = _sig(target)
        phys["max_shift"] = _sig(_shift(frame, refine, errors, eta, phys, f0, fmax))
        if phys["max_shift"] < 0.004:
            continue
        return phys
    return None


def _kind_for(seed, rng, frame):
    if (seed // 2) % 6 == 5:
        return None
    kinds = ["ground_spring", "added_mass", "joint_flexibility", "local_damping"]
    w = [1.0, 1.0, 1.0 if frame.joints() else 0.0, 1.0]
    if frame.clamps:
        kinds.append("boundary_flexibility")
        w.append(3.0)
    w = np.array(w) / np.sum(w)
    return str(rng.choice(kinds, p=w))


def _layout(rng, frame, coupling):
    """1-5 accelerometers, then 10-40 roving-hammer DOFs that at least one accelerometer sees.

    ``coupling(dof_a, dof_b)``: relative modal coupling in the band (0..1); a lab does not hit a frame where its
    sensors cannot respond (in-plane hits with only out-of-plane sensors on a planar frame)."""
    clamps = set(frame.clamps)
    nodes = [n for n in sorted(frame.nodes) if n not in clamps]
    n_ref = int(rng.integers(1, 6))
    sensors, sused = [], set()
    while len(sensors) < n_ref:
        n, d = int(rng.choice(nodes)), int(rng.integers(1, 4))
        if (n, d) in sused or coupling((n, d), None) < 0.05:
            continue
        sused.add((n, d))
        sensors.append((n, d))
    ok = {(n, d) for n in nodes for d in (1, 2, 3) if max(coupling((n, d), s) for s in sensors) >= 0.02}
    n_hit = int(min(rng.integers(10, 41), len(ok)))
    order = list(rng.permutation(nodes))
    hits, used = [], set()
    rnd = 0
    while len(hits) < n_hit:
        for n in order:
            if len(hits) >= n_hit:
                break
            dirs = [d for d in (1, 2, 3) if (n, d) not in used and (n, d) in ok]
            if not dirs or (rnd == 0 and any(u[0] == n for u in used)):
                continue
            d = int(rng.choice(dirs))
            used.add((int(n), d))
            hits.append((int(n), -d if rng.random() < 0.2 else d))
        rnd += 1
    sensors = [(n, -d if rng.random() < 0.15 else d) for n, d in sensors]
    return hits, sensors


def _coupling(t, frame, fmax):
    """coupling(a, b): sum over in-band modes of |phi_a phi_b|, relative to the largest such value."""
    f, phi = t.modes(30)
    sel = (f > 0.5) & (f <= fmax)
    free = t.free_dofs()
    pos = {g: i for i, g in enumerate(free)}
    P = {}
    for n in frame.nodes:
        for d in (1, 2, 3):
            g = t.dof(n, d)
            P[(n, d)] = np.abs(phi[pos[g], sel]) if g in pos else np.zeros(int(sel.sum()))
    norm_self = max(float(np.sum(v * v)) for v in P.values())
    cache = {}

    def c(a, b):
        if b is None:
            return float(np.sum(P[a] ** 2)) / norm_self
        key = (a, b)
        if key not in cache:
            cache[key] = float(np.sum(P[a] * P[b]))
        return cache[key] / np.sqrt(float(np.sum(P[a] ** 2)) * float(np.sum(P[b] ** 2)) + 1e-300)
    return c


def make_case(seed: int) -> Case:
    rng = np.random.default_rng(seed)
    topo = TOPOLOGY_ORDER[(seed // 2) % len(TOPOLOGY_ORDER)]
    frame = build_topology(topo, rng)
    refine = int(rng.integers(2, 4))
    errors = {}
    for s in sorted(frame.sections):
        errors[s] = {q: _sig(1.0 + float(rng.choice([-1, 1])) * rng.uniform(0.01, 0.03), 5) for q in ("E", "rho")}
    eta = {s: _sig(rng.uniform(0.002, 0.008)) for s in sorted(frame.sections)}
    mtot = total_mass(frame)
    if frame.mounts:
        fm = rng.uniform(8.0, 15.0)
        kv = _sig(mtot * (2 * np.pi * fm) ** 2 / 4)
        frame.mounts = [(n, c, kv if c == 3 else _sig(0.5 * kv), ge) for n, c, _, ge in frame.mounts]
    if frame.cords:
        fs = rng.uniform(1.5, 3.0)
        n = len(frame.cords)
        kv = _sig(mtot * (2 * np.pi * fs) ** 2 / n)
        kh = _sig(mtot * G_ACC / n / rng.uniform(0.8, 1.5))
        frame.cords = [(c, kv, kh) for c, _, _ in frame.cords]
    element_card = "CBEAM" if rng.random() < 0.5 else "CBAR"
    nominal_damping = "TABDMP1" if rng.random() < 0.5 else "none"
    base = build_truth(frame, refine, errors, eta)
    f0 = base.frequencies(30)
    r = _n_rigid(frame)
    n_band = int(rng.integers(6, 11))
    fmax = float(math.ceil(1.08 * f0[r + n_band - 1] / 10.0) * 10.0)
    kind = _kind_for(seed, rng, frame)
    physics = None
    if kind is not None:
        physics = _choose_physics(rng, frame, refine, errors, eta, f0, fmax, kind)
        if physics is None and kind != "ground_spring":      # no admissible place: fall back to a spring
            kind = "ground_spring"
            physics = _choose_physics(rng, frame, refine, errors, eta, f0, fmax, kind)
        if physics is None:
            raise RuntimeError(f"seed {seed}: no admissible place for {kind}")
    hits, sensors = _layout(rng, frame, _coupling(base, frame, fmax))
    n_lines = 2000
    noise = float(rng.uniform(0.0005, 0.0008))
    binary = bool(rng.random() < 0.5)
    name = f"case{seed:03d}_{topo}"
    # the truth's natural frequencies without the concealed effect (what the nominal should match after its
    # parameters) and with it (what the test measured)
    f1 = f0 if physics is None else build_truth(frame, refine, errors, eta, physics).frequencies(30)
    info = {"truth_frequencies_hz": [_sig(v, 6) for v in f0 if v <= fmax * 1.2],
            "truth_frequencies_with_effect_hz": [_sig(v, 6) for v in f1 if v <= fmax * 1.2],
            "n_modes_in_band": int(np.sum((f0 > 0.5) & (f0 <= fmax))), "total_mass_kg": _sig(mtot, 4)}
    return Case(seed, name, frame, refine, errors, eta, physics, element_card, nominal_damping, (0.0, fmax),
                n_lines, hits, sensors, noise, 5, binary, info)
