"""pLSCF estimator: reduced normal equations, poles, participation, weights, estimator API."""
import numpy as np
import pytest

from identification import PolyMAX, frequency_weights, modal_system, poles_at_order, reduced_normal_matrix
from identification.stabilisation import mac_vectors
from modalab.core.errors import ModalabValueError, NotFittedError


def _brute_reduced(H, w, theta, p):
    """Reduced matrix from explicit Γ_o, Υ_o (Peeters 2004): 2 Σ_o (T_o − S_oᵀ R_o⁻¹ S_o)."""
    n_out, n_in, nf = H.shape
    Om = np.exp(1j * np.outer(theta, np.arange(p + 1)))          # (nf, p+1)
    M = 0
    for o in range(n_out):
        G = w[o][:, None] * Om
        U = -w[o][:, None] * np.einsum("ki,kr->kri", H[o].T, Om).reshape(nf, -1)   # columns (r, i)
        R, S, T = (G.conj().T @ G).real, (G.conj().T @ U).real, (U.conj().T @ U).real
        M = M + T - S.T @ np.linalg.solve(R, S)
    return 2 * M


class TestReducedMatrix:
    def test_matches_explicit_normal_equations(self):
        rng = np.random.default_rng(1)
        n_out, n_in, nf, p = 3, 2, 60, 5
        H = rng.normal(size=(n_out, n_in, nf)) + 1j * rng.normal(size=(n_out, n_in, nf))
        theta = np.linspace(0.05, np.pi, nf)
        for w in (np.ones((n_out, nf)), rng.uniform(0.2, 1.0, size=(n_out, nf))):
            M = reduced_normal_matrix(H, w, theta, p, chunk=2)
            np.testing.assert_allclose(M, _brute_reduced(H, w, theta, p), rtol=1e-8, atol=1e-8 * np.abs(M).max())
            np.testing.assert_allclose(M, M.T)

    def test_lower_orders_use_the_leading_block(self):
        mm, _ = modal_system([50.0, 120.0], [0.02, 0.01], 4, rng=0)
        f = np.linspace(1, 200, 400)
        frf = mm.frf(f, references=[mm.dofs[0]], quantity="receptance")
        dt = 1 / (2 * f[-1])
        M = reduced_normal_matrix(frf.H, frequency_weights(frf), 2 * np.pi * f * dt, 12)
        lam_a, _ = poles_at_order(M, 6, 1, dt)
        lam_b, _ = poles_at_order(M[:7, :7].copy(), 6, 1, dt)
        np.testing.assert_allclose(np.sort_complex(lam_a), np.sort_complex(lam_b))
        with pytest.raises(ModalabValueError, match="needs a reduced matrix"):
            poles_at_order(M, 13, 1, dt)


class TestPoles:
    @pytest.mark.parametrize("quantity", ["receptance", "mobility", "accelerance"])
    def test_noise_free_poles_exact(self, quantity):
        fn, zeta = np.array([31.0, 77.0, 140.0]), np.array([0.02, 0.01, 0.005])
        mm, _ = modal_system(fn, zeta, 6, rng=3)
        frf = mm.frf(np.linspace(2, 250, 800), references=[mm.dofs[0], mm.dofs[3]], quantity=quantity)
        pm = PolyMAX(max_order=12, min_order=6, select=list(fn), refine=False).fit(frf)
        lam = pm.poles_[-1]
        true = -zeta * 2 * np.pi * fn + 1j * 2 * np.pi * fn * np.sqrt(1 - zeta ** 2)
        for t in true:
            assert np.min(np.abs(lam - t)) / abs(t) < 1e-7
        np.testing.assert_allclose(pm.modes_.freq_hz, fn, rtol=1e-7)
        np.testing.assert_allclose(pm.modes_.damping, zeta, rtol=1e-5)
        # the local refinement keeps exact poles (to the accuracy of its local residual model)
        pr = PolyMAX(max_order=12, min_order=6, select=list(fn), refine=True).fit(frf)
        np.testing.assert_allclose(pr.modes_.freq_hz, fn, rtol=1e-6)
        np.testing.assert_allclose(pr.modes_.damping, zeta, rtol=1e-4)

    def test_participation_is_shape_at_references(self):
        fn, zeta = np.array([40.0, 90.0]), np.array([0.01, 0.02])
        mm, phi = modal_system(fn, zeta, 5, rng=4)
        refs = [mm.dofs[0], mm.dofs[2], mm.dofs[4]]
        frf = mm.frf(np.linspace(5, 150, 500), references=refs, quantity="accelerance")
        pm = PolyMAX(max_order=6, select=list(fn)).fit(frf)
        mac = np.diag(mac_vectors(pm.selected_.participation, phi[[0, 2, 4]].astype(complex)))
        assert np.all(mac > 1 - 1e-8)

    def test_poles_per_order_count(self):
        mm, _ = modal_system([40.0], [0.01], 3, rng=0)
        frf = mm.frf(np.linspace(5, 100, 300), references=[mm.dofs[0], mm.dofs[1]])
        M = reduced_normal_matrix(frf.H, np.ones((3, 300)), 2 * np.pi * frf.freq_hz / 200, 5)
        for n in range(1, 6):
            lam, L = poles_at_order(M, n, 2, 1 / 200)
            assert lam.size <= 2 * n and L.shape == (2, lam.size)
            np.testing.assert_allclose(np.linalg.norm(L, axis=0), 1.0)


class TestWeights:
    def _frf(self, coherence=True):
        mm, _ = modal_system([40.0], [0.01], 3, rng=0)
        frf = mm.frf(np.linspace(5, 100, 200), references=[mm.dofs[0]])
        if coherence:
            coh = np.full(frf.shape, 0.99)
            coh[..., 50:60] = 0.5
            frf = frf._replace(coherence=coh, metadata={"n_averages": 4})
        return frf

    def test_coherence_weights_follow_coherence(self):
        w = frequency_weights(self._frf(), "coherence", normalise=False)
        assert np.allclose(w[:, :50], 0.99) and np.allclose(w[:, 50:60], 0.5)

    def test_variance_weights_inverse_std(self):
        frf = self._frf()
        w = frequency_weights(frf, "variance", normalise=False)
        g2 = 0.99
        expected = 1 / np.sqrt((1 - g2) / (2 * 4 * g2) * np.abs(frf.H[:, 0, 0]) ** 2)
        np.testing.assert_allclose(w[:, 0], expected)

    def test_bad_weighting_messages(self):
        with pytest.raises(ModalabValueError, match="has no coherence"):
            frequency_weights(self._frf(False), "coherence")
        with pytest.raises(ModalabValueError, match="weighting"):
            frequency_weights(self._frf(), "magic")

    def test_fit_with_coherence_weighting(self):
        pm = PolyMAX(max_order=8, weighting="coherence", select=[40.0]).fit(self._frf())
        np.testing.assert_allclose(pm.modes_.freq_hz, [40.0], rtol=1e-6)


class TestEstimatorApi:
    def test_init_stores_parameters_only(self):
        pm = PolyMAX(max_order=20, weighting="coherence")
        assert pm.max_order == 20 and pm.weighting == "coherence"
        assert not [k for k in vars(pm) if k.endswith("_")]

    def test_not_fitted(self):
        with pytest.raises(NotFittedError, match="call fit"):
            PolyMAX().poles_
        with pytest.raises(NotFittedError):
            PolyMAX().synthesise()

    def test_fit_returns_self(self):
        mm, _ = modal_system([40.0], [0.01], 3, rng=0)
        frf = mm.frf(np.linspace(5, 100, 200), references=[mm.dofs[0]])
        pm = PolyMAX(max_order=6, select=[40.0])
        assert pm.fit(frf) is pm
        syn = pm.synthesise()
        np.testing.assert_allclose(syn.H, pm.frf_.H, rtol=1e-6, atol=1e-9 * np.abs(syn.H).max())

    @pytest.mark.parametrize("kw, msg", [({"max_order": 0}, "positive integer"), ({"max_order": 2.5}, "positive"),
                                         ({"min_order": 9, "max_order": 4}, "min_order")])
    def test_bad_parameters(self, kw, msg):
        mm, _ = modal_system([40.0], [0.01], 3, rng=0)
        frf = mm.frf(np.linspace(5, 100, 200), references=[mm.dofs[0]])
        with pytest.raises(ModalabValueError, match=msg):
            PolyMAX(**kw).fit(frf)

    def test_too_few_lines_and_wrong_type(self):
        mm, _ = modal_system([40.0], [0.01], 3, rng=0)
        frf = mm.frf(np.linspace(5, 100, 20), references=[mm.dofs[0]])
        with pytest.raises(ModalabValueError, match="frequency lines cannot support"):
            PolyMAX(max_order=30).fit(frf)
        with pytest.raises(ModalabValueError, match="modalab.FRF"):
            PolyMAX().fit(np.ones((2, 1, 10)))


def test_a_refinement_that_leaves_the_diagram_keeps_the_diagrams_pole():
    """A local single-pole refinement over merged close modes drifts (issue 14: 314.35 Hz, zeta 1.07 %, stable
    over 25 orders, refined to 311.5 Hz, zeta 4.4 %): such a pole keeps the diagram's estimate; an ordinary
    refinement (a few % of the damping, a fraction of the bandwidth) is kept."""
    from identification.polymax import _keep_consistent_refinement

    def pole(f, z):
        w = 2 * np.pi * f
        return complex(-z * w, w * np.sqrt(1 - z * z))

    diagram = np.array([pole(314.35, 0.0107), pole(100.0, 0.01), pole(50.0, 0.02), pole(200.0, 0.01)])
    refined = np.array([pole(311.5, 0.044), pole(100.05, 0.0105), pole(50.0, 0.009), pole(203.0, 0.01)])
    out = _keep_consistent_refinement(diagram, refined, 2.0)
    assert out[0] == diagram[0]                  # damping x4: the diagram's pole
    assert out[1] == refined[1]                  # a small refinement stays
    assert out[2] == diagram[2]                  # damping halved and more
    assert out[3] == diagram[3]                  # moved 3 Hz, more than zeta * f = 2 Hz
