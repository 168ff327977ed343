"""Selection and acceptance of a term (issue 13): the exact FRF screening's picks judged on the FRFs, the
Woodbury update of the screening at singular values, candidates that cannot be evaluated named.

Own synthetic case (not a benchmark case): a free-free 3-D beam of ten elements, truth = nominal + a spring to
ground across the beam (4+Y, 2e4 N/m: a new mode at 36 Hz, the second bending mode in Y moved by 1.4 %), the
spring's DOF not measured, 0.3 % complex noise.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

from modalab.core.frf import FRF
from updating.diagnosis import findings
from updating.diagnosis import workflow as wf
from updating.diagnosis.frfscreen import _singular, _updated_errors
from updating.fe import Spring
from updating.fe.models.beams import beam_model

RESP = [f"{i}+Z" for i in (1, 3, 5, 6, 8, 11)] + [f"{i}+Y" for i in (1, 6, 9, 11)]


def _case(spring: bool):
    nominal = beam_model(10, length=1.0, kind="beam3d", bc="free")
    nominal.global_ge = 0.01
    truth = nominal.copy()
    if spring:
        truth.add_element(Spring(9001, a=(4, 2), b=None, k=2e4))
    return nominal, measured(truth, np.linspace(5, 900, 600), RESP, ["11+Y", "11+Z"], seed=1)


def measured(truth, f, responses, references, seed: int) -> FRF:
    """The receptance FRFs of ``truth`` at ``f`` with 0.3 % complex noise (seeded) and coherence 0.999."""
    H = truth.frf(f, responses, references, quantity="receptance")
    rng = np.random.default_rng(seed)
    Hn = H.H * (1 + 0.003 * (rng.standard_normal(H.H.shape) + 1j * rng.standard_normal(H.H.shape)) / np.sqrt(2))
    return FRF(freq_hz=f, H=Hn, responses=H.responses, references=H.references,
               coherence=np.full(H.H.shape, 0.999), quantity="receptance")


def _judge_picks(spring: bool):
    nominal, meas = _case(spring)
    d = wf.Diagnoser(wf.DiagnoserConfig(max_lines=80, progress=lambda m: None))
    d._t0, d.timings = time.perf_counter(), {}
    d.baseline(nominal, meas)
    d.localise()
    d._options(0)
    return d, d._judge_picks(0, 1)


def test_the_screening_pick_is_judged_on_the_frfs_and_named():
    d, picked = _judge_picks(True)
    assert picked is not None
    c, alts = picked
    assert c.physics == "ground_spring" and c.dofs == ("4+Y",), c.label
    assert d.pm_cur.parameter_names[-1].startswith("k_4_2")
    # the state follows the FRF fit: the spring's value is the truth's, the error at the noise
    pm, fr = d._frf_cur
    assert fr.p[-1] == pytest.approx(2e4, rel=0.05)
    assert fr.error < 0.2 * d.upd.error
    assert np.array_equal(d.p_cur, fr.p)


def test_no_pick_passes_on_data_from_the_nominal():
    d, picked = _judge_picks(False)
    assert picked is None
    assert d.current == []


def test_the_rank_r_update_is_woodbury_and_infinite_where_singular():
    rng = np.random.default_rng(0)
    n_m, n_r, r, n_s = 3, 2, 2, 4
    c = lambda *sh: rng.standard_normal(sh) + 1j * rng.standard_normal(sh)  # noqa: E731
    Hm, Hr, H0, H = c(n_m, r, n_s), c(r, n_r, n_s), c(n_m, n_r, n_s), c(n_m, n_r, n_s)
    Hll = c(r, r, n_s)
    sign, w, den2 = np.ones((n_m, n_r, 1)), np.ones((n_m, n_r, n_s)), np.ones((n_m, n_r, n_s))
    inv = c(2, n_s)
    got = _updated_errors(inv, Hll, Hm, Hr, H0, sign, H, w, den2, float(w.sum()))
    for t in range(2):
        dH = np.stack([Hm[:, :, f] @ np.linalg.inv(inv[t, f] * np.eye(r) + Hll[:, :, f]) @ Hr[:, :, f]
                       for f in range(n_s)], axis=-1)
        want = np.sqrt(np.sum(np.abs(H0 - dH - H) ** 2) / w.sum())
        assert got[t] == pytest.approx(want, rel=1e-10)
    # a value making the r × r system singular at one line: the updated model is unbounded there
    Hll[:, :, 2] = np.array([[1.0, 1.0], [1.0, 1.0]])
    inv[0, 2] = 0.0
    got = _updated_errors(inv, Hll, Hm, Hr, H0, sign, H, w, den2, float(w.sum()))
    assert got[0] == np.inf and np.isfinite(got[1])


def test_an_update_is_infinite_exactly_where_its_system_is_singular():
    """The singularity test (a determinant bound before the SVD per line) gives the condition number's verdicts."""
    rng = np.random.default_rng(1)
    n_m, n_r, n_s = 3, 2, 5
    c = lambda *sh: rng.standard_normal(sh) + 1j * rng.standard_normal(sh)  # noqa: E731
    Hm, Hr, H0, H, Hll, inv = c(n_m, 1, n_s), c(1, n_r, n_s), c(n_m, n_r, n_s), c(n_m, n_r, n_s), c(1, 1, n_s), c(3, n_s)
    sign, w, den2 = np.ones((n_m, n_r, 1)), np.ones((n_m, n_r, n_s)), np.ones((n_m, n_r, n_s))
    inv[0, 3] = -Hll[0, 0, 3]                       # 1/(θ f) + H_ll = 0 at one line: unbounded there
    inv[1, 1] = -Hll[0, 0, 1] * (1 + 1e-12)         # nearly, not exactly: finite
    got = _updated_errors(inv, Hll, Hm, Hr, H0, sign, H, w, den2, float(w.sum()))
    assert got[0] == np.inf and np.isfinite(got[1:]).all()
    for t in (1, 2):
        dH = np.einsum("mf,rf->mrf", Hm[:, 0], Hr[0]) / (inv[t] + Hll[0, 0])
        want = np.sqrt(np.sum(np.abs(H0 - dH - H) ** 2) / w.sum())
        assert got[t] == pytest.approx(want, rel=1e-9)
    A = (inv[:, :, None, None] + Hll[0, 0][None, :, None, None])
    assert np.array_equal(_singular(A), ~(np.linalg.cond(A) < 1 / np.finfo(float).eps))
    for r in (2, 3, 6):                 # exactly, nearly and far from singular, and tiny but regular
        A = c(8, 20, r, r)
        A[0, 0, 0] = A[0, 0, 1]
        A[1, 1, 0] = A[1, 1, 1] + 1e-17 * c(r)
        A[2, 2, 0] = A[2, 2, 1] + 1e-14 * c(r)
        A[3, 3, 0] = A[3, 3, 1] + 1e-10 * c(r)
        A[4, 4] *= 1e-200
        A[5, 5] = 0.0
        want = ~(np.linalg.cond(A) < 1 / np.finfo(float).eps)
        assert want[0, 0] and want[5, 5] and not want[3, 3] and not want[4, 4]
        assert np.array_equal(_singular(A), want)


def test_candidates_not_evaluated_are_named_in_the_statement():
    fit = {k: {"frf_error_held_out": 0.1} for k in ("nominal", "parameters_only", "with_physics")}
    ne = [{"candidate": "spring to ground at 3+Z", "physics": "ground_spring", "reason": "Singular matrix"}]
    s = findings.statement([], fit, "response DOFs 3+Z", ne)
    assert "1 candidate(s) could not be evaluated" in s and "spring to ground at 3+Z" in s
    assert "could not be evaluated" not in findings.statement([], fit, "response DOFs 3+Z")


def test_verdicts_are_said_and_kept_for_diagnosis_json():
    said = []
    d, picked = _judge_picks(True)
    d.config = wf.DiagnoserConfig(max_lines=80, progress=said.append)
    c, _ = picked
    d._decide("rejected", c, "held-out error up")
    assert d.decisions[-1] == {"decision": "rejected", "candidate": c.label, "physics": "ground_spring",
                               "reason": "held-out error up"}
    assert said[-1] == f"  rejected: {c.label} (held-out error up)"      # the progress line as before
    doc = findings.Diagnosis(findings=[], parameters={}, fit={}, statement="", model=None,
                       decisions=list(d.decisions)).to_dict()
    assert doc["decisions"][-1]["reason"] == "held-out error up"
