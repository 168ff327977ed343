"""Unit tests of the diagnosis engine: candidate library, condensed residual, diagnosis.json schema."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from updating.diagnosis import build_library
from updating.correlation.condensation import condensed_residual
from updating.diagnosis.terms import _augment
from updating.fe import Beam2D, BeamProperty, FEModel, Material, ParametricFEModel, TubeSection


def _small(spc=False):
    m = FEModel("small beam")
    for i in range(4):
        m.add_node(i + 1, (0.3 * i, 0.0, 0.0))
    m.add_material(Material(1, E=210e9, rho=7850.0))
    m.add_property(BeamProperty(1, 1, TubeSection(0.02, 0.016), name="a"))
    m.add_property(BeamProperty(2, 1, TubeSection(0.03, 0.026), name="b"))
    for i, pid in zip(range(3), (1, 1, 2)):
        m.add_element(Beam2D(i + 1, i + 1, i + 2, pid, plane="xz"))
    if spc:
        m.add_spc(1, "35")
    return m


def _apply(model, cand, value):
    m_aug, pars, scales = _augment(model, [cand])
    pm = ParametricFEModel(m_aug, pars)
    return pm, pm.structure([value / scales[0]])


def _idx(structure, label):
    return [str(d) for d in structure.dofs].index(label)


def test_ground_spring_adds_k_on_its_dof():
    m = _small()
    base = m.structure()
    c = next(c for c in build_library(m, kinds=["ground_spring"]) if c.dofs == ("3+Z",))
    _, s = _apply(m, c, 250.0)
    dK = (s.K - base.K).toarray()
    i = _idx(base, "3+Z")
    expect = np.zeros_like(dK)
    expect[i, i] = 250.0
    np.testing.assert_allclose(dK, expect, atol=1e-6)
    np.testing.assert_allclose(c.G.toarray(), expect / 250.0)


def test_added_mass_adds_m_on_translations():
    m = _small()
    base = m.structure()
    c = next(c for c in build_library(m, kinds=["added_mass"]) if c.value_name == "m" and c.nodes == (2,))
    _, s = _apply(m, c, 0.3)
    dM = (s.M - base.M).toarray()
    i = _idx(base, "2+Z")
    assert dM[i, i] == pytest.approx(0.3)
    dM[i, i] = 0.0
    assert np.abs(dM).max() < 1e-12
    assert (s.K - base.K).count_nonzero() == 0


def test_group_damping_is_eta_times_element_stiffness():
    m = _small()
    base = m.structure()
    c = next(c for c in build_library(m, kinds=["local_damping"]) if c.elements == (3,))
    _, s = _apply(m, c, 0.2)
    D = s.D.toarray() if s.D is not None else np.zeros((base.n_dof,) * 2)
    np.testing.assert_allclose(D, 0.2 * c.G.toarray(), atol=1e-9 * np.abs(D).max())
    assert np.abs(D).max() > 0


def test_dashpot_is_viscous():
    m = _small()
    c = next(c for c in build_library(m, kinds=["local_damping"]) if c.matrix == "C" and c.dofs == ("4+Z",))
    _, s = _apply(m, c, 3.0)
    i = _idx(s, "4+Z")
    assert s.C.toarray()[i, i] == pytest.approx(3.0)


def test_boundary_release_frees_the_dof_into_a_spring():
    m = _small(spc=True)
    base = m.structure()
    cands = build_library(m, kinds=["boundary_flexibility"])
    assert {c.dofs for c in cands} == {("1+Z",), ("1+RY",)}
    c = next(c for c in cands if c.dofs == ("1+RY",))
    _, s = _apply(m, c, 1e3)
    assert s.n_dof == base.n_dof + 1
    i = _idx(s, "1+RY")
    K0 = m.copy()
    K0.spcs = [x for x in K0.spcs if x.node != 1]
    K0.add_spc(1, "3")
    free = K0.structure()
    np.testing.assert_allclose((s.K - free.K).toarray()[i, i], 1e3)
    # a very stiff support gives back the clamped model's frequencies
    _, stiff = _apply(m, c, 1e12)
    w0 = np.sort(np.linalg.eigvals(np.linalg.solve(base.M.toarray(), base.K.toarray())).real)[:3]
    w1 = np.sort(np.linalg.eigvals(np.linalg.solve(stiff.M.toarray(), stiff.K.toarray())).real)[:3]
    np.testing.assert_allclose(w1, w0, rtol=1e-4)


def test_joint_split_adds_a_node_coupled_by_a_spring():
    m = _small()
    base = m.structure()
    cands = [c for c in build_library(m, kinds=["joint_flexibility"]) if c.dofs == ("3+RY",)]
    assert cands, "the junction of properties a and b at node 3 is a joint candidate"
    pm, s = _apply(m, cands[0], 500.0)
    assert s.n_dof == base.n_dof + 1                     # one new independent component (RY of the new grid)
    # a rigid joint gives back the nominal model
    _, rigid = _apply(m, cands[0], 1e9)
    ev = lambda x: np.sort(np.linalg.eigvals(np.linalg.solve(x.M.toarray(), x.K.toarray())).real)[2:6]  # noqa: E731
    np.testing.assert_allclose(ev(rigid), ev(base), rtol=1e-3)
    assert ev(s)[0] < ev(base)[0]                        # a flexible joint softens the structure


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), n_meas=st.integers(2, 6))
def test_condensed_residual_identity(seed, n_meas):
    """All DOFs measured: r = −ΔZ x exactly; the true model with any measured subset: r = 0."""
    rng = np.random.default_rng(seed)
    n = 6
    A = rng.standard_normal((n, n))
    K = A @ A.T + n * np.eye(n)
    M = np.diag(rng.uniform(0.5, 2.0, n))
    dK = np.zeros((n, n))
    j = rng.integers(n)
    dK[j, j] = rng.uniform(0.5, 3.0)
    dM = np.zeros((n, n))
    dM[(j + 1) % n, (j + 1) % n] = rng.uniform(0.1, 0.5)
    s = 1j * np.array([0.3, 0.9, 1.7])
    F = np.zeros((n, 1))
    F[0, 0] = 1.0
    x = np.stack([np.linalg.solve(K + dK + sk ** 2 * (M + dM), F) for sk in s], axis=2)   # (n, 1, n_s)
    _, r, T, _ = condensed_residual(K, M, None, None, s, np.arange(n), x, F)
    expect = -np.stack([(dK + sk ** 2 * dM) @ x[:, :, k] for k, sk in enumerate(s)], axis=2)
    np.testing.assert_allclose(r, expect, atol=1e-10 * np.abs(expect).max())
    meas = np.sort(rng.choice(np.arange(1, n), n_meas - 1, replace=False))
    meas = np.concatenate([[0], meas])
    _, r2, _, _ = condensed_residual(K + dK, M + dM, None, None, s, meas, x[meas], F)
    assert np.abs(r2).max() < 1e-10


CONTROL = Path(__file__).resolve().parents[2] / "examples" / "concealed" / "bar_control"


def test_diagnosis_json_schema(tmp_path):
    from modalab.core import uff
    from updating.fe.bulk import build_model, read_bdf
    from updating.diagnosis import diagnose
    model = build_model(read_bdf(CONTROL / "nominal.bdf"))
    diag = diagnose(model, uff.read_frf(CONTROL / "measured.uff"))
    d = json.loads(json.dumps(diag.to_dict()))
    assert set(d) >= {"findings", "parameters", "fit", "statement"}
    assert isinstance(d["findings"], list) and isinstance(d["statement"], str)
    for name, p in d["parameters"].items():
        assert set(p) >= {"initial", "updated", "std"}
    for block in ("nominal", "parameters_only", "with_physics"):
        assert set(d["fit"][block]) >= {"frf_error_held_out", "freq_error_max_pct", "mac_min"}
        assert d["fit"][block]["frf_error_held_out"] >= 0
    assert d["findings"] == []
    # diagnosis.json has one writer (the diagnose stage's, through modalab.app.outputs) and one schema
    from modalab.app.outputs import validate, write_json
    from updating.diagnosis.report import write_figures
    path = write_json(tmp_path / "report" / "diagnosis.json", diag.to_dict())
    saved = json.loads(path.read_text())
    assert saved["findings"] == [] and saved["statement"] == d["statement"]
    validate(path, "diagnosis")
    write_figures(diag, tmp_path / "report")
    assert any(p.suffix == ".png" for p in (tmp_path / "report").iterdir())


def test_finding_schema():
    from updating.diagnosis.findings import Finding
    m = _small()
    c = next(c for c in build_library(m, kinds=["ground_spring"]) if c.dofs == ("2+Z",))
    f = Finding(c, 210.0, 16.0, "because").to_dict()
    assert f["physics"] == "ground_spring" and f["nodes"] == [2] and f["dofs"] == ["2+Z"] and f["elements"] == []
    assert f["values"] == [{"name": "k", "value": 210.0, "unit": "N/m", "std": 16.0}]
    assert f["evidence"] == "because"


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_sparse_and_dense_paths_agree(seed):
    """The per-line sparse LU path (large models) equals the batched dense path."""
    import modalab.core.dense as dense
    import updating.correlation.condensation as dyn
    rng = np.random.default_rng(seed)
    n = 8
    A = rng.standard_normal((n, n))
    K = A @ A.T + n * np.eye(n)
    M = np.diag(rng.uniform(0.5, 2.0, n))
    Dm = 0.02 * K
    s = 1j * np.array([0.4, 1.1, 2.3]) + 0.05
    meas = np.sort(rng.choice(n, 4, replace=False))
    F = np.zeros((n, 2))
    F[meas[0], 0] = F[meas[1], 1] = 1.0
    x = rng.standard_normal((4, 2, 3)) + 1j * rng.standard_normal((4, 2, 3))
    old = dense.SOLVE_LIMIT
    try:
        dense.SOLVE_LIMIT = 1000
        a = dyn.condensed_residual(K, M, None, Dm, s, meas, x, F)
        ca = dyn.solve_columns(K, M, None, Dm, s, [0, 3])
        dense.SOLVE_LIMIT = 1
        b = dyn.condensed_residual(K, M, None, Dm, s, meas, x, F)
        cb = dyn.solve_columns(K, M, None, Dm, s, [0, 3])
    finally:
        dense.SOLVE_LIMIT = old
    for u, v in zip(a, b):
        np.testing.assert_allclose(u, v, rtol=1e-9, atol=1e-12 * np.abs(u).max())
    np.testing.assert_allclose(ca, cb, rtol=1e-9, atol=1e-14)


def test_kinds_are_a_validated_set():
    from modalab.core.errors import ModalabValueError
    from updating.diagnosis.library import KINDS, validate_kinds
    assert validate_kinds(None) == frozenset(KINDS)
    assert validate_kinds(["added_mass", "ground_spring"]) == {"added_mass", "ground_spring"}
    with pytest.raises(ModalabValueError, match="'ground_sprng'.*did you mean 'ground_spring'"):
        build_library(_small(), kinds=["ground_sprng"])
    with pytest.raises(ModalabValueError, match="no kind"):
        validate_kinds([])


def test_cli_kinds_typo_is_an_error_suggesting_the_closest(capsys):
    from modalab.app.cli import main
    rc = main(["diagnose", str(CONTROL / "nominal.bdf"), str(CONTROL / "measured.uff"), "--kinds", "joint_flex"])
    err = capsys.readouterr().err
    assert rc == 2 and "did you mean joint_flexibility?" in err and "Traceback" not in err


def test_a_clamp_releases_its_rotations_together_into_one_stiffness():
    from updating.fe import Beam3D
    m = FEModel("post")
    for i in range(4):
        m.add_node(i + 1, (0.0, 0.0, 0.3 * i))
    m.add_material(Material(1, E=210e9, rho=7850.0))
    m.add_property(BeamProperty(1, 1, TubeSection(0.04, 0.034), name="post"))
    for i in range(3):
        m.add_element(Beam3D(i + 1, i + 1, i + 2, 1, orientation=(1.0, 0.0, 0.0)))
    m.add_spc(1, "123456")
    base = m.structure()
    cands = [c for c in build_library(m, kinds=["boundary_flexibility"]) if "rotations" in c.label]
    assert len(cands) == 1 and set(cands[0].dofs) == {"1+RX", "1+RY", "1+RZ"}
    pm, s = _apply(m, cands[0], 2e4)
    assert s.n_dof == base.n_dof + 3
    for lbl in ("1+RX", "1+RY", "1+RZ"):
        i = _idx(s, lbl)
        assert s.K.toarray()[i, i] == pytest.approx(2e4 + _own_stiffness(m, cands[0], lbl), rel=1e-9)
    # very stiff rotations give back the clamped frequencies
    _, stiff = _apply(m, cands[0], 1e12)
    f0 = np.sort(_gen(base))[:4]
    f1 = np.sort(_gen(stiff))[:4]
    np.testing.assert_allclose(f1, f0, rtol=1e-4)


def _gen(st):
    import scipy.linalg as sla
    return sla.eigh(st.K.toarray(), st.M.toarray(), eigvals_only=True)


def _own_stiffness(m, cand, lbl):
    """The diagonal stiffness of the released component without the spring (value 0)."""
    _, s0 = _apply(m, cand, 0.0)
    i = _idx(s0, lbl)
    return s0.K.toarray()[i, i]
