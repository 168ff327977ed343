"""A free model of a test article hung on soft cords: the suspension's lines are left out of the fits; local
damping is fitted at several distinct places of the screening (issue 13).

Own synthetic cases (not benchmark cases): a free-free 2-D aluminium beam of ten elements (first elastic mode
about 100 Hz), measured on a suspension of two soft springs (suspension modes about 2-3 Hz) or truly free.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

from modalab.core.frf import FRF
from updating.correlation.metrics import analysis_modes
from updating.diagnosis import terms, testmodes
from updating.diagnosis import workflow as wf
from updating.diagnosis.library import Candidate
from updating.fe import Spring
from updating.fe.models.beams import beam_model

RESP = [f"{i}+Z" for i in (1, 3, 5, 7, 9, 11)]


def _measured(model, f):
    H = model.frf(f, RESP, ["11+Z"], quantity="receptance")
    return FRF(freq_hz=f, H=H.H, responses=H.responses, references=H.references,
               coherence=np.full(H.H.shape, 0.999), quantity="receptance")


def _nominal():
    m = beam_model(10, length=1.0, bc="free")
    m.global_ge = 0.01
    return m


def _suspended(nominal, k=60.0):
    truth = nominal.copy()
    for eid, node in ((9001, 1), (9002, 11)):
        truth.add_element(Spring(eid, a=(node, 3), b=None, k=k))
    return truth


def test_a_suspension_is_detected_and_its_lines_left_out():
    nominal = _nominal()
    f = np.linspace(0.25, 600, 1200)
    st = nominal.structure()
    f1 = float(analysis_modes(st, 8).freq_hz[2])          # two rigid-body modes in the plane, then bending
    cut = testmodes.suspension_band(st, _measured(_suspended(nominal), f))
    assert cut == pytest.approx(testmodes.SUSPENSION_RATIO * f1, rel=1e-6)
    # the same free beam measured truly free: nothing to leave out
    assert testmodes.suspension_band(st, _measured(nominal, f)) is None
    # a clamped model carries its support: never a suspension, whatever the data
    clamped = beam_model(10, length=1.0, bc="cantilever")
    assert testmodes.suspension_band(clamped.structure(), _measured(_suspended(nominal), f)) is None
    # the diagnosis fits only the lines above the suspension band and says so in its steps
    d = wf.Diagnoser(wf.DiagnoserConfig(max_lines=60, max_nfev=4, progress=lambda m: None))
    d._t0, d.timings = time.perf_counter(), {}
    d.baseline(nominal, _measured(_suspended(nominal), f))
    assert d.suspension_hz == pytest.approx(cut)
    assert d.data.freq_hz.min() >= cut and d.train.freq_hz.min() >= cut


def test_a_suspension_the_line_spacing_does_not_resolve_is_detected():
    """The suspension's two modes (bounce and pitch) both fall between the first two lines: the receptance,
    falling as 1/ω⁴ in power, has its maximum at the first line and no peak; the accelerance, flat on the free
    beam's mass line, rises from the first line to the second and peaks there (held-out 3173's cords at
    0.51-2.2 Hz, lines 0.365 Hz apart)."""
    nominal = _nominal()
    st = nominal.structure()
    truth = _suspended(nominal, k=0.6)                    # bounce and pitch at 0.24 and 0.41 Hz
    fa = analysis_modes(truth.structure(), 8).freq_hz
    f_bounce, f_pitch, f1 = float(fa[0]), float(fa[1]), float(analysis_modes(st, 8).freq_hz[2])
    df = 0.5 * (0.5 * f_pitch + f_bounce)               # f_pitch / 2 < df < f_bounce
    f = np.arange(1, 1 + int(600 / df)) * df
    assert f[0] < f_bounce < f_pitch < f[1]
    meas = _measured(truth, f)
    P = np.sum(np.abs(meas.H[:, :, f <= 0.1 * f1]) ** 2, axis=(0, 1))
    assert np.argmax(P) == 0                             # the receptance alone: no peak to find
    assert testmodes.suspension_band(st, meas) == pytest.approx(testmodes.SUSPENSION_RATIO * f1, rel=1e-6)
    # the same lines on the beam measured truly free: nothing to leave out
    assert testmodes.suspension_band(st, _measured(nominal, f)) is None


def test_a_stiff_support_is_not_a_suspension():
    nominal = _nominal()
    f = np.linspace(0.25, 600, 1200)
    # 30 times stiffer: the support's modes at about a quarter of the first elastic frequency (not a suspension)
    st = nominal.structure()
    f1 = float(analysis_modes(st, 8).freq_hz[2])
    meas = _measured(_suspended(nominal, k=1800.0), f)
    assert testmodes.suspension_band(st, meas) is None
    # ... whose resonance the data do show, between a tenth and a half of the first elastic frequency
    P = np.sum(np.abs(meas.H) ** 2, axis=(0, 1))
    band = (f > 0.1 * f1) & (f < 0.5 * f1)
    assert P[band].max() > 10 * P[band].min()


def _cand(nodes, key):
    return Candidate("local_damping", key, tuple(nodes), (), (), "eta", "-", "D", True, key=key)


def test_damping_places_are_distinct():
    ranked = [(_cand((5, 6), "a"), 0.1, 0.3), (_cand((6, 7), "b"), 0.1, 0.25), (_cand((4, 5, 6), "c"), 0.1, 0.2),
              (_cand((9, 10), "d"), 0.1, 0.1), (_cand((10, 11), "e"), 0.1, 0.05), (_cand((1, 2), "f"), 0.1, 0.01)]
    got = [c.key for c, _, _ in terms._distinct_places(ranked, 3)]
    assert got == ["a", "d", "f"]
    assert [c.key for c, _, _ in terms._distinct_places(ranked, 1)] == ["a"]


def test_no_dashpot_to_ground_on_a_suspended_free_model():
    nominal = _nominal()
    f = np.linspace(0.25, 600, 1200)
    out = {}
    for name, truth in (("suspended", _suspended(nominal)), ("free", nominal)):
        d = wf.Diagnoser(wf.DiagnoserConfig(max_lines=60, max_nfev=4, progress=lambda m: None))
        d._t0, d.timings = time.perf_counter(), {}
        d.baseline(nominal, _measured(truth, f))
        lib = d._library(nominal)
        out[name] = {c.matrix for c in lib if c.physics == "local_damping"}
    assert out["free"] == {"C", "D"}            # a truly free test: dashpots to ground stay candidates
    assert out["suspended"] == {"D"}             # on its suspension: the grounded dissipation is the suspension's
