"""Eigen-solvers and FRF synthesis (updating.fe.solvers, updating.fe.damping)."""
import numpy as np
import pytest

from modalab.core.errors import ModalabValueError
from updating.fe import (Damper, LumpedMass, ModalDampingTable, eigen_dense, eigen_sparse, frf_direct, frf_modal,
                         modes_of, rayleigh_coefficients)
from updating.fe.solvers import cholmod_available, normal_modes
from updating.fe.models.beams import beam_model
from updating.fe.models.garteur import garteur_model


@pytest.fixture(scope="module")
def garteur():
    return garteur_model(6)


class TestEigen:
    def test_negative_shift_returns_rigid_modes_of_free_free_model(self, garteur):
        s = garteur.system()
        info = {}
        w, phi = eigen_sparse(s.K, s.M, 14, info=info, solver="splu")
        wd, pd = eigen_dense(s.K, s.M, 14)
        assert np.all(wd[:6] / (2 * np.pi) < 1e-3)
        assert info["shift"] < 0 and info["n_solves"] > 0
        assert np.all(w[:6] / (2 * np.pi) < 1e-3)          # six rigid-body modes ≈ 0 Hz
        assert w[6] / (2 * np.pi) > 4.0
        np.testing.assert_allclose(w[6:], wd[6:], rtol=1e-8)
        for W, P in ((w, phi), (wd, pd)):
            res = np.linalg.norm(s.K @ P - (s.M @ P) * W ** 2, axis=0) / np.linalg.norm(s.K @ P, axis=0)
            assert res[6:].max() < 1e-7
        # mass-normalised, M-orthogonal
        np.testing.assert_allclose(phi.T @ (s.M @ phi), np.eye(14), atol=1e-8)
        # the rigid modes are in the null space of K
        assert np.abs(s.K @ phi[:, :6]).max() < 1e-6 * abs(s.K).max()

    def test_positive_shift_is_refused(self, garteur):
        s = garteur.system()
        with pytest.raises(ModalabValueError, match="negative shift"):
            eigen_sparse(s.K, s.M, 5, shift=10.0)

    def test_auto_method_switches_to_lanczos_for_big_models(self):
        m = beam_model(100, kind="beam3d", length=10.0)        # 606 DOFs
        s = m.system()
        info = {}
        w, _ = normal_modes(s.K, s.M, 10, dense_limit=500, info=info)
        assert info["n_solves"] > 0                           # Lanczos was used
        wd, _ = normal_modes(s.K, s.M, 10, method="dense")
        np.testing.assert_allclose(w[6:], wd[6:], rtol=1e-7)

    def test_lumped_mass_massless_rotations_dense_and_sparse_agree(self):
        # cantilever: a free-free 3-D beam with lumped mass has a massless, stiffness-free
        # rigid torsion — a genuinely singular problem that the solvers report
        m = beam_model(30, kind="beam3d", coupled_mass=False, bc="cantilever")
        s = m.system()
        assert np.any(s.M.diagonal() == 0)
        wd, pd = eigen_dense(s.K, s.M, 12)
        ws, ps = eigen_sparse(s.K, s.M, 12)
        np.testing.assert_allclose(ws, wd, rtol=1e-8)
        # condensed shapes satisfy the full eigenproblem
        r = s.K @ pd[:, 8] - wd[8] ** 2 * (s.M @ pd[:, 8])
        assert np.abs(r).max() < 1e-6 * np.abs(s.K @ pd[:, 8]).max()

    def test_massless_mechanism_is_constrained_exactly(self):
        # free-free 3-D beam with lumped mass: the rigid torsion has neither mass nor stiffness; both solvers
        # constrain it (Nastran's MECHFIX) and return the same finite modes as with a tiny torsional inertia
        from updating.fe.solvers import massless_mechanisms
        s = beam_model(10, kind="beam3d", coupled_mass=False).system()
        fix, N = massless_mechanisms(s.K, s.M)
        assert fix.size == 1 and N.shape == (s.n_dof, 1)
        assert np.abs(s.K @ N).max() < 1e-8 * abs(s.K).max() and np.abs(s.M @ N).max() == 0
        ws, ps = eigen_sparse(s.K, s.M, 8, solver="splu")
        wd, pd = eigen_dense(s.K, s.M, 8)
        np.testing.assert_allclose(ws[5:], wd[5:], rtol=1e-8)
        assert np.all(wd[:5] / (2 * np.pi) < 1e-3) and wd[5] / (2 * np.pi) > 1.0    # 5 rigid modes with mass
        r = s.K @ pd - (s.M @ pd) * wd ** 2
        assert np.abs(r).max() < 1e-7 * np.abs(s.K @ pd).max()
        np.testing.assert_allclose(pd.T @ (s.M @ pd), np.eye(8), atol=1e-8)
        # a cantilever has no massless mechanism
        c = beam_model(10, kind="beam3d", coupled_mass=False, bc="cantilever").system()
        assert massless_mechanisms(c.K, c.M)[0].size == 0

    def test_dofs_with_neither_mass_nor_stiffness_on_a_mass_dof_are_reported(self):
        # a translational DOF with mass but the stiffness matrix indefinite is still refused, with a message
        s = beam_model(6, kind="beam3d").system()
        K = s.K.tolil()
        K[3, 3] = -abs(K[3, 3]) * 10
        with pytest.raises(ModalabValueError, match="not positive definite"):
            eigen_dense(K.tocsr(), s.M, 8)

    @pytest.mark.skipif(not cholmod_available(), reason="scikit-sparse not installed")
    def test_cholmod_path(self, garteur):
        s = garteur.system()
        w1, _ = eigen_sparse(s.K, s.M, 10, solver="cholmod")
        w2, _ = eigen_sparse(s.K, s.M, 10, solver="splu")
        np.testing.assert_allclose(w1[6:], w2[6:], rtol=1e-9)

    def test_modes_mapped_back_to_dependent_dofs(self, garteur):
        md = garteur.modes(10)
        pts = garteur.metadata["points"]
        red = garteur.reduction()
        dep = [d for d in red.dependent if d.node == pts["wing_centre"]]
        assert len(dep) == 6
        # the wing centre moves rigidly with the fuselage node: u_w = u_f + θ_f × r
        sel = md.select_dofs([f"{pts['wing_centre']}+{c}" for c in ("X", "Y", "Z")]).shapes
        f = md.select_dofs([f"{pts['fuselage_wing']}+{c}" for c in ("X", "Y", "Z", "RX", "RY", "RZ")]).shapes
        r = garteur.node_xyz(pts["wing_centre"]) - garteur.node_xyz(pts["fuselage_wing"])
        expect = f[:3] + np.cross(f[3:].T, r).T
        np.testing.assert_allclose(sel, expect, atol=1e-12)
        assert md.scaling == "unit_modal_mass"


class TestFRF:
    @pytest.fixture(scope="class")
    @classmethod
    def damped(cls):
        m = beam_model(16, kind="beam3d")
        m.global_ge = 0.02
        return m

    def test_direct_frf_matches_core_structure(self, damped):
        s = damped.system()
        f = np.array([30.0, 55.0, 140.0])
        a = frf_direct(s, f, ["5+Z", "9+Y"], ["1+Z"], quantity="receptance")
        b = s.structure().frf(f, ["5+Z", "9+Y"], ["1+Z"], quantity="receptance", method="direct")
        np.testing.assert_allclose(a.H, b.H, rtol=1e-10)

    def test_modal_with_residual_matches_direct(self, damped):
        s = damped.system()
        f = np.linspace(5, 400, 80)          # up to ~2 elastic bending modes per plane
        resp, ref = ["17+Z", "9+Z", "5+Y", "3+RZ"], ["17+Z", "5+Y"]
        direct = frf_direct(s, f, resp, ref, quantity="accelerance")
        with_res = frf_modal(s, f, resp, ref, n_modes=16, residual=True)
        without = frf_modal(s, f, resp, ref, n_modes=16, residual=False)
        err_res = np.abs(with_res.H - direct.H).max() / np.abs(direct.H).max()
        err_no = np.abs(without.H - direct.H).max() / np.abs(direct.H).max()
        assert err_res < 2e-3
        assert err_res < err_no / 10
        # with every mode kept the synthesis is exact, residual or not
        n = s.n_dof
        full = frf_modal(s, f, resp, ref, n_modes=n, residual=False)
        np.testing.assert_allclose(full.H, direct.H, rtol=1e-7, atol=1e-9 * np.abs(direct.H).max())

    @pytest.mark.parametrize("damping", ["hysteretic", "viscous"])
    @pytest.mark.parametrize("quantity", ["receptance", "accelerance"])
    def test_modal_frf_at_s_equals_direct_at_s(self, damping, quantity):
        """Issue 15, a typed window: frf_modal and FEModel.frf(method='modal') evaluate at s = iω + β like
        frf_direct (every mode kept: exact), carry β, and differ from the FRF at s = iω."""
        from updating.fe import rayleigh_coefficients

        m = beam_model(10, kind="beam3d")
        if damping == "hysteretic":
            m.global_ge = 0.02
        else:
            m.rayleigh = rayleigh_coefficients(20.0, 0.01, 400.0, 0.02)
        s, f, beta = m.system(), np.linspace(5, 400, 60), 6.0
        resp, ref = ["9+Z", "5+Y", "3+RZ"], ["9+Z", "5+Y"]
        direct = frf_direct(s, f, resp, ref, quantity=quantity, beta=beta)
        for modal in (frf_modal(s, f, resp, ref, n_modes=s.n_dof, residual=False, quantity=quantity,
                                window_beta_per_s=beta),
                      m.frf(f, resp, ref, quantity=quantity, method="modal", n_modes=s.n_dof, residual=False,
                            window_beta_per_s=beta)):
            assert modal.window_beta_per_s == beta
            np.testing.assert_allclose(modal.H, direct.H, rtol=1e-7, atol=1e-9 * np.abs(direct.H).max())
        at_iw = frf_modal(s, f, resp, ref, n_modes=s.n_dof, residual=False, quantity=quantity)
        assert at_iw.window_beta_per_s == 0.0
        assert np.abs(at_iw.H - direct.H).max() > 1e-2 * np.abs(direct.H).max()
        assert m.frf(f, resp, ref, quantity=quantity, beta=beta).window_beta_per_s == beta   # the older keyword
        with pytest.raises(ModalabValueError, match="window_beta_per_s"):
            frf_modal(s, f, resp, ref, window_beta_per_s=-1.0)

    def test_modal_damping_table_gives_peak_height(self):
        # a single-DOF oscillator: m = 2 kg, k = 8e4 N/m; ζ = 2 % from a table
        from updating.fe import FEModel, Spring
        m = FEModel()
        m.add_node(1, (0, 0, 0))
        m.add_element(LumpedMass(1, 1, 2.0))
        for c in (2, 3):
            m.add_element(Spring(10 + c, (1, c), None, 8e4))
        m.add_element(Spring(11, (1, 1), None, 8e4))
        for c in (4, 5, 6):
            m.add_element(Spring(20 + c, (1, c), None, 1.0))
        m.add_element(LumpedMass(2, 1, 0.0, inertia=[1e-3] * 3))
        fn = np.sqrt(8e4 / 2) / (2 * np.pi)
        tab = ModalDampingTable((0.0, 1000.0), (0.02, 0.02))
        s = m.system()
        h = frf_modal(s, [fn], ["1+X"], ["1+X"], modal_damping=tab, residual=False, quantity="receptance")
        assert abs(h.H[0, 0, 0]) == pytest.approx(1 / (2 * 0.02 * 8e4), rel=1e-9)
        # a viscous damper of the same ζ gives the same peak with the direct solver
        for c in (1, 2, 3):
            m.add_element(Damper(30 + c, (1, c), None, 2 * 0.02 * np.sqrt(8e4 * 2)))
        hd = frf_direct(m.system(), [fn], ["1+X"], ["1+X"], quantity="receptance")
        np.testing.assert_allclose(hd.H, h.H, rtol=1e-9)

    def test_model_frf_between_dependent_dofs_is_reciprocal(self):
        m = garteur_model(3)
        m.global_ge = 0.02
        p = m.metadata["points"]
        a, b = f"{p['wing_centre']}+Z", f"{p['right_drum_centre']}+Y"     # both are rigid-link dependents
        f = [7.0, 21.0]
        h = m.frf(f, [a, b], [a, b], quantity="receptance")
        np.testing.assert_allclose(h.H[0, 1], h.H[1, 0], rtol=1e-9)
        hm = m.frf(f, [a, b], [a, b], quantity="receptance", method="modal", n_modes=60)
        np.testing.assert_allclose(hm.H, h.H, rtol=2e-3, atol=1e-3 * np.abs(h.H).max())
        with pytest.raises(ValueError, match="method"):
            m.frf(f, [a], [a], method="exact")

    def test_modes_report_modal_damping(self, damped):
        md = modes_of(damped.system(), 10)
        el = md.freq_hz > 1
        np.testing.assert_allclose(md.damping[el], 0.01, rtol=1e-8)   # ζ = G/2
        assert np.all(md.damping[~el] == 0)


class TestDampingHelpers:
    def test_table_kinds(self):
        t = ModalDampingTable((10.0, 20.0), (0.02, 0.04), kind="G")
        np.testing.assert_allclose(t.zeta([5.0, 15.0, 30.0]), [0.01, 0.015, 0.02])
        q = ModalDampingTable((0.0,), (25.0,), kind="Q")
        assert q.zeta(3.0) == pytest.approx(0.02)
        with pytest.raises(ValueError, match="ascend"):
            ModalDampingTable((2.0, 1.0), (0.1, 0.1))

    def test_rayleigh_coefficients_hit_both_points(self):
        a, b = rayleigh_coefficients(10.0, 0.01, 100.0, 0.03)
        for f, z in ((10.0, 0.01), (100.0, 0.03)):
            w = 2 * np.pi * f
            assert a / (2 * w) + b * w / 2 == pytest.approx(z)


# ----------------------------------------------------------------- a lumped-mass GVT deck without SPC (issue 16 #7)
# free-free Euler-Bernoulli roots of cos βL cosh βL = 1 (then (2n + 1)π/2 to double precision)
_BETA_FREE = (4.730040745, 7.853204624, 10.99560784, 14.13716549) + tuple((2 * n + 1) * np.pi / 2 for n in range(5, 9))


def _free_beam_deck(path, n_el, *, coupmass=False, length=1.2):
    """A Nastran deck as a GVT engineer's: CBAR/PBARL along x, no SPC, lumped mass unless ``coupmass`` (a
    lumped CBAR has no torsional inertia: the rigid torsion is a massless mechanism)."""
    lines = ["SOL 103", "CEND", "BEGIN BULK", "EIGRL,10,,,20"]
    if coupmass:
        lines.append("PARAM,COUPMASS,1")
    lines += ["MAT1,1,7.e10,,.33,2700.", "PBARL,1,1,,BAR", "+,.05,.008"]
    lines += [f"GRID,{i + 1},,{length * i / n_el:.8f},0.,0." for i in range(n_el + 1)]
    lines += [f"CBAR,{i + 1},1,{i + 1},{i + 2},0.,1.,0." for i in range(n_el)]
    path.write_text("\n".join(lines + ["ENDDATA", ""]).replace("\n", "\r\n"))
    return path


def _closed_form_hz(length=1.2):
    E, rho, b, h = 7e10, 2700.0, 0.05, 0.008
    A = b * h
    out = []
    for I in (b * h ** 3 / 12, h * b ** 3 / 12):            # the two bending planes
        out += [bl ** 2 / (2 * np.pi * length ** 2) * np.sqrt(E * I / (rho * A)) for bl in _BETA_FREE]
    return np.sort(out)[:8]


@pytest.mark.parametrize("method", ["dense", "sparse"])
def test_lumped_mass_free_free_deck_without_spc(tmp_path, method):
    from updating.fe.bulk import build_model, read_bdf
    model = build_model(read_bdf(_free_beam_deck(tmp_path / "gvt.bdf", 60)))
    s = model.system()
    assert not model.coupled_mass and np.any(s.M.diagonal() == 0)
    w, phi = normal_modes(s.K, s.M, 16, method=method)
    f = w / (2 * np.pi)
    assert np.all(f[:5] < 1e-2)                      # 5 rigid modes with mass (the torsion has none)
    fe = f[5:]
    bend = [x for x in fe if x < 1500][:8]            # the first axial/torsion modes are far higher
    truth = _closed_form_hz()
    assert len(bend) == 8
    # Euler-Bernoulli: within 1.5 % (the strong plane has some shear flexibility), 0.5 % for the slender plane
    np.testing.assert_allclose(bend, truth, rtol=1.5e-2)
    weak = [0, 1, 2, 4]
    np.testing.assert_allclose(np.asarray(bend)[weak], truth[weak], rtol=5e-3)
    # and a consistent-mass mesh four times finer agrees too (an independent discretisation)
    fine = build_model(read_bdf(_free_beam_deck(tmp_path / "fine.bdf", 240, coupmass=True))).system()
    wf, pf = normal_modes(fine.K, fine.M, 20, method="sparse")
    yz = np.array([d.axis in (2, 3) for d in fine.dofs])
    lateral = np.einsum("ij,ij->j", pf[yz], (fine.M @ pf)[yz])          # share of kinetic energy in y, z
    fine_bend = (wf / (2 * np.pi))[(lateral > 0.5) & (wf / (2 * np.pi) > 1.0)][:8]     # no torsion, no axial
    np.testing.assert_allclose(bend, fine_bend, rtol=1e-2)          # lumped vs coupled mass, 60 vs 240 elements
