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

from modalab.core.modes import ModeSet
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
    from modalab.core.errors import ModalabValueError
    nominal, test, rec, cat = _truth_modes("bar_control", n_modes=1)
    with pytest.raises(ModalabValueError, match="at least 2"):
        diagnose_modes(nominal, test)


# ------------------------------------------------------------ a GVT deck with Nastran's default lumped mass, no SPC
# The truth is an Euler-Bernoulli beam written here (consistent mass, four times finer, E 2 % higher): it shares
# neither elements nor solvers with the code under test.
_L, _B, _H, _E, _RHO, _NEL = 1.2, 0.05, 0.008, 7e10, 2700.0, 20


def _gvt_deck(path, n_el=_NEL, extra=(), card="CBEAM"):
    """CBEAM/PBEAML BAR along x, no SPC, no COUPMASS (lumped mass: massless bending rotations; the CBEAM's
    lumped torsional inertia, as in Nastran; ``card="CBAR"``: PBARL, no torsional inertia, a massless rigid
    torsion); DIM1 (8 mm) along the element z axis, so that the vertical plane is the flexible one."""
    prop = {"CBEAM": "PBEAML", "CBAR": "PBARL"}[card]
    lines = ["SOL 103", "CEND", "BEGIN BULK", "MAT1,1,7.e10,,.33,2700.", f"{prop},1,1,,BAR", "+,.008,.05"]
    lines += [f"GRID,{i + 1},,{_L * i / n_el:.8f},0.,0." for i in range(n_el + 1)]
    lines += [f"{card},{i + 1},1,{i + 1},{i + 2},0.,1.,0." for i in range(n_el)]
    path.write_text("\n".join(lines + list(extra) + ["ENDDATA", ""]))
    from updating.fe.bulk import build_model, read_bdf
    return build_model(read_bdf(path))


def _independent_beam(masses=(), n_modes=7, e_factor=1.02, refine=4, n_deck=_NEL):
    """Vertical free-free modes (Hz) and w shapes at the deck's grids of a consistent-mass Euler-Bernoulli beam."""
    import scipy.linalg as sla
    n_el = n_deck * refine
    le = _L / n_el
    EI, rA = _E * e_factor * _B * _H ** 3 / 12, _RHO * _B * _H
    k = EI / le ** 3 * np.array([[12, 6 * le, -12, 6 * le], [6 * le, 4 * le ** 2, -6 * le, 2 * le ** 2],
                                 [-12, -6 * le, 12, -6 * le], [6 * le, 2 * le ** 2, -6 * le, 4 * le ** 2]])
    m = rA * le / 420 * np.array([[156, 22 * le, 54, -13 * le], [22 * le, 4 * le ** 2, 13 * le, -3 * le ** 2],
                                  [54, 13 * le, 156, -22 * le], [-13 * le, -3 * le ** 2, -22 * le, 4 * le ** 2]])
    n = 2 * (n_el + 1)
    K, M = np.zeros((n, n)), np.zeros((n, n))
    for e in range(n_el):
        K[2 * e:2 * e + 4, 2 * e:2 * e + 4] += k
        M[2 * e:2 * e + 4, 2 * e:2 * e + 4] += m
    for grid, mass in masses:                                  # grid numbers of the deck (1-based)
        M[2 * (grid - 1) * refine, 2 * (grid - 1) * refine] += mass
    w2, V = sla.eigh(K, M)
    el = np.flatnonzero(w2 > (2 * np.pi) ** 2)[:n_modes]
    return np.sqrt(w2[el]) / (2 * np.pi), V[0::2][::refine][:, el]


def _gvt_modes(masses=(), n_modes=7, noise=0.01):
    f, phi = _independent_beam(masses, n_modes)
    phi = phi * (1 + noise * np.random.default_rng(11).standard_normal(phi.shape))
    return ModeSet(freq_hz=f, shapes=phi, dofs=[f"{i + 1}+Z" for i in range(_NEL + 1)])


@pytest.mark.parametrize("path", ["exact", "subspace"])
def test_lumped_deck_without_spc_finds_a_concealed_mass(tmp_path, monkeypatch, path):
    import updating.diagnosis.modal_fit as MD
    if path == "subspace":          # the Ritz-subspace screening and fits of large models, on this small one
        monkeypatch.setattr(MD, "SUBSPACE_ABOVE", 50)
    model = _gvt_deck(tmp_path / "gvt.bdf")
    assert not model.coupled_mass and not model.spcs
    diag = diagnose_modes(model, _gvt_modes(masses=[(18, 0.06)]))
    assert len(diag.findings) == 1, diag.statement
    f = diag.findings[0]
    assert f.candidate.physics == "added_mass" and min(abs(n - 18) for n in f.candidate.nodes) <= 1
    assert f.value == pytest.approx(0.06, rel=0.3)
    assert not f.ambiguous
    # z sensors: no candidate acting only in the lateral plane (y, rotations about x or z) may claim evidence
    for c, _, _ in diag.ranking:
        if len(c.dofs) == 1:
            assert c.dofs[0].split("+")[-1] in ("Z", "RY"), c.label
    assert "Nothing is missing" not in diag.statement


@pytest.mark.parametrize("path", ["exact", "subspace"])
def test_lumped_deck_nominal_modes_leave_everything_at_nominal(tmp_path, monkeypatch, path):
    import updating.diagnosis.modal_fit as MD
    if path == "subspace":
        monkeypatch.setattr(MD, "SUBSPACE_ABOVE", 50)
    model = _gvt_deck(tmp_path / "gvt.bdf")
    ms = model.modes(16)
    z = ms.select_dofs([f"{i + 1}+Z" for i in range(_NEL + 1)])
    sh = np.real(z.shapes)
    seen = (ms.freq_hz > 1.0) & (np.linalg.norm(sh, axis=0) > 1e-6 * np.linalg.norm(sh, axis=0).max())
    test = ModeSet(freq_hz=ms.freq_hz[seen][:6], shapes=sh[:, seen][:, :6], dofs=z.dofs)
    diag = diagnose_modes(model, test)
    assert diag.findings == []
    assert "Nothing is missing" in diag.statement
    for name, p in diag.parameters.items():
        assert p["updated"] == pytest.approx(1.0, abs=1e-4), name


def test_a_failing_eigen_solution_is_an_error_not_a_residual():
    from modalab.core.errors import ModalabValueError
    from modalab.core.structure import Structure
    from updating.diagnosis.modes import ModalResidual
    r = ModalResidual(ModeSet(freq_hz=[0.3, 0.5], shapes=np.ones((3, 2)), dofs=["1+Z", "2+Z", "3+Z"]))
    for k2, msg in ((-100.0, "not positive definite"), (-1.0, "not positive semi-definite")):
        st = Structure(M=np.eye(3), K=np.diag([4.0, k2, 9.0]), dofs=["1+Z", "2+Z", "3+Z"])   # indefinite
        with pytest.raises(ModalabValueError, match=msg):
            r(st)


def test_frequency_only_four_numbers_two_parameters(tmp_path):
    # issue 16 #15: no IndexError, no physics claimed, and a training error is never called held-out
    model = _gvt_deck(tmp_path / "gvt.bdf")
    f, _ = _independent_beam(masses=[(18, 0.06)], n_modes=4)
    diag = diagnose_modes(model, ModeSet(freq_hz=f, shapes=np.zeros((0, 4)), dofs=[]))
    assert diag.findings == []
    assert "cannot separate missing physics from parameter error" in diag.statement
    assert "held-out" not in diag.statement and "the same modes the fit used" in diag.statement
    assert "mac_min" not in diag.fit["nominal"]


def test_frequency_only_mirror_masses_are_one_ambiguous_finding(tmp_path):
    # a free-free uniform beam: a mass at grid 9 or at its mirror grid 33 gives the same frequencies (a
    # 40-element deck: the 20-element one's lumped-mass discretisation error is itself a pattern of ~2 %).  A
    # CBAR deck: its lumped mass has no torsional inertia, so the model has no torsion modes among the bending
    # ones (the truth has none; frequencies alone cannot tell a torsion mode from a bending one)
    model = _gvt_deck(tmp_path / "gvt.bdf", n_el=40, card="CBAR")
    f, _ = _independent_beam(masses=[(9, 0.08)], n_modes=7, n_deck=40)
    diag = diagnose_modes(model, ModeSet(freq_hz=f, shapes=np.zeros((0, 7)), dofs=[]), kinds=("added_mass",))
    assert len(diag.findings) == 1, diag.statement
    fd = diag.findings[0]
    assert fd.candidate.physics == "added_mass" and fd.ambiguous
    places = {n for n in fd.candidate.nodes} | {n for a, _, _ in fd.alternatives for n in a.nodes}
    assert min(abs(n - 9) for n in places) <= 1 and min(abs(n - 33) for n in places) <= 1
    assert diag.statement.startswith("AMBIGUOUS")
    assert fd.to_dict()["ambiguous"] is True
    assert fd.value == pytest.approx(0.08, rel=0.35)


def test_candidates_never_sit_on_dependent_dofs(tmp_path):
    from updating.diagnosis import build_library
    from updating.diagnosis.modes import _on_independent_dofs
    model = _gvt_deck(tmp_path / "gvt.bdf", extra=["GRID,100,,1.3,0.,0.", "RBE2,500,21,123456,100"])
    st = model.structure()
    lib = build_library(model, kinds=("ground_spring", "added_mass"))
    assert any(100 in c.nodes for c in lib)                      # the library offers them ...
    kept = _on_independent_dofs(lib, st)
    assert kept and not any(100 in c.nodes for c in kept)        # ... the modes-only diagnosis does not


def test_map_puts_test_nodes_on_model_grids(tmp_path):
    from updating.diagnosis.modes import map_test_modes
    model = _gvt_deck(tmp_path / "gvt.bdf")
    test = _gvt_modes()
    renamed = ModeSet(freq_hz=test.freq_hz, shapes=-test.shapes,
                      dofs=[f"{1000 + d.node}+Z" for d in test.dofs])
    (tmp_path / "map.csv").write_text("test_dof,model_dof\n" + "".join(
        f"{1000 + d.node}+Z,{d.node}-Z\n" for d in test.dofs))
    mapped = map_test_modes(renamed, model, tmp_path / "map.csv")
    assert [str(d) for d in mapped.dofs] == [f"{d.node}-Z" for d in test.dofs]
    # selecting 12-Z negates: the mapped set reads the original shapes on the model's +Z
    back = mapped.select_dofs([f"{d.node}+Z" for d in test.dofs])
    np.testing.assert_allclose(back.shapes, test.shapes)


def test_cli_map_needs_modes_alone(tmp_path):
    from modalab.app.cli import main
    _gvt_deck(tmp_path / "gvt.bdf")
    (tmp_path / "m.uff").write_text("")
    (tmp_path / "map.csv").write_text("1+Z,1+Z\n")
    assert main(["diagnose", str(tmp_path / "gvt.bdf"), str(tmp_path / "m.uff"), "--map",
                 str(tmp_path / "map.csv")]) == 2


def test_cli_diagnose_modes_with_map(tmp_path, capsys):
    # test nodes 1001.. (sensor numbering) on model grids 1..: without the map the run refuses, with it the
    # nominal model's own modes leave nothing to find
    import json
    from modalab.app.cli import main
    model = _gvt_deck(tmp_path / "gvt.bdf")
    ms = model.modes(16)
    z = ms.select_dofs([f"{i + 1}+Z" for i in range(_NEL + 1)])
    sh = np.real(z.shapes)
    seen = (ms.freq_hz > 1.0) & (np.linalg.norm(sh, axis=0) > 1e-6 * np.linalg.norm(sh, axis=0).max())
    ModeSet(freq_hz=ms.freq_hz[seen][:5], shapes=sh[:, seen][:, :5],
            dofs=[f"{1000 + d.node}+Z" for d in z.dofs]).to_json(tmp_path / "gvt_modes.json")
    (tmp_path / "map.toml").write_text("[nodes]\n" + "".join(f'"{1000 + i}" = {i}\n' for i in range(1, _NEL + 2)))
    args = ["diagnose", str(tmp_path / "gvt.bdf"), "--modes", str(tmp_path / "gvt_modes.json")]
    assert main(args) == 2
    assert "node numbering" in capsys.readouterr().err
    assert main(args + ["--map", str(tmp_path / "map.toml"), "--json", str(tmp_path / "d.json")]) == 0
    d = json.loads((tmp_path / "d.json").read_text())
    assert d["findings"] == [] and "Nothing is missing" in d["statement"]


@pytest.mark.parametrize("kind,node,theta", [("K", 15, 3e5), ("M", 18, 0.2)])
def test_subspace_low_rank_update_matches_the_exact_modes(tmp_path, kind, node, theta):
    # the screening's low-rank update in the lowest-mode subspace extended by the candidate's own static
    # corrections against a full eigen-solution of the changed model (a stiff spring, a heavy mass)
    import scipy.sparse as sp
    from updating.diagnosis.frfscreen import _low_rank
    from updating.diagnosis.modes import ModalSubspace
    from updating.fe import eigen_dense
    st = _gvt_deck(tmp_path / "gvt.bdf", n_el=80).structure()      # 486 DOFs: 24 modes are far from complete
    idx = [i for i, d in enumerate(st.dofs) if d.node == 4 * node and (d.axis == 3 if kind == "K" else d.axis <= 3)]
    G = sp.csr_matrix((np.ones(len(idx)), (idx, idx)), shape=(st.n_dof, st.n_dof))
    rows, L = _low_rank(G)
    basis = ModalSubspace(st, [], 150.0, 8)              # the lowest 24 modes (to ~700 Hz)
    W, Kr, b = basis.extended(rows, L)
    if kind == "K":
        w2 = np.linalg.eigvalsh(Kr + theta * b @ b.T)
        we, _ = eigen_dense(st.K + theta * G, st.M, 20)
    else:
        import scipy.linalg as sla
        w2 = sla.eigh(Kr, np.eye(Kr.shape[0]) + theta * b @ b.T, eigvals_only=True)
        we, _ = eigen_dense(st.K, st.M + theta * G, 20)
    f_sub = np.sqrt(np.clip(w2[:20], 0, None)) / (2 * np.pi)
    f_ex = we / (2 * np.pi)
    el = (f_ex > 1.0) & (f_ex < 225.0)                   # the modes pairing uses: to 1.5 × the top test mode
    assert np.abs(f_sub[el] / f_ex[el] - 1).max() < 1e-4
    # without the candidate's static correction the stiff spring or heavy mass would be far off
    m = basis.size
    w2v = np.linalg.eigvalsh(Kr[:m, :m] + theta * b[:m] @ b[:m].T) if kind == "K" else \
        sla.eigh(Kr[:m, :m], np.eye(m) + theta * b[:m] @ b[:m].T, eigvals_only=True)
    f_modes_only = np.sqrt(np.clip(w2v[:20], 0, None)) / (2 * np.pi)
    assert np.abs(f_modes_only[el] / f_ex[el] - 1).max() > 10 * np.abs(f_sub[el] / f_ex[el] - 1).max()
