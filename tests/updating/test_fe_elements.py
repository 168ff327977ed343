"""Element tests against closed-form results and invariants (updating.fe.elements)."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from updating.fe import (Beam2D, Beam3D, BeamProperty, Damper, FEModel, GeneralSection, LumpedMass, Material,
                         RectangularSection, Rod, RodProperty, Spring, Timoshenko3D, TubeSection, eigen_dense)
from updating.fe.elements.base import AssemblyContext
from updating.fe.models.beams import beam_model, closed_form_hz, timoshenko_pinned_hz

E, RHO, NU = 70e9, 2700.0, 0.3
B, H = 0.02, 0.01
SEC = RectangularSection(B, H)


def elastic_hz(model, n):
    s = model.system()
    w, _ = eigen_dense(s.K, s.M)
    f = w / (2 * np.pi)
    return f[f > 1.0][:n]  # rigid-body modes come out below 0.01 Hz


def _share(phi, dofs, axis):
    """Fraction of each mode's translational amplitude² along ``axis``."""
    tr = np.array([d.axis <= 3 for d in dofs])
    on = np.array([d.axis == axis for d in dofs])
    return (phi[on] ** 2).sum(0) / (phi[tr] ** 2).sum(0)


def _errors(bc, kind, meshes, coupled=True, n=3):
    exact = closed_form_hz(bc, n, 1.0, E, SEC.Iy, RHO, SEC.A)
    return [np.abs(elastic_hz(beam_model(k, bc=bc, kind=kind, coupled_mass=coupled), n) - exact) / exact
            for k in meshes]


class TestBeamConvergence:
    """Natural frequencies converge to Euler–Bernoulli closed form at the expected rate."""

    @pytest.mark.parametrize("bc", ["free", "cantilever", "pinned"])
    def test_consistent_mass_converges_at_h4(self, bc):
        e1, e2, e3 = _errors(bc, "beam2d", (4, 8, 16))
        # eigenvalue error of the cubic Hermite element is O(h^4): halving h divides it by ~16
        rate = np.log2(e2[:2] / e3[:2])
        assert np.all(rate > 3.5), rate
        assert np.all(e3 < 2e-4), e3
        assert np.all(e1 > e2) and np.all(e2 > e3)

    @pytest.mark.parametrize("bc", ["free", "cantilever"])
    def test_lumped_mass_converges_at_h2(self, bc):
        # (for the pinned beam the lumped mass is superconvergent, O(h^4), by symmetry)
        e2, e3 = _errors(bc, "beam2d", (16, 32), coupled=False, n=2)
        rate = np.log2(e2 / e3)
        assert np.all((rate > 1.7) & (rate < 2.3)), rate

    @pytest.mark.parametrize("bc", ["free", "cantilever", "pinned"])
    def test_3d_frame_matches_2d_in_bending(self, bc):
        f2 = elastic_hz(beam_model(10, bc=bc, kind="beam2d"), 3)
        m3 = beam_model(10, bc=bc, kind="beam3d")
        s = m3.system()
        w, phi = eigen_dense(s.K, s.M)
        # the x–z bending modes of the 3-D frame (DOF +Z dominant) equal the 2-D beam ones
        f3 = (w / (2 * np.pi))[(_share(phi, s.dofs, 3) > 0.5) & (w > 2 * np.pi)][:3]
        np.testing.assert_allclose(f3, f2, rtol=1e-9)

    def test_bending_planes_follow_orientation(self):
        # along X with v = +Y: bending towards Y uses Iz = h b^3/12, towards Z uses Iy = b h^3/12
        m = beam_model(12, bc="free", kind="beam3d")
        md = m.modes(20)
        s = md.shapes
        dofs = md.dofs
        el = md.freq_hz > 1.0
        fy = md.freq_hz[el & (_share(s, dofs, 2) > 0.5)][0]
        fz = md.freq_hz[el & (_share(s, dofs, 3) > 0.5)][0]
        assert fy / fz == pytest.approx(B / H, rel=1e-9)


class TestTimoshenko:
    def test_thick_pinned_beam_matches_timoshenko_theory(self):
        sec = RectangularSection(0.1, 0.1)  # L/h = 5: shear and rotary inertia matter
        m = beam_model(40, bc="pinned", kind="timoshenko3d", section=sec)
        G = E / (2 * (1 + NU))
        exact = timoshenko_pinned_hz(2, 1.0, E, G, sec.Iy, RHO, sec.A, 5 / 6)
        eb = closed_form_hz("pinned", 2, 1.0, E, sec.Iy, RHO, sec.A)
        s = m.system()
        w, phi = eigen_dense(s.K, s.M)
        f = (w / (2 * np.pi))[_share(phi, s.dofs, 3) > 0.5][:2]
        np.testing.assert_allclose(f, exact, rtol=2e-3)
        assert np.all(f < 0.985 * eb)  # clearly below Euler–Bernoulli (1.6 % and 6 %)

    def test_slender_limit_equals_euler_bernoulli(self):
        sec = GeneralSection(A=SEC.A, Iy=SEC.Iy, Iz=SEC.Iz, J=SEC.J)  # no shear factors: shear-rigid
        ctx_model = FEModel()
        ctx_model.add_material(Material(1, E, NU, RHO))
        ctx_model.add_property(BeamProperty(1, 1, sec))
        ctx_model.add_node(1, (0, 0, 0))
        ctx_model.add_node(2, (0.3, 0.4, 0.1))
        ctx = AssemblyContext(ctx_model)
        kt = Timoshenko3D(1, 1, 2, 1, (0, 0, 1)).matrices(ctx).K
        kb = Beam3D(1, 1, 2, 1, (0, 0, 1)).matrices(ctx).K
        np.testing.assert_allclose(kt, kb, rtol=1e-12, atol=1e-6)


def _two_node_model(section=SEC, x2=(1.0, 0.0, 0.0), coupled=True):
    m = FEModel(coupled_mass=coupled)
    m.add_material(Material(1, E, NU, RHO))
    m.add_property(BeamProperty(1, 1, section, nsm=0.1))
    m.add_property(RodProperty(2, 1, A=1e-4, J=2e-9))
    m.add_node(1, (0.0, 0.0, 0.0))
    m.add_node(2, x2)
    return m


def _rigid_modes(xyz):
    """6 rigid-body motions of the stacked nodes (6 DOFs each)."""
    R = []
    for x in xyz:
        blk = np.zeros((6, 6))
        blk[:3, :3] = np.eye(3)
        blk[3:, 3:] = np.eye(3)
        rx, ry, rz = x
        # translation from rotation θ: θ × r
        blk[:3, 3:] = np.array([[0, rz, -ry], [-rz, 0, rx], [ry, -rx, 0]])
        R.append(blk)
    return np.vstack(R)


unit = st.floats(-1, 1, allow_nan=False)


class TestFrameInvariants:
    @settings(max_examples=30, deadline=None)
    @given(d=st.tuples(unit, unit, unit), v=st.tuples(unit, unit, unit),
           cls=st.sampled_from([Beam3D, Timoshenko3D]), coupled=st.booleans())
    def test_symmetric_psd_rank_and_rigid_body(self, d, v, cls, coupled):
        d, v = np.array(d), np.array(v)
        if np.linalg.norm(d) < 0.1 or np.linalg.norm(np.cross(d, v)) < 0.05 * np.linalg.norm(d):
            return
        m = _two_node_model(x2=tuple(d), coupled=coupled)
        em = cls(1, 1, 2, 1, tuple(v)).matrices(AssemblyContext(m))
        K, M = em.K, em.M
        assert np.allclose(K, K.T, rtol=0, atol=1e-9 * abs(K).max())
        assert np.allclose(M, M.T, rtol=0, atol=1e-12 * abs(M).max())
        ev = np.linalg.eigvalsh(K)
        assert ev.min() > -1e-9 * ev.max()
        assert (ev > 1e-8 * ev.max()).sum() == 6           # 12 DOFs - 6 rigid-body motions
        Rb = _rigid_modes([np.zeros(3), d])
        assert np.abs(K @ Rb).max() < 1e-7 * abs(K).max()
        # rigid translation carries the element's full mass (ρA + nsm) L
        mass = (RHO * SEC.A + 0.1) * np.linalg.norm(d)
        for k in range(3):
            assert Rb[:, k] @ M @ Rb[:, k] == pytest.approx(mass, rel=1e-10)
        evm = np.linalg.eigvalsh(M)
        assert evm.min() > -1e-12 * evm.max()

    def test_consistent_mass_positive_definite(self):
        m = _two_node_model()
        M = Timoshenko3D(1, 1, 2, 1, (0, 0, 1)).matrices(AssemblyContext(m)).M
        assert np.linalg.eigvalsh(M).min() > 0


class TestOffsets:
    @settings(max_examples=10, deadline=None)
    @given(wa=st.tuples(unit, unit, unit), wb=st.tuples(unit, unit, unit), cls=st.sampled_from([Beam3D, Timoshenko3D]))
    def test_offsets_equal_rigid_links_to_offset_nodes(self, wa, wb, cls):
        wa, wb = 0.1 * np.array(wa), 0.1 * np.array(wb)

        def system(with_offsets):
            m = _two_node_model(x2=(1.0, 0.2, 0.0))
            if with_offsets:
                m.add_element(cls(1, 1, 2, 1, (0, 0, 1), offset_a=wa, offset_b=wb))
            else:
                m.add_node(3, wa)
                m.add_node(4, np.array([1.0, 0.2, 0.0]) + wb)
                m.add_element(cls(1, 3, 4, 1, (0, 0, 1)))
                m.add_rbe2(2, 1, [3])
                m.add_rbe2(3, 2, [4])
            return m.system()

        a, b = system(True), system(False)
        assert a.dofs == b.dofs
        np.testing.assert_allclose(a.K.toarray(), b.K.toarray(), rtol=0, atol=1e-12 * abs(a.K).max())
        np.testing.assert_allclose(a.M.toarray(), b.M.toarray(), rtol=0, atol=1e-12 * abs(a.M).max())


class TestBeam2D:
    def test_xz_plane_sign_convention(self):
        # θy = −w′: a rigid rotation about +Y by θ moves node 2 (at x = L) by w = −θ L
        m = _two_node_model()
        em = Beam2D(1, 1, 2, 1, plane="xz").matrices(AssemblyContext(m))
        assert [d[1] for d in em.dofs] == [3, 5, 3, 5]
        th = 1e-3
        u = np.array([0.0, th, -th * 1.0, th])
        assert np.abs(em.K @ u).max() < 1e-9 * abs(em.K).max() * th

    @settings(max_examples=20, deadline=None)
    @given(ang=st.floats(-np.pi, np.pi))
    def test_inclined_axial_beam_rigid_body(self, ang):
        m = _two_node_model(x2=(np.cos(ang), np.sin(ang), 0.0))
        em = Beam2D(1, 1, 2, 1, plane="xy", axial=True).matrices(AssemblyContext(m))
        # translations X, Y and rotation about Z
        x2, y2 = np.cos(ang), np.sin(ang)
        R = np.array([[1, 0, 0, 1, 0, 0], [0, 1, 0, 0, 1, 0], [0, 0, 1, -y2, x2, 1]], float).T
        assert np.abs(em.K @ R).max() < 1e-7 * abs(em.K).max()
        assert (np.linalg.eigvalsh(em.K) > 1e-8 * abs(em.K).max()).sum() == 3

    def test_not_along_x_without_axial_is_an_error(self):
        m = _two_node_model(x2=(1.0, 0.0, 0.5))
        with pytest.raises(ValueError, match="not along X"):
            Beam2D(1, 1, 2, 1, plane="xz").matrices(AssemblyContext(m))


class TestRod:
    def test_free_free_axial_frequencies(self):
        L, n = 2.0, 40
        m = FEModel()
        m.add_material(Material(1, E, NU, RHO))
        m.add_property(RodProperty(1, 1, A=1e-4, J=1e-9))
        for i in range(n + 1):
            m.add_node(i + 1, (L * i / n, 0, 0))
            m.add_spc(i + 1, "2356")  # keep only axial and torsion
        for i in range(n):
            m.add_element(Rod(i + 1, i + 1, i + 2, 1))
        s = m.system()
        ix = [i for i, d in enumerate(s.dofs) if d.axis == 1]
        K, M = s.K.toarray()[np.ix_(ix, ix)], s.M.toarray()[np.ix_(ix, ix)]
        w, _ = eigen_dense(K, M)
        c = np.sqrt(E / RHO)
        exact = np.array([1, 2]) * c / (2 * L)
        np.testing.assert_allclose(w[1:3] / (2 * np.pi), exact, rtol=1.5e-3)  # linear element: error (kh)²/24
        assert w[0] < 1e-5 * w[1]


class TestScalarAndMass:
    def test_spring_on_rotation_and_ground(self):
        m = FEModel()
        m.add_node(1, (0, 0, 0))
        m.add_node(2, (1, 0, 0))
        m.add_element(Spring(1, (1, 5), (2, 5), 300.0))
        m.add_element(Spring(2, (1, 5), None, 100.0, ge=0.1))
        m.add_element(Damper(3, (2, 5), None, 2.0))
        mats = m.assemble()
        assert [str(d) for d in mats.dofs] == ["1+RY", "2+RY"]
        np.testing.assert_allclose(mats.K.toarray(), [[400, -300], [-300, 300]])
        np.testing.assert_allclose(mats.D.toarray(), [[10, 0], [0, 0]])
        np.testing.assert_allclose(mats.C.toarray(), [[0, 0], [0, 2]])

    def test_spring_errors_name_the_element(self):
        with pytest.raises(ValueError, match="element 7"):
            Spring(7, (1, 9), None, 1.0)
        with pytest.raises(ValueError, match="itself"):
            Spring(8, (1, 3), (1, 3), 1.0)

    @settings(max_examples=25, deadline=None)
    @given(r=st.tuples(unit, unit, unit), mass=st.floats(0.01, 10), axis=st.integers(0, 2))
    def test_conm2_offset_rotary_inertia(self, r, mass, axis):
        r = np.array(r)
        J = np.diag([0.1, 0.2, 0.3])
        m = FEModel()
        m.add_node(1, (0, 0, 0))
        el = LumpedMass(1, 1, mass, inertia=J, offset=r)
        Mm = el.matrices(AssemblyContext(m)).M
        e = np.eye(3)[axis]
        # kinetic energy of a unit rotation about a basic axis: J_axis + m |e × r|²
        u = np.concatenate([np.zeros(3), e])
        assert u @ Mm @ u == pytest.approx(J[axis, axis] + mass * np.sum(np.cross(e, r) ** 2), rel=1e-12)
        assert np.allclose(Mm, Mm.T)
        assert Mm[:3, :3] == pytest.approx(mass * np.eye(3))

    def test_conm2_axes_rotate_inertia(self):
        c, s = np.cos(0.3), np.sin(0.3)
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        m = FEModel()
        m.add_node(1, (0, 0, 0))
        M = LumpedMass(1, 1, 1.0, inertia=[1.0, 2.0, 3.0], axes=R).matrices(AssemblyContext(m)).M
        np.testing.assert_allclose(M[3:, 3:], R @ np.diag([1, 2, 3]) @ R.T)


class TestSections:
    def test_rectangle_and_tube_properties(self):
        s = RectangularSection(0.1, 0.01)
        assert s.Iy == pytest.approx(0.1 * 0.01 ** 3 / 12)
        assert s.Iz == pytest.approx(0.01 * 0.1 ** 3 / 12)
        # Roark: J = a c^3 (1/3 - 0.21 (c/a)(1 - (c/a)^4/12)); for c/a = 0.1 = 0.3123335 a c³
        assert s.J == pytest.approx(0.1 * 1e-6 * 0.3123335, rel=1e-6)
        t = TubeSection(0.01, 0.008)
        assert t.J == pytest.approx(2 * t.Iy)
        assert t.A == pytest.approx(np.pi / 4 * (1e-4 - 6.4e-5))

    def test_bad_section_and_material_values(self):
        with pytest.raises(ValueError, match="both sides"):
            RectangularSection(0.0, 0.01)
        with pytest.raises(ValueError, match="do > di"):
            TubeSection(0.01, 0.02)
        with pytest.raises(ValueError, match="positive modulus"):
            Material(1, E=-1.0)
