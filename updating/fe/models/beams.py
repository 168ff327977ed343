"""Simple beam test structures and their closed-form natural frequencies.

* :func:`beam_model` — a uniform straight beam along X with free-free,
  cantilever or pinned (simply supported) ends, as 2-D (w, θ) or 3-D frame elements.
* :func:`closed_form_hz` — Euler–Bernoulli natural frequencies
  ``ω_n = (β_n L)² √(EI / (ρA L⁴))`` for those boundary conditions
  (Blevins, *Formulas for Natural Frequency and Mode Shape*, table 8-1).
* :func:`timoshenko_pinned_hz` — exact Timoshenko frequencies of a simply
  supported beam (roots of EIk⁴ − ρAω² − (ρI + EIρ/κG)k²ω² + ρIρ/(κG) ω⁴ = 0, k = nπ/L).
* :func:`thesis_beam` / :func:`thesis_beam_parameters` — the 20-DOF free-free
  beam of the thesis' section 5.2 (Tables 3–4).

The thesis beam.  Nine 2-D beam elements, nodes 1..10 with (w, θ) each
(labels ``n+Z`` and ``n+RY``, the x–z plane), tubular sections with the outer
and inner diameters of Table 3 (analytical or pseudo-experimental columns),
elastic suspension cords at nodes 1 and 10 modelled as grounded springs on w
(100 N/m or 1000 N/m in the thesis).  Table 4 gives the experimental/analytical
ratios of Young's modulus, density and Poisson's ratio per element.

The thesis does not give the element lengths, the material or the
nominal modulus and density (Figure 25 is not reproduced).  Chosen here,
and documented as choices: steel-like E = 210 GPa, ρ = 7850 kg/m³, ν = 0.3
and element length 0.3 m (beam 2.7 m).  With 100 N/m cords they put the
suspension (cord) modes of the analytical model at 13 and 35 rad/s and the first
two elastic modes at 65 and 114 rad/s: the bounce mode lies in the 0–20 rad/s band
the thesis names as cord-dominated and the first elastic mode inside the 40–80 rad/s
band used for updating.  Note that these cords are not "soft" for this light beam: the
free-free first elastic mode is at 43.9 rad/s, so 100 N/m cords raise it to 65 rad/s and
1000 N/m cords to 122 rad/s (see ``tests/updating/test_case_beam_mci.py`` for what that
does to parameter-only updating).
Poisson's ratio does not enter an Euler–Bernoulli beam, so its Table 4 ratio
is stored in the materials but has no effect.
"""
from __future__ import annotations

import numpy as np

from modalab.core.errors import ModalabValueError
from updating.fe import (Beam2D, Beam3D, BeamProperty, FEModel, Material, Parameter, Spring,
                         Timoshenko3D, TubeSection)
from updating.fe import RectangularSection

__all__ = ["beam_model", "closed_form_hz", "timoshenko_pinned_hz", "BETA_L", "thesis_beam",
           "thesis_beam_parameters", "THESIS_TABLE3_MM", "THESIS_TABLE4_RATIOS", "mesh_line"]

_FREE = [4.730040744862704, 7.853204624095838, 10.995607838001671, 14.137165491257464, 17.27875965739948]
_CANT = [1.875104068711961, 4.694091132974175, 7.854757438237613, 10.995540734875467, 14.13716839104647]


def _beta(bc, n):
    if bc == "free":
        return _FREE[n - 1] if n <= len(_FREE) else (2 * n + 1) * np.pi / 2
    if bc == "cantilever":
        return _CANT[n - 1] if n <= len(_CANT) else (2 * n - 1) * np.pi / 2
    if bc == "pinned":
        return n * np.pi
    raise ModalabValueError(f"boundary condition {bc!r}; expected 'free', 'cantilever' or 'pinned'")


#: β_n L for the first elastic modes of each boundary condition
BETA_L = {bc: [_beta(bc, n) for n in range(1, 6)] for bc in ("free", "cantilever", "pinned")}


def closed_form_hz(bc: str, n_modes: int, length: float, E: float, I: float, rho: float, A: float) -> np.ndarray:
    """Euler–Bernoulli bending frequencies (Hz) of the first ``n_modes`` elastic modes."""
    c = np.sqrt(E * I / (rho * A)) / length ** 2
    return np.array([_beta(bc, n) ** 2 * c / (2 * np.pi) for n in range(1, n_modes + 1)])


def timoshenko_pinned_hz(n_modes: int, length: float, E: float, G: float, I: float, rho: float, A: float,
                         kappa: float) -> np.ndarray:
    """Exact lower-branch Timoshenko frequencies (Hz) of a simply supported beam."""
    out = []
    for n in range(1, n_modes + 1):
        k = n * np.pi / length
        a = rho * I * rho / (kappa * G)
        b = -(rho * A + (rho * I + E * I * rho / (kappa * G)) * k ** 2)
        c = E * I * k ** 4
        w2 = (-b - np.sqrt(b * b - 4 * a * c)) / (2 * a)
        out.append(np.sqrt(w2) / (2 * np.pi))
    return np.array(out)


def mesh_line(model: FEModel, p0, p1, n_elements: int, pid: int, orientation, *, first_nid: int,
              first_eid: int, element=Beam3D, breakpoints=()) -> list:
    """Add nodes and frame elements on the segment p0 → p1; return the node ids in order.

    ``n_elements`` elements of near-equal length, with nodes forced at the
    fractions ``breakpoints`` (0..1) of the length (each sub-segment gets its share,
    at least one element).  Nodes already present at a point are reused.
    """
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    cuts = sorted({0.0, 1.0, *[float(b) for b in breakpoints]})
    ts = [0.0]
    for a, b in zip(cuts[:-1], cuts[1:]):
        k = max(1, int(round(n_elements * (b - a))))
        ts.extend(a + (b - a) * np.arange(1, k + 1) / k)
    nids = []
    nid = first_nid
    for t in ts:
        x = p0 + t * (p1 - p0)
        hit = next((n.nid for n in model.nodes.values() if np.allclose(n.xyz, x, atol=1e-9)), None)
        if hit is None:
            while nid in model.nodes:
                nid += 1
            model.add_node(nid, x)
            hit = nid
        nids.append(hit)
    eid = first_eid
    for a, b in zip(nids[:-1], nids[1:]):
        while eid in model.elements or eid in model.rbe2s:
            eid += 1
        if element is Beam2D:
            model.add_element(Beam2D(eid, a, b, pid, plane=orientation))
        else:
            model.add_element(element(eid, a, b, pid, orientation))
    return nids


def beam_model(n_elements: int, *, length: float = 1.0, E: float = 70e9, rho: float = 2700.0, nu: float = 0.3,
               section=None, bc: str = "free", kind: str = "beam2d", coupled_mass: bool = True) -> FEModel:
    """Uniform beam along X from 0 to ``length``.

    kind : 'beam2d' (w, θ in the x–z plane: DOFs +Z, +RY), 'beam3d' or 'timoshenko3d'.
    bc : 'free', 'cantilever' (node 1 clamped) or 'pinned' (both ends pinned; for 3-D
    frames also axial and torsion held at node 1 so only bending remains free).
    section : default a 20 × 10 mm rectangle (b along y, h along z).
    """
    if kind not in ("beam2d", "beam3d", "timoshenko3d"):
        raise ModalabValueError(f"kind {kind!r}; expected 'beam2d', 'beam3d' or 'timoshenko3d'")
    if n_elements < 1:
        raise ModalabValueError(f"n_elements = {n_elements}; expected >= 1")
    m = FEModel(f"{bc} {kind} beam", coupled_mass=coupled_mass)
    m.add_material(Material(1, E=E, nu=nu, rho=rho))
    m.add_property(BeamProperty(1, 1, section or RectangularSection(0.02, 0.01), name="beam"))
    if kind == "beam2d":
        nids = mesh_line(m, (0, 0, 0), (length, 0, 0), n_elements, 1, "xz", first_nid=1, first_eid=1,
                         element=Beam2D)
    else:
        el = Beam3D if kind == "beam3d" else Timoshenko3D
        nids = mesh_line(m, (0, 0, 0), (length, 0, 0), n_elements, 1, (0, 1, 0), first_nid=1, first_eid=1,
                         element=el)
    a, b = nids[0], nids[-1]
    if bc == "cantilever":
        m.add_spc(a, "35" if kind == "beam2d" else "123456")
    elif bc == "pinned":
        if kind == "beam2d":
            m.add_spc(a, "3")
            m.add_spc(b, "3")
        else:
            m.add_spc(a, "1234")
            m.add_spc(b, "23")
    elif bc != "free":
        raise ModalabValueError(f"boundary condition {bc!r}; expected 'free', 'cantilever' or 'pinned'")
    m.metadata["end_nodes"] = (a, b)
    return m


#: Table 3 of the thesis: (outer, inner) diameters in mm per element
THESIS_TABLE3_MM = {
    "experimental": [(10.50, 8.40), (10.20, 8.30), (10.00, 8.00), (9.10, 6.20), (9.90, 6.12), (9.10, 6.11),
                     (7.20, 5.56), (7.10, 5.43), (7.40, 5.12)],
    "analytical": [(10.00, 8.00), (9.00, 8.00), (9.00, 8.00), (9.00, 6.00), (9.00, 6.00), (9.00, 6.00),
                   (7.00, 5.50), (7.00, 5.50), (7.00, 5.50)],
}
#: Table 4: experimental/analytical ratios (E, ρ, ν) per element
THESIS_TABLE4_RATIOS = [(1.20, 1.05, 1.50)] * 3 + [(1.05, 0.98, 0.80)] * 3 + [(0.96, 1.00, 1.20)] * 3


def thesis_beam(variant: str = "analytical", *, cord_stiffness: float | None = 100.0, element_length: float = 0.3,
                E: float = 210e9, rho: float = 7850.0, nu: float = 0.3) -> FEModel:
    """The 20-DOF free-free tube beam of the thesis' section 5.2 (see the module docstring).

    variant : 'analytical' (Table 3 analytical diameters, nominal material) or
    'experimental' (Table 3 experimental diameters and Table 4 material ratios).
    cord_stiffness : N/m of the grounded springs on w at nodes 1 and 10 (None: no cords).
    Element i has material i and property i named ``"e{i}"``; the cords are spring
    elements 101 and 110 in group ``"cords"``.
    """
    if variant not in THESIS_TABLE3_MM:
        raise ModalabValueError(f"variant {variant!r}; expected 'analytical' or 'experimental'")
    m = FEModel(f"thesis 5.2 beam ({variant})")
    for i in range(10):
        m.add_node(i + 1, (i * element_length, 0.0, 0.0))
    for i, (do, di) in enumerate(THESIS_TABLE3_MM[variant]):
        rE, rr, rn = THESIS_TABLE4_RATIOS[i] if variant == "experimental" else (1.0, 1.0, 1.0)
        m.add_material(Material(i + 1, E=E * rE, nu=nu * rn, rho=rho * rr))
        m.add_property(BeamProperty(i + 1, i + 1, TubeSection(do * 1e-3, di * 1e-3), name=f"e{i + 1}"))
        m.add_element(Beam2D(i + 1, i + 1, i + 2, i + 1, plane="xz"))
    if cord_stiffness:
        m.add_element(Spring(101, (1, 3), None, cord_stiffness, group="cords"))
        m.add_element(Spring(110, (10, 3), None, cord_stiffness, group="cords"))
    return m


def thesis_beam_parameters(model: FEModel, fields=("E", "rho")) -> list:
    """Element multipliers as in the thesis (p = 1 nominal): ``E_e1`` ... ``rho_e9``."""
    pars = []
    for f in fields:
        for pid in sorted(model.properties):
            name = model.properties[pid].name
            pars.append(Parameter(f"{f}_{name}", f, properties=[pid]))
    return pars
