"""Poly-reference LSFD, residuals, scaling, window correction, refinement and indicators."""
import numpy as np
import pytest

from identification import (driving_points, lsfd, mcf, modal_system, modes_from_poles, mov, mpc, mpd,
                            plot_automac, plot_synthesis, refine_poles, frf_correlation, synthesis_error)
from modalab.core.errors import ModalabValueError

FN = np.array([35.0, 80.0, 150.0, 260.0])
ZETA = np.array([0.02, 0.01, 0.015, 0.01])


def _poles(fn=FN, z=ZETA):
    w = 2 * np.pi * fn
    return -z * w + 1j * w * np.sqrt(1 - z ** 2)


def _case(quantity="accelerance", refs=(0, 3), f=np.linspace(5, 300, 900), n_dof=6):
    mm, phi = modal_system(FN, ZETA, n_dof, rng=11)
    frf = mm.frf(f, references=[mm.dofs[k] for k in refs], quantity=quantity)
    return frf, phi


class TestLSFD:
    @pytest.mark.parametrize("quantity", ["receptance", "mobility", "accelerance"])
    def test_exact_residues_and_unit_modal_mass(self, quantity):
        frf, phi = _case(quantity)
        lam = _poles()
        L = phi[[0, 3]].astype(complex)
        res = lsfd(frf, lam, L)
        # A_r = ψ_r l_rᵀ equals φ_r φ_r(ref)ᵀ / (2iω_d) (receptance units for every quantity)
        A_true = phi[:, None, :] * phi[[0, 3]][None, :, :] / (2j * lam.imag)[None, None, :]
        np.testing.assert_allclose(res.residues, A_true, rtol=1e-6, atol=1e-9 * np.abs(A_true).max())
        np.testing.assert_allclose(res.lower, 0, atol=1e-6 * np.abs(frf.H).max())
        modes, _ = modes_from_poles(frf, lam, L)
        assert modes.scaling == "unit_modal_mass"
        sign = np.sign(np.real(modes.shapes[0]) * phi[0])
        np.testing.assert_allclose(modes.shapes * sign, phi, rtol=1e-5, atol=1e-8)
        np.testing.assert_allclose(modes.freq_hz, FN, rtol=1e-12)
        np.testing.assert_allclose(modes.damping, ZETA, rtol=1e-10)
        # A = φ Lᵀ with L the reported participation
        np.testing.assert_allclose(modes.shapes[:, None, :] * modes.participation[None], A_true, rtol=1e-5,
                                   atol=1e-9 * np.abs(A_true).max())

    def test_residuals_absorb_out_of_band_modes(self):
        frf, phi = _case("accelerance", f=np.linspace(60, 200, 600))     # 35 and 260 Hz lie outside
        lam, L = _poles()[1:3], phi[[0, 3]][:, 1:3].astype(complex)
        with_r = lsfd(frf, lam, L)
        without = lsfd(frf, lam, L, lower_residual=False, upper_residual=False)
        e_with = synthesis_error(with_r.synthesise(frf).H, frf.H).max()
        e_without = synthesis_error(without.synthesise(frf).H, frf.H).max()
        assert e_with < 0.1 * e_without
        assert np.all(frf_correlation(with_r.synthesise(frf).H, frf.H) > 0.998)
        assert np.abs(with_r.lower).max() > 0 and np.abs(with_r.upper).max() > 0

    def test_dc_line_rejected(self):
        frf, phi = _case(f=np.linspace(0, 300, 900))
        with pytest.raises(ModalabValueError, match="above 0 Hz"):
            lsfd(frf, _poles(), phi[[0, 3]])

    def test_driving_points_with_signs(self):
        frf, _ = _case()
        assert driving_points(frf) == [(0, 0, 1), (3, 1, 1)]
        flipped = frf.select(responses=["1-Z", "2+Z", "3+Z", "4+Z", "5+Z", "6+Z"])
        assert driving_points(flipped)[0] == (0, 0, -1)
        modes, _ = modes_from_poles(flipped, _poles(), frf.H[:1, :, :1].squeeze()[:, None] * 0 +
                                    _case()[1][[0, 3]].astype(complex))
        _, phi = _case()
        np.testing.assert_allclose(np.abs(modes.shapes[0]), np.abs(phi[0]), rtol=1e-5)

    def test_no_driving_point_unit_max(self):
        frf, phi = _case(refs=(0,))
        frf = frf.select(responses=["2+Z", "3+Z", "4+Z"])
        modes, _ = modes_from_poles(frf, _poles(), phi[[0]].astype(complex))
        assert modes.scaling == "unit_max"
        np.testing.assert_allclose(np.abs(modes.shapes).max(axis=0), 1.0)
        assert np.all(np.isnan(modes.indicators["MOV"]))

    def test_window_correction(self):
        beta = 3.0
        mm, phi = modal_system(FN, ZETA, 6, rng=11, window_beta=beta)
        frf = mm.frf(np.linspace(5, 300, 900), references=[mm.dofs[0]])
        measured = _poles() - beta
        modes, res = modes_from_poles(frf, measured, np.ones((1, 4)), window_beta=beta)
        np.testing.assert_allclose(modes.damping, ZETA, rtol=1e-10)
        np.testing.assert_allclose(res.lam, measured)
        sign = np.sign(np.real(modes.shapes[0]) * phi[0])
        np.testing.assert_allclose(modes.shapes.real * sign, phi, rtol=1e-5, atol=1e-8)

    def test_refine_recovers_perturbed_poles(self):
        frf, phi = _case()
        true = _poles()
        rough = -ZETA * 1.3 * 2 * np.pi * FN * 1.002 + 1j * true.imag * 1.002
        out = refine_poles(frf, rough, phi[[0, 3]].astype(complex))
        # exact up to the local quadratic model of the out-of-window modes
        np.testing.assert_allclose(out, true, rtol=1e-5)
        np.testing.assert_allclose(-out.real / np.abs(out), ZETA, rtol=1e-3)

    def test_figures(self, tmp_path):
        frf, phi = _case()
        modes, res = modes_from_poles(frf, _poles(), phi[[0, 3]].astype(complex))
        plot_synthesis(frf, res.synthesise(frf), path=tmp_path / "syn.png")
        plot_automac(modes, path=tmp_path / "mac.png")
        assert (tmp_path / "syn.png").stat().st_size > 10_000 and (tmp_path / "mac.png").stat().st_size > 5_000


class TestIndicators:
    def test_real_mode(self):
        v = np.array([[1.0], [-2.0], [0.5]]) * np.exp(0.7j)          # a rotated real vector
        assert mpc(v)[0] == pytest.approx(1.0)
        assert mcf(v)[0] == pytest.approx(0.0, abs=1e-12)
        assert mpd(v)[0] == pytest.approx(0.0, abs=1e-6)

    def test_complex_mode_closed_form(self):
        v = np.array([[1.0], [1j]])                                   # phases 0 and 90 deg, equal amplitude
        assert mpc(v)[0] == pytest.approx(0.0, abs=1e-12)
        assert mcf(v)[0] == pytest.approx(1.0)
        assert mpd(v)[0] == pytest.approx(45.0)
        w = np.array([[1.0], [np.exp(0.2j)]])
        # |φᵀφ|²/(φᴴφ)² = |1 + e^{0.4i}|²/4 = cos²(0.2)
        assert mpc(w)[0] == pytest.approx(np.cos(0.2) ** 2)

    def test_mov(self):
        lam = _poles()[:2]
        phi = np.array([[0.3, -0.2], [0.1, 0.4]])
        R = phi ** 2 / (2j * lam.imag)[None, :]
        np.testing.assert_allclose(mov(lam, R), [1.0, 1.0])
        np.testing.assert_allclose(mov(lam, -R), [0.0, 0.0])


class TestRefinementJacobian:
    @pytest.mark.parametrize("quantity", ["receptance", "accelerance"])
    def test_kaufman_gradient_is_exact(self, quantity):
        """J_Kaufman^T r equals the finite-difference gradient of the projected residual (A⁺r = 0)."""
        from scipy.optimize._numdiff import approx_derivative

        from identification.lsfd import _LocalProjection, _basis

        mm, _ = modal_system(np.array([40.0, 47.0, 90.0]), np.array([0.02, 0.01, 0.015]), 5, rng=1)
        f = np.linspace(30, 60, 200)
        frf = mm.frf(f, references=[mm.dofs[0], mm.dofs[2]], quantity=quantity)
        H = frf.H * (1 + 0.02 * np.random.default_rng(0).normal(size=frf.H.shape))
        q = {"receptance": 0, "accelerance": 2}[quantity]
        lam = np.array([-0.02 * 2 * np.pi * 40 + 2j * np.pi * 40.3, -0.01 * 2 * np.pi * 47 + 2j * np.pi * 47.1])
        L = np.array([[1, 0.5 + 0.2j], [0.3 - 0.1j, 1]])
        Y = H.transpose(1, 2, 0).reshape(-1, 5)
        Y = np.concatenate([Y.real, Y.imag])
        x_loc = (f - 45) / 15
        extra = np.zeros((2, f.size, 6), complex)
        for i in range(2):
            extra[i, :, 3 * i:3 * i + 3] = np.stack([np.ones_like(x_loc), x_loc, x_loc ** 2], axis=1)
        extra = extra.reshape(2 * f.size, -1)
        extra = np.concatenate([extra, 1j * extra], 1)
        extra = np.concatenate([extra.real, extra.imag], 0)
        poly = np.stack([np.ones_like(x_loc), x_loc, x_loc ** 2], axis=1)
        for k in (0, 1):
            vp = _LocalProjection(2j * np.pi * f, q, lam, L, k, poly, Y, np.linalg.norm(Y))
            x = np.array([abs(lam[k]) * 1.001, -lam[k].real / abs(lam[k]) * 1.1])
            # the segment-wise projection off the quadratics equals the dense least squares on [extra, modes]
            lam_x = lam.copy()
            lam_x[k] = vp.pole(x)
            A = np.concatenate([extra, _basis(2j * np.pi * f, q, lam_x, L, False, False)], axis=1)
            Yn = Y / np.linalg.norm(Y)
            dense = Yn - A @ np.linalg.lstsq(A, Yn, rcond=None)[0]
            np.testing.assert_allclose(vp.residual(x), dense.ravel(), atol=1e-10)
            J = vp.jacobian(x)
            Jn = approx_derivative(vp.residual, x, method="3-point")
            r = vp.residual(x)
            np.testing.assert_allclose(J.T @ r, Jn.T @ r, rtol=1e-6)


def test_contribution_equals_the_energy_of_each_mode_synthesis():
    """The closed-form modal contribution equals Σ|A g + Ā gc|² / Σ|H|² summed explicitly."""
    mm, _ = modal_system(np.array([40.0, 47.0, 90.0]), np.array([0.02, 0.01, 0.015]), 5, rng=1)
    frf = mm.frf(np.linspace(10, 120, 300), references=[mm.dofs[0], mm.dofs[2]], quantity="mobility")
    lam = -np.array([0.02, 0.01, 0.015]) * 2 * np.pi * np.array([40.0, 47.0, 90.0]) \
        + 2j * np.pi * np.array([40.0, 47.0, 90.0]) * np.sqrt(1 - np.array([0.02, 0.01, 0.015]) ** 2)
    modes, res = modes_from_poles(frf, lam, np.array([[1.0, 0.5, 0.2], [0.3, 1.0, -0.4]], complex))
    s = 2j * np.pi * frf.freq_hz
    tot = np.sum(np.abs(frf.H) ** 2)
    for r in range(3):
        g = s / (s - res.lam[r])
        gc = s / (s - res.lam[r].conj())
        Ar = res.residues[:, :, r]
        Hr = Ar[..., None] * g + Ar.conj()[..., None] * gc
        assert modes.indicators["contribution"][r] == pytest.approx(np.sum(np.abs(Hr) ** 2) / tot, rel=1e-10)


def test_many_references_structured_lsfd_equals_the_dense_solve(monkeypatch):
    """With many references the residual columns are eliminated reference by reference: same solution."""
    from identification import lsfd_linear as lsfd_mod       # where the threshold lives (lsfd re-exports the fit)
    from identification.lsfd import lsfd as lsfd_fit

    mm, _ = modal_system(np.array([40.0, 47.0, 90.0]), np.array([0.02, 0.01, 0.015]), 12, rng=3)
    frf = mm.frf(np.linspace(20, 120, 300), references=mm.dofs[:12], quantity="accelerance")
    frf = frf._replace(H=frf.H * (1 + 0.01 * np.random.default_rng(1).normal(size=frf.H.shape)))
    lam = mm.poles[:3]
    P = np.random.default_rng(2).normal(size=(12, 3)) + 1j * np.random.default_rng(3).normal(size=(12, 3))
    assert frf.n_in > lsfd_mod._DENSE_RESIDUAL_MAX_IN
    fast = lsfd_fit(frf, lam, P)
    monkeypatch.setattr(lsfd_mod, "_DENSE_RESIDUAL_MAX_IN", 100)
    dense = lsfd_fit(frf, lam, P)
    for k in ("psi", "lower", "upper"):
        a, b = getattr(fast, k), getattr(dense, k)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * np.abs(b).max())
