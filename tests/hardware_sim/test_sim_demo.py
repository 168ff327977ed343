"""The demo structure: the grillage elements against beam theory, and the demo's documented properties."""
import time

import numpy as np
import pytest
import scipy.linalg as sla
from hypothesis import given, settings, strategies as st

from hardware_sim import DEMO_POINTS, BeamSection, demo_lab, demo_structure, grillage, simulate_roving_test

SEC = BeamSection.rectangle(0.020, 0.010)          # aluminium 20 x 10 mm


def straight_beam(L=1.0, n_el=20, angle=0.0, flip_every_other=False):
    c, s = np.cos(angle), np.sin(angle)
    coords = {i + 1: (c * L * i / n_el, s * L * i / n_el) for i in range(n_el + 1)}
    members = [((i + 2, i + 1) if flip_every_other and i % 2 else (i + 1, i + 2)) + (SEC,) for i in range(n_el)]
    M, K, _, dofs = grillage(coords, members)
    return M.toarray(), K.toarray(), dofs


def freqs(M, K):
    w2 = sla.eigh(K, M, eigvals_only=True)
    return np.sqrt(np.clip(w2, 0, None)) / (2 * np.pi)


class TestGrillageElement:
    def test_free_free_beam_bending_and_torsion_match_theory(self):
        M, K, _ = straight_beam()
        f = freqs(M, K)
        assert np.all(f[:3] < 1e-3 * f[3])                       # heave, pitch, roll: 3 rigid modes
        b = np.sqrt(SEC.E * SEC.I / (SEC.rho * SEC.A)) / (2 * np.pi)
        roots = [4.730041, 7.853205, 10.995608, 14.137165, 17.278760, 20.420352, 23.561945]
        bending = [r ** 2 * b for r in roots]
        torsion = [0.5 * np.sqrt(SEC.G * SEC.J / (SEC.rho * SEC.Ip))]             # 1156 Hz, between bending 6 and 7
        expected = np.sort(bending + torsion)
        elastic = f[3:3 + expected.size]
        assert elastic == pytest.approx(expected, rel=5e-3)

    @settings(max_examples=10, deadline=None)
    @given(angle=st.floats(-np.pi, np.pi))
    def test_frequencies_do_not_depend_on_orientation_or_node_order(self, angle):
        M0, K0, _ = straight_beam(n_el=8)
        M1, K1, _ = straight_beam(n_el=8, angle=angle, flip_every_other=True)
        assert freqs(M1, K1)[3:] == pytest.approx(freqs(M0, K0)[3:], rel=1e-9)

    def test_l_frame_tip_deflection_is_exact(self):
        """Clamped L-frame, vertical tip load: δ = P a³/3EI + P b³/3EI + P b² a/GJ (bending + torsion)."""
        a, b, P = 0.7, 0.4, 10.0
        M, K, _, dofs = grillage({1: (0, 0), 2: (a, 0), 3: (a, b)}, [(1, 2, SEC), (2, 3, SEC)])
        K = K.toarray()[3:, 3:]
        f = np.zeros(6)
        f[3] = P                                                  # node 3, Z
        u = np.linalg.solve(K, f)
        EI, GJ = SEC.E * SEC.I, SEC.G * SEC.J
        assert u[3] == pytest.approx(P * a ** 3 / (3 * EI) + P * b ** 3 / (3 * EI) + P * b * b * a / GJ, rel=1e-10)
        assert dofs[:3] == ["1+Z", "1+RX", "1+RY"]

    def test_rectangle_section(self):
        s = BeamSection.rectangle(0.1, 0.01)
        assert s.A == pytest.approx(1e-3) and s.I == pytest.approx(0.1 * 1e-6 / 12)
        assert s.J == pytest.approx(0.1 * 1e-6 * (1 / 3 - 0.21 * 0.1 * (1 - 1e-4 / 12)))


class TestDemoStructure:
    def test_documented_properties(self):
        s = demo_structure()
        assert s.n_dof == 45 and len(s.coords) == 15
        z = np.zeros(s.n_dof)
        z[0::3] = 1.0
        assert z @ (s.M @ z) == pytest.approx(2700 * (0.05 * 0.025 * 1.2 + 0.1 * 0.012 * 1.6))
        w, _ = s.normal_modes()
        f = w / (2 * np.pi)
        assert f[:5] == pytest.approx([2.70, 3.31, 4.07, 18.97, 67.45], abs=0.01)
        assert f[2] < 0.25 * f[3]                                  # suspension well below the first elastic mode

    @pytest.mark.parametrize("damping", ["viscous", "hysteretic"])
    def test_damping_is_light(self, damping):
        mm = demo_structure(damping).modal_model()
        p = mm.poles[mm.poles.imag > 0]
        f, zeta = np.abs(p) / (2 * np.pi), np.abs(p.real) / np.abs(p)
        assert np.all((zeta[f < 5] > 0.025) & (zeta[f < 5] < 0.035))
        el = (f > 10) & (f < 1000)
        assert np.all((zeta[el] >= 0.0045) & (zeta[el] <= 0.02))
        assert mm.hysteretic == (damping == "hysteretic")

    def test_modal_frf_equals_direct_solve(self):
        for damping in ("viscous", "hysteretic"):
            s = demo_structure(damping)
            fr = [5.0, 18.9, 123.0, 444.0]
            a = s.frf(fr, ["19+Z", "1+Z"], ["14+Z"])
            b = s.frf(fr, ["19+Z", "1+Z"], ["14+Z"], method="direct")
            assert np.allclose(a.H, b.H, rtol=1e-8, atol=0)

    def test_unknown_damping(self):
        with pytest.raises(ValueError, match="damping 'coulomb'"):
            demo_structure("coulomb")


def test_demo_roving_test_runs():
    """The README's first command simulates this: 11 points x 3 hits."""
    t = time.perf_counter()
    lab = demo_lab(0)
    recs = simulate_roving_test(lab, DEMO_POINTS, hits_per_point=3)
    elapsed = time.perf_counter() - t
    assert len(recs) == 33 and not any(r.overloaded for r in recs)
    assert [str(r.dofs[0]) for r in recs[::3]] == list(DEMO_POINTS)
    # a sensible hammer test: the peak response stays well inside the accelerometers' range
    peak = max(np.abs(r.response).max() for r in recs)
    assert 20.0 < peak < 0.8 * recs[0].metadata["range"][1]
    print(f"demo roving test: {elapsed:.2f} s")
