"""Modes-only diagnosis (no FRFs): stiffness and mass categories from identified modes.

The test modes are the truth structures of examples/concealed (finer mesh, background parameter errors)
observed at the nominal grids' w DOFs: the six lowest modes, shapes with 0.2 % and 2 % scatter per entry (a
GVT's shape quality).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from modalab.modes import ModeSet
from updating.diagnosis import diagnose_modes

HERE = Path(__file__).resolve().parents[2] / "examples" / "concealed"


def _truth_modes(name, n_modes=6, noise=0.002):
    sys.path.insert(0, str(HERE))
    try:
        import build as B
    finally:
        sys.path.remove(str(HERE))
    kind, cat, effect, rec = B.CASES[name]
    rng = np.random.default_rng(100 + list(B.CASES).index(name))
    nominal = B._structures(1)[kind]()
    errors = {pid: (1 + rng.uniform(-0.05, 0.05), 1 + rng.uniform(-0.03, 0.03)) for pid in nominal.properties}
    truth = B._structures(B.REFINE, rng=rng, errors=errors)[kind]()
    effect(truth, B.REFINE)
    dofs = [f"{n}+Z" for n in sorted(nominal.nodes) if not (kind == "strip" and n == 1)]
    ms = truth.modes(n_modes).select_dofs(dofs)
    phi = np.real(ms.shapes)
    phi = phi * (1 + noise * np.random.default_rng(5).standard_normal(phi.shape))      # relative scatter per entry
    return nominal, ModeSet(freq_hz=ms.freq_hz, shapes=phi, dofs=ms.dofs), rec, cat


@pytest.mark.parametrize("noise", [0.002, 0.02])
@pytest.mark.parametrize("name", ["bar_ground_spring", "bar_added_mass", "stepped_ground_spring", "strip_added_mass"])
def test_modes_only_names_stiffness_and_mass(name, noise):
    nominal, test, rec, cat = _truth_modes(name, noise=noise)
    diag = diagnose_modes(nominal, test)
    assert len(diag.findings) == 1, [f.candidate.label for f in diag.findings]
    f = diag.findings[0]
    assert f.candidate.physics == cat
    assert min(abs(n - m) for n in f.candidate.nodes for m in rec["nodes"]) <= 1
    assert f.value == pytest.approx(rec["value"], rel=0.30)
    fit = diag.fit
    assert fit["with_physics"]["freq_error_max_pct"] < fit["parameters_only"]["freq_error_max_pct"] / 3
    assert fit["with_physics"]["mac_min"] >= fit["parameters_only"]["mac_min"] - 1e-6


@pytest.mark.parametrize("noise", [0.002, 0.02])
def test_modes_only_control_finds_nothing(noise):
    nominal, test, rec, cat = _truth_modes("bar_control", noise=noise)
    diag = diagnose_modes(nominal, test)
    assert diag.findings == []
    assert "Nothing is missing" in diag.statement


def test_modes_only_needs_two_modes():
    from modalab.errors import ModalabValueError
    nominal, test, rec, cat = _truth_modes("bar_control", n_modes=1)
    with pytest.raises(ModalabValueError, match="at least 2"):
        diagnose_modes(nominal, test)
