"""Updating parameters: exact derivative matrices vs central differences (updating.fe.parameters)."""
import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings, strategies as st

from updating.fe import (Beam3D, BeamProperty, Damper, FEModel, GeneralSection, LumpedMass, Material, Parameter,
                         ParametricFEModel, RectangularSection, Spring, Timoshenko3D, TubeSection, eigen_dense)
from updating.fe.parametric import Derivative, ParametricModel
from updating.fe.models.beams import thesis_beam, thesis_beam_parameters


def build(element=Beam3D):
    """A small free-free frame with every kind of parameter target."""
    m = FEModel("param test")
    m.add_material(Material(1, E=70e9, nu=0.31, rho=2700, ge=0.01))
    m.add_material(Material(2, E=200e9, nu=0.3, rho=7800))
    m.add_property(BeamProperty(1, 1, RectangularSection(0.05, 0.008), name="plate"))
    m.add_property(BeamProperty(2, 2, TubeSection(0.02, 0.016), name="tube", nsm=0.3))
    m.add_property(BeamProperty(3, 1, GeneralSection(A=4e-4, Iy=2e-9, Iz=5e-9, J=4e-9, ky=0.8, kz=0.7),
                                name="general", ge=0.03))
    xs = [(0, 0, 0), (0.2, 0, 0), (0.4, 0.05, 0), (0.6, 0.05, 0.1), (0.8, 0.0, 0.1), (1.0, 0.0, 0.0)]
    for i, x in enumerate(xs):
        m.add_node(i + 1, x)
    for i, pid in enumerate([1, 1, 2, 2, 3]):
        m.add_element(element(i + 1, i + 1, i + 2, pid, (0.1, 0.3, 1.0)))
    m.add_element(Spring(10, (1, 3), None, 500.0, ge=0.05, group="susp"))
    m.add_element(Spring(11, (6, 3), None, 500.0, ge=0.05, group="susp"))
    m.add_element(Spring(12, (2, 5), (5, 5), 80.0, group="torsion"))
    m.add_element(Damper(13, (3, 2), None, 4.0, group="dash"))
    m.add_element(LumpedMass(14, 4, 0.3, inertia=[1e-4, 2e-4, 3e-4], offset=(0.0, 0.02, 0.01), group="mass"))
    m.add_node(7, (0.5, 0.1, 0.2))
    m.add_rbe2(20, 3, [7])
    m.add_element(LumpedMass(15, 7, 0.1, group="mass"))
    m.global_ge = 0.004
    m.rayleigh = (0.3, 2e-6)
    return m


PARAMS = [
    Parameter("E_plate", "E", properties=["plate"]),
    Parameter("t_plate", "h", properties=["plate"]),                       # I ∝ t³, J non-linear in t
    Parameter("b_plate", "b", properties=["plate"], mode="value"),
    Parameter("rho_mat2", "rho", materials=[2]),
    Parameter("do_tube", "do", properties=["tube"]),
    Parameter("di_tube", "di", properties=["tube"], mode="value"),
    Parameter("nsm_tube", "nsm", properties=["tube"]),
    Parameter("nu_plate", "nu", properties=["plate"]),
    Parameter("Iy_general", "Iy", properties=["general"]),
    Parameter("ge_general", "ge", properties=["general"], mode="value"),
    Parameter("ge_mat1", "ge", materials=[1]),
    Parameter("k_susp", "k", groups=["susp"]),
    Parameter("ge_susp", "ge", groups=["susp"], mode="value"),
    Parameter("k_torsion", "k", elements=[12], mode="value"),
    Parameter("c_dash", "c", groups=["dash"]),
    Parameter("m_mass", "mass", groups=["mass"]),
    Parameter("J_mass", "inertia", elements=[14]),
    Parameter("G", "global_ge", mode="value"),
    Parameter("alpha", "rayleigh_alpha", mode="value"),
    Parameter("beta", "rayleigh_beta"),
]

# Scale factors that keep a section valid.  The tube is do=0.02, di=0.016: the outer diameter may shrink
# only while do > di (factor > 0.8) with room for the central-difference step, so 0.85; the inner one may
# grow up to 1.2 (0.0192 < 0.02).  Other parameters take any factor in [0.7, 1.2].
SCALE_RANGE = {"do_tube": (0.85, 1.2), "di_tube": (0.7, 1.2)}


def central_difference(pm, p, i, rel=1e-5):
    h = rel * max(abs(p[i]), 1e-3)
    pp, pm_ = p.copy(), p.copy()
    pp[i] += h
    pm_[i] -= h
    a, b = pm.structure(pp), pm.structure(pm_)
    out = {}
    for k in "KMCD":
        A, B = getattr(a, k), getattr(b, k)
        if A is None and B is None:
            out[k] = None
        else:
            z = sp.csr_matrix(pm.structure(p).K.shape)
            out[k] = ((A if A is not None else z) - (B if B is not None else z)) / (2 * h)
    return out


def rel_err(exact, fd, floor):
    """max |exact − fd| / max(max |exact|, floor); ``floor`` is the size below which a derivative counts as 0."""
    e = exact.toarray() if exact is not None else 0.0
    f = fd.toarray() if fd is not None else 0.0
    return np.abs(e - f).max(initial=0.0) / max(np.abs(e).max(initial=0.0), floor)


@pytest.fixture(scope="module", params=[Beam3D, Timoshenko3D], ids=["EB", "Timoshenko"])
def pm(request):
    return ParametricFEModel(build(request.param), PARAMS)


class TestDerivatives:
    def test_protocol(self, pm):
        assert isinstance(pm, ParametricModel)
        assert pm.parameter_names == [p.name for p in PARAMS]
        assert pm.structure().n_dof == len(pm.dofs)
        ds = pm.derivatives()
        assert len(ds) == len(PARAMS) and all(isinstance(d, Derivative) for d in ds)
        # value-mode parameters start at the physical nominal value, factors at 1
        assert pm.p0[PARAMS.index(next(p for p in PARAMS if p.name == "b_plate"))] == pytest.approx(0.05)
        assert pm.p0[0] == 1.0

    def test_all_derivatives_match_central_differences(self, pm):
        # central differences of a smooth function: truncation error O(h²) ≈ 1e-10 here
        rng = np.random.default_rng(0)
        p = pm.p0 * (1 + 0.1 * rng.uniform(-1, 1, pm.n_params))
        ds = pm.derivatives(p)
        for i, (par, d) in enumerate(zip(PARAMS, ds)):
            fd = central_difference(pm, p, i)
            s0 = pm.structure(p)
            for k in "KMCD":
                A = getattr(s0, k)
                # differences carry rounding noise ~1e-11·|A|/|p|: a derivative entry smaller than
                # 1e-3·|A|/|p| is judged against that floor instead of its own (tiny) size
                floor = 1e-3 * abs(A).max() / max(abs(p[i]), 1e-3) if A is not None else 1e-300
                err = rel_err(getattr(d, "d" + k), fd[k], floor)
                assert err < 1e-6, (par.name, k, err)
            assert any(getattr(d, "d" + k) is not None for k in "KMCD"), par.name

    def test_thickness_cubed_relation_exact(self):
        # a single EB beam along X, v = +Y: local z = Z, Iy = b t³/12 → the x–z bending block ∝ t³
        m = FEModel()
        m.add_material(Material(1, E=70e9, nu=0.3, rho=2700))
        m.add_property(BeamProperty(1, 1, RectangularSection(0.05, 0.01), name="s"))
        m.add_node(1, (0, 0, 0))
        m.add_node(2, (0.5, 0, 0))
        m.add_element(Beam3D(1, 1, 2, 1, (0, 1, 0)))
        pm = ParametricFEModel(m, [Parameter("t", "h", properties=["s"], mode="value")])
        t = 0.013
        dK = pm.derivatives([t])[0].dK.toarray()
        K = pm.structure([t]).K.toarray()
        iz = [i for i, d in enumerate(pm.dofs) if d.axis in (3, 5)]
        np.testing.assert_allclose(dK[np.ix_(iz, iz)], 3 / t * K[np.ix_(iz, iz)], rtol=1e-13)
        iy = [i for i, d in enumerate(pm.dofs) if d.axis in (2, 6)]   # Iz = t b³/12 ∝ t
        np.testing.assert_allclose(dK[np.ix_(iy, iy)], 1 / t * K[np.ix_(iy, iy)], rtol=1e-13)

    def test_young_modulus_factor_derivative_is_the_group_stiffness(self):
        # K is linear in E (G follows E through ν): ∂K/∂p at p = 1 is the plate group's K exactly
        m = build()
        pm = ParametricFEModel(m, [Parameter("E", "E", properties=["plate"])])
        dK = pm.derivatives()[0].dK
        plate = FEModel.copy(m)
        plate.elements = {e: el for e, el in m.elements.items() if getattr(el, "pid", None) == 1}
        from updating.fe import assemble
        Kp = pm.reduction.reduce(assemble(plate, include_global=False).K)
        np.testing.assert_allclose(dK.toarray(), Kp.toarray(), rtol=1e-12, atol=1e-12 * abs(Kp).max())
        dD = pm.derivatives()[0].dD            # ge_mat1 (0.01) + G (0.004) on the same elements
        np.testing.assert_allclose(dD.toarray(), 0.014 * Kp.toarray(), rtol=1e-10, atol=1e-9 * abs(Kp).max())

    @settings(max_examples=12, deadline=None)
    @given(it=st.integers(0, len(PARAMS) - 1).flatmap(
        lambda i: st.tuples(st.just(i), st.floats(*SCALE_RANGE.get(PARAMS[i].name, (0.7, 1.2))))))
    def test_eigenvalue_sensitivity_consistent(self, it):
        # dλ/dp = φᵀ(∂K/∂p − λ ∂M/∂p)φ (Fox & Kapoor) agrees with differenced eigenvalues
        i, t = it
        pm = ParametricFEModel(build(), [PARAMS[i]])
        p = pm.p0 * t
        s = pm.structure(p)
        w, phi = eigen_dense(s.K, s.M, 9)
        d = pm.derivatives(p)[0]
        lam = w[8] ** 2
        v = phi[:, 8]
        dK = d.dK.toarray() if d.dK is not None else 0
        dM = d.dM.toarray() if d.dM is not None else 0
        analytic = v @ ((dK - lam * dM) @ v) if (d.dK is not None or d.dM is not None) else 0.0
        h = 1e-4 * max(abs(p[0]), 1e-3)
        lp = []
        for sgn in (1, -1):
            q = p.copy()
            q[0] += sgn * h
            sq = pm.structure(q)
            lp.append(eigen_dense(sq.K, sq.M, 9)[0][8] ** 2)
        fd = (lp[0] - lp[1]) / (2 * h)
        assert analytic == pytest.approx(fd, rel=1e-5, abs=1e-7 * lam / max(abs(p[0]), 1e-3))


class TestParameterErrors:
    def test_bad_selectors_and_fields(self):
        m = build()
        with pytest.raises(ValueError, match="no field 'h'"):
            ParametricFEModel(m, [Parameter("x", "h", properties=["tube"])])
        with pytest.raises(ValueError, match="no property is named 'wing'"):
            ParametricFEModel(m, [Parameter("x", "E", properties=["wing"])])
        with pytest.raises(ValueError, match="exactly one selector"):
            Parameter("x", "E")
        with pytest.raises(ValueError, match="no updatable field 'k'"):
            ParametricFEModel(m, [Parameter("x", "k", elements=[14])])
        with pytest.raises(ValueError, match="different nominal"):
            ParametricFEModel(m, [Parameter("x", "E", materials=[1, 2], mode="value")])
        with pytest.raises(ValueError, match="duplicate parameter names"):
            ParametricFEModel(m, [Parameter("x", "E", materials=[1]), Parameter("x", "rho", materials=[1])])
        with pytest.raises(ValueError, match="mode"):
            Parameter("x", "E", materials=[1], mode="scale")

    def test_model_is_not_modified(self):
        m = build()
        pm = ParametricFEModel(m, PARAMS)
        K0 = m.assemble().K.toarray()
        pm.structure(pm.p0 * 1.3)
        pm.derivatives(pm.p0 * 1.3)
        np.testing.assert_array_equal(m.assemble().K.toarray(), K0)
        assert m.material(1).E == 70e9


class TestThesisBeamParameters:
    def test_element_multipliers_reproduce_pseudo_experiment_materials(self):
        ana = thesis_beam("analytical", cord_stiffness=None)
        pars = thesis_beam_parameters(ana)
        assert len(pars) == 18 and pars[0].name == "E_e1"
        pm = ParametricFEModel(ana, pars)
        from updating.fe.models.beams import THESIS_TABLE4_RATIOS
        p = np.array([r[0] for r in THESIS_TABLE4_RATIOS] + [r[1] for r in THESIS_TABLE4_RATIOS])
        s = pm.structure(p)
        # same as the experimental model built with the analytical diameters
        exp = thesis_beam("analytical", cord_stiffness=None)
        for i, (rE, rr, _) in enumerate(THESIS_TABLE4_RATIOS):
            mat = exp.materials[i + 1]
            exp.materials[i + 1] = Material(i + 1, E=mat.E * rE, nu=mat.nu, rho=mat.rho * rr)
        se = exp.structure()
        np.testing.assert_allclose(s.K.toarray(), se.K.toarray(), rtol=1e-12)
        np.testing.assert_allclose(s.M.toarray(), se.M.toarray(), rtol=1e-12)
        assert len(pm.dofs) == 20
