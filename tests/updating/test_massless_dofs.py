"""Massless DOFs and massless mechanisms on a real-looking deck (issue 16 item 7), and deterministic modes.

The deck is a GVT engineer's: CBAR/PBARL along x, no SPC (free-free), Nastran's default lumped mass (no
PARAM,COUPMASS), so the rotations carry no mass and the rigid torsion is a massless mechanism (a CBEAM's lumped
mass has torsional inertia, as in Nastran: see ``test_lumped_cbeam_deck_has_six_rigid_modes``).  The reference is
an independent discretisation: a coupled-mass deck four times finer.  Every eigen path is checked on it: the
core :class:`Structure` (dense, and Lanczos above 2000 DOFs), the FE solvers, the diagnosis Ritz basis, the
sensitivity solver and the FRFs (modal and direct).
"""
import numpy as np
import pytest

from modalab.core.eigen import dense_modes, lanczos_modes, massless_dofs, massless_mechanisms
from updating.fe.bulk import build_model, read_bdf

_L = 1.2


def _deck(path, n_el, *, coupmass=False, split=0, card="CBAR"):
    """The deck; elements 1..``split`` carry a second (identical) property, PID 2.  ``card`` CBAR (PBARL) or
    CBEAM (PBEAML)."""
    prop = {"CBAR": "PBARL", "CBEAM": "PBEAML"}[card]
    lines = ["SOL 103", "CEND", "BEGIN BULK"] + (["PARAM,COUPMASS,1"] if coupmass else [])
    lines += ["MAT1,1,7.e10,,.33,2700.", f"{prop},1,1,,BAR", "+,.008,.05", f"{prop},2,1,,BAR", "+,.008,.05"]
    lines += [f"GRID,{i + 1},,{_L * i / n_el:.8f},0.,0." for i in range(n_el + 1)]
    lines += [f"{card},{i + 1},{2 if i < split else 1},{i + 1},{i + 2},0.,1.,0." for i in range(n_el)]
    path.write_text("\r\n".join(lines + ["ENDDATA", ""]))
    return build_model(read_bdf(path))


@pytest.fixture(scope="module")
def lumped(tmp_path_factory):
    return _deck(tmp_path_factory.mktemp("deck") / "gvt.bdf", 30)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """Elastic frequencies (Hz) of a coupled-mass deck four times finer (an independent discretisation)."""
    st = _deck(tmp_path_factory.mktemp("fine") / "fine.bdf", 120, coupmass=True).structure()
    return _bending_hz(st, *st.normal_modes(30))


def _bending_hz(st, w, phi):
    """Elastic bending frequencies (Hz): most kinetic energy in the y, z translations (no torsion, no axial)."""
    yz = np.array([d.axis in (2, 3) for d in st.dofs])
    lateral = np.einsum("ij,ij->j", phi[yz], (st.M @ phi)[yz])
    f = w / (2 * np.pi)
    return f[(lateral > 0.5) & (f > 1.0)]


def test_core_structure_lumped_free_free_deck(lumped, reference):
    st = lumped.structure()
    assert massless_dofs(st.M).size == 3 * 31 and not lumped.spcs and not lumped.coupled_mass
    fix, N = massless_mechanisms(st.K, st.M)
    assert fix.size == 1                                       # the rigid torsion: neither mass nor stiffness
    w, phi = st.normal_modes(None)
    # infinite-frequency (massless) directions never come back: one finite mode per DOF with mass
    assert w.size == st.n_dof - massless_dofs(st.M).size and np.all(np.isfinite(w))
    f = w / (2 * np.pi)
    # six rigid-body motions: five modes with mass near 0 Hz and the massless torsion, constrained (MECHFIX)
    assert np.all(f[:5] < 1e-2) and f[5] > 10.0
    # elastic frequencies agree with the finer coupled-mass deck (lumped mass, 30 vs 120 elements)
    np.testing.assert_allclose(_bending_hz(st, w, phi)[:8], reference[:8], rtol=1.5e-2)
    # mass-normalised shapes that satisfy the full (uncondensed) eigenproblem, massless DOFs included
    np.testing.assert_allclose(phi.T @ (st.M @ phi), np.eye(w.size), atol=1e-8)
    r = st.K @ phi[:, :20] - (st.M @ phi[:, :20]) * w[:20] ** 2
    assert np.abs(r).max() < 1e-7 * np.abs(st.K @ phi[:, :20]).max()
    # the exact FRF: modal synthesis (all modes) and direct solve agree (the direct solve was singular)
    fr = [5.0, 60.0, 300.0]
    hm = st.frf(fr, ["10+Z", "20+Y"], ["10+Z"], method="modal").H
    hd = st.frf(fr, ["10+Z", "20+Y"], ["10+Z"], method="direct").H
    np.testing.assert_allclose(hm, hd, rtol=1e-6, atol=1e-12 * np.abs(hd).max())


def test_core_lanczos_and_dense_agree_above_the_dense_limit(tmp_path):
    st = _deck(tmp_path / "gvt367.bdf", 366).structure()        # 367 grids, 2202 DOFs: Lanczos path
    w, phi = st.normal_modes(14)
    wd, _ = dense_modes(st.K, st.M, 14)
    assert np.all(w[:5] / (2 * np.pi) < 1e-2)
    # (the CBAR deck's elastic modes agree to 4e-8 between the two solvers, the CBEAM deck's to 1e-8)
    np.testing.assert_allclose(w[5:], wd[5:], rtol=1e-7)
    np.testing.assert_allclose(phi.T @ (st.M @ phi), np.eye(14), atol=1e-8)
    # the same model solved twice: bit-identical (a fixed ARPACK start vector)
    w2, phi2 = st.normal_modes(14)
    assert np.array_equal(w, w2) and np.array_equal(phi, phi2)


def test_lanczos_refuses_more_modes_than_finite_ones(lumped):
    st = lumped.structure()
    n_finite = st.n_dof - massless_dofs(st.M).size
    with pytest.raises(Exception, match="finite modes"):
        lanczos_modes(st.K, st.M, n_finite + 3)


@pytest.mark.parametrize("n_above", [10_000, 50])
def test_ritz_basis_on_the_lumped_deck(lumped, monkeypatch, n_above):
    import modalab.core.dense as dense
    import updating.diagnosis.ritz as R
    monkeypatch.setattr(dense, "MODES_LIMIT", n_above)          # dense and Lanczos modes (the one rule)
    st = lumped.structure()
    w, _ = st.normal_modes(20)
    cols = [st.dofs.index(d) for d in st.dofs if d.node in (1, 16, 31) and d.axis in (2, 3)]
    rb = R.RitzBasis(st, cols, 400.0)                           # the static correction was singular here
    _, _, w2, _, _ = rb.modal(st)
    np.testing.assert_allclose(np.sqrt(w2[5:12]), w[5:12], rtol=1e-8)
    assert np.all(np.sqrt(w2[:5]) / (2 * np.pi) < 1e-2)


def test_solve_modes_about_a_positive_shift_on_the_lumped_deck(lumped):
    from updating.fe import Parameter, ParametricFEModel
    from updating.fe.sensitivity import solve_modes
    import modalab.core.dense as S
    pm = ParametricFEModel(lumped, [Parameter("E", "E", properties=tuple(lumped.properties))])
    w, _ = lumped.structure().normal_modes(12)
    old = S.EIGEN_LIMIT
    S.EIGEN_LIMIT = 10                                          # force the Lanczos paths on this small deck
    try:
        sol = solve_modes(pm, n_modes=4, sigma=(2 * np.pi * 170.0) ** 2)
        again = solve_modes(pm, n_modes=4, sigma=(2 * np.pi * 170.0) ** 2)
        neg = solve_modes(pm, n_modes=10)
    finally:
        S.EIGEN_LIMIT = old
    np.testing.assert_allclose(np.sort(sol.omega), w[5:9], rtol=1e-8)        # the four nearest 170 Hz
    assert np.array_equal(sol.lam, again.lam) and np.array_equal(sol.phi, again.phi)
    np.testing.assert_allclose(neg.omega[5:], w[5:10], rtol=1e-8)


@pytest.mark.parametrize("method", ["nelson", "modal"])
def test_eigenvector_sensitivities_on_the_lumped_deck(tmp_path, method):
    """Nelson's method and the modal method on a free-free lumped-mass deck (K - λM was singular through the
    massless mechanism: the derivatives came out NaN) against central differences of the eigen-solution."""
    from updating.fe import Parameter, ParametricFEModel
    from updating.fe.sensitivity import eigenvector_sensitivities, solve_modes
    m = _deck(tmp_path / "two.bdf", 20, split=7)
    pm = ParametricFEModel(m, [Parameter("E_root", "E", properties=(2,)), Parameter("E_tip", "E", properties=(1,))])
    sol = solve_modes(pm)
    d = eigenvector_sensitivities(pm, modes=[5, 6], solution=sol, method=method)
    assert np.all(np.isfinite(d))
    h = 1e-6
    for i in range(2):
        e = h * np.eye(2)[i]
        up, dn = solve_modes(pm, pm.p0 + e), solve_modes(pm, pm.p0 - e)
        for a, r in enumerate((5, 6)):
            x1, x0 = (s.phi[:, r] * np.sign(s.phi[:, r] @ (sol.M @ sol.phi[:, r])) for s in (up, dn))
            fd = (x1 - x0) / (2 * h)
            assert np.abs(d[:, a, i] - fd).max() < 1e-5 * np.abs(fd).max()


def test_fe_frfs_on_the_lumped_deck(lumped):
    from updating.fe.solvers import frf_direct, frf_modal
    sy = lumped.system()
    fr = [7.0, 45.0, 210.0]
    hd = frf_direct(sy, fr, ["31+Z", "8+Z"], ["31+Z"]).H
    hm = frf_modal(sy, fr, ["31+Z", "8+Z"], ["31+Z"], residual=False).H      # all finite modes: exact
    np.testing.assert_allclose(hm, hd, rtol=1e-8)
    # truncated, with the residual flexibility at the shift (the factorisation of K - σM was singular here)
    ht = frf_modal(sy, fr, ["31+Z", "8+Z"], ["31+Z"], n_modes=14).H
    hn = frf_modal(sy, fr, ["31+Z", "8+Z"], ["31+Z"], n_modes=14, residual=False).H
    err, err_no = (np.abs(h - hd).max() / np.abs(hd).max() for h in (ht, hn))
    assert err < 3e-3 and err < err_no / 3


def test_fe_solvers_are_deterministic():
    """The same model solved twice by every iterative eigen path gives bit-identical eigenvalues (ARPACK
    starts from a fixed vector; without one it draws a new random start each call)."""
    from updating.fe.models import beam_model
    from updating.fe.solvers import eigen_sparse
    s = beam_model(120, kind="beam3d", coupled_mass=False).system()
    runs = [eigen_sparse(s.K, s.M, 12) for _ in range(3)]
    for w, phi in runs[1:]:
        assert np.array_equal(w, runs[0][0]) and np.array_equal(phi, runs[0][1])


def test_two_pass_subspace_extension_equals_the_explicit_one(lumped, monkeypatch):
    """The modes-only screening extends its subspace per candidate from a deflated static correction (two
    passes over the basis): the same Ritz frequencies, for springs of any size, and the same measured rows as
    the explicit Gram-Schmidt extension, without falling back to it."""
    from updating.diagnosis.modes import ModalSubspace, _extended_rows
    st = lumped.structure()
    idx = {(d.node, d.axis): i for i, d in enumerate(st.dofs)}
    mi = np.array([idx[(n, 3)] for n in range(1, 32, 3)])
    basis = ModalSubspace(st, [], 400.0, 20)
    explicit = basis.extended
    fallbacks = []
    monkeypatch.setattr(basis, "extended", lambda *a: (fallbacks.append(a), explicit(*a))[1])
    for node, axes in ((17, (1, 2, 3)), (9, (3,)), (30, (5,)), (7, (3,)), (31, (3,)), (1, (1, 2, 3))):
        rows = np.array([idx[(node, a)] for a in axes])
        L = np.eye(rows.size)
        W, Kr, b = explicit(rows, L)
        Wm, Kr2, b2 = _extended_rows(basis, rows, L, mi)
        assert Kr2.shape == Kr.shape
        for theta in (0.0, 1e3, 1e6, 1e9):                  # a spring θ b bᵀ on the extended basis
            w_a = np.linalg.eigvalsh(Kr + theta * b @ b.T)
            w_b = np.linalg.eigvalsh(Kr2 + theta * b2 @ b2.T)
            np.testing.assert_allclose(w_b, w_a, rtol=1e-7, atol=1e-8 * w_a.max())
        Wa = basis.rows_of(mi, W)       # the new directions may be rotated among themselves: compare W Wᵀ
        np.testing.assert_allclose(Wm @ Wm.T, Wa @ Wa.T, atol=1e-7 * np.abs(Wa @ Wa.T).max())
    assert not fallbacks


def test_correlate_cli_on_a_lumped_free_free_deck(tmp_path, capsys):
    """``modalab correlate`` on a GVT deck with lumped mass and no SPC, above the dense limit (367 grids, 2202
    DOFs: Lanczos), against modes of an independent consistent-mass beam at 26 grids: the rigid-body modes
    are kept out and the vertical bending modes pair in order."""
    from modalab.app.cli import main
    from modalab.core.modes import ModeSet
    m = _deck(tmp_path / "gvt.bdf", 366)
    ref = _deck(tmp_path / "fine.bdf", 732, coupmass=True).structure()        # independent: twice finer, coupled
    w, phi = ref.normal_modes(24)
    z = np.array([d.axis == 3 for d in ref.dofs])
    vert = np.einsum("ij,ij->j", phi[z], (ref.M @ phi)[z]) > 0.5
    sel = np.flatnonzero(vert & (w / (2 * np.pi) > 1.0))[:5]
    grids = np.linspace(0, 366, 26).round().astype(int)
    rows = [ref.dofs.index(next(d for d in ref.dofs if d.node == 2 * g + 1 and d.axis == 3)) for g in grids]
    test = ModeSet(freq_hz=w[sel] / (2 * np.pi), shapes=phi[rows][:, sel], dofs=[f"{g + 1}+Z" for g in grids])
    test.to_json(tmp_path / "modes.json")
    assert main(["correlate", str(tmp_path / "gvt.bdf"), str(tmp_path / "modes.json"), "--same-ids",
                 "--json", str(tmp_path / "c.json")]) == 0
    import json
    c = json.loads((tmp_path / "c.json").read_text())
    assert [p["test_mode"] for p in c["pairs"]] == [1, 2, 3, 4, 5]
    assert min(p["mac"] for p in c["pairs"]) > 0.99 and max(abs(p["freq_error_pct"]) for p in c["pairs"]) < 1.0
    assert "5 rigid-body analysis mode(s) excluded" in capsys.readouterr().out


def test_lumped_cbeam_deck_has_six_rigid_modes(tmp_path):
    """Nastran's lumped CBEAM mass carries the torsional inertia ρ·Ip·L/2 at each end (PARAM,COUPMASS): a
    free-free lumped CBEAM deck has six rigid-body modes with mass and no massless mechanism; the lumped CBAR
    deck keeps its massless rigid torsion (translational mass only)."""
    beam = _deck(tmp_path / "cbeam.bdf", 30, card="CBEAM")
    bar = _deck(tmp_path / "cbar.bdf", 30, card="CBAR")
    st, sb = beam.structure(), bar.structure()
    assert not beam.coupled_mass
    rx = np.array([d.axis == 4 for d in st.dofs])
    b, h, rho, le = 0.05, 0.008, 2700.0, _L / 30
    ip = b * h * (b * b + h * h) / 12                         # polar moment of the 8 x 50 mm bar section
    d = st.M.diagonal()[rx]
    np.testing.assert_allclose(d[1:-1], rho * ip * le, rtol=1e-12)      # two half-elements at an inner grid
    np.testing.assert_allclose(d[[0, -1]], rho * ip * le / 2, rtol=1e-12)
    assert np.all(sb.M.diagonal()[rx] == 0)
    # the total torsional inertia is the coupled mass matrix's (rigid torsion about x)
    cp = _deck(tmp_path / "coup.bdf", 30, card="CBEAM", coupmass=True).structure()
    u = rx.astype(float)
    assert float(u @ (st.M @ u)) == pytest.approx(float(u @ (cp.M @ u)), rel=1e-12)
    assert massless_mechanisms(st.K, st.M)[0].size == 0 and massless_mechanisms(sb.K, sb.M)[0].size == 1
    f = st.normal_modes(12)[0] / (2 * np.pi)
    assert np.all(f[:6] < 1e-2) and f[6] > 10.0               # six rigid modes with mass, then elastic
    # bending is untouched: the same elastic bending frequencies as the CBAR deck's
    np.testing.assert_allclose(_bending_hz(st, *st.normal_modes(20))[:6], _bending_hz(sb, *sb.normal_modes(20))[:6],
                               rtol=2e-2)
