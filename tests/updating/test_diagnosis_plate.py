"""Diagnosis on a shell model (CQUAD4/PSHELL): a suspended aluminium plate with a concealed point mass.

Truth: the same 8 × 6 Quad4 plate (0.4 × 0.3 × 0.003 m) with E + 3 %, ρ − 1 %, loss factor 0.01 and 30 g at
an interior node; receptances at 20 Z DOFs for two references, 1 % noise.  The model has 378 DOFs, so the
diagnosis judges candidates by the FRF fit in a Ritz basis.
"""
from __future__ import annotations

import numpy as np
import pytest

from modalab.core.frf import FRF
from updating.diagnosis import diagnose
from updating.fe import FEModel, LumpedMass, Material, Quad4, ShellProperty, Spring


def _plate(E=70e9, rho=2700.0, nx=8, ny=6):
    m = FEModel("plate", global_ge=0.01)
    m.add_material(Material(1, E=E, nu=0.33, rho=rho, name="alu"))
    m.add_property(ShellProperty(1, 1, 0.003, name="plate"))

    def nid(i, j):
        return 1 + i + j * (nx + 1)
    for j in range(ny + 1):
        for i in range(nx + 1):
            m.add_node(nid(i, j), (0.4 * i / nx, 0.3 * j / ny, 0.0))
    for j in range(ny):
        for i in range(nx):
            m.add_element(Quad4(1 + i + j * nx, nid(i, j), nid(i + 1, j), nid(i + 1, j + 1), nid(i, j + 1), 1))
    for k, n in enumerate((nid(1, 1), nid(nx - 1, 1), nid(nx // 2, ny - 1))):       # soft suspension
        m.add_element(Spring(900 + k, (n, 3), None, 200.0))
    return m, nid


@pytest.mark.slow
def test_a_mass_on_a_shell_plate_is_named_located_and_sized():
    nominal, nid = _plate()
    truth, _ = _plate(E=70e9 * 1.03, rho=2700.0 * 0.99)
    node = nid(5, 4)
    truth.add_element(LumpedMass(999, node, mass=0.03))
    truth._changed()
    resp = [f"{nid(i, j)}+Z" for j in range(0, 7, 2) for i in range(0, 9, 2)]
    refs = [f"{nid(2, 2)}+Z", f"{nid(8, 6)}+Z"]
    resp += [r for r in refs if r not in resp]
    f = np.linspace(1.0, 300.0, 500)
    H = truth.frf(f, resp, refs, quantity="receptance")
    rng = np.random.default_rng(1)
    noise = (rng.standard_normal(H.H.shape) + 1j * rng.standard_normal(H.H.shape)) / np.sqrt(2)
    meas = FRF(freq_hz=f, H=H.H * (1 + 0.01 * noise), responses=H.responses, references=H.references,
               coherence=np.ones(H.H.shape), quantity="receptance")
    d = diagnose(nominal, meas)
    assert [f.candidate.physics for f in d.findings] == ["added_mass"], d.statement
    found = nominal.nodes[d.findings[0].candidate.nodes[0]].xyz
    assert np.linalg.norm(np.subtract(found, nominal.nodes[node].xyz)) <= 0.051      # within one element
    assert d.findings[0].value == pytest.approx(0.03, rel=0.3)
    assert d.parameters["E_plate"]["updated"] == pytest.approx(1.03, abs=0.01)
    assert d.fit["with_physics"]["frf_error_held_out"] < d.fit["parameters_only"]["frf_error_held_out"] / 3
