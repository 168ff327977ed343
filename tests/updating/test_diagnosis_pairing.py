"""The pairing behind the diagnosis' fit blocks (issue 13, failure 3; issue 14 #1): rigid-body and
suspension modes are left out on purpose, a pair needs a MAC and a frequency window."""
from __future__ import annotations

import pathlib

import numpy as np

from modalab.core.modes import ModeSet
from updating.correlation.metrics import analysis_modes
from updating.diagnosis.testmodes import _mode_metrics, _rigid_fraction, pair_test_modes
from updating.fe.models.garteur import garteur_model


def _z_modes(structure, n):
    tm = analysis_modes(structure, n)
    return tm.select_dofs([str(d) for d in structure.dofs if d.axis == 3][::3])


def test_rigid_fraction_separates_rigid_body_from_elastic_modes():
    st = garteur_model(suspension=False).structure()
    w, phi = st.normal_modes(10)
    frac = _rigid_fraction(st, phi)
    assert np.all(frac[:6] > 0.99) and np.all(frac[6:] < 0.5)


def test_suspension_modes_of_the_test_are_not_paired_with_rigid_body_modes():
    free = garteur_model(suspension=False).structure()
    tm = _z_modes(garteur_model(suspension=True).structure(), 16)
    p = pair_test_modes(free, tm)
    assert len(p["excluded_model_hz"]) == 6 and max(p["excluded_model_hz"]) < 0.01
    assert len(p["excluded_test_hz"]) >= 4 and max(p["excluded_test_hz"]) < 1.0
    m = _mode_metrics(free, tm)
    assert m["freq_error_max_pct"] < 5 and m["mac_min"] > 0.95 and m["n_pairs"] >= 9


def test_a_far_mode_is_unpaired_not_paired():
    st = garteur_model(suspension=True).structure()
    tm = _z_modes(st, 16)
    # the test's 8th mode moved to 3x its frequency: same shape, no partner within the window
    f = np.array(tm.freq_hz, float)
    f[8] *= 3.0
    moved = ModeSet(freq_hz=f, shapes=tm.shapes, dofs=tm.dofs)
    p = pair_test_modes(st, moved)
    assert 8 not in {t for _, t in p["pairs"]}
    assert max(abs(e) for e in p["freq_error_pct"]) < 1.0
    assert f[8] in p["unpaired_test_hz"]


def test_fit_block_metrics_are_numbers():
    """The fit blocks hold numbers only (the report tabulates them); the mode lists go to 'pairing'."""
    free = garteur_model(suspension=False).structure()
    m = _mode_metrics(free, _z_modes(garteur_model(suspension=True).structure(), 16))
    assert all(isinstance(v, (int, float)) for v in m.values()), m


CHAIN = pathlib.Path(__file__).resolve().parents[1] / "data" / "chain3.bdf"


def test_a_mode_on_modelled_supports_is_paired_not_left_out():
    """A mass chain on a ground spring (fresh user, issue 14): its first mode (12.5 Hz) moves the chain almost
    rigidly, but on a spring the model has: it is a mode of the structure, paired like the others (it was left
    out as 'suspension' below a 15.6 Hz cutoff, and the fit metrics ignored it)."""
    from updating.fe.bulk import build_model, read_bdf

    st = build_model(read_bdf(CHAIN)).structure()
    tm = analysis_modes(st, 3)
    assert 12.0 < tm.freq_hz[0] < 13.0 and _rigid_fraction(st, np.asarray(tm.shapes))[0] > 0.9
    p = pair_test_modes(st, tm)
    assert p["excluded_model_hz"] == [] and p["excluded_test_hz"] == [] and p["cutoff_hz"] == 0.0
    assert sorted(t for _, t in p["pairs"]) == [0, 1, 2] and max(abs(e) for e in p["freq_error_pct"]) < 1e-6
