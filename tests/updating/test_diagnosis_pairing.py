"""The pairing behind the diagnosis' fit blocks (issue 13, failure 3; issue 14 #1): rigid-body and
suspension modes are left out on purpose, a pair needs a MAC and a frequency window."""
from __future__ import annotations

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
