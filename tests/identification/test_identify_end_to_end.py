"""End-to-end identification: the acceptance case of issue 4 and the identify() entry point.

A 10-mode system with a close pair (240 Hz, ζ = 0.6 % and 247 Hz, ζ = 1.2 %), 30
outputs, 4000 lines, complex noise of 1.5 % of each FRF's RMS: every mode must be found
automatically with frequency error <= 0.1 %, damping error <= 5 %, MAC >= 0.99 and no
spurious mode, with one and with three references.
"""
import json

import numpy as np

from modalab.app.outputs import write_json
import pytest

from identification import (PolyMAX, identify, load_selection_file, mac_vectors, modal_system, noisy_frf)
from identification.synthetic import TEN_MODES_DAMPING, TEN_MODES_HZ
from modalab.core.modes import ModeSet

FREQ = np.linspace(0.25, 1000.0, 4000)


def _case(n_ref, seed, noise=0.015, quantity="accelerance"):
    mm, phi = modal_system(TEN_MODES_HZ, TEN_MODES_DAMPING, 30, rng=seed)
    refs = [mm.dofs[k] for k in (0, 11, 22)[:n_ref]]
    return noisy_frf(mm, FREQ, refs, noise=noise, quantity=quantity, rng=seed + 100), phi


def _check(modes, phi):
    assert modes.n_modes == TEN_MODES_HZ.size, f"found {np.round(modes.freq_hz, 2)}"
    ferr = np.abs(modes.freq_hz / TEN_MODES_HZ - 1)
    zerr = np.abs(modes.damping / TEN_MODES_DAMPING - 1)
    mac = np.diag(mac_vectors(modes.shapes, phi))
    assert ferr.max() <= 1e-3, ferr
    assert zerr.max() <= 0.05, zerr
    assert mac.min() >= 0.99, mac


@pytest.mark.parametrize("seed", [0, 1])
def test_ten_modes_single_reference(seed):
    frf, phi = _case(1, seed)
    modes, report = identify(frf, max_order=100)
    _check(modes, phi)
    # the close pair comes out as two modes with their own damping
    pair = modes.select_modes((modes.freq_hz > 235) & (modes.freq_hz < 250))
    assert pair.n_modes == 2 and pair.damping[1] > 1.5 * pair.damping[0]
    # driving point present: unit modal mass shapes (real approximation equals the true shapes up to sign)
    assert modes.scaling == "unit_modal_mass"
    rs = modes.real_shapes
    ratio = np.abs(np.sum(rs * phi, axis=0) / np.sum(phi * phi, axis=0))
    # the scale comes from one driving point: its accuracy follows |φ_dp| (small for some modes here)
    np.testing.assert_allclose(ratio, 1.0, atol=0.1)
    strong = np.abs(phi[0]) > 0.1
    np.testing.assert_allclose(ratio[strong], 1.0, atol=0.02)
    assert np.all(report.frf_correlation > 0.99)


@pytest.mark.parametrize("seed", [0, 3])
def test_ten_modes_three_references(seed):
    frf, phi = _case(3, seed)
    modes, report = identify(frf, max_order=40)
    _check(modes, phi)
    # participation on the references: A_r = φ_r L_rᵀ with L_r = Q_r φ_r(references), Q_r = 1/(2iω_d)
    lam = modes.poles
    Lexp = modes.shapes[[0, 11, 22]] / (2j * lam.imag)[None, :]
    np.testing.assert_allclose(modes.participation, Lexp, rtol=0.05, atol=0.02 * np.abs(Lexp).max())
    assert modes.participation.shape == (3, 10)
    assert np.all(modes.indicators["MPC"] > 0.99)
    assert np.all(modes.indicators["MPD"] < 5.0)
    assert np.all(modes.indicators["MOV"] > 0.9)


@pytest.mark.parametrize("quantity", ["receptance", "mobility"])
def test_other_quantities_same_modes(quantity):
    frf, phi = _case(3, 5, quantity=quantity)
    modes, _ = identify(frf, max_order=40)
    _check(modes, phi)


def test_exponential_window_correction():
    """FRFs of a windowed response (poles moved by −β) identify the structure's damping after correction."""
    beta = 4.0                                                    # 1/s, adds ~ β/ω to each damping ratio
    mm, phi = modal_system(TEN_MODES_HZ, TEN_MODES_DAMPING, 30, rng=7, window_beta=beta)
    frf = noisy_frf(mm, FREQ, [mm.dofs[0], mm.dofs[11], mm.dofs[22]], noise=0.01, rng=8)
    raw, _ = identify(frf, max_order=40, window_correction=False)
    frf.window_beta_per_s = beta
    corrected, rep = identify(frf, max_order=40)
    assert corrected.metadata["window_beta_per_s"] == beta
    assert rep.settings["window_correction"] == {"beta_per_s": beta, "source": "file"}
    # the same correction from the option when the FRF carries no beta
    by_option, rep2 = identify(frf._replace(window_beta_per_s=0.0), max_order=40, exp_beta=beta)
    np.testing.assert_array_equal(by_option.damping, corrected.damping)
    assert rep2.settings["window_correction"]["source"] == "option"
    _check(corrected, phi)
    # without the correction the low modes look far more damped (ζ + β/ω_n)
    added = beta / (2 * np.pi * TEN_MODES_HZ)
    np.testing.assert_allclose(raw.damping - corrected.damping, added, rtol=0.05)


def test_manual_selection_and_outputs(tmp_path):
    frf, phi = _case(3, 2)
    sel = tmp_path / "sel.toml"
    sel.write_text("freq_hz = [95.2, 240.3, 246.8, 702]\n")
    assert load_selection_file(sel) == [95.2, 240.3, 246.8, 702.0]
    modes, report = identify(frf, max_order=40, select=sel, plots_dir=tmp_path / "plots", band_hz=(20, 1000))
    np.testing.assert_allclose(modes.freq_hz, [95, 240, 247, 702], rtol=1e-3)
    for name in ("stabilisation", "synthesis", "automac"):
        assert report.figures[name].exists() and report.figures[name].stat().st_size > 10_000
    # JSON outputs round-trip
    modes.to_json(tmp_path / "modes.json")
    back = ModeSet.from_json(tmp_path / "modes.json")
    np.testing.assert_allclose(back.shapes, modes.shapes)
    d = json.loads(write_json(tmp_path / "report.json", report.to_dict()).read_text())   # the stage's writer
    assert d["selected"]["source"] == "manual" and d["settings"]["max_order"] == 40
    # a JSON list works as well, and an explicit list gives the same modes
    (tmp_path / "sel.json").write_text("[95.2, 240.3, 246.8, 702]")
    m2, _ = identify(frf, max_order=40, select=tmp_path / "sel.json", band_hz=(20, 1000))
    m3, _ = identify(frf, max_order=40, select=[95.2, 240.3, 246.8, 702], band_hz=(20, 1000))
    np.testing.assert_allclose(m2.freq_hz, m3.freq_hz)


def test_references_subset_and_estimator_attributes():
    frf, phi = _case(3, 4)
    modes, report = identify(frf, max_order=60, references=["12+Z"], band_hz=(300, 1000))
    assert [str(r) for r in modes.references] == ["12+Z"] and report.settings["references"] == ["12+Z"]
    np.testing.assert_allclose(modes.freq_hz, TEN_MODES_HZ[5:], rtol=1e-3)
    pm = PolyMAX(max_order=30).fit(frf)
    assert pm.orders_.tolist() == list(range(1, 31))
    assert len(pm.poles_) == len(pm.participation_) == 30
    assert pm.reduced_matrix_shape_ == (31 * 3, 31 * 3)
    assert pm.participation_[-1].shape[0] == 3


def test_simulated_lab_hammer_test_with_exponential_window():
    """Full foundation chain: simulated roving-hammer hits → H1 with an exponential window →
    reciprocity (transpose) → identify.  The damping of the structure comes back after the
    window correction; without it every mode looks more damped by β/ω_n."""
    from acquisition.spectral import estimate_frf_roving
    from acquisition.windows import ExponentialWindow
    from hardware_sim.demo import demo_lab
    from hardware_sim.lab import simulate_roving_test

    lab = demo_lab(rng=1)
    recs = simulate_roving_test(lab, ["19+Z", "12+Z", "1+Z", "4+Z", "7+Z", "14+Z"], hits_per_point=3)
    frf = estimate_frf_roving(recs, exp_window=ExponentialWindow(end_level=0.05)).transpose()
    beta = frf.window_beta_per_s
    assert beta > 0.5
    # the demo structure's modal damping (hardware_sim.demo.demo_structure, viscous)
    w, _ = lab.structure.normal_modes(12)
    f = w / (2 * np.pi)
    f = f[(f > 10) & (f < 120)]
    zeta = np.minimum(0.005 + 0.01 * f / 1000.0, 0.02)
    modes, _ = identify(frf, band_hz=(10, 120), max_order=40)
    np.testing.assert_allclose(modes.freq_hz, f, rtol=1e-3)
    np.testing.assert_allclose(modes.damping, zeta, rtol=0.05)
    raw, _ = identify(frf, band_hz=(10, 120), max_order=40, window_correction=False)
    np.testing.assert_allclose(raw.damping - zeta, beta / (2 * np.pi * f), rtol=0.1)
