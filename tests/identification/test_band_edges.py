"""A resonance that an edge of the analysis band cuts (issue 14 audit: the README's --band 5 700 cut the
demo's 695.5 Hz mode; it was not identified, and the 678 Hz mode beside it came out flagged as a merged pair)."""
import numpy as np
import pytest

from identification import edge_resonances, modal_system, noisy_frf


@pytest.fixture(scope="module")
def frf():
    model, _ = modal_system([40.0, 120.0, 197.0], 0.01, n_dof=6, rng=3)
    return noisy_frf(model, np.arange(0, 256, 0.25), references=model.dofs[:2], rng=4, noise=0.01)


def test_a_resonance_at_the_upper_edge_is_found_with_a_band_that_clears_it(frf):
    cut = edge_resonances(frf.freq_hz, frf.H, (5.0, 200.0))
    assert len(cut) == 1
    r = cut[0]
    assert r["edge"] == "upper" and r["edge_hz"] == 200.0 and abs(r["freq_hz"] - 197.0) <= 0.5
    # half-power width of a 1 % damped mode: 2 zeta f = 3.9 Hz
    assert r["width_hz"] == pytest.approx(2 * 0.01 * 197.0, rel=0.15)
    assert r["suggest_hz"] >= 197.0 + 3 * r["width_hz"] and r["suggest_hz"] <= frf.freq_hz[-1]
    assert edge_resonances(frf.freq_hz, frf.H, (5.0, r["suggest_hz"])) == []


def test_a_resonance_at_the_lower_edge_inside_or_outside_the_band(frf):
    for lo in (39.6, 40.4):                         # the 40 Hz peak (width 0.8 Hz) just outside, just inside
        cut = edge_resonances(frf.freq_hz, frf.H, (lo, 150.0))
        assert [(r["edge"], round(r["freq_hz"])) for r in cut] == [("lower", 40)], (lo, cut)
        assert cut[0]["suggest_hz"] < 40.0 - 3 * cut[0]["width_hz"] + 1e-9


def test_bands_whose_edges_lie_between_resonances_cut_nothing(frf):
    for band in ((5.0, 150.0), (20.0, 220.0), (60.0, 180.0), (45.0, 100.0)):
        assert edge_resonances(frf.freq_hz, frf.H, band) == [], band
