"""Nominal structures of the discovery benchmark: frames of rectangular and circular tubes.

A :class:`Frame` is what a Nastran user would model: grids, members (chains of beam elements of one section),
clamps, mounts, lumped masses.  The truth mesh refines each nominal element (see ``cases.py``); nominal grids
are a subset of the truth grids.  Every builder takes a ``numpy.random.Generator`` and draws realistic sizes.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Frame", "TOPOLOGIES", "build_topology"]

STEEL = {"name": "steel", "E": 2.1e11, "nu": 0.3, "rho": 7850.0}
ALU = {"name": "aluminium", "E": 7.0e10, "nu": 0.33, "rho": 2700.0}


@dataclass
class Frame:
    topology: str
    description: str
    material: dict
    nodes: dict = field(default_factory=dict)        # nid -> xyz (nominal grids)
    sections: dict = field(default_factory=dict)     # name -> {"kind": "TUBE"/"BOX", "dims": (...)}
    members: list = field(default_factory=list)      # {"name", "section", "nodes": [...], "vref"}
    clamps: list = field(default_factory=list)       # nids clamped in all six components (SPC1 123456)
    mounts: list = field(default_factory=list)       # (nid, comp, k, ge) CELAS springs to ground (nominal too)
    masses: list = field(default_factory=list)       # (nid, m) CONM2 (nominal too)
    cords: list = field(default_factory=list)        # (nid, k_vertical, k_horizontal): truth only (suspension)
    free_free: bool = False                          # nominal without any support
    _key: dict = field(default_factory=dict)

    def node_at(self, xyz) -> int:
        k = tuple(np.round(np.asarray(xyz, float), 6))
        if k not in self._key:
            nid = len(self.nodes) + 1
            self.nodes[nid] = np.array(k, float)
            self._key[k] = nid
        return self._key[k]

    def member(self, name, section, a, b, h, vref):
        """Member from a to b in elements of about h metres; a node met on the way is reused (T-joints)."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = max(2, int(round(np.linalg.norm(b - a) / h)))
        ids = [self.node_at(a + (b - a) * i / n) for i in range(n + 1)]
        self.members.append({"name": name, "section": section, "nodes": ids, "vref": np.asarray(vref, float)})
        return ids

    def elements(self):
        """[(eid, n1, n2, member index)] in a stable order (eid from 1)."""
        out = []
        for m, mem in enumerate(self.members):
            for a, b in zip(mem["nodes"], mem["nodes"][1:]):
                out.append((len(out) + 1, a, b, m))
        return out

    def joints(self):
        """{nid: [member index whose END is at nid]} for nodes where two or more members meet."""
        touch: dict = {}
        for m, mem in enumerate(self.members):
            for n in mem["nodes"]:
                touch.setdefault(n, set()).add(m)
        out = {}
        for n, ms in touch.items():
            if len(ms) >= 2:
                ends = [m for m in sorted(ms) if n in (self.members[m]["nodes"][0], self.members[m]["nodes"][-1])]
                if ends:
                    out[n] = ends
        return out

    def edges(self):
        return [(a, b) for _, a, b, _ in self.elements()]


def _tube(rng):
    ro = rng.choice([0.010, 0.0125, 0.015, 0.016, 0.020, 0.025])
    t = rng.choice([0.0015, 0.002, 0.0025, 0.003])
    return {"kind": "TUBE", "dims": (float(ro), float(ro - t))}


def _box(rng):
    b = rng.choice([0.020, 0.025, 0.030, 0.040])
    h = rng.choice([0.020, 0.030, 0.040, 0.050])
    t = rng.choice([0.0015, 0.002, 0.003])
    return {"kind": "BOX", "dims": (float(b), float(h), float(t))}


def _section(rng, kind=None):
    kind = kind or ("TUBE" if rng.random() < 0.5 else "BOX")
    return _tube(rng) if kind == "TUBE" else _box(rng)


def _mat(rng):
    return dict(STEEL if rng.random() < 0.6 else ALU)


def _len(rng, lo, hi, step=0.05):
    return float(np.round(rng.uniform(lo, hi) / step) * step)


def _ladder(f, rng, lx, ly, h, n_cross):
    f.sections["rail"] = _section(rng)
    f.sections["cross"] = _section(rng)
    z = np.array([0.0, 0.0, 1.0])
    f.member("rail", "rail", (0, 0, 0), (lx, 0, 0), h, z)
    f.member("rail", "rail", (0, ly, 0), (lx, ly, 0), h, z)
    xs = np.linspace(0, lx, n_cross)
    rail_x = sorted({float(f.nodes[n][0]) for n in f.members[0]["nodes"]})
    for x in xs:
        x = min(rail_x, key=lambda v: abs(v - x))            # cross members at rail grids
        f.member("cross", "cross", (x, 0, 0), (x, ly, 0), h, z)


def free_frame(rng):
    f = Frame("free_frame", "free-free ladder frame (two rails, cross members)", _mat(rng))
    _ladder(f, rng, _len(rng, 0.8, 1.2), _len(rng, 0.4, 0.6), 0.1, int(rng.integers(2, 4)))
    f.free_free = True
    return f


def suspended_frame(rng):
    f = Frame("suspended_frame", "ladder frame hanging on soft elastic cords (nominal free-free)", _mat(rng))
    _ladder(f, rng, _len(rng, 0.8, 1.2), _len(rng, 0.4, 0.6), 0.1, int(rng.integers(2, 4)))
    f.free_free = True
    corners = [f.members[0]["nodes"][0], f.members[0]["nodes"][-1], f.members[1]["nodes"][0],
               f.members[1]["nodes"][-1]]
    f.cords = [(n, None, None) for n in corners]                 # stiffness set from the mass in cases.py
    return f


def clamped_post(rng):
    f = Frame("clamped_post", "vertical post clamped at its base (SPC1 123456), a bracket arm and a tip mass",
              _mat(rng))
    f.sections["post"] = _section(rng)
    f.sections["arm"] = _section(rng)
    hgt = _len(rng, 0.6, 1.0)
    f.member("post", "post", (0, 0, 0), (0, 0, hgt), 0.1, (1, 0, 0))
    arm = _len(rng, 0.2, 0.35)
    f.member("arm", "arm", (0, 0, hgt), (arm, 0, hgt), 0.1, (0, 0, 1))
    f.clamps = [f.members[0]["nodes"][0]]
    f.masses = [(f.members[1]["nodes"][-1], float(np.round(rng.uniform(0.1, 0.5), 2)))]
    return f


def clamped_portal(rng):
    f = Frame("clamped_portal", "portal frame, both feet clamped (SPC1 123456)", _mat(rng))
    f.sections["post"] = _section(rng)
    f.sections["beam"] = _section(rng)
    hgt, span = _len(rng, 0.5, 0.8), _len(rng, 0.5, 0.9)
    f.member("post", "post", (0, 0, 0), (0, 0, hgt), 0.1, (1, 0, 0))
    f.member("post", "post", (span, 0, 0), (span, 0, hgt), 0.1, (1, 0, 0))
    f.member("beam", "beam", (0, 0, hgt), (span, 0, hgt), 0.1, (0, 0, 1))
    f.clamps = [f.members[0]["nodes"][0], f.members[1]["nodes"][0]]
    return f


def mounted_frame(rng):
    f = Frame("mounted_frame", "ladder frame on four elastomer mounts (CELAS springs, 3 translations each)", _mat(rng))
    _ladder(f, rng, _len(rng, 0.8, 1.1), _len(rng, 0.4, 0.6), 0.1, int(rng.integers(2, 4)))
    corners = [f.members[0]["nodes"][0], f.members[0]["nodes"][-1], f.members[1]["nodes"][0],
               f.members[1]["nodes"][-1]]
    f.mounts = [(n, c, None, 0.08) for n in corners for c in (1, 2, 3)]      # k set from the mass in cases.py
    return f


def planar_frame(rng):
    f = Frame("planar_frame", "planar rectangular frame with a diagonal brace (free-free)", _mat(rng))
    f.sections["chord"] = _section(rng)
    f.sections["brace"] = _section(rng, "TUBE")
    lx, lz = _len(rng, 0.6, 1.0), _len(rng, 0.4, 0.6)
    y = np.array([0.0, 1.0, 0.0])
    f.member("chord", "chord", (0, 0, 0), (lx, 0, 0), 0.1, y)
    f.member("chord", "chord", (0, 0, lz), (lx, 0, lz), 0.1, y)
    f.member("chord", "chord", (0, 0, 0), (0, 0, lz), 0.1, y)
    f.member("chord", "chord", (lx, 0, 0), (lx, 0, lz), 0.1, y)
    f.member("brace", "brace", (0, 0, 0), (lx, 0, lz), 0.12, y)
    f.free_free = True
    return f


def space_frame(rng):
    f = Frame("space_frame", "3-D table frame: top rectangle, four legs, one brace (free-free)", _mat(rng))
    f.sections["top"] = _section(rng)
    f.sections["leg"] = _section(rng)
    f.sections["brace"] = _section(rng, "TUBE")
    lx, ly, hz = _len(rng, 0.5, 0.8), _len(rng, 0.4, 0.6), _len(rng, 0.4, 0.6)
    z = np.array([0.0, 0.0, 1.0])
    x = np.array([1.0, 0.0, 0.0])
    for a, b in (((0, 0, hz), (lx, 0, hz)), ((0, ly, hz), (lx, ly, hz)), ((0, 0, hz), (0, ly, hz)),
                 ((lx, 0, hz), (lx, ly, hz))):
        f.member("top", "top", a, b, 0.1, z)
    for (px, py) in ((0, 0), (lx, 0), (0, ly), (lx, ly)):
        f.member("leg", "leg", (px, py, 0), (px, py, hz), 0.1, x)
    f.member("brace", "brace", (0, 0, 0), (lx, 0, 0), 0.12, z)
    f.free_free = True
    return f


def t_joint(rng):
    f = Frame("t_joint", "T-joint of two welded tubes (free-free)", _mat(rng))
    f.sections["main"] = _section(rng)
    f.sections["branch"] = _section(rng)
    L = _len(rng, 0.8, 1.2)
    b = _len(rng, 0.4, 0.7)
    f.member("main", "main", (0, 0, 0), (L, 0, 0), 0.1, (0, 0, 1))
    xs = sorted(float(f.nodes[n][0]) for n in f.members[0]["nodes"])
    xj = min(xs, key=lambda v: abs(v - L * rng.uniform(0.35, 0.65)))
    if rng.random() < 0.5:
        f.member("branch", "branch", (xj, 0, 0), (xj, b, 0), 0.1, (0, 0, 1))     # in the plane XY
    else:
        f.member("branch", "branch", (xj, 0, 0), (xj, 0, b), 0.1, (0, 1, 0))     # in the plane XZ
    f.free_free = True
    return f


TOPOLOGIES = {"free_frame": free_frame, "suspended_frame": suspended_frame, "clamped_post": clamped_post,
              "clamped_portal": clamped_portal, "mounted_frame": mounted_frame, "planar_frame": planar_frame,
              "space_frame": space_frame, "t_joint": t_joint}


def build_topology(name, rng) -> Frame:
    return TOPOLOGIES[name](rng)
