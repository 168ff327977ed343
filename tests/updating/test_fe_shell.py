"""Flat shell elements Quad4 (MITC4) and Tria3 (DKT): plate frequencies vs closed forms, rigid-body modes,
patch tests, CQUAD4/CTRIA3/PSHELL bulk data round trip, thickness/modulus derivatives, bad input."""
import numpy as np
import pytest
import scipy.linalg as sla

from modalab.core.errors import BulkDataError, ModalabValueError
from updating.fe.bulk import build_model, read_bdf, to_bulk, write_bdf
from updating.fe import (BeamProperty, FEModel, GeneralSection, Material, Parameter, ParametricFEModel, Quad4,
                         ShellProperty, Tria3, eigen_sparse)
from updating.fe.sensitivity import frequency_sensitivities, solve_modes

E, NU, RHO = 210e9, 0.3, 7850.0


def plate(n=12, a=0.5, b=0.5, t=0.005, tri=False, bc="ss", coupled=True, R=None, distort=0.0, seed=0,
          origin=(0.0, 0.0, 0.0), cd_rng=None):
    """n×n mesh of an a×b plate (Quad4, or each quad split into two Tria3), optionally rotated by R and
    with interior nodes moved at random by up to ``distort`` times the element size.

    bc: 'ss' simply supported (w and the rotation about the edge held; in-plane DOFs u, v, θz held at every
    node so that only bending is left), 'cant' clamped along x = 0 (everything else free), 'free'.
    """
    m = FEModel("plate", coupled_mass=coupled)
    m.add_material(Material(1, E=E, nu=NU, rho=RHO))
    m.add_property(ShellProperty(1, 1, t))
    R = np.eye(3) if R is None else np.asarray(R)
    rng = np.random.default_rng(seed)

    def nid(i, j):
        return 1 + i + (n + 1) * j

    for j in range(n + 1):
        for i in range(n + 1):
            p = np.array([a * i / n, b * j / n, 0.0])
            if distort and 0 < i < n and 0 < j < n:
                p[:2] += rng.uniform(-distort, distort, 2) * np.array([a, b]) / n
            cd = None
            if cd_rng is not None and nid(i, j) % 3 == 0:
                cd = sla.expm(np.cross(np.eye(3), cd_rng.normal(size=3)))     # random CD axes
            m.add_node(nid(i, j), R @ p + np.asarray(origin), cd=cd)
    eid = 1
    for j in range(n):
        for i in range(n):
            q = (nid(i, j), nid(i + 1, j), nid(i + 1, j + 1), nid(i, j + 1))
            if tri:
                m.add_element(Tria3(eid, q[0], q[1], q[2], 1))
                m.add_element(Tria3(eid + 1, q[0], q[2], q[3], 1))
                eid += 2
            else:
                m.add_element(Quad4(eid, *q, 1))
                eid += 1
    for j in range(n + 1):
        for i in range(n + 1):
            c = ""
            if bc == "ss":
                c = "126"
                if i in (0, n):
                    c += "34"          # edge along y: w = 0 and θx = ∂w/∂y = 0
                if j in (0, n):
                    c += "35"          # edge along x: w = 0 and θy = −∂w/∂x = 0
            elif bc == "cant" and i == 0:
                c = "123456"
            if c:
                m.add_spc(nid(i, j), "".join(sorted(set(c))))
    return m


def freqs(m, k):
    s = m.system()
    w, _ = eigen_sparse(s.K, s.M, k, shift=-1.0)
    return w / (2 * np.pi)


def kirchhoff_ss(a, b, t, k):
    """ω_mn = π²(m²/a² + n²/b²)√(D/ρt), D = Et³/12(1−ν²) (Navier; Leissa 1969, NASA SP-160, ch. 4), in Hz."""
    D = E * t ** 3 / (12 * (1 - NU ** 2))
    w = sorted(np.pi ** 2 * (p ** 2 / a ** 2 + q ** 2 / b ** 2) * np.sqrt(D / (RHO * t))
               for p in range(1, 6) for q in range(1, 6))
    return np.array(w[:k]) / (2 * np.pi)


# ------------------------------------------------------- (a) simply supported plate
@pytest.mark.parametrize("tri, n, tol", [(False, 24, 0.015), (False, 12, 0.035), (True, 16, 0.03),
                                         (True, 24, 0.015)])
def test_simply_supported_plate_vs_kirchhoff(tri, n, tol):
    # steel plate 0.5 × 0.5 m, t = 5 mm; consistent mass.  Measured errors: Quad4 12×12 +0.7/+2.7/+2.7/+3.0 %,
    # 24×24 +0.15/+0.6/+0.6/+0.6 % (O(h²)); Tria3 (split quads) 24×24 +0.2/+0.5/+0.7/+0.8 %
    f = freqs(plate(n=n, tri=tri), 4)
    ref = kirchhoff_ss(0.5, 0.5, 0.005, 4)
    err = f / ref - 1
    assert np.all(np.abs(err) < tol), err
    assert np.all(err > -0.002), err       # consistent mass, conforming-like element: from above
    # (1,2)/(2,1) pair: equal for the symmetric quad mesh, split by the diagonals of the triangles
    assert f[2] == pytest.approx(f[1], rel=1e-2 if tri else 1e-9)


def test_quad4_converges_at_second_order():
    ref = kirchhoff_ss(0.5, 0.5, 0.005, 4)
    e12 = freqs(plate(n=12), 4) / ref - 1
    e24 = freqs(plate(n=24), 4) / ref - 1
    ratio = e12 / e24
    assert np.all((ratio > 3.0) & (ratio < 6.0)), ratio          # h² convergence (4 up to shear effects)


def test_lumped_mass_plate():
    m = plate(n=12, coupled=False)
    M = m.assemble().M
    rot = [k for k, d in enumerate(m.dofs) if d.axis > 3]
    assert abs(M[rot][:, rot]).max() == 0                    # Nastran-style: no rotary inertia
    assert M.sum() == pytest.approx(3 * RHO * 0.005 * 0.25, rel=1e-12)   # total mass in x, y and z
    f = freqs(m, 4)
    err = f / kirchhoff_ss(0.5, 0.5, 0.005, 4) - 1
    assert np.all(np.abs(err) < 0.02), err      # lumped mass: from below, −0.4/−0.15/−0.15/−1.6 %
    assert err[0] < 0


# ------------------------------------------------------- (b) cantilever plate
# λ² = ωa²√(ρt/D) of a square plate clamped on one edge, ν = 0.3 (Leissa 1969, NASA SP-160, ch. 4, C-F-F-F)
LEISSA_CANTILEVER = np.array([3.492, 8.525, 21.43, 27.33, 31.11])


@pytest.mark.parametrize("tri", [False, True])
def test_cantilever_plate_vs_leissa(tri):
    a, t = 0.5, 0.005
    D = E * t ** 3 / (12 * (1 - NU ** 2))
    w = 2 * np.pi * freqs(plate(n=12, tri=tri, t=t, bc="cant"), 5)
    lam = w * a ** 2 * np.sqrt(RHO * t / D)
    err = lam / LEISSA_CANTILEVER - 1
    assert np.all(np.abs(err) < 0.02), (lam, err)


def test_mixed_quad_and_triangle_mesh():
    # Quad4 (MITC4) and Tria3 (DKT) share w, θx, θy conventions: a mesh mixing them is as good as either
    a, t, n = 0.5, 0.005, 12
    m = plate(n=n, t=t, bc="cant")
    quads = [e for e in m.elements.values() if (e.eid - 1) % n >= n // 2]     # right half → triangles
    nxt = max(m.elements) + 1
    for q in quads:
        del m.elements[q.eid]
        m.add_element(Tria3(q.eid, q.n1, q.n2, q.n3, 1))
        m.add_element(Tria3(nxt, q.n1, q.n3, q.n4, 1))
        nxt += 1
    D = E * t ** 3 / (12 * (1 - NU ** 2))
    lam = 2 * np.pi * freqs(m, 5) * a ** 2 * np.sqrt(RHO * t / D)
    err = lam / LEISSA_CANTILEVER - 1
    assert np.all(np.abs(err) < 0.02), (lam, err)


def test_cantilever_in_a_rotated_plane_gives_the_same_frequencies():
    R = sla.expm(np.array([[0, -0.4, 0.7], [0.4, 0, -0.3], [-0.7, 0.3, 0]]))
    for tri in (False, True):
        f0 = freqs(plate(n=6, tri=tri, bc="cant"), 8)
        f1 = freqs(plate(n=6, tri=tri, bc="cant", R=R), 8)
        np.testing.assert_allclose(f1, f0, rtol=1e-9)


def test_nodes_with_displacement_systems_give_the_same_frequencies():
    f0 = freqs(plate(n=4, bc="cant"), 8)
    m = plate(n=4, bc="cant", cd_rng=np.random.default_rng(1))
    assert sum(nd.cd is not None for nd in m.nodes.values()) == 8
    np.testing.assert_allclose(freqs(m, 8), f0, rtol=1e-9)


# ------------------------------------------------------- (c) thin-plate limit: no shear locking
@pytest.mark.parametrize("tri, n", [(False, 24), (True, 16)])
def test_no_shear_locking_in_the_thin_limit(tri, n):
    a = 0.5
    t_thin = a / 1000
    f_thin = freqs(plate(n=n, tri=tri, t=t_thin), 4)
    err = f_thin / kirchhoff_ss(a, a, t_thin, 4) - 1
    assert np.all(np.abs(err) < 0.02), err
    # bending frequencies scale with t: a locking element would be much stiffer when thin
    f_thick = freqs(plate(n=n, tri=tri, t=a / 100), 4)
    np.testing.assert_allclose(f_thin * 10, f_thick, rtol=2e-3)


# ------------------------------------------------------- (d) rigid-body modes
@pytest.mark.parametrize("tri", [False, True])
def test_free_mesh_has_exactly_six_rigid_body_modes(tri):
    R = sla.expm(np.array([[0, -0.3, 0.5], [0.3, 0, -0.2], [-0.5, 0.2, 0]]))
    m = plate(n=3, a=0.3, b=0.24, tri=tri, bc="free", R=R, distort=0.3, origin=(1.0, 2.0, 3.0))
    s = m.system()
    lam = sla.eigh(s.K.toarray(), s.M.toarray(), eigvals_only=True)
    rel = lam / lam.max()
    assert np.all(np.abs(rel[:6]) < 1e-10), rel[:8]
    assert rel[6] > 1e-8, rel[:8]


# ------------------------------------------------------- (e) patch tests
def _patch_field(m, R, grad, curv):
    """Nodal displacement vector (model DOF order) of u = grad·x (in-plane, local) and w = ½ xᵀ curv x."""
    dofs = m.dofs
    u = np.zeros(len(dofs))
    (a, b), (c, d) = grad
    kx, ky, kxy = curv
    for k, dof in enumerate(dofs):
        x, y, _ = R.T @ m.nodes[dof.node].xyz
        loc_t = np.array([a * x + b * y, c * x + d * y, 0.5 * kx * x * x + 0.5 * ky * y * y + kxy * x * y])
        loc_r = np.array([ky * y + kxy * x, -(kx * x + kxy * y), 0.5 * (c - b)])
        vals = np.concatenate([R @ loc_t, R @ loc_r])
        u[k] = vals[dof.axis - 1]
    return u


@pytest.mark.parametrize("tri", [False, True])
@pytest.mark.parametrize("kind", ["membrane", "bending"])
def test_constant_strain_patch_of_distorted_elements(tri, kind):
    R = sla.expm(np.array([[0, -0.2, 0.6], [0.2, 0, -0.5], [-0.6, 0.5, 0]]))
    a, b, t = 0.3, 0.2, 0.004
    m = plate(n=4, a=a, b=b, t=t, tri=tri, bc="free", R=R, distort=0.35, seed=3)
    if kind == "membrane":
        grad, curv = ((1e-3, 4e-4), (-2e-4, -5e-4)), (0.0, 0.0, 0.0)
        eps = np.array([1e-3, -5e-4, 4e-4 - 2e-4])
        Dmat = E * t / (1 - NU ** 2)
    else:
        grad, curv = ((0.0, 0.0), (0.0, 0.0)), (0.02, -0.01, 0.005)
        eps = -np.array([0.02, -0.01, 2 * 0.005])
        Dmat = E * t ** 3 / (12 * (1 - NU ** 2))
    Dm = Dmat * np.array([[1, NU, 0], [NU, 1, 0], [0, 0, (1 - NU) / 2]])
    u = _patch_field(m, R, grad, curv)
    K = m.assemble().K
    f = K @ u
    energy = 0.5 * u @ f
    exact = 0.5 * eps @ Dm @ eps * a * b
    assert energy == pytest.approx(exact, rel=1e-9)
    interior = [k for k, d in enumerate(m.dofs) if 0 < (d.node - 1) % 5 < 4 and 0 < (d.node - 1) // 5 < 4]
    assert interior
    scale = np.abs(f).max()
    assert np.abs(f[interior]).max() < 1e-9 * scale


def test_batched_assembly_matches_element_by_element():
    # two properties on two materials, distorted elements: the vectorised kernel must pick each element's values
    from updating.fe.assembly import assemble
    for tri in (False, True):
        m = plate(n=3, tri=tri, bc="free", distort=0.3)
        m.add_material(Material(2, E=70e9, nu=0.33, rho=2700, ge=0.03))
        m.add_property(ShellProperty(2, 2, 0.002, nsm=1.2))
        for eid in list(m.elements)[::2]:
            el = m.elements[eid]
            m.elements[eid] = type(el)(el.eid, *el.nodes, 2)
        ref = {k: 0 for k in ("K", "M", "D")}
        for el in m.elements.values():
            part = assemble(m, elements=[el])
            for k in ref:
                ref[k] = ref[k] + (getattr(part, k) if getattr(part, k) is not None else 0)
        full = assemble(m)
        for k in ref:
            np.testing.assert_allclose(getattr(full, k).toarray(), ref[k].toarray(),
                                       atol=1e-12 * abs(full.K).max(), err_msg=k)


# ------------------------------------------------------- structural damping from the material
def test_material_ge_gives_hysteretic_matrix():
    m = plate(n=2, bc="free")
    m.materials[1] = Material(1, E=E, nu=NU, rho=RHO, ge=0.02)
    mats = m.assemble()
    np.testing.assert_allclose(mats.D.toarray(), 0.02 * mats.K.toarray(), atol=1e-12 * abs(mats.K).max())


# ------------------------------------------------------- (f) bulk data round trip
def _deck(n=4):
    lines = ["SOL 103", "CEND", "SPC = 1", "BEGIN BULK", "PARAM,COUPMASS,1", "MAT1,1,2.1+11,,.3,7850.,,,.01",
             "$ name: skin", "PSHELL,1,1,.005,1,,1,,1.5", "PSHELL,2,1,.004,1"]

    def nid(i, j):
        return 1 + i + (n + 1) * j

    for j in range(n + 1):
        for i in range(n + 1):
            lines.append(f"GRID,{nid(i, j)},,{round(0.1 * i, 6)},{round(0.08 * j, 6)},{round(0.01 * i * j, 6)}")
    e = 1
    for j in range(n):
        for i in range(n):
            q = (nid(i, j), nid(i + 1, j), nid(i + 1, j + 1), nid(i, j + 1))
            if i < 2:
                lines.append(f"CQUAD4,{e},1,{q[0]},{q[1]},{q[2]},{q[3]}")
                e += 1
            else:
                lines.append(f"CTRIA3,{e},2,{q[0]},{q[1]},{q[2]}")
                lines.append(f"CTRIA3,{e + 1},2,{q[0]},{q[2]},{q[3]},0.")
                e += 2
    lines.append("SPC1,1,123456," + ",".join(str(nid(0, j)) for j in range(n + 1)))
    lines.append(f"CONM2,100,{nid(n, n)},,0.2")
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


def test_bulk_round_trip_identical_frequencies():
    a = read_bdf(_deck())
    assert sum(type(c).__name__ == "Cquad4" for c in a.elements.values()) == 8
    assert sum(type(c).__name__ == "Ctria3" for c in a.elements.values()) == 16
    m = build_model(a)
    assert isinstance(m.elements[1], Quad4) and isinstance(m.elements[3], Tria3)
    assert m.properties[1].name == "skin" and m.properties[1].nsm == 1.5
    f0 = m.modes(10).freq_hz
    for fmt in ("small", "large", "free"):
        b = read_bdf(write_bdf(to_bulk(m, template=a), format=fmt))
        assert b == a
        np.testing.assert_allclose(build_model(b).modes(10).freq_hz, f0, rtol=1e-12)
        c = read_bdf(write_bdf(a, format=fmt))                  # plain read → write → read
        assert c == a
    # without a template: everything rebuilt from the model objects
    fresh = read_bdf(write_bdf(to_bulk(m)))
    np.testing.assert_allclose(build_model(fresh).modes(10).freq_hz, f0, rtol=1e-12)


def test_updated_thickness_is_exported():
    a = read_bdf(_deck())
    m = build_model(a)
    pm = ParametricFEModel(m, [Parameter("t_skin", "t", properties=["skin"]),
                               Parameter("E", "E", properties=[2])])
    mu = pm.model_at(np.array([1.1, 0.95]))
    b = read_bdf(write_bdf(to_bulk(mu, template=a)))
    assert b.properties[1].t == pytest.approx(0.0055, rel=1e-12)
    assert b.properties[2].mid1 != 1 and b.materials[b.properties[2].mid1].E == pytest.approx(0.95 * 2.1e11)
    np.testing.assert_allclose(build_model(b).modes(8).freq_hz, mu.modes(8).freq_hz, rtol=1e-10)


@pytest.mark.parametrize("card, pattern", [
    ("CQUAD4,1,1,1,2,3,4,,.002", r"ZOFFS = 0.002"),
    ("CQUAD4,1,1,1,2,3,4,30.", r"THETA = 30.0"),
    ("CQUAD4,1,1,1,2,3,4,7", r"MCID = 7"),
    ("CQUAD4,1,1,1,2,3,4\n,,,.01,.01,.01,.01", r"corner thicknesses"),
])
def test_unsupported_shell_fields_are_rejected_by_build_model(card, pattern):
    deck = ("MAT1,1,2.1+11,,.3,7850.\nPSHELL,1,1,.005,1,,1\nGRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\n"
            "GRID,3,,1.,1.,0.\nGRID,4,,0.,1.,0.\n" + card + "\n")
    b = read_bdf(deck)
    assert read_bdf(write_bdf(b)) == b                     # still read and written back
    with pytest.raises(BulkDataError, match=pattern) as ei:
        build_model(b)
    assert "CQUAD4 1" in str(ei.value)


@pytest.mark.parametrize("pshell, pattern", [
    ("PSHELL,1,1,.005", r"MID2 blank"),
    ("PSHELL,1,1,.005,2,,1", r"MID2 = 2 differs"),
    ("PSHELL,1,1,.005,1,,1\n,,,2", r"MID4"),
])
def test_unsupported_pshell_is_rejected(pshell, pattern):
    deck = ("MAT1,1,2.1+11,,.3,7850.\nMAT1,2,7.+10,,.3,2700.\n" + pshell +
            "\nGRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\nGRID,3,,1.,1.,0.\nCTRIA3,1,1,1,2,3\n")
    with pytest.raises(BulkDataError, match=pattern):
        build_model(read_bdf(deck))


def test_shell_card_field_errors():
    with pytest.raises(BulkDataError, match="repeat a grid"):
        read_bdf("CQUAD4,1,1,1,2,2,4\n", xref=False)
    with pytest.raises(BulkDataError, match="PSHELL"):
        read_bdf("GRID,1\nGRID,2\nGRID,3\nCTRIA3,1,1,1,2,3\nPROD,1,1,1.\nMAT1,1,1.,,.3\n")


# ------------------------------------------------------- (g) derivatives
@pytest.mark.parametrize("tri", [False, True])
def test_frequency_derivatives_wrt_thickness_and_modulus(tri):
    m = plate(n=6, tri=tri, bc="cant")
    m.properties[1] = ShellProperty(1, 1, 0.005, nsm=2.0)
    pars = [Parameter("t", "t", properties=[1]), Parameter("E", "E", materials=[1]),
            Parameter("nu", "nu", properties=[1]), Parameter("rho", "rho", materials=[1]),
            Parameter("nsm", "nsm", properties=[1], mode="value")]
    pm = ParametricFEModel(m, pars)
    modes = [0, 1, 2, 3]
    S = frequency_sensitivities(pm, modes=modes)
    for i in range(len(pars)):
        h = 1e-3 * max(1.0, abs(pm.p0[i]))
        p = pm.p0.copy()
        p[i] += h
        fp = np.sqrt(solve_modes(pm, p, 6).lam[modes]) / (2 * np.pi)
        p[i] -= 2 * h
        fm = np.sqrt(solve_modes(pm, p, 6).lam[modes]) / (2 * np.pi)
        fd = (fp - fm) / (2 * h)
        np.testing.assert_allclose(S[:, i], fd, rtol=2e-5, atol=1e-6 * np.abs(S).max(), err_msg=pars[i].name)
    # bending ∝ t³, mass ∝ t: ∂f/∂(t factor) ≈ f · (1 − nsm share) — a thickness that only scaled
    # linearly would give about half of it
    f = np.sqrt(solve_modes(pm, None, 6).lam[modes]) / (2 * np.pi)
    share = 2.0 / (RHO * 0.005 + 2.0)
    np.testing.assert_allclose(S[:, 0], f * (1 + share / 2), rtol=0.02)


def test_thickness_parameter_is_checked():
    m = plate(n=2, bc="free")
    with pytest.raises(ModalabValueError, match="no field 'h'"):
        ParametricFEModel(m, [Parameter("h", "h", properties=[1])])


# ------------------------------------------------------- bad input
def _one(elem, xyz, prop=None):
    m = FEModel("one")
    m.add_material(Material(1, E=E, nu=NU, rho=RHO))
    m.add_property(prop or ShellProperty(1, 1, 0.005))
    for k, x in enumerate(xyz):
        m.add_node(k + 1, x)
    m.add_element(elem)
    return m


def test_negative_thickness():
    with pytest.raises(ModalabValueError, match=r"t = -0.001"):
        ShellProperty(7, 1, -0.001)


def test_degenerate_quad_zero_area():
    m = _one(Quad4(5, 1, 2, 3, 4, 1), [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0)])
    with pytest.raises(ModalabValueError, match=r"element 5 \(Quad4\).*zero area"):
        m.assemble()


def test_degenerate_triangle():
    m = _one(Tria3(6, 1, 2, 3, 1), [(0, 0, 0), (1, 1, 1), (2, 2, 2)])
    with pytest.raises(ModalabValueError, match=r"element 6 \(Tria3\).*zero area"):
        m.assemble()


def test_warped_quad():
    m = _one(Quad4(8, 1, 2, 3, 4, 1), [(0, 0, 0), (1, 0, 0.2), (1, 1, 0), (0, 1, 0.2)])
    with pytest.raises(ModalabValueError, match=r"element 8 \(Quad4\).*warped: ratio .* = 0.1 > 0.05"):
        m.assemble()
    ok = _one(Quad4(8, 1, 2, 3, 4, 1), [(0, 0, 0), (1, 0, 0.02), (1, 1, 0), (0, 1, 0.02)])
    assert ok.assemble().K.nnz > 0


def test_non_convex_or_misordered_quad():
    m = _one(Quad4(9, 1, 2, 3, 4, 1), [(0, 0, 0), (1, 1, 0), (1, 0, 0), (0, 1, 0)])
    with pytest.raises(ModalabValueError, match=r"element 9 \(Quad4\)"):
        m.assemble()


def test_shell_needs_a_shell_property():
    m = _one(Quad4(3, 1, 2, 3, 4, 1), [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
             prop=BeamProperty(1, 1, GeneralSection(1e-4, 1e-8, 1e-8, 2e-8)))
    with pytest.raises(ModalabValueError, match="element 3 .*ShellProperty"):
        m.assemble()
