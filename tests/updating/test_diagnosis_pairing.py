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


CONTROL = pathlib.Path(__file__).resolve().parents[2] / "examples" / "concealed" / "bar_control"


def test_a_diagnosis_says_a_test_mode_without_partner_once_not_once_per_fit_block(caplog):
    """The concealed set's control case with a test mode no model has (the first mode's shape at 5x the highest
    frequency): the proof pairs each of the three fit blocks (and the overlays pair again), and the note that
    the mode has no partner was logged by the pairing each time, 8 times in all; now once, naming the blocks.
    The one-line summary of the candidate library was logged twice (the observability check builds it too)."""
    from modalab.core import uff
    from updating.diagnosis import diagnose
    from updating.diagnosis.testmodes import peak_modes
    from updating.fe.bulk import build_model, read_bdf

    model = build_model(read_bdf(CONTROL / "nominal.bdf"))
    frf = uff.read_frf(CONTROL / "measured.uff")
    pk = peak_modes(frf)
    S = np.asarray(pk.shapes)
    far = 5 * float(np.max(pk.freq_hz))
    tm = ModeSet(freq_hz=[*pk.freq_hz, far], shapes=np.column_stack([S, S[:, 0]]), dofs=pk.dofs)
    with caplog.at_level("INFO"):
        d = diagnose(model, frf, test_modes=tm)
    said = [r.getMessage() for r in caplog.records if "partner" in r.getMessage()]
    assert len(said) == 1, said
    assert sum(r.getMessage().startswith("candidate library") for r in caplog.records) == 1
    assert "fit blocks nominal, parameters_only and with_physics" in said[0], said
    assert f"{tm.n_modes} ({far:.4g} Hz)" in said[0], said
    for block in ("nominal", "parameters_only", "with_physics"):
        assert far in d.pairing[block]["unpaired_test_hz"]
        assert d.fit[block]["n_unpaired_test"] >= 1


def test_fit_blocks_that_leave_out_different_modes_are_said_apart(caplog):
    """Blocks that differ in which test modes they leave out get one line each (the reasons of the last)."""
    from updating.diagnosis.testmodes import say_unpaired

    st = garteur_model(suspension=True).structure()
    tm = _z_modes(st, 16)
    f = np.array(tm.freq_hz, float)
    f[8] *= 3.0
    moved = ModeSet(freq_hz=f, shapes=tm.shapes, dofs=tm.dofs)
    same, far = pair_test_modes(st, tm), pair_test_modes(st, moved)
    assert same["unpaired_reason"] == {} and list(far["unpaired_reason"]) == [8]
    with caplog.at_level("INFO", logger="updating.diagnosis.testmodes"):
        say_unpaired({"nominal": far, "parameters_only": far, "with_physics": same}, moved)
        say_unpaired({"nominal": far, "parameters_only": same, "with_physics": far}, moved)
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 2, said
    assert said[0].startswith("test modes without a model partner in the fit blocks nominal and parameters_only: "
                              f"9 ({f[8]:.4g} Hz): "), said
    assert "fit blocks nominal and with_physics: 9" in said[1], said
