"""Assembly, coordinate systems, damping matrices and constraints (updating.fe)."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from modalab.core.dof import Dof
from updating.fe import (Beam3D, BeamProperty, FEModel, LumpedMass, Material, RectangularSection, Spring,
                         eigen_dense)
from updating.fe.models.beams import beam_model


def rotation(a, b, c):
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    Rz = np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1]])
    Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    Rx = np.array([[1, 0, 0], [0, cc, -sc], [0, sc, cc]])
    return Rz @ Ry @ Rx


def frame(cd=None, ge=0.0):
    """An L-shaped free-free frame with a lumped mass: 3 members, 7 nodes."""
    m = FEModel("L frame")
    m.add_material(Material(1, E=70e9, nu=0.3, rho=2700, ge=ge))
    m.add_property(BeamProperty(1, 1, RectangularSection(0.03, 0.01), name="bar"))
    for i, x in enumerate([(0, 0, 0), (0.3, 0, 0), (0.6, 0, 0), (0.6, 0.3, 0), (0.6, 0.6, 0), (0.6, 0.6, 0.3),
                           (0.6, 0.6, 0.6)]):
        m.add_node(i + 1, x, cd=(cd if (cd is not None and i % 2 == 1) else None))
    for i in range(6):
        m.add_element(Beam3D(i + 1, i + 1, i + 2, 1, (0.3, 0.5, 1.0)))
    m.add_element(LumpedMass(20, 4, 0.5, inertia=[1e-3, 2e-3, 3e-3], offset=(0.01, 0.02, 0.0)))
    return m


class TestAssembly:
    def test_dofs_sorted_and_positive(self):
        m = frame()
        assert m.dofs[:7] == [Dof(1, a) for a in range(1, 7)] + [Dof(2, 1)]
        assert m.n_dof == 42

    def test_symmetric_psd_six_rigid_modes(self):
        mats = frame().assemble()
        K, M = mats.K.toarray(), mats.M.toarray()
        assert np.allclose(K, K.T, atol=1e-9 * abs(K).max())
        assert np.allclose(M, M.T, atol=1e-12 * abs(M).max())
        ek = np.linalg.eigvalsh(K)
        assert ek.min() > -1e-9 * ek.max()
        assert np.linalg.eigvalsh(M).min() > 0
        w, _ = eigen_dense(mats.K, mats.M)
        assert (w < 1e-4 * w.max()).sum() == 6
        assert w[6] > 2 * np.pi * 10  # first elastic mode well above 10 Hz

    @settings(max_examples=10, deadline=None)
    @given(angles=st.tuples(*[st.floats(-3, 3)] * 3))
    def test_cd_systems_rotate_but_keep_frequencies(self, angles):
        R = rotation(*angles)
        m0, m1 = frame(), frame(cd=R)
        a0, a1 = m0.assemble(), m1.assemble()
        # K_cd = Tᵀ K_basic T with u_basic = R u_cd on the rotated nodes
        T = np.eye(m0.n_dof)
        for i, d in enumerate(m0.dofs):
            if d.node % 2 == 0 and d.axis in (1, 4):
                T[i:i + 3, i:i + 3] = R
        np.testing.assert_allclose(a1.K.toarray(), T.T @ a0.K.toarray() @ T, atol=1e-6 * abs(a0.K).max())
        np.testing.assert_allclose(a1.M.toarray(), T.T @ a0.M.toarray() @ T, atol=1e-12)
        w0, _ = eigen_dense(a0.K, a0.M)
        w1, _ = eigen_dense(a1.K, a1.M)
        np.testing.assert_allclose(w1[6:], w0[6:], rtol=1e-7)

    def test_spring_acts_in_node_cd_system(self):
        # a grounded spring on component 1 of a node whose CD x-axis is basic Y stiffens basic Y
        R = rotation(np.pi / 2, 0, 0)
        m = FEModel()
        m.add_node(1, (0, 0, 0), cd=R)
        m.add_element(LumpedMass(1, 1, 2.0))
        m.add_element(Spring(2, (1, 1), None, 800.0))
        mats = m.assemble()
        K = mats.K.toarray()
        assert K[0, 0] == 800.0 and np.count_nonzero(K) == 1
        # the mass is isotropic so it is unchanged by the rotation
        np.testing.assert_allclose(mats.M.toarray()[:3, :3], 2 * np.eye(3), atol=1e-15)
        # a rotated node touched only by scalar elements keeps just the components they use
        s = FEModel()
        s.add_node(1, (0, 0, 0), cd=R)
        s.add_element(Spring(1, (1, 2), None, 10.0))
        assert [str(d) for d in s.dofs] == ["1+Y"]

    def test_structural_damping_material_and_global(self):
        m = frame(ge=0.02)
        m.global_ge = 0.01
        mats = m.assemble()
        np.testing.assert_allclose(mats.D.toarray(), 0.03 * mats.K.toarray(), rtol=1e-12, atol=1e-6)
        m.rayleigh = (0.5, 1e-5)
        mats = m.assemble()
        np.testing.assert_allclose(mats.C.toarray(), 0.5 * mats.M.toarray() + 1e-5 * mats.K.toarray(), atol=1e-9)

    def test_property_ge_overrides_material(self):
        m = frame(ge=0.02)
        m.properties[1] = BeamProperty(1, 1, RectangularSection(0.03, 0.01), ge=0.05)
        mats = m.assemble()
        np.testing.assert_allclose(mats.D.toarray(), 0.05 * mats.K.toarray(), atol=1e-6)

    def test_errors_name_the_culprit(self):
        m = frame()
        with pytest.raises(ValueError, match="duplicate node id 3"):
            m.add_node(3, (0, 0, 0))
        with pytest.raises(ValueError, match="duplicate element id 2"):
            m.add_element(Beam3D(2, 1, 2, 1))
        m.add_element(Beam3D(30, 1, 99, 1))
        with pytest.raises(ValueError, match="node 99"):
            m.dofs
        m2 = frame()
        m2.add_element(Beam3D(31, 1, 2, 7))
        with pytest.raises(ValueError, match="property id 7"):
            m2.assemble()
        m3 = frame()
        m3.add_element(Beam3D(32, 1, 3, 1, orientation=(1, 0, 0)))
        with pytest.raises(ValueError, match="parallel"):
            m3.assemble()


def rigid_motion(model, u0, theta, about):
    """Full-DOF vector of a small rigid motion (translation u0, rotation theta about point `about`)."""
    x = np.zeros(model.n_dof)
    for i, d in enumerate(model.dofs):
        n = model.nodes[d.node]
        ub = np.concatenate([u0 + np.cross(theta, n.xyz - about), theta])
        R = np.eye(3) if n.cd is None else n.cd
        uc = np.concatenate([R.T @ ub[:3], R.T @ ub[3:]])
        x[i] = uc[d.axis - 1]
    return x


class TestRigidLinks:
    def _linked(self, cd=None, components="123456"):
        m = frame()
        m.add_node(50, (0.6, 0.2, 0.15), cd=cd)
        m.add_node(51, (0.8, 0.2, 0.15))
        m.add_rbe2(100, 3, [50, 51], components)
        return m

    @settings(max_examples=10, deadline=None)
    @given(angles=st.tuples(*[st.floats(-3, 3)] * 3), u0=st.tuples(*[st.floats(-1, 1)] * 3),
           th=st.tuples(*[st.floats(-1, 1)] * 3))
    def test_T_reproduces_rigid_motion_of_the_independent_node(self, angles, u0, th):
        m = self._linked(cd=rotation(*angles))
        red = m.reduction()
        assert len(red.dependent) == 12 and red.T.shape == (m.n_dof, m.n_dof - 12)
        u0, th = np.array(u0), np.array(th)
        full = rigid_motion(m, u0, th, np.zeros(3))
        ia = [m.dofs.index(d) for d in red.dofs]
        np.testing.assert_allclose(red.expand(full[ia]), full, atol=1e-12)

    def test_rigid_link_adds_no_elastic_energy_and_keeps_six_rigid_modes(self):
        m = self._linked()
        m.add_element(LumpedMass(60, 51, 0.3))
        s = m.system()
        w, phi = eigen_dense(s.K, s.M)
        assert (w < 1e-4 * w.max()).sum() == 6

    def test_rbe2_equals_very_stiff_connector(self):
        # a rigid link vs. a very stiff short beam carrying an offset mass: same first modes
        def build(rigid):
            m = beam_model(12, bc="free", kind="beam3d")
            m.add_node(99, (0.5, 0.0, 0.2))
            m.add_element(LumpedMass(98, 99, 0.05, inertia=[1e-5] * 3))
            mid = 7
            if rigid:
                m.add_rbe2(97, mid, [99])
            else:
                m.add_material(Material(9, E=70e9 * 1e5, nu=0.3, rho=0.0))
                m.add_property(BeamProperty(9, 9, RectangularSection(0.02, 0.02)))
                m.add_element(Beam3D(97, mid, 99, 9, (1, 0, 0)))
            return m

        fr = build(True).modes(12).freq_hz
        fs = build(False).modes(12).freq_hz
        np.testing.assert_allclose(fr[6:], fs[6:], rtol=1e-4)

    def test_partial_components_and_chains(self):
        m = frame()
        m.add_node(50, (0.6, 0.2, 0.15))
        m.add_node(51, (0.9, 0.2, 0.15))
        m.add_rbe2(100, 3, [50])                  # 50 follows 3
        m.add_rbe2(101, 50, [51], "123")          # 51 translations follow 50 (chain)
        m.add_element(LumpedMass(60, 51, 0.3))
        red = m.reduction()
        assert Dof(51, 4) in red.dofs and Dof(51, 1) not in red.dofs
        full = rigid_motion(m, np.array([0.1, -0.2, 0.3]), np.array([0.02, 0.01, -0.03]), np.zeros(3))
        ia = [m.dofs.index(d) for d in red.dofs]
        np.testing.assert_allclose(red.expand(full[ia]), full, atol=1e-12)

    def test_link_errors(self):
        m = frame()
        m.add_node(50, (0.6, 0.2, 0.15))
        m.add_rbe2(100, 3, [50])
        m.add_rbe2(101, 5, [50], "3")
        with pytest.raises(ValueError, match="dependent in rigid links 100 and 101"):
            m.reduction()
        m = frame()
        m.add_node(50, (0.6, 0.2, 0.15))
        m.add_rbe2(100, 3, [50])
        m.add_spc(50, "1")
        with pytest.raises(ValueError, match="SPC on 50\\+X"):
            m.reduction()
        m = frame()
        m.add_node(50, (0.6, 0.2, 0.15))
        m.add_node(51, (0.7, 0.2, 0.15))
        m.add_rbe2(100, 50, [51])
        m.add_rbe2(101, 51, [50])
        with pytest.raises(ValueError, match="cycle"):
            m.reduction()
        with pytest.raises(ValueError, match="components"):
            m.add_rbe2(102, 1, [2], "17")


class TestSPC:
    def test_spc_removes_dofs_and_expands_to_zero(self):
        m = beam_model(6, bc="cantilever", kind="beam3d")
        s = m.system()
        assert s.n_dof == m.n_dof - 6
        assert all(d.node != 1 for d in s.dofs)
        md = m.modes(4)
        assert np.all(md.shapes[:6] == 0)
        assert md.dofs == m.dofs

    def test_spc_on_dependent_of_fixed_independent(self):
        # fixing the independent node drops the dependent node's motion too
        m = frame()
        m.add_node(50, (0.6, 0.2, 0.15))
        m.add_rbe2(100, 3, [50])
        m.add_spc(3)
        red = m.reduction()
        rows = [i for i, d in enumerate(m.dofs) if d.node in (3, 50)]
        assert red.T[rows].nnz == 0
