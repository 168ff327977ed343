"""Correlation criteria (thesis 2.2) on vectors whose answers follow by hand, and correlate() end to end."""
import json

import numpy as np
import pytest
import scipy.linalg as sla

from modalab.core.errors import DofError, ModalabValueError, ShapeError
from modalab.core.frf import FRF
from modalab.core.modes import ModeSet
from modalab.core.structure import Structure
from updating.correlation.metrics import (automac, comac, correlate, cross_orthogonality, csac, csf, ecomac, frac,
                                  frequency_table, frf_correlation, mac, macx, mixed_orthogonality, msf)
from updating.correlation.dofmap import DofMap


def chain(n=8, seed=5):
    rng = np.random.default_rng(seed)
    k = rng.uniform(1.0, 2.0, n) * 1e4
    m = rng.uniform(1.0, 2.0, n)
    K = np.zeros((n, n))
    K[0, 0] = k[0]
    for i in range(1, n):
        K[np.ix_([i - 1, i], [i - 1, i])] += k[i] * np.array([[1, -1], [-1, 1]])
    return K, np.diag(m), [f"{i + 1}+Z" for i in range(n)]


class TestMAC:
    def test_hand_values(self):
        a = np.array([[1.0], [0.0]])
        x = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
        np.testing.assert_allclose(mac(a, x), [[1.0, 0.0, 0.5]])       # eq. 2.63: cos²(45°) = 0.5

    def test_complex_conjugate_and_phase(self):
        v = np.array([1.0 + 1j, 2.0 - 0.5j, 0.3j])
        assert mac(v, v * np.exp(1.1j))[0, 0] == pytest.approx(1.0)
        w = np.array([1.0, 1.0j])
        assert mac(w, w.conj())[0, 0] == pytest.approx(0.0, abs=1e-15)  # conjugate modes: MAC 0 ...
        assert macx(w, w.conj())[0, 0] == pytest.approx(1.0)           # ... MACX 1

    def test_macx_equals_mac_for_real(self):
        rng = np.random.default_rng(0)
        a, x = rng.normal(size=(6, 3)), rng.normal(size=(6, 4))
        np.testing.assert_allclose(macx(a, x), mac(a, x), rtol=1e-12)

    def test_zero_vector_gives_zero(self):
        assert mac(np.zeros(3), np.ones(3))[0, 0] == 0.0

    def test_mass_weighted(self):
        K, M, dofs = chain()
        _, phi = sla.eigh(K, M)
        W = mac(phi, phi, weight=M)
        np.testing.assert_allclose(W, np.eye(8), atol=1e-12)          # M-orthogonal modes
        assert mac(phi, phi)[0, 1] > 1e-6                              # plain MAC is not diagonal

    def test_errors(self):
        with pytest.raises(ShapeError, match="DOFs"):
            mac(np.ones((3, 1)), np.ones((4, 1)))
        with pytest.raises(ModalabValueError, match="NaN"):
            mac(np.array([1.0, np.nan]), np.ones(2))
        with pytest.raises(ShapeError, match="weighting"):
            mac(np.ones(3), np.ones(3), weight=np.eye(2))

    def test_automac(self):
        rng = np.random.default_rng(2)
        A = automac(rng.normal(size=(5, 4)))
        np.testing.assert_allclose(A, A.T)
        np.testing.assert_allclose(np.diag(A), 1.0)

    def test_modeset_label_signs(self):
        a = ModeSet(freq_hz=[1.0], shapes=[[1.0], [2.0]], dofs=["1+Z", "2+Z"])
        x = ModeSet(freq_hz=[1.0], shapes=[[1.0], [-2.0]], dofs=["1+Z", "2-Z"])
        assert mac(a, x)[0, 0] == pytest.approx(1.0)
        y = ModeSet(freq_hz=[1.0], shapes=[[1.0], [2.0]], dofs=["1+Z", "3+Z"])
        with pytest.raises(ShapeError, match="labels"):
            mac(a, y)


class TestMSF:
    def test_scales_one_onto_another(self):
        a = np.array([[1.0, 2.0], [2.0, 0.0], [-1.0, 1.0]])
        x = a * np.array([2.5, -0.4])
        s = msf(x, a)                                                 # eq. 2.62, signed
        np.testing.assert_allclose(s, [2.5, -0.4])
        np.testing.assert_allclose(a * s, x)

    def test_complex_factor(self):
        a = np.array([1.0, 2.0, -0.5])
        np.testing.assert_allclose(msf(a * (1 - 2j), a), [1 - 2j])

    def test_least_squares_with_noise(self):
        a = np.array([1.0, 0.0])
        x = np.array([2.0, 1.0])                                      # best factor: 2
        assert msf(x, a)[0] == pytest.approx(2.0)

    def test_needs_paired_columns(self):
        with pytest.raises(ShapeError, match="paired"):
            msf(np.ones((3, 2)), np.ones((3, 1)))


class TestCOMAC:
    def test_perfect_and_scaled(self):
        rng = np.random.default_rng(3)
        a = rng.normal(size=(6, 3))
        np.testing.assert_allclose(comac(a, a * [2.0, -3.0, 0.5]), 1.0)
        np.testing.assert_allclose(ecomac(a, a * [2.0, -3.0, 0.5]), 0.0, atol=1e-14)

    def test_hand_value(self):
        # DOF 1: A=(1, 1), X=(1, -1) up to sign: |.| terms give (1+1)²/(2·2) = 1
        # DOF 2: A=(1, 0), X=(0, 1): 0
        a = np.array([[1.0, 1.0], [1.0, 0.0]])
        x = np.array([[1.0, -1.0], [0.0, 1.0]])
        np.testing.assert_allclose(comac(a, x, normalize=False), [1.0, 0.0])

    def test_localises_a_bad_dof(self):
        rng = np.random.default_rng(4)
        a = rng.normal(size=(8, 4))
        x = a.copy()
        x[5] = rng.normal(size=4)
        c, e = comac(a, x), ecomac(a, x)
        assert np.argmin(c) == 5 and np.argmax(e) == 5


class TestOrthogonality:
    def test_mass_normalised_modes_give_identity(self):
        K, M, dofs = chain()
        _, phi = sla.eigh(K, M)
        np.testing.assert_allclose(cross_orthogonality(phi, phi, M), np.eye(8), atol=1e-12)    # eq. 2.65
        np.testing.assert_allclose(mixed_orthogonality(phi[:, :3], M), np.eye(3), atol=1e-12)  # eq. 2.66

    def test_normalize_removes_scaling(self):
        K, M, dofs = chain()
        _, phi = sla.eigh(K, M)
        x = phi[:, :3] * [3.0, 0.2, -5.0]
        np.testing.assert_allclose(np.abs(cross_orthogonality(phi[:, :3], x, M, normalize=True)), np.eye(3),
                                   atol=1e-12)
        np.testing.assert_allclose(mixed_orthogonality(x, M, normalize=True), np.eye(3), atol=1e-12)

    def test_reduced_mass_on_test_dofs(self):
        from updating.correlation.reduction import serep
        K, M, dofs = chain()
        red = serep(K, M, ["2+Z", "5+Z", "8+Z"], dofs=dofs)
        _, phi = sla.eigh(K, M)
        pt = phi[[1, 4, 7], :3]
        np.testing.assert_allclose(mixed_orthogonality(pt, red.M), np.eye(3), atol=1e-10)

    def test_shape_error(self):
        with pytest.raises(ShapeError, match="mass matrix"):
            cross_orthogonality(np.ones((3, 1)), np.ones((3, 1)), np.eye(4))


class TestFRF:
    def setup_method(self):
        K, M, dofs = chain(n=4)
        self.st = Structure(M=M, K=K, C=1e-4 * K, dofs=dofs)
        self.f = np.linspace(1.0, 40.0, 300)
        self.H = self.st.frf(self.f, responses=dofs, references=["4+Z"])

    def test_identical_frfs(self):
        np.testing.assert_allclose(frac(self.H, self.H), 1.0)
        np.testing.assert_allclose(csac(self.H, self.H), 1.0)
        np.testing.assert_allclose(csf(self.H, self.H), 1.0)

    def test_scaled_frfs(self):
        # shape-only criteria ignore a factor of 2, CSF sees it: 2·2/(1+4) = 0.8
        np.testing.assert_allclose(frac(self.H, 2 * self.H.H), 1.0)
        np.testing.assert_allclose(csac(self.H.H, 2 * self.H.H), 1.0)
        np.testing.assert_allclose(csf(self.H.H, 2 * self.H.H), 0.8)

    def test_shifted_model_drops_frac(self):
        K, M, dofs = chain(n=4)
        other = Structure(M=M, K=1.1 * K, C=1e-4 * K, dofs=dofs)
        Ho = other.frf(self.f, responses=dofs, references=["4+Z"])
        assert np.all(frac(Ho, self.H) < 0.9)
        assert csac(Ho, self.H).min() < 0.5

    def test_frf_correlation_with_structure_and_map(self):
        test = FRF(freq_hz=self.f, H=-self.H.select(responses=["2+Z", "3+Z"]).H,
                   responses=["102+Z", "103+Z"], references=["4+Z"])
        dm = DofMap(dofs={"102+Z": "2-Z", "103+Z": "3-Z"})
        fc = frf_correlation(self.st, test, dofmap=dm)
        np.testing.assert_allclose(fc.frac, 1.0)
        np.testing.assert_allclose(fc.csf, 1.0, atol=1e-12)
        np.testing.assert_allclose(fc.analysis.H, test.H, rtol=1e-10)
        json.dumps(fc.to_dict())

    def test_frequency_mismatch(self):
        other = self.st.frf(self.f[:-1], references=["4+Z"])
        with pytest.raises(ShapeError, match="synthesise"):
            frf_correlation(other, self.H)


class TestCorrelate:
    @pytest.fixture()
    def modes(self):
        K, M, dofs = chain()
        w2, phi = sla.eigh(K, M)
        an = ModeSet(freq_hz=np.sqrt(w2) / (2 * np.pi), shapes=phi, dofs=dofs, scaling="unit_modal_mass")
        return an

    def test_self_correlation(self, modes):
        test = modes.select_modes([0, 1, 2, 3]).select_dofs(["2+Z", "4+Z", "6+Z", "7+Z", "8+Z"])
        test.shapes = test.shapes * 4.0
        r = correlate(modes, test)
        assert r.pairs == [(0, 0), (1, 1), (2, 2), (3, 3)]
        np.testing.assert_allclose(r.freq_error_pct, 0.0, atol=1e-12)
        np.testing.assert_allclose(r.msf, 4.0)
        np.testing.assert_allclose(r.comac, 1.0)
        np.testing.assert_allclose(r.ecomac, 0.0, atol=1e-14)
        assert r.pairing.unpaired_test == [] and r.pairing.unpaired_analysis == [4, 5, 6, 7]
        d = json.loads(json.dumps(r.to_dict()))
        assert d["pairs"][0]["test_mode"] == 1 and d["pairs"][0]["mac"] == pytest.approx(1.0)
        assert d["summary"]["n_pairs"] == 4 and set(d["comac"]) == {"2+Z", "4+Z", "6+Z", "7+Z", "8+Z"}
        t = r.table()
        assert "4 pairs" in t and "out of order" not in t

    def test_frequency_errors_in_percent(self, modes):
        test = modes.select_modes([0, 1]).select_dofs(["2+Z", "5+Z", "8+Z"])
        test.freq_hz = modes.freq_hz[:2] * np.array([1.0 / 1.1, 1.0 / 0.95])
        r = correlate(modes, test)
        np.testing.assert_allclose(r.freq_error_pct, [10.0, -5.0], rtol=1e-10)
        rows = frequency_table(modes.freq_hz, test.freq_hz, r.pairs)
        assert rows[1]["freq_error_pct"] == pytest.approx(-5.0)

    def test_with_dofmap_file(self, modes, tmp_path):
        p = tmp_path / "m.csv"
        p.write_text("101+Z,2-Z\n102+Z,5+Z\n103+Z,8+Z\n")
        sel = modes.select_modes([0, 1, 2]).select_dofs(["2-Z", "5+Z", "8+Z"])
        test = ModeSet(freq_hz=sel.freq_hz, shapes=sel.shapes, dofs=["101+Z", "102+Z", "103+Z"])
        r = correlate(modes, test, dofmap=str(p))
        assert [p[0] for p in r.pairs] == [0, 1, 2]
        np.testing.assert_allclose(r.pairing.mac, 1.0)

    def test_unmapped_test_dof(self, modes):
        test = ModeSet(freq_hz=[1.0], shapes=np.ones((2, 1)), dofs=["2+Z", "55+Z"])
        with pytest.raises(DofError, match="55"):
            correlate(modes, test)

    def test_wrong_types(self, modes):
        with pytest.raises(ModalabValueError, match="ModeSet"):
            correlate(modes.shapes, modes)

    def test_plots_written(self, modes, tmp_path):
        from updating.correlation.plots import plot_frf_overlay, save_correlation_plots
        test = modes.select_modes([0, 1, 2]).select_dofs(["2+Z", "5+Z", "8+Z"])
        r = correlate(modes, test)
        paths = save_correlation_plots(r, tmp_path / "plots")
        assert set(paths) == {"mac", "frequencies", "comac"}
        for p in paths.values():
            assert p.stat().st_size > 1000 and p.read_bytes()[:4] == b"\x89PNG"
        K, M, dofs = chain(n=4)
        st = Structure(M=M, K=K, C=1e-4 * K, dofs=dofs)
        H = st.frf(np.linspace(1, 40, 50), references=["1+Z"])
        out = plot_frf_overlay(H, H, tmp_path / "frf.pdf")
        assert out.read_bytes()[:4] == b"%PDF"
        with pytest.raises(ModalabValueError, match="does not exist"):
            plot_frf_overlay(H, H, tmp_path / "missing" / "frf.png")

    def test_structure_as_analysis(self, modes):
        K, M, dofs = chain()
        test = modes.select_modes([0, 2]).select_dofs(["2+Z", "5+Z", "8+Z"])
        r = correlate(Structure(M=M, K=K, dofs=dofs), test)
        assert r.analysis.n_modes == 8 and r.pairs == [(0, 0), (2, 1)]
        np.testing.assert_allclose(r.freq_error_pct, 0.0, atol=1e-9)
