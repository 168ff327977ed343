"""Building FE models from bulk data: GARTEUR deck vs Python model, sections, COUPMASS, damping, systems."""
import math
from pathlib import Path

import numpy as np
import pytest

from modalab.core.errors import BulkDataError
from updating.fe.bulk import build_model, read_bdf, section_properties, to_bulk, write_bdf
from updating.fe import GeneralSection, ParametricFEModel, RectangularSection, TubeSection
from updating.fe.models.garteur import garteur_model, garteur_parameters

DATA = Path(__file__).parent / "data"
GARTEUR_BDF = Path(__file__).resolve().parents[2] / "updating" / "fe" / "models" / "garteur.bdf"


def mac_diag(a, b):
    return np.abs(np.sum(a * b, 0)) ** 2 / (np.sum(a * a, 0) * np.sum(b * b, 0))


# ---------------------------------------------------------------------- GARTEUR
class TestGarteur:
    @pytest.fixture(scope="class")
    @classmethod
    def models(cls):
        return build_model(read_bdf(GARTEUR_BDF)), garteur_model()

    def test_same_modes(self, models):
        mb, mp = models
        sb, sp = mb.modes(16), mp.modes(16)
        assert sb.dofs == sp.dofs
        fb, fp = sb.freq_hz[6:], sp.freq_hz[6:]          # 6 rigid-body modes first (free-free)
        assert np.all(sp.freq_hz[:6] < 1e-3 * fp[0])
        np.testing.assert_allclose(fb, fp, rtol=1e-8, err_msg="garteur.bdf no longer matches garteur_model(); "
                                   "if the Python model's defaults changed on purpose, regenerate the deck with "
                                   "write_bdf(to_bulk(garteur_model()), path) as its header says")
        mac = mac_diag(np.real(sb.shapes[:, 6:]), np.real(sp.shapes[:, 6:]))
        assert np.all(mac > 1 - 1e-8), mac

    def test_matrices_identical(self, models):
        mb, mp = models
        ab, ap = mb.assemble(), mp.assemble()
        for A, B in ((ab.K, ap.K), (ab.M, ap.M)):
            assert abs(A - B).max() <= 1e-9 * abs(B).max()

    def test_named_groups_and_parameters(self, models):
        mb, mp = models
        names = ("E_wing", "t_wing", "rho_fuselage", "m_drum")
        pb = ParametricFEModel(mb, garteur_parameters(mb, names))
        pp = ParametricFEModel(mp, garteur_parameters(mp, names))
        for db, dp in zip(pb.derivatives(), pp.derivatives()):
            for A, B in ((db.dK, dp.dK), (db.dM, dp.dM)):
                if B is None:
                    assert A is None or abs(A).max() == 0
                else:
                    assert abs(A - B).max() <= 1e-9 * abs(B).max()
        assert isinstance(mb.prop(2).section, RectangularSection) and mb.prop(2).name == "wing"


# ------------------------------------------------------------------- sections
class TestSections:
    def test_bar(self):
        p = section_properties("BAR", [0.02, 0.01])           # DIM1 along z, DIM2 along y
        assert p["A"] == pytest.approx(2e-4)
        assert p["I1"] == pytest.approx(0.02 * 0.01 ** 3 / 12)
        assert p["I2"] == pytest.approx(0.01 * 0.02 ** 3 / 12)
        # Saint-Venant: square 0.1406 a^4 (Timoshenko & Goodier), thin strip b t^3/3 (1 - 0.63 t/b)
        assert section_properties("BAR", [1.0, 1.0])["J"] == pytest.approx(0.1406, rel=3e-3)
        assert section_properties("BAR", [0.01, 1.0])["J"] == pytest.approx(1e-6 / 3 * (1 - 0.63 * 0.01), rel=1e-3)

    def test_rod_and_tube(self):
        r = 0.01
        p = section_properties("ROD", [r])
        assert (p["A"], p["I1"], p["I2"], p["J"]) == pytest.approx(
            (math.pi * r ** 2, math.pi * r ** 4 / 4, math.pi * r ** 4 / 4, math.pi * r ** 4 / 2))
        ro, t = 0.05, 0.0005                                  # thin tube: I -> pi r^3 t, J -> 2 pi r^3 t
        p = section_properties("TUBE", [ro, ro - t])
        rm = ro - t / 2
        assert p["A"] == pytest.approx(2 * math.pi * rm * t, rel=1e-12)
        assert p["I1"] == pytest.approx(math.pi * rm ** 3 * t, rel=1e-4)
        assert p["J"] == pytest.approx(2 * math.pi * rm ** 3 * t, rel=1e-4)

    def test_box(self):
        b, h, t3, t4 = 0.1, 0.06, 0.004, 0.003
        p = section_properties("BOX", [b, h, t3, t4])
        hi = h - 2 * t3
        A = 2 * b * t3 + 2 * hi * t4
        I1 = 2 * (b * t3 ** 3 / 12 + b * t3 * ((h - t3) / 2) ** 2) + 2 * (t4 * hi ** 3 / 12)
        I2 = 2 * (t3 * b ** 3 / 12) + 2 * (hi * t4 ** 3 / 12 + hi * t4 * ((b - t4) / 2) ** 2)
        Am = (b - t4) * (h - t3)
        J = 4 * Am ** 2 / (2 * (b - t4) / t3 + 2 * (h - t3) / t4)     # Bredt
        assert (p["A"], p["I1"], p["I2"], p["J"]) == pytest.approx((A, I1, I2, J), rel=1e-12)

    def test_symmetric_i(self):
        h, w, tw, tf = 0.2, 0.1, 0.006, 0.01
        p = section_properties("I", [h, w, w, tw, tf, tf])
        hw = h - 2 * tf
        assert p["A"] == pytest.approx(2 * w * tf + hw * tw)
        assert p["I1"] == pytest.approx((w * h ** 3 - (w - tw) * hw ** 3) / 12)
        assert p["I2"] == pytest.approx(2 * tf * w ** 3 / 12 + hw * tw ** 3 / 12)
        assert p["J"] == pytest.approx((2 * w * tf ** 3 + hw * tw ** 3) / 3)

    def test_unsymmetric_i_centroid(self):
        # T-like I: bottom flange only thin; centroid by hand
        h, wb, wt, tw, tb, tt = 0.1, 0.02, 0.08, 0.005, 0.004, 0.01
        p = section_properties("I", [h, wb, wt, tw, tb, tt])
        parts = [(wb * tb, tb / 2), (tw * (h - tb - tt), tb + (h - tb - tt) / 2), (wt * tt, h - tt / 2)]
        A = sum(a for a, _ in parts)
        yc = sum(a * y for a, y in parts) / A
        I1 = (wb * tb ** 3 + tw * (h - tb - tt) ** 3 + wt * tt ** 3) / 12 + sum(a * (y - yc) ** 2 for a, y in parts)
        assert p["I1"] == pytest.approx(I1, rel=1e-12)

    def test_pbeaml_and_pbarl_sections_in_model(self):
        deck = ("GRID    1\nGRID    2               1.\nMAT1    1       7.+10           .3      2700.\n"
                "PBEAML  1       1               BOX\n        .1      .06     .004    .003\n"
                "PBARL   2       1               TUBE\n        .01     .008\n"
                "PBARL   3       1               I\n        .2      .1      .1      .006    .01     .01\n"
                "CBEAM   1       1       1       2       0.      0.      1.\n")
        m = build_model(read_bdf(deck))
        s1 = m.prop(1).section
        ref = section_properties("BOX", [0.1, 0.06, 0.004, 0.003])
        assert isinstance(s1, GeneralSection)
        assert (s1.A, s1.Iz, s1.Iy, s1.J) == pytest.approx((ref["A"], ref["I1"], ref["I2"], ref["J"]))
        assert m.prop(2).section == TubeSection(do=0.02, di=0.016)
        assert m.prop(3).section.Iz == pytest.approx(section_properties("I", [.2, .1, .1, .006, .01, .01])["I1"])

    def test_tapered_beam_rejected(self):
        deck = ("GRID    1\nGRID    2               1.\nMAT1    1       7.+10           .3\n"
                "PBEAML  1       1               BAR\n        .02     .01             YES     1.      .03     .01\n"
                "CBEAM   1       1       1       2       0.      0.      1.\n")
        with pytest.raises(BulkDataError, match=r"PBEAML 1.*tapered"):
            build_model(read_bdf(deck))


def cantilever(n=20, L=1.0, coupmass=1, dims=(".02", ".01"), extra=""):
    lines = [f"PARAM,COUPMASS,{coupmass}", "MAT1,1,7.+10,,.3,2700.",
             f"PBARL,1,1,,BAR\n,{dims[0]},{dims[1]}"]
    for i in range(n + 1):
        lines.append(f"GRID,{i + 1},,{L * i / n!r},0.,0.")
    for i in range(n):
        lines.append(f"CBAR,{i + 1},1,{i + 1},{i + 2},0.,1.,0.")
    lines.append("SPC1,1,123456,1")
    return "\n".join(lines) + "\n" + extra


class TestBeamMapping:
    def test_pbarl_bar_planes_against_euler_bernoulli(self):
        m = build_model(read_bdf(cantilever()))
        modes = m.modes(4)
        E, rho, b, h = 7e10, 2700.0, 0.02, 0.01            # DIM1 = 0.02 along z, DIM2 = 0.01 along y
        A = b * h
        f = lambda I: 1.8751040687 ** 2 / (2 * math.pi) * math.sqrt(E * I / (rho * A))  # noqa: E731
        f_y, f_z = f(b * h ** 3 / 12), f(h * b ** 3 / 12)  # I1 (plane 1, along y) and I2
        np.testing.assert_allclose(modes.freq_hz[:2], [f_y, f_z], rtol=1e-5)
        tip = [i for i, d in enumerate(modes.dofs) if d.node == 21]
        first = {modes.dofs[i].axis: abs(modes.shapes[i, 0]) for i in tip}
        assert first[2] > 1e3 * first[3]                   # first mode bends along basic y (plane 1)

    def test_cbar_with_shear_factors_is_timoshenko(self):
        deck = ("GRID    1\nGRID    2               1.\nMAT1    1       7.+10           .3\n"
                "PBAR    1       1       1.-4    1.-9    1.-9    1.-9\n        \n+\n+       .8      .8\n"
                "CBAR    1       1       1       2       0.      0.      1.\n")
        m = build_model(read_bdf(deck))
        assert type(m.elements[1]).__name__ == "Timoshenko3D"
        assert m.prop(1).section.ky == 0.8


# ------------------------------------------------------------- mass and damping
ONE_BAR = ("GRID    1\nGRID    2               2.\nMAT1    1       7.+10           .3      2700.   \n"
           "PBAR    1       1       1.-4    2.-9    3.-9    4.-9\n"
           "CBAR    1       1       1       2       0.      0.      1.\n")


class TestCoupmass:
    rhoAL = 2700.0 * 1e-4 * 2.0

    def mass(self, param=""):
        m = build_model(read_bdf(ONE_BAR + param))
        M = m.assemble().M.toarray()
        idx = {(d.node, d.axis): i for i, d in enumerate(m.dofs)}
        return M, idx

    def test_lumped_is_the_default(self):
        M, idx = self.mass()
        M2, _ = self.mass("PARAM   COUPMASS-1\n")
        np.testing.assert_array_equal(M, M2)
        assert np.count_nonzero(M - np.diag(np.diag(M))) == 0
        for n in (1, 2):
            for a in (1, 2, 3):
                assert M[idx[n, a], idx[n, a]] == pytest.approx(self.rhoAL / 2)
            for a in (4, 5, 6):
                assert M[idx[n, a], idx[n, a]] == 0.0

    def test_coupled(self):
        M, idx = self.mass("PARAM   COUPMASS1\n")
        m, L = self.rhoAL, 2.0
        assert M[idx[1, 1], idx[1, 1]] == pytest.approx(m / 3)
        assert M[idx[1, 1], idx[2, 1]] == pytest.approx(m / 6)
        assert M[idx[1, 2], idx[1, 2]] == pytest.approx(156 * m / 420)
        assert M[idx[1, 2], idx[1, 6]] == pytest.approx(22 * L * m / 420)
        assert M[idx[1, 2], idx[2, 2]] == pytest.approx(54 * m / 420)
        for a in (1, 2, 3):                          # rigid translation: same total mass both ways
            r = np.zeros(len(idx))
            r[[idx[1, a], idx[2, a]]] = 1.0
            assert r @ M @ r == pytest.approx(m)

    def test_wtmass_scales_mass_only(self):
        a = build_model(read_bdf(ONE_BAR + "CONM2   9       2               1.5\n")).assemble()
        b = build_model(read_bdf(ONE_BAR + "CONM2   9       2               1.5\nPARAM   WTMASS  .25\n")).assemble()
        assert abs(b.M - 0.25 * a.M).max() <= 1e-15 * abs(a.M).max()
        assert abs(b.K - a.K).max() == 0


class TestDamping:
    def test_ge_and_param_g(self):
        deck = ONE_BAR.replace("2700.   ", "2700.                   .02")
        mats = build_model(read_bdf(deck + "PARAM   G       .01\n")).assemble()
        assert abs(mats.D - 0.03 * mats.K).max() <= 1e-12 * abs(mats.K).max()

    def test_spring_ge_and_dampers(self):
        deck = ("GRID    1\nGRID    2               1.\nCELAS2  1       1000.   1       1       2       1       .05\n"
                "CELAS1  2       7       2       3\nPELAS   7       500.    .1\n"
                "CDAMP2  3       4.      1       2\nCDAMP1  4       8       2       2\nPDAMP   8       6.\n"
                "CONM2   5       1               1.\nCONM2   6       2               1.\n")
        m = build_model(read_bdf(deck))
        mats = m.assemble()
        idx = {(d.node, d.axis): i for i, d in enumerate(m.dofs)}
        K, D, Cm = mats.K.toarray(), mats.D.toarray(), mats.C.toarray()
        assert K[idx[1, 1], idx[2, 1]] == -1000.0 and K[idx[2, 3], idx[2, 3]] == 500.0
        assert D[idx[1, 1], idx[1, 1]] == pytest.approx(50.0) and D[idx[2, 3], idx[2, 3]] == pytest.approx(50.0)
        assert Cm[idx[1, 2], idx[1, 2]] == 4.0 and Cm[idx[2, 2], idx[2, 2]] == 6.0
        assert m.elements[2].group == "PELAS 7"

    def test_tabdmp1(self):
        m = build_model(read_bdf(DATA / "frame_small.bdf"))
        assert m.modal_damping.zeta(50.0) == pytest.approx(0.015)
        assert m.global_ge == 0.01 and m.coupled_mass


# ------------------------------------------------------------ systems and sets
class TestSystems:
    def test_cd_spring_direction(self):
        # grid 1 displaces in a system rotated 90 deg about z: its component 1 is basic y
        base = ("CORD2R  5               0.      0.      0.      0.      0.      1.\n        0.      1.      0.\n"
                "GRID,1,,0.,0.,0.,{cd}\nGRID    2\n"
                "RBE2    1       1       123456  2\nCONM2   2       2               2.\n"
                "CELAS2  3       800.    1       1\nCELAS2  4       200.    2       2\n"
                "CELAS2  5       50.     2       1\nSPC1    1       3456    1\n")
        m = build_model(read_bdf(base.format(cd=5)))
        w = m.modes().omega
        np.testing.assert_allclose(np.sort(w), np.sqrt([50.0 / 2, 1000.0 / 2]), rtol=1e-10)
        # without CD the 800 N/m spring would act along x
        w0 = build_model(read_bdf(base.format(cd=" "))).modes().omega
        np.testing.assert_allclose(np.sort(w0), np.sqrt([200.0 / 2, 850.0 / 2]), rtol=1e-10)

    def test_orientation_vector_in_cd_of_ga(self):
        cord = "CORD2R  5               0.      0.      0.      0.      0.      1.\n        0.      1.      0.\n"
        a = cantilever(8).replace("GRID,1,,0.0,0.,0.", "GRID,1,,0.0,0.,0.,5").replace("CBAR,1,1,1,2,0.,1.,0.",
                                                                                    "CBAR,1,1,1,2,1.,0.,0.")
        ma = build_model(read_bdf(cord + a))
        mb = build_model(read_bdf(cantilever(8)))
        np.testing.assert_allclose(ma.modes(4).freq_hz, mb.modes(4).freq_hz, rtol=1e-10)
        assert np.allclose(ma.elements[1].orientation, (0.0, 1.0, 0.0))

    def test_conm2_cid_minus_one(self):
        a = build_model(read_bdf("GRID    1       \nCONM2   1       1       -1      2.      .1      .2      .3\n"))
        b = build_model(read_bdf("GRID    1       \nCONM2   1       1               2.      .1      .2      .3\n"))
        np.testing.assert_array_equal(a.assemble().M.toarray(), b.assemble().M.toarray())

    def test_spc_selection(self):
        deck = ONE_BAR + "SPC1    1       123456  1\nSPC1    2       123     1\n"
        with pytest.raises(BulkDataError, match=r"2 SPC sets \[1, 2\]"):
            build_model(read_bdf(deck))
        assert build_model(read_bdf(deck), spc_id=2).system().n_dof == 9
        assert build_model(read_bdf("SOL 103\nCEND\nSPC = 1\nBEGIN BULK\n" + deck)).system().n_dof == 6
        add = deck + "SPCADD  3       2       1\n"
        assert build_model(read_bdf(add), spc_id=3).system().n_dof == 6

    def test_all_styles_build_the_same_matrices(self):
        ref = build_model(read_bdf(DATA / "frame_small.bdf")).assemble()
        for name in ("frame_large_femap.bdf", "frame_free.bdf", "frame_pynastran.bdf"):
            got = build_model(read_bdf(DATA / name)).assemble()
            for k in ("K", "M", "C", "D"):
                A, B = getattr(got, k), getattr(ref, k)
                assert abs(A - B).max() == 0, (name, k)

    def test_frame_modes_are_finite_and_positive(self):
        m = build_model(read_bdf(DATA / "frame_small.bdf"))
        f = m.modes(6).freq_hz
        assert np.all(np.isfinite(f)) and np.all(f > 1.0)


class TestUnsupportedFeatures:
    def test_offsets_and_pins(self):
        cbar = "CBAR    1       1       1       2       0.      0.      1.\n"
        cord = "CORD2R  5               0.      0.      0.      0.      0.      1.\n        0.      1.      0.\n"
        # W1A = 0.1 along x of grid 1's CD system (basic y) equals the same offset given in basic (OFFT GBG)
        in_cd = cord + ONE_BAR.replace("GRID    1\n", "GRID,1,,0.,0.,0.,5\n").replace(
            cbar, cbar + "                        .1\n")
        in_basic = cord + ONE_BAR.replace("GRID    1\n", "GRID,1,,0.,0.,0.,5\n").replace(
            cbar, cbar[:-1].ljust(64) + "GBG\n                        0.      .1\n")
        a, b = (build_model(read_bdf(d)) for d in (in_cd, in_basic))
        assert np.allclose(a.elements[1].offset_a, (0.0, 0.1, 0.0))
        assert abs(a.assemble().K - b.assemble().K).max() == 0
        assert read_bdf(write_bdf(to_bulk(a, template=read_bdf(in_cd)))) == read_bdf(in_cd)
        with pytest.raises(BulkDataError, match=r"CBAR 1.*element system"):
            build_model(read_bdf(ONE_BAR.replace(cbar, cbar[:-1].ljust(64) + "GOO\n                        .1\n")))
        pins = ONE_BAR.replace(cbar, cbar + "        456\n")
        with pytest.raises(BulkDataError, match=r"CBAR 1.*pin flags"):
            build_model(read_bdf(pins))


def test_compare_with_pynastran_if_installed():
    pyn = pytest.importorskip("pyNastran.bdf.bdf")
    model = pyn.read_bdf(str(DATA / "frame_pynastran.bdf"), xref=True, debug=None)
    ours = read_bdf(DATA / "frame_pynastran.bdf")
    for nid, g in model.nodes.items():
        np.testing.assert_allclose(g.get_position(), ours.grid_xyz(nid), atol=1e-12)
