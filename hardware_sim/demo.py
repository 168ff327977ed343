"""The built-in demo structure: a small aluminium "aeroplane" cross on soft bungees.

A planar grillage of Euler–Bernoulli beam elements with out-of-plane bending
and St-Venant torsion (DOFs ``Z``, ``RX``, ``RY`` at each node; the in-plane
motion is not modelled because a hammer test in Z does not excite it),
built with numpy/scipy only.  It has the modal character of the GARTEUR
SM-AG19 testbed in miniature: a fuselage and a flexible wing, close
symmetric/antisymmetric pairs, three suspension modes well below the first
elastic mode.

Geometry and material (SI)
--------------------------
* Material: aluminium 6082, E = 70 GPa, G = 26.3 GPa (ν = 0.33), ρ = 2700 kg/m³.
* Fuselage: along X from x = −0.6 m (node 1, tail) to x = +0.6 m (node 7, nose),
  nodes 1..7 every 0.2 m; solid bar 50 mm wide (Y) × 25 mm high (Z).
* Wing: along Y from y = −0.8 m (node 11, left tip) to y = +0.8 m (node 19, right tip),
  nodes 11..14 and 16..19 every 0.2 m, joined to the fuselage at its centre
  node 4 (x = y = 0; there is no node 15); flat bar 100 mm chord (X) × 12 mm thick (Z).
* Suspension: four vertical bungee springs of 1000 N/m under nodes 2, 6 (x = ∓0.4 m)
  and 13, 17 (y = ∓0.4 m).
* Mass 9.23 kg; 15 nodes, 45 DOFs.

Damping
-------
``damping='viscous'`` (default): classical (proportional) modal damping
``C = M Φ diag(2 ζ_r ω_r) Φᵀ M`` with ζ = 3 % on the three suspension modes
(bungees) and ζ_r = 0.5 % + 1 % · f_r / 1 kHz (capped at 2 %) on the elastic
modes: 0.52 % at the first, 1.2 % at 700 Hz.  ``damping='hysteretic'``:
structural damping ``D = η K_beam + η_s K_springs`` with η = 1 % (ζ ≈ 0.5 %)
for the aluminium and η_s = 6 % for the bungees: the damping that bulk data state exactly (PARAM G, the
springs' GE), which ``modalab sim`` and ``acquire --backend sim`` simulate for ``structure = "demo"``.

Natural frequencies (Hz): suspension 2.70, 3.31, 4.07; elastic 18.97, 67.45,
70.95, 118.4, 203.4, 216.5, 224.9, 268.9, 285.7, 437.2, 443.4, 582.2, ...

Functions
---------
BeamSection       section and material of a grillage member.
grillage          assemble M, K of a planar grillage.
demo_structure    the demo :class:`modalab.core.structure.Structure`.
demo_channels     hammer (2.25 mV/N) + three accelerometers (50 mV/g) at 19+Z, 12+Z, 1+Z.
demo_setup        2048 Hz, 8192 samples (4 s, 0.25 Hz lines), 128 pretrigger samples.
demo_lab          a ready :class:`SimulatedLab` on the demo structure (hammer ``DEMO_HAMMER``: 100 N, medium tip).
DEMO_POINTS       the default roving-hammer points (11 Z DOFs).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from modalab.core.errors import ModalabValueError
from modalab.core.structure import Structure
from modalab.core.units import G as G_STANDARD

from .hammer import Hammer
from .lab import SimulatedLab
from .setup import AcquisitionSetup, ChannelSetup, FaultConfig

__all__ = ["BeamSection", "grillage", "demo_structure", "demo_channels", "demo_setup", "demo_lab",
           "DEMO_HAMMER", "DEMO_POINTS", "DEMO_REFERENCES", "ALUMINIUM", "ETA_BEAM", "ETA_BUNGEE"]

_DIRS = (3, 4, 5)          # Z, RX, RY


@dataclass(frozen=True)
class BeamSection:
    """A grillage member: Young's and shear moduli (Pa), density (kg/m³), area A (m²),
    out-of-plane bending second moment I (m⁴), torsion constant J (m⁴) and polar
    second moment Ip (m⁴, for the torsional inertia ρ·Ip per unit length)."""

    E: float
    G: float
    rho: float
    A: float
    I: float
    J: float
    Ip: float

    @classmethod
    def rectangle(cls, width: float, height: float, E: float = 70e9, G: float = 26.3e9,
                  rho: float = 2700.0) -> "BeamSection":
        """Solid rectangle ``width`` (in plane) × ``height`` (out of plane), in m.

        Torsion constant by Roark: ``J = a b³ [1/3 − 0.21 (b/a)(1 − b⁴/(12 a⁴))]`` with a ≥ b.
        """
        if not (width > 0 and height > 0):
            raise ModalabValueError(f"section {width!r} x {height!r} m must have positive sides")
        a, b = max(width, height), min(width, height)
        J = a * b ** 3 * (1 / 3 - 0.21 * (b / a) * (1 - b ** 4 / (12 * a ** 4)))
        return cls(E=E, G=G, rho=rho, A=width * height, I=width * height ** 3 / 12, J=J,
                   Ip=(width * height ** 3 + height * width ** 3) / 12)


ALUMINIUM = dict(E=70e9, G=26.3e9, rho=2700.0)
#: loss factors of ``damping='hysteretic'``: the aluminium members and the bungees (D = η K_beam + η_s K_springs)
ETA_BEAM = 0.01
ETA_BUNGEE = 0.06


def _element(sec: BeamSection, p1, p2):
    """Global 6×6 stiffness and consistent mass of a grillage element, DOFs (Z, RX, RY) per node."""
    d = np.asarray(p2, float)[:2] - np.asarray(p1, float)[:2]
    L = float(np.hypot(*d))
    if L <= 0:
        raise ModalabValueError(f"grillage element between {p1} and {p2} has zero length")
    c, s = d / L
    EI, GJ = sec.E * sec.I, sec.G * sec.J
    kb = EI / L ** 3 * np.array([[12, 6 * L, -12, 6 * L], [6 * L, 4 * L * L, -6 * L, 2 * L * L],
                                 [-12, -6 * L, 12, -6 * L], [6 * L, 2 * L * L, -6 * L, 4 * L * L]])
    mb = sec.rho * sec.A * L / 420 * np.array([[156, 22 * L, 54, -13 * L], [22 * L, 4 * L * L, 13 * L, -3 * L * L],
                                               [54, 13 * L, 156, -22 * L], [-13 * L, -3 * L * L, -22 * L, 4 * L * L]])
    kt = GJ / L * np.array([[1.0, -1.0], [-1.0, 1.0]])
    mt = sec.rho * sec.Ip * L / 6 * np.array([[2.0, 1.0], [1.0, 2.0]])
    # local DOFs per node: w, θt (about the axis e), θb (about n = ẑ × e); slope dw/dξ = −θb
    P = np.zeros((4, 6))
    P[0, 0], P[1, 2], P[2, 3], P[3, 5] = 1, -1, 1, -1
    Q = np.zeros((2, 6))
    Q[0, 1], Q[1, 4] = 1, 1
    Kl = P.T @ kb @ P + Q.T @ kt @ Q
    Ml = P.T @ mb @ P + Q.T @ mt @ Q
    R = np.array([[1, 0, 0], [0, c, s], [0, -s, c]])
    T = np.kron(np.eye(2), R)
    return T.T @ Kl @ T, T.T @ Ml @ T


def grillage(coords: dict, members, springs: dict | None = None, masses: dict | None = None):
    """Assemble a planar grillage (out-of-plane bending + torsion) of Euler–Bernoulli elements.

    Parameters
    ----------
    coords : {node: (x, y[, z])} in m; z is ignored (the grillage lies in the XY plane).
    members : iterable of ``(node_a, node_b, BeamSection)``.
    springs : optional {node: k} vertical (Z) springs to ground, N/m.
    masses : optional {node: m} lumped masses, kg.

    Returns
    -------
    M, K_beam, K_springs : scipy.sparse CSR matrices on ``dofs``.
    dofs : labels ``'n+Z', 'n+RX', 'n+RY'`` for every node in ascending order.
    """
    nodes = sorted(coords)
    pos = {n: i for i, n in enumerate(nodes)}
    ndof = 3 * len(nodes)
    rows, cols, kv, mv = [], [], [], []
    for a, b, sec in members:
        if a not in pos or b not in pos:
            raise ModalabValueError(f"member ({a}, {b}) uses a node without coordinates; known nodes: {nodes}")
        ke, me = _element(sec, coords[a], coords[b])
        idx = np.r_[3 * pos[a]: 3 * pos[a] + 3, 3 * pos[b]: 3 * pos[b] + 3]
        rows.append(np.repeat(idx, 6))
        cols.append(np.tile(idx, 6))
        kv.append(ke.ravel())
        mv.append(me.ravel())
    r, c = np.concatenate(rows), np.concatenate(cols)
    K = sp.coo_matrix((np.concatenate(kv), (r, c)), shape=(ndof, ndof)).tocsr()
    M = sp.coo_matrix((np.concatenate(mv), (r, c)), shape=(ndof, ndof)).tocsr()
    ks = np.zeros(ndof)
    for n, k in (springs or {}).items():
        ks[3 * pos[n]] += float(k)
    lm = np.zeros(ndof)
    for n, m in (masses or {}).items():
        lm[3 * pos[n]] += float(m)
    M = (M + sp.diags(lm)).tocsr()
    M = ((M + M.T) / 2).tocsr()
    K = ((K + K.T) / 2).tocsr()
    dofs = [f"{n}+{d}" for n in nodes for d in ("Z", "RX", "RY")]
    return M, K, sp.diags(ks).tocsr(), dofs


def _demo_geometry():
    fus = BeamSection.rectangle(0.050, 0.025, **ALUMINIUM)
    wing = BeamSection.rectangle(0.100, 0.012, **ALUMINIUM)
    coords = {n: (-0.6 + 0.2 * (n - 1), 0.0, 0.0) for n in range(1, 8)}
    wing_nodes = [11, 12, 13, 14, 4, 16, 17, 18, 19]
    for i, n in enumerate(wing_nodes):
        if n != 4:
            coords[n] = (0.0, -0.8 + 0.2 * i, 0.0)
    members = [(n, n + 1, fus) for n in range(1, 7)]
    members += [(a, b, wing) for a, b in zip(wing_nodes[:-1], wing_nodes[1:])]
    springs = {2: 1000.0, 6: 1000.0, 13: 1000.0, 17: 1000.0}
    return coords, members, springs


def demo_structure(damping: str = "viscous") -> Structure:
    """The demo aeroplane cross (see the module docstring) with ``'viscous'`` or ``'hysteretic'`` damping."""
    coords, members, springs = _demo_geometry()
    M, Kb, Ks, dofs = grillage(coords, members, springs)
    K = (Kb + Ks).tocsr()
    if damping == "viscous":
        omega, phi = Structure(M=M, K=K, dofs=dofs).normal_modes()
        f = omega / (2 * math.pi)
        zeta = np.where(f < 10.0, 0.03, np.minimum(0.005 + 0.01 * f / 1000.0, 0.02))
        Mphi = M @ phi
        C = Mphi @ np.diag(2 * zeta * omega) @ Mphi.T
        return Structure(M=M, K=K, C=(C + C.T) / 2, dofs=dofs, coords=coords,
                         name="modalab demo aeroplane (viscous)")
    if damping == "hysteretic":
        return Structure(M=M, K=K, D=(ETA_BEAM * Kb + ETA_BUNGEE * Ks).tocsr(), dofs=dofs, coords=coords,
                         name="modalab demo aeroplane (hysteretic)")
    raise ModalabValueError(f"damping {damping!r}; expected 'viscous' or 'hysteretic'")


#: the demo's hammer: 0.16 kg, medium tip, 100 N hits (harder driving-point hits at the light wing
#: tips overload the 100 g accelerometers' front end, as they would on the bench)
DEMO_HAMMER = Hammer(force_n=100.0)

#: default roving-hammer points (Z on fuselage and wing)
DEMO_POINTS = ("1+Z", "3+Z", "4+Z", "5+Z", "7+Z", "11+Z", "12+Z", "14+Z", "16+Z", "18+Z", "19+Z")
#: the fixed accelerometers (references after reciprocity)
DEMO_REFERENCES = ("19+Z", "12+Z", "1+Z")


def demo_channels(hammer_point: str = "4+Z", references=DEMO_REFERENCES) -> list[ChannelSetup]:
    """A modal hammer (2.25 mV/N, ±5 V → ±2222 N) and accelerometers of 50 mV/g (±5 V → ±981 m/s², 100 g)."""
    ch = [ChannelSetup(dof=hammer_point, role="force", sensitivity=2.25e-3, range_v=5.0, noise_v_rms=1e-5,
                       name="ai0 hammer")]
    for i, d in enumerate(references, start=1):
        ch.append(ChannelSetup(dof=d, role="response", sensitivity=0.05 / G_STANDARD, range_v=5.0,
                               noise_v_rms=1e-5, name=f"ai{i} accelerometer"))
    return ch


def demo_setup(**kw) -> AcquisitionSetup:
    """2048 Hz, 8192 samples (4 s, 0.25 Hz lines), 128 pretrigger samples, 5 N trigger; overrides by keyword."""
    base = dict(sample_rate_hz=2048.0, n_samples=8192, pretrigger_samples=128, trigger_level=5.0)
    base.update(kw)
    return AcquisitionSetup(**base)


def demo_lab(rng=0, *, damping: str = "viscous", hammer: Hammer | None = None, faults: FaultConfig | None = None,
             channels=None, setup=None, **kw) -> SimulatedLab:
    """A :class:`SimulatedLab` on :func:`demo_structure` with :func:`demo_channels` and :func:`demo_setup`."""
    return SimulatedLab(demo_structure(damping), channels if channels is not None else demo_channels(),
                        setup if setup is not None else demo_setup(),
                        hammer=hammer if hammer is not None else DEMO_HAMMER, faults=faults, rng=rng, **kw)
