"""Property: pLSCF recovers the poles of synthetic systems (random modes, references, quantity)."""
import numpy as np
from hypothesis import given, settings, strategies as st

from identification import PolyMAX, modal_system


@st.composite
def systems(draw):
    n = draw(st.integers(1, 3))
    # well separated frequencies (>= 8 % apart) between 20 and 400 Hz
    gaps = draw(st.lists(st.floats(0.08, 0.8), min_size=n, max_size=n))
    f0 = draw(st.floats(20.0, 60.0))
    fn = f0 * np.cumprod(1 + np.array(gaps))
    zeta = np.array(draw(st.lists(st.floats(0.002, 0.05), min_size=n, max_size=n)))
    n_ref = draw(st.integers(1, 2))
    quantity = draw(st.sampled_from(["receptance", "mobility", "accelerance"]))
    seed = draw(st.integers(0, 2 ** 16))
    return fn, zeta, n_ref, quantity, seed


@settings(max_examples=12, deadline=None)
@given(systems())
def test_polymax_recovers_synthetic_poles(case):
    fn, zeta, n_ref, quantity, seed = case
    mm, phi = modal_system(fn, zeta, 4, rng=seed)
    # keep every mode observable from the references
    phi[:n_ref] = np.sign(phi[:n_ref]) * np.maximum(np.abs(phi[:n_ref]), 0.2)
    mm, _ = modal_system(fn, zeta, 4, shapes=phi)
    f = np.linspace(fn[0] / 4, fn[-1] * 1.3, 1500)
    frf = mm.frf(f, references=[mm.dofs[k] for k in range(n_ref)], quantity=quantity)
    pm = PolyMAX(max_order=24 // n_ref, refine=False).fit(frf)
    lam = pm.poles_[-1]
    true = -zeta * 2 * np.pi * fn + 1j * 2 * np.pi * fn * np.sqrt(1 - zeta ** 2)
    for t in true:
        k = np.argmin(np.abs(lam - t))
        assert abs(lam[k] - t) / abs(t) < 1e-4          # z-domain model of finite order
        assert abs(lam[k].real - t.real) / abs(t.real) < 1e-2
    # automatic selection finds exactly the true modes on noise-free data
    np.testing.assert_allclose(pm.modes_.freq_hz, fn, rtol=1e-4)
